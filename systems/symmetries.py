"""Noether's theorem beyond cyclic coordinates: the charges of continuous symmetries.

A generator xi(q, t), one component per coordinate, moves a configuration by
q -> q + eps xi. Along a motion its charge Q = sum_i p_i xi_i changes at the rate

    dQ/dt = sum_i (dL/dq_i + Q_i) xi_i + sum_i p_i (sum_j dxi_i/dq_j qdot_j + dxi_i/dt),

by Lagrange's equations dp_i/dt = dL/dq_i + Q_i (Q_i the generalized forces of the
enabled effects). The terms without Q_i are the change of L along xi, the others the work
of the effects along xi: Q is conserved exactly when L is invariant and the effects do no
work along xi (Noether's theorem for a point symmetry). The force lambda grad f of a
holonomic constraint f(q, t) = 0 does none when grad f . xi = 0, which is required
identically. For a scene given by H alone the same rate is {Q, H} + sum_i Q_i xi_i,
formed from Hamilton's equations. The rate is tested to vanish identically at random
real states (coordinates and velocities of both signs), against the size of its terms: a
charge is only reported when it is conserved, and a state where something cannot be
evaluated never counts for it.

The candidate generators:

- scenes with ``[particles]``: the rotations of the whole space about z (and x, y in
  three dimensions) and its translations along x, y (z). Each moves every particle by
  dr_i = omega x r_i or by a unit vector; the generator in q solves (dr_i/dq) xi = dr_i
  for all particles at once. Numerically at random states first: a solution that is the
  same number everywhere is taken as that (small) rational number (a polar angle: 1);
  otherwise, where the particles' mass matrix is diagonal (Cartesian positions), the
  mass-weighted solution xi_j = sum_i m_i dr_i/dq_j . dr_i / M_jj is kept symbolically
  (x: -y, y: x; in a rotating frame a translation turns with time, cos(w t) and
  -sin(w t), and dxi/dt takes part in dQ/dt). The solution is then checked to move
  every particle exactly as the rotation or translation does; a motion that leaves the
  configuration space (the rotation of a bead on a driven hoop, a rotation of masses
  that can only slide along x) has no generator;
- scenes without particles: coordinates named ``x``, ``y``, ``z`` with a common suffix
  per body (``x1, y1, x2, y2`` or ``x_a, y_a``) are the bodies' Cartesian positions, and
  the same rotations and translations act on them (rotations about x and y, and
  translations along z, only when every body has a z);
- the user's generators of ``[symmetries]`` (``Scene.symmetries``).

The charges are named ``L_x``, ``L_y``, ``L_z`` (angular momentum about an axis),
``P_x``, ``P_y``, ``P_z`` (total linear momentum) and by the user's names. A charge whose
generator is a constant combination of those already listed (a cyclic coordinate's
p_q: in planetary motion L_z is p_theta) is not listed again.
"""

from __future__ import annotations

import random
import re
import weakref
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from fractions import Fraction
from typing import TYPE_CHECKING

import numpy as np
import sympy

from systems.calculus import Calculus
from systems.expressions import as_expr

try:
    import symengine
except ImportError:  # pragma: no cover - a dependency; sympy's lambdify is only slower
    symengine = None

if TYPE_CHECKING:
    from systems.mechanics import Mechanics
    from systems.scene import Scene

AXES = ("x", "y", "z")
ROTATIONS = ("L_x", "L_y", "L_z")
TRANSLATIONS = ("P_x", "P_y", "P_z")
ENERGY = "E"
"""The name under which ``Mechanics.conserved`` lists the energy of a Lagrangian whose t
is a total time derivative (``systems.classification.gauge_energy``)."""
RESERVED = frozenset({"H", ENERGY, *ROTATIONS, *TRANSLATIONS})
"""Charge names a ``[symmetries]`` entry may not take (nor any ``p_<...>``)."""

TOLERANCE = 1e-9
"""Relative size, against the sum of the magnitudes of its terms, below which dQ/dt
(or a residual of the generator's equations) counts as zero."""
SAMPLES = 6
ATTEMPTS = 40
"""Random states tried to find ``SAMPLES`` where everything evaluates to real numbers."""
_BODY = re.compile(r"^([xyz])(.*)$")


@dataclass(frozen=True)
class Generator:
    """A candidate symmetry q -> q + eps xi.

    Attributes
    ----------
    name : str
        The charge's name: ``L_x`` ... ``P_z``, or a ``[symmetries]`` key.
    xi : tuple of sympy.Expr, shape (n,)
        One component per coordinate, in the coordinates, t and the parameters.
    kind : str
        ``"rotation"``, ``"translation"`` or ``"given"`` (from ``[symmetries]``).
    """

    name: str
    xi: tuple[sympy.Expr, ...]
    kind: str


@dataclass(frozen=True)
class Charge:
    """A conserved Noether charge.

    Attributes
    ----------
    name : str
    generator : Generator
    phase : sympy.Expr
        Q = sum_i p_i xi_i in (q, p, t).
    velocity : sympy.Expr
        The same in (q, qdot, t) through the momenta p_i(q, qdot, t); in (q, p, t) for a
        scene whose Hamiltonian has no Lagrangian.
    """

    name: str
    generator: Generator
    phase: sympy.Expr
    velocity: sympy.Expr


# -- candidates ----------------------------------------------------------------------------


def generators(scene: Scene) -> tuple[Generator, ...]:
    """The candidate generators of a scene, in the order their charges are listed.

    Rotations and translations of the particles' space (or of the bodies named by
    Cartesian coordinates), then the ``[symmetries]`` entries. Nothing here says whether
    a candidate is a symmetry: see ``conserved_charges``.

    Returns
    -------
    tuple of Generator
        Each with n = ``len(scene.coordinates)`` components.
    """
    found = _particle_generators(scene) if scene.particles else _cartesian_generators(scene)
    for name, entries in scene.symmetries:
        given = dict(entries)
        xi = tuple(
            scene.expression(f"symmetries.{name}.{q}") if q in given else sympy.S.Zero
            for q in scene.coordinates
        )
        found.append(Generator(name, xi, "given"))
    return tuple(found)


def _motions(dimension: int) -> dict[str, Callable[[Sequence[sympy.Expr]], tuple]]:
    """Charge name -> the displacement dr of a point r under the rotation or translation."""
    zero, one = sympy.S.Zero, sympy.S.One
    if dimension == 2:
        return {
            "L_z": lambda r: (-r[1], r[0]),
            "P_x": lambda r: (one, zero),
            "P_y": lambda r: (zero, one),
        }
    return {
        "L_x": lambda r: (zero, -r[2], r[1]),
        "L_y": lambda r: (r[2], zero, -r[0]),
        "L_z": lambda r: (-r[1], r[0], zero),
        "P_x": lambda r: (one, zero, zero),
        "P_y": lambda r: (zero, one, zero),
        "P_z": lambda r: (zero, zero, one),
    }


def _particle_generators(scene: Scene) -> list[Generator]:
    transformation = scene.transformation
    positions = transformation.positions
    q = tuple(scene.symbols[name] for name in scene.coordinates)
    # one row per position component (particle-major), one column per coordinate
    jacobian = [
        [sympy.diff(component, qj) if qj in component.free_symbols else sympy.S.Zero for qj in q]
        for position in positions
        for component in position
    ]
    solver = _MotionSolver(scene, jacobian, transformation.mass_matrix, transformation.masses)
    displacements = {
        name: [c for position in positions for c in motion(position)]
        for name, motion in _motions(len(positions[0])).items()
    }
    solver.evaluate(list(displacements.values()))
    found = []
    for which, (name, displacement) in enumerate(displacements.items()):
        xi = solver.solve(displacement, which)
        if xi is not None:
            kind = "rotation" if name in ROTATIONS else "translation"
            found.append(Generator(name, xi, kind))
    return found


class _MotionSolver:
    """Solves (dr/dq) xi = dr for xi, stacked over the particles.

    ``jacobian`` is a list of N*d rows (particle-major, component-minor) of n entries;
    plain lists, since indexing a sympy Matrix entry by entry cost more than the rest.
    """

    def __init__(self, scene: Scene, jacobian: list[list[sympy.Expr]], mass_matrix, masses):
        self.scene = scene
        self.jacobian = jacobian
        self.n = len(scene.coordinates)
        dimension = len(scene.particles[0].position)
        self.row_masses = [m for m in masses for _ in range(dimension)]
        entries = mass_matrix.tolist()
        self.diagonal = all(
            entries[j][k] == 0 for j in range(self.n) for k in range(self.n) if j != k
        )
        self.mass_diagonal = [entries[j][j] for j in range(self.n)]
        self.rng = random.Random(20261123)

    def evaluate(self, displacements: list[list[sympy.Expr]]) -> None:
        """The Jacobian's entries and every motion's displacement at the same random
        states, at once (one evaluator: building one per motion was most of the cost)."""
        rows, n = len(self.jacobian), self.n
        entries = [e for row in self.jacobian for e in row]
        entries += [d for displacement in displacements for d in displacement]
        where = [k for k, e in enumerate(entries) if e != 0]  # mostly zeros: not evaluated
        found = _values(
            self.scene, [entries[k] for k in where], self.rng, velocities=False, momenta=False
        )
        self.values = np.zeros((len(found), len(entries)))
        self.values[:, where] = found
        self.rows = rows * n + np.arange(len(displacements))[:, None] * rows + np.arange(rows)

    def solve(self, displacement: list[sympy.Expr], which: int) -> tuple[sympy.Expr, ...] | None:
        """xi with (dr/dq) xi = dr for the motion ``displacement``, the ``which``-th given
        to ``evaluate``; None where the motion leaves the configuration space."""
        rows, n = len(self.jacobian), self.n
        values = np.concatenate(
            [self.values[:, : rows * n], self.values[:, self.rows[which]]], axis=1
        )
        solutions = []
        for row in values[np.all(np.isfinite(values), axis=1)][:SAMPLES]:
            A, b = row[: rows * n].reshape(rows, n), row[rows * n :]
            x = np.linalg.lstsq(A, b, rcond=None)[0]
            if np.abs(A @ x - b).max() > TOLERANCE * max(1.0, np.abs(b).max()):
                return None  # the motion leaves the configuration space
            solutions.append(x)
        if len(solutions) < SAMPLES:
            return None
        solutions = np.array(solutions)
        xi = []
        for j in range(n):
            number = _constant(solutions[:, j])
            if number is None and self.diagonal:
                b = sympy.Add(
                    *[
                        m * row[j] * d
                        for m, row, d in zip(
                            self.row_masses, self.jacobian, displacement, strict=True
                        )
                        if row[j] != 0 and d != 0
                    ]
                )
                number = _simplest(sympy.cancel(b / self.mass_diagonal[j]))
            if number is None:
                return None
            xi.append(number)
        # J xi - dr, kept as its terms: a sum is tested against the size of its terms
        residual = []
        for row, d in zip(self.jacobian, displacement, strict=True):
            terms = [e * x for e, x in zip(row, xi, strict=True) if e != 0 and x != 0] + [-d]
            if sympy.Add(*terms) != 0:
                residual.append([term for term in terms if term != 0])
        if not _vanish_together(self.scene, residual, self.rng):
            return None
        return tuple(xi)


def _cartesian_generators(scene: Scene) -> list[Generator]:
    """Rotations and translations of bodies given by coordinates x<s>, y<s> (, z<s>)."""
    bodies: dict[str, dict[str, sympy.Symbol]] = {}
    for name in scene.coordinates:
        match = _BODY.match(name)
        if match:
            bodies.setdefault(match.group(2), {})[match.group(1)] = scene.symbols[name]
    bodies = {suffix: axes for suffix, axes in bodies.items() if "x" in axes and "y" in axes}
    if not bodies:
        return []
    dimension = 3 if all("z" in axes for axes in bodies.values()) else 2
    index = {scene.symbols[name]: i for i, name in enumerate(scene.coordinates)}
    found = []
    for name, motion in _motions(dimension).items():
        xi = [sympy.S.Zero] * len(scene.coordinates)
        for axes in bodies.values():
            r = tuple(axes[a] for a in AXES[:dimension])
            for symbol, moved in zip(r, motion(r), strict=True):
                xi[index[symbol]] = moved
        kind = "rotation" if name in ROTATIONS else "translation"
        found.append(Generator(name, tuple(xi), kind))
    return found


# -- constraint forces ---------------------------------------------------------------------


def constraint_rows(scene: Scene) -> list[tuple[str, sympy.Expr]]:
    """Each declared constraint as (kind, its expression): ``holonomic`` and
    ``unilateral`` f(q, t), ``nonholonomic`` a(q, t) . qdot + b(q, t)."""
    return [
        (kind, scene.expression(f"constraints.{kind}[{k}]"))
        for kind in ("holonomic", "unilateral", "nonholonomic")
        for k in range(len(getattr(scene, f"{kind}_constraints", ())))
    ]


def pushes_along(scene: Scene, coordinate: str) -> bool:
    """True if a constraint's force may have a component along ``coordinate``.

    The force of every constraint is -A^T lambda, A its row: grad f of a holonomic or
    unilateral f(q, t), the velocity coefficients a of a nonholonomic a . qdot + b. The
    force has no component along q_k exactly when column k of every row vanishes
    identically, decided symbolically (``sympy.simplify``): a coordinate that appears in a
    row only through other columns (the heading phi of a rolling disk, in
    cos(phi) psi_dot) feels no force, and its momentum is conserved when L does not
    depend on it and no effect acts on it.
    """
    position = scene.symbols[coordinate]
    velocity = scene.symbols[f"{coordinate}_dot"]
    for kind, f in constraint_rows(scene):
        by = velocity if kind == "nonholonomic" else position
        if not f.has(by):
            continue
        column = sympy.diff(f, by)
        if column != 0 and sympy.simplify(column) != 0:
            return True
    return False


# -- the test ------------------------------------------------------------------------------


def conserved_charges(
    scene: Scene,
    *,
    t: sympy.Symbol,
    q: Sequence[sympy.Symbol],
    qdot: Sequence[sympy.Symbol],
    p: Sequence[sympy.Symbol],
    lagrangian: sympy.Expr | None,
    momenta: Sequence[sympy.Expr] | None,
    velocities: Sequence[sympy.Expr],
    pdot: Sequence[sympy.Expr],
    forces: Sequence[sympy.Expr],
    listed: Mapping[str, sympy.Expr] = {},  # noqa: B006 - read only
) -> tuple[Charge, ...]:
    """The charges of the candidate generators that are conserved, in their order.

    Parameters
    ----------
    scene
        The scene (its particles, coordinate names and ``[symmetries]``).
    t, q, qdot, p
        The scene's symbols; q, qdot and p of length n.
    lagrangian, momenta
        L(q, qdot, t) and p_i(q, qdot, t), or None for a Hamiltonian without Lagrangian.
    velocities, pdot
        Hamilton's equations (n each) in (q, p, t), effects included; used only when
        there is no Lagrangian.
    forces
        The enabled effects' generalized forces Q_i(q, qdot, t), shape (n,).
    listed
        The conserved quantities already found (``"H"``, ``"p_<q>"``): a charge whose
        generator is a constant combination of theirs (and of those accepted before it)
        is left out.

    Returns
    -------
    tuple of Charge
    """
    candidates = generators(scene)
    if not candidates:
        return ()
    n = len(q)
    rng = random.Random(20261124)
    by_lagrangian = lagrangian is not None and momenta is not None
    if by_lagrangian:
        calculus = Calculus(scene.symbols.values())
        gradient = calculus.gradient(lagrangian, q)
        rate = [g + f for g, f in zip(gradient, forces, strict=True)]
        P, V = tuple(momenta), tuple(qdot)
    else:
        rate, P, V = list(pdot), tuple(p), tuple(velocities)
    basis = [
        tuple(sympy.S.One if k == i else sympy.S.Zero for k in range(n))
        for i, name in enumerate(scene.coordinates)
        if f"p_{name}" in listed
    ]
    # the directions each constraint's force acts along: grad f of a holonomic or
    # unilateral f(q, t), the velocity coefficients a of a nonholonomic a . qdot + b
    constraints = [
        [sympy.diff(f, x) for x in (qdot if kind == "nonholonomic" else q)]
        for kind, f in constraint_rows(scene)
    ]
    charges = []
    for generator in candidates:
        xi = generator.xi
        if all(component == 0 for component in xi):
            continue
        terms = []
        for i in range(n):
            if xi[i] == 0:
                continue
            terms.append(rate[i] * xi[i])
            moved = xi[i].free_symbols
            terms += [P[i] * sympy.diff(xi[i], q[j]) * V[j] for j in range(n) if q[j] in moved]
            if t in moved:
                terms.append(P[i] * sympy.diff(xi[i], t))
        terms = [term for term in terms if term != 0]
        # a constraint's force lambda grad f does no work along xi when grad f . xi = 0
        work = [
            [g * x for g, x in zip(gradient_f, xi, strict=True) if g * x != 0]
            for gradient_f in constraints
        ]
        if not _vanish_together(scene, [terms, *work], rng):
            continue
        if basis and _combination(scene, xi, basis, rng):
            continue
        basis.append(xi)
        phase = sympy.Add(*[pi * x for pi, x in zip(p, xi, strict=True) if x != 0])
        velocity = phase
        if momenta is not None:
            velocity = sympy.Add(*[m * x for m, x in zip(momenta, xi, strict=True) if x != 0])
        charges.append(Charge(generator.name, generator, phase, velocity))
    return tuple(charges)


def _values(
    scene: Scene,
    exprs: Sequence[sympy.Expr],
    rng: random.Random,
    *,
    velocities: bool = True,
    momenta: bool = True,
) -> np.ndarray:
    """``exprs`` at ``ATTEMPTS`` random states, shape (ATTEMPTS, len(exprs)); NaN (or
    inf) where a value is not a finite real number.

    Coordinates (velocities, momenta) have either sign and magnitude in [0.3, 1.7], t
    and the parameters are in [0.3, 1.7]. Evaluated for all states at once (symengine's
    ``Lambdify``: one scalar evaluation per expression and state, with the state as a
    dictionary of every symbol, took 9 s for twenty particles in space).
    """
    signed = list(scene.coordinates)
    signed += scene.velocity_names if velocities else []
    signed += scene.momentum_names if momenta else []
    positive = ["t", *(name for name, _ in scene.parameters)]
    symbols = [scene.symbols[name] for name in (*signed, *positive)]
    draw = np.random.default_rng(rng.getrandbits(64))
    states = draw.uniform(0.3, 1.7, size=(ATTEMPTS, len(symbols)))
    states[:, : len(signed)] *= draw.choice((-1.0, 1.0), size=(ATTEMPTS, len(signed)))
    exprs = [as_expr(e) for e in exprs]
    result = np.empty((ATTEMPTS, len(exprs)))
    # numbers (most of a Jacobian, a translation) need no evaluator: building one is
    # the cost here
    varying = [k for k, e in enumerate(exprs) if not e.is_Number]
    for k, e in enumerate(exprs):
        if e.is_Number:
            result[:, k] = float(e)
    if varying:
        result[:, varying] = _evaluate([exprs[k] for k in varying], symbols, states)
    return result


def _evaluate(exprs: list[sympy.Expr], symbols: list, states: np.ndarray) -> np.ndarray:
    """``exprs`` at ``states`` (shape (S, len(symbols))), shape (S, len(exprs))."""
    with np.errstate(all="ignore"):
        if symengine is not None:
            try:
                function = symengine.Lambdify(symbols, exprs, real=True)
            except (RuntimeError, TypeError, ValueError, NotImplementedError, AttributeError):
                function = None
            if function is not None:
                return np.asarray(function(states), dtype=float).reshape(len(states), len(exprs))
        function = sympy.lambdify(symbols, exprs, modules="numpy")
        columns = function(*states.T)
        return np.array(
            [np.broadcast_to(np.asarray(c, dtype=float), (len(states),)) for c in columns]
        ).T


def _vanish_together(scene: Scene, sums: list[list[sympy.Expr]], rng: random.Random) -> bool:
    """True if every sum of terms in ``sums`` is zero identically: at ``SAMPLES`` random
    states where all terms are finite reals, |sum| <= TOLERANCE * sum |term| for each.
    Too few such states: False (never taken to hold)."""
    if all(not terms for terms in sums):
        return True
    values = _values(scene, [term for terms in sums for term in terms], rng)
    good = values[np.all(np.isfinite(values), axis=1)][:SAMPLES]
    if len(good) < SAMPLES:
        return False
    start = 0
    for terms in sums:
        block = good[:, start : start + len(terms)]
        start += len(terms)
        if np.any(np.abs(block.sum(axis=1)) > TOLERANCE * np.abs(block).sum(axis=1)):
            return False
    return True


def _combination(scene: Scene, xi, basis, rng: random.Random) -> bool:
    """True if ``xi`` = sum_k c_k basis_k with constant c_k, at random states."""
    vectors = [xi, *basis]
    n = len(xi)
    values = _values(scene, [c for v in vectors for c in v], rng, velocities=False)
    good = values[np.all(np.isfinite(values), axis=1)][:SAMPLES]
    if len(good) < SAMPLES:
        return False
    # (SAMPLES, 1 + k, n) -> one row per (state, component), one column per vector
    stacked = good.reshape(len(good), len(vectors), n).transpose(0, 2, 1).reshape(-1, len(vectors))
    target, columns = stacked[:, 0], stacked[:, 1:]
    coefficients = np.linalg.lstsq(columns, target, rcond=None)[0]
    residual = np.abs(columns @ coefficients - target).max()
    return bool(residual <= TOLERANCE * max(1.0, np.abs(target).max()))


SIMPLIFY_OPS = 80
"""A generator component with at most this many operations is also tried with
``sympy.trigsimp`` (a rotating frame's -y (sin^2 + cos^2) is -y)."""


def _simplest(expr: sympy.Expr) -> sympy.Expr:
    if not expr.has(sympy.sin, sympy.cos) or sympy.count_ops(expr) > SIMPLIFY_OPS:
        return expr
    simpler = sympy.trigsimp(expr)
    return simpler if sympy.count_ops(simpler) < sympy.count_ops(expr) else expr


def _constant(values: np.ndarray) -> sympy.Expr | None:
    """A small rational number equal to every value (to 1e-9), or None."""
    first = float(values[0])
    if np.abs(values - first).max() > TOLERANCE * max(1.0, abs(first)):
        return None
    fraction = Fraction(first).limit_denominator(1000)
    if abs(float(fraction) - first) > TOLERANCE * max(1.0, abs(first)):
        return None
    return sympy.Rational(fraction.numerator, fraction.denominator)


# -- for the views ---------------------------------------------------------------------------

_PHASE: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()
_FUNCTIONS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def phase_space_charges(mechanics: Mechanics) -> dict[str, sympy.Expr]:
    """The Noether charges listed in ``mechanics.conserved`` (all but ``H``, ``E`` and the
    ``p_<q>``), each as Q = sum_i p_i xi_i(q, t) in (q, p, t), in their order.

    The generators are formed again from the scene (cheap; the derivation decided which
    are conserved) and remembered per ``Mechanics``.
    """
    try:
        return dict(_PHASE[mechanics])
    except KeyError:
        pass
    names = [
        name
        for name in mechanics.conserved
        if name not in ("H", ENERGY) and not name.startswith("p_")
    ]
    found = {}
    if names:
        by_name = {g.name: g for g in generators(mechanics.scene)}
        for name in names:
            xi = by_name[name].xi
            found[name] = sympy.Add(
                *[p * x for p, x in zip(mechanics.p, xi, strict=True) if x != 0]
            )
    _PHASE[mechanics] = found
    return dict(found)


def charge_functions(mechanics: Mechanics) -> dict[str, Callable[..., np.ndarray]]:
    """Numpy functions of the charges: ``f(t, Y, P) -> (N,)`` for times t of shape (N,),
    states Y of shape (N, 2n) and the parameter values P of shape (k,) in the scene's
    order. Made by ``sympy.lambdify`` from the derived charges (never from scene text),
    once per ``Mechanics``."""
    try:
        return dict(_FUNCTIONS[mechanics])
    except KeyError:
        pass
    scene = mechanics.scene
    params = [scene.symbols[name] for name, _ in scene.parameters]
    arguments = [mechanics.t, *mechanics.q, *mechanics.p, *params]
    functions = {}
    for name, expr in phase_space_charges(mechanics).items():
        compiled = sympy.lambdify(arguments, expr, modules="numpy")

        def evaluate(t, Y, P, compiled=compiled):
            t = np.asarray(t, dtype=float)
            Y = np.asarray(Y, dtype=float)
            values = compiled(t, *Y.T, *np.asarray(P, dtype=float))
            return np.broadcast_to(np.asarray(values, dtype=float), t.shape).copy()

        functions[name] = evaluate
    _FUNCTIONS[mechanics] = functions
    return dict(functions)
