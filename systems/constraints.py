"""Constraints with Lagrange multipliers: holonomic, nonholonomic and unilateral.

A scene may keep more coordinates than it has degrees of freedom and tie them together
(``[constraints]``). Three kinds are integrated:

- holonomic ``Phi(q, t) = 0`` (``holonomic = ["x**2 + y**2 - l**2"]``);
- nonholonomic ``a(q, t) . qdot + b(q, t) = 0``, linear in the velocities and not
  integrable to an equation in q (``nonholonomic = ["x_dot - R*cos(phi)*psi_dot"]``);
- unilateral ``g(q, t) >= 0`` (``unilateral = ["y"]``): a wall or a floor, free until
  the system reaches it, then an impact (Newton's restitution law) or a resting contact.

Every constraint contributes one *velocity row*: the coefficients of qdot in its time
derivative (``Phi_q``, ``a``, ``G = g_q``), a velocity-free part (``Phi_t``, ``b``,
``g_t``) and ``gamma``, the part of its second (holonomic, unilateral) or first
(nonholonomic) time derivative without qddot, with a minus sign. With A the rows that act
(every holonomic and nonholonomic one; a unilateral one only while in contact) the
equations of motion are

    M(q, t) qddot + A^T lambda = F(q, qdot, t),
    A qddot = gamma(q, qdot, t),

one multiplier per row; the force of the constraints on the coordinates is
``-A^T lambda``. For a pendulum in Cartesian x, y with ``Phi = x**2 + y**2 - l**2`` it is
``-2 lambda (x, y)``: the string's tension is ``2 lambda l``. With the same convention a
unilateral contact pushes (``-G^T lambda`` points into g > 0) while lambda <= 0, and is
released when lambda would turn positive (pull).

The derivation itself (``systems.mechanics``) stays that of the free coordinates: M, F,
the momenta p = dL/dqdot and H(q, p) are those of the unconstrained Lagrangian, and a
state is still ``(q, p)``. What this module adds:

- the symbolic pieces (``rows``, ``holonomic``: values, velocity rows and gamma), the
  constraints for the classification (``declared``), and the degrees of freedom
  (``degrees_of_freedom``, ``configuration_degrees_of_freedom``);
- the kernel source for a constrained scene (``kernel_source``): its ``rhs`` is Hamilton's
  equations with the constraint force, ``pdot = dL/dq + Q - A^T lambda``, lambda from
  the saddle-point system ``[[M, A^T], [A, 0]] [qddot; lambda] = [F; gamma]`` solved at
  every evaluation, and ``c_project`` puts a state back onto the constraints after every
  step of the ``constrained`` integrator family; the impacts and contacts of unilateral
  constraints are handled by that family's step (``systems/integrators/kernels.py``);
- numpy counterparts for diagnostics (``Numeric``: multipliers, violation, projection of
  an initial state).

The projection (Hairer, Lubich & Wanner, *Geometric Numerical Integration*, IV.4) moves q
by Newton's iterations on ``Phi(q, t) = 0`` (and ``g = 0`` for the contacts) along the
correction of least kinetic metric, ``dq = M^-1 A^T (A M^-1 A^T)^-1 Phi``, and then the
velocities onto ``A qdot + c = 0`` (every acting row, nonholonomic ones included) the same
way; the momenta are then p(q, qdot).
"""

from __future__ import annotations

import copy
import functools
import math
import random
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import sympy

from systems import lambdified
from systems.classification import NO_CONSTRAINTS, Constraints
from systems.expressions import as_expr
from systems.mechanics import DerivationError
from systems.scene import CONSTRAINT_KINDS

KINDS = tuple(CONSTRAINT_KINDS)
"""The kinds of ``[constraints]``, in the order of their rows and multipliers."""

RANK_TOLERANCE = 1e-9
"""Singular values of the rows below this fraction of the largest count as zero."""

PROJECTION_ITERATIONS = 8
"""Newton iterations of the position projection before it is given up."""

RESTITUTION = "restitution"
"""The parameter that holds Newton's coefficient of restitution e of every unilateral
constraint (1, elastic impacts, when the scene has no such parameter)."""

CONTACT_GAP = 1e-10
"""A state is in contact with a unilateral constraint when |g| <= CONTACT_GAP max(1, |q|)
and |G qdot + g_t| <= CONTACT_SPEED max(1, |qdot|) (and the contact pushes): how a run
starts and how the multipliers of a stored state are computed."""

CONTACT_SPEED = 1e-8
"""See ``CONTACT_GAP``: the normal velocity of a state in contact, relative to max(1,
|qdot|). A rebound that would rise less than the contact gap (v+**2 <= 2 |a_n| CONTACT_GAP
max(1, |q|)) makes a resting contact instead (``c_switch``)."""


@dataclass(frozen=True, eq=False)
class Rows:
    """The symbolic pieces of k constraints on n coordinates, one velocity row each.

    Attributes
    ----------
    kinds : tuple of k str
        ``"holonomic"``, ``"nonholonomic"`` or ``"unilateral"``, in this order.
    values : tuple of k sympy.Expr
        Phi(q, t), a(q, t) . qdot + b(q, t), or g(q, t).
    jacobian : sympy.Matrix, shape (k, n)
        The velocity coefficients: Phi_q, a, or G = g_q.
    time_derivative : tuple of k sympy.Expr
        The velocity-free part of the row: Phi_t, b, or g_t.
    gamma : tuple of k sympy.Expr
        The right-hand side of ``A qddot = gamma``, in (q, qdot, t).
    """

    kinds: tuple[str, ...]
    values: tuple[sympy.Expr, ...]
    jacobian: sympy.Matrix
    time_derivative: tuple[sympy.Expr, ...]
    gamma: tuple[sympy.Expr, ...]

    @property
    def k(self) -> int:
        return len(self.values)

    def of_kind(self, kind: str) -> Rows | None:
        """The rows of one kind, or None if there are none."""
        index = [i for i, k in enumerate(self.kinds) if k == kind]
        if not index:
            return None
        return Rows(
            tuple(self.kinds[i] for i in index),
            tuple(self.values[i] for i in index),
            self.jacobian.extract(index, list(range(self.jacobian.cols))),
            tuple(self.time_derivative[i] for i in index),
            tuple(self.gamma[i] for i in index),
        )


Holonomic = Rows
"""The holonomic rows (``holonomic(mechanics)``) are ``Rows`` of that kind only."""


def counts(scene) -> dict[str, int]:
    """The number of constraints of each kind the scene declares."""
    return {kind: len(getattr(scene, f"{kind}_constraints", ())) for kind in KINDS}


def count(scene) -> int:
    """The number of constraints of every kind (= multipliers) the scene declares (0 for
    most scenes)."""
    return sum(counts(scene).values())


def constrained(scene) -> bool:
    """True if the scene declares constraints of any kind (``[constraints]``): its
    equations carry multipliers and only the ``constrained`` family integrates it."""
    return count(scene) > 0


def declared(scene) -> Constraints:
    """The scene's constraints as ``systems.classification.Constraints``."""
    if not constrained(scene):
        return NO_CONSTRAINTS
    return Constraints(
        **{
            kind: tuple(
                scene.expression(f"constraints.{kind}[{i}]") for i in range(counts(scene)[kind])
            )
            for kind in KINDS
        }
    )


def multiplier_names(scene) -> list[str]:
    """The CSV columns of the multipliers: ``lambda_1`` .. ``lambda_k``, one per
    constraint, holonomic ones first, then nonholonomic, then unilateral (none without
    constraints)."""
    return [f"lambda_{i + 1}" for i in range(count(scene))]


def restitution_index(scene) -> int | None:
    """The index of the ``restitution`` parameter in the parameter vector, or None."""
    names = [name for name, _ in scene.parameters]
    return names.index(RESTITUTION) if RESTITUTION in names else None


def constrains(scene, coordinate: str) -> bool:
    """True if some constraint contains ``coordinate`` or its velocity: the coordinate is
    then not cyclic, and its momentum is not reported as conserved.

    A holonomic or unilateral constraint that contains it pushes along it. A nonholonomic
    one may not (the rolling disk's heading phi appears only in cos(phi), and p_phi is
    conserved), but the Routhian reduction by such a coordinate would drop the
    constraints of the others, which depend on it: it is not offered.
    """
    symbols = {scene.symbols[coordinate], scene.symbols[f"{coordinate}_dot"]}
    given = declared(scene)
    every = (*given.holonomic, *given.nonholonomic, *given.unilateral)
    return any(symbols & f.free_symbols for f in every)


def rows(mechanics) -> Rows | None:
    """Every constraint's velocity row (holonomic, nonholonomic, then unilateral), or
    None without constraints. Remembered on the mechanics."""
    scene = mechanics.scene
    if not constrained(scene):
        return None
    cache = mechanics._cache
    if "constraint rows" not in cache:
        q, qd, t = mechanics.q, mechanics.qdot, mechanics.t
        given = declared(scene)
        kinds, values, jacobian, free, gamma = [], [], [], [], []
        for kind in KINDS:
            for f in getattr(given, kind):
                if kind == "nonholonomic":
                    row = [sympy.diff(f, v) for v in qd]
                    part = as_expr(f.xreplace(dict.fromkeys(qd, sympy.S.Zero)))
                    c = f  # a . qdot + b; dc/dt = a qddot + (dc/dq) qdot + dc/dt
                else:
                    row = [sympy.diff(f, x) for x in q]
                    part = sympy.diff(f, t)
                    # c = Phi_q qdot + Phi_t; dc/dt = Phi_q qddot + (dc/dq) qdot + dc/dt
                    c = sum((row[j] * qd[j] for j in range(len(q))), part)
                rest = sum(
                    (sympy.diff(c, x) * v for x, v in zip(q, qd, strict=True)), sympy.diff(c, t)
                )
                kinds.append(kind)
                values.append(f)
                jacobian.append(row)
                free.append(part)
                gamma.append(as_expr(-rest))
        cache["constraint rows"] = Rows(
            tuple(kinds), tuple(values), sympy.Matrix(jacobian), tuple(free), tuple(gamma)
        )
    return cache["constraint rows"]


def holonomic(mechanics) -> Rows | None:
    """Phi, Phi_q, Phi_t and gamma of the holonomic constraints, or None without any."""
    pieces = rows(mechanics)
    return None if pieces is None else pieces.of_kind("holonomic")


def degrees_of_freedom(mechanics) -> int:
    """The velocity degrees of freedom: coordinates minus independent bilateral
    constraints, n - rank([Phi_q; a]) (holonomic and nonholonomic rows).

    Without nonholonomic constraints this is the textbook's count (coordinates minus
    independent constraints). Nonholonomic ones restrict the velocities only: the
    configuration still needs ``configuration_degrees_of_freedom`` coordinates.
    Unilateral constraints restrict where the system may go, not how many numbers
    describe it: they do not count. The rank is the largest found at a few random states
    (coordinates, t and parameters drawn from [0.3, 1.7]), so a rank that drops only on
    a special set does not count.
    """
    return mechanics.n - _rank(mechanics, ("holonomic", "nonholonomic"))


def configuration_degrees_of_freedom(mechanics) -> int:
    """Coordinates minus independent holonomic constraints, n - rank(Phi_q): how many
    coordinates the configuration needs (nonholonomic constraints do not reduce them)."""
    return mechanics.n - _rank(mechanics, ("holonomic",))


def _rank(mechanics, kinds: Sequence[str]) -> int:
    pieces = rows(mechanics)
    if pieces is None:
        return 0
    index = [i for i, kind in enumerate(pieces.kinds) if kind in kinds]
    if not index:
        return 0
    symbols = [mechanics.t, *mechanics.q, *mechanics.params.values()]
    matrix = [as_expr(pieces.jacobian[i, j]) for i in index for j in range(mechanics.n)]
    f = sympy.lambdify(symbols, matrix, modules="math")
    rng = random.Random(4321)
    best = 0
    for _ in range(5):
        try:
            values = np.array(f(*(rng.uniform(0.3, 1.7) for _ in symbols)), dtype=float)
        except (ValueError, ZeroDivisionError, OverflowError):
            continue
        if not np.all(np.isfinite(values)):
            continue
        s = np.linalg.svd(values.reshape(len(index), mechanics.n), compute_uv=False)
        if s.size and s[0] > 0:
            best = max(best, int(np.sum(s > RANK_TOLERANCE * s[0])))
    return best


def check(mechanics) -> None:
    """Refuse constraints that cannot be integrated, naming the field and why.

    Raises
    ------
    DerivationError
        For dependent bilateral (holonomic and nonholonomic) constraints or as many
        independent ones as coordinates, a system without a Lagrangian mass matrix, a
        mass matrix that depends on the velocities (L not quadratic in them), or a
        ``restitution`` outside [0, 1].
    """
    scene = mechanics.scene
    k = counts(scene)
    if not sum(k.values()):
        return
    n = mechanics.n
    first = next(f"constraints.{kind}" for kind in KINDS if k[kind])

    def fail(reason: str, field: str = first) -> DerivationError:
        return DerivationError(reason, source=scene.source, field=field)

    bilateral = k["holonomic"] + k["nonholonomic"]
    if bilateral:
        field = "constraints.nonholonomic" if k["nonholonomic"] else "constraints.holonomic"
        rank = _rank(mechanics, ("holonomic", "nonholonomic"))
        if rank < bilateral:
            what = (
                "their Jacobian dPhi/dq"
                if not k["nonholonomic"]
                else "their velocity coefficients (dPhi/dq and a)"
            )
            raise fail(
                f"the {bilateral} constraints are not independent (the rank of {what} is "
                f"{rank}): leave out the ones that follow from the others",
                field,
            )
        if bilateral >= n:
            raise fail(
                f"{bilateral} independent constraints on {n} coordinates leave no degree of "
                "freedom; there is nothing to move",
                field,
            )
    if mechanics.mass_matrix is None:
        raise fail(
            "constraints need the mass matrix d2L/dqdot2, and this Hamiltonian's Legendre "
            "transform does not invert; give the system by T and V or by a Lagrangian"
        )
    if any(as_expr(e).free_symbols & set(mechanics.qdot) for e in mechanics.mass_matrix):
        raise fail(
            "constraints need a Lagrangian quadratic in the velocities (a mass matrix "
            "d2L/dqdot2 that does not depend on them)"
        )
    index = restitution_index(scene)
    if k["unilateral"] and index is not None:
        e = scene.parameters[index][1]
        if not 0.0 <= e <= 1.0:
            raise fail(
                f"the coefficient of restitution must lie between 0 (plastic impacts) and 1 "
                f"(elastic ones), not {e:g}",
                "system.parameters",
            )


# -- kernel source ------------------------------------------------------------------------


PRIMITIVES = (
    "c_free_rhs",
    "c_positions",
    "c_rows",
    "c_mass",
    "c_velocities",
    "c_momenta",
    "c_saddle",
    "c_gamma",
)
"""A constrained scene's own functions, in the order of the drivers' ``cs`` tuple (the
constrained families' ``Family.functions``); the multipliers, projections, contacts and
impacts are the drivers' (``systems/integrators/kernels.py``), the same for every scene."""


def sizes(mechanics) -> np.ndarray:
    """The drivers' ``sizes`` (int64, (4,)): the number of constraints, of holonomic ones,
    of bilateral ones, and the index of the parameter ``restitution`` (-1 without)."""
    number = counts(mechanics.scene)  # not ``rows``: a reopened scene needs no rows
    kh = number["holonomic"]
    kb = kh + number["nonholonomic"]
    index = restitution_index(mechanics.scene)
    return np.array([sum(number.values()), kh, kb, -1 if index is None else index], np.int64)


def _primitive_parts(mechanics):
    """(name, arguments, [(target, expression)], needs the velocities first) of each of
    ``PRIMITIVES``: targets are indices into ``out`` (``(i,)`` or ``(i, j)``)."""
    pieces = rows(mechanics)
    n, k = mechanics.n, pieces.k
    m = n + k
    M = mechanics.mass_matrix
    positions = [
        sympy.S.Zero if kind == "nonholonomic" else f
        for kind, f in zip(pieces.kinds, pieces.values, strict=True)
    ]
    jacobian = [((i, j), pieces.jacobian[i, j]) for i in range(k) for j in range(n)]
    jacobian += [((i, n), pieces.time_derivative[i]) for i in range(k)]
    saddle = [((i, j), M[i, j]) for i in range(n) for j in range(n)]
    saddle += [((i, m), mechanics.forcing[i]) for i in range(n)]
    saddle += [((n + i, m), pieces.gamma[i]) for i in range(k)]
    saddle += [((n + i, j), pieces.jacobian[i, j]) for i in range(k) for j in range(n)]
    state = ("t", "y", "P", "out")
    return [
        ("c_free_rhs", state, list(enumerate(mechanics.hamilton_equations)), False),
        ("c_positions", state, list(enumerate(positions)), False),
        ("c_rows", state, jacobian, False),
        ("c_mass", state, [((i, j), M[i, j]) for i in range(n) for j in range(n)], False),
        ("c_velocities", state, list(enumerate(mechanics.velocities)), False),
        ("c_momenta", ("t", "q", "qdot", "P", "out"), list(enumerate(mechanics.momenta)), False),
        ("c_saddle", state, saddle, True),
        ("c_gamma", state, list(enumerate(pieces.gamma)), True),
    ]


def kernel_source(writer, mechanics) -> str:
    """A constrained scene's own functions (``PRIMITIVES``) as Python source, for numba
    (``systems.compiled``); ``writer`` is the compiled module's kernel writer.

    For the state ``y = (q, p)`` (shape (2n,)) and K constraints (holonomic, then
    nonholonomic, then unilateral): ``c_free_rhs(t, y, P, out)`` Hamilton's equations
    without the constraints' force; ``c_positions(t, y, P, out)`` Phi and g (K,; 0 for a
    nonholonomic row); ``c_rows(t, y, P, out)`` the rows (K, n + 1: the Jacobian and the
    velocity-free parts Phi_t, b, g_t as column n); ``c_mass(t, y, P, out)`` M (into the
    top left of out); ``c_velocities(t, y, P, out)`` qdot; ``c_momenta(t, q, qdot, P,
    out)`` p; ``c_saddle(t, y, P, W)`` M, F, gamma and the rows into the saddle-point
    system W (m, m + 1), m = n + K; ``c_gamma(t, y, P, out)`` gamma (K,).
    """
    parts = []
    scene = mechanics.scene
    to_velocities = _velocity_lines(writer, mechanics)
    for name, arguments, pairs, first in _primitive_parts(mechanics):
        out = "W" if name == "c_saddle" else "out"
        targets = [(f"{out}[{_index(target)}]", expr) for target, expr in pairs]
        signature = f"{name}({', '.join(arguments[:-1])}, {out})"
        if name == "c_momenta":
            unpack = writer.unpack("q", scene.coordinates)
            unpack += writer.unpack("qdot", scene.velocity_names)
        else:
            unpack = writer.unpack_state()
        before = to_velocities if first else ()
        parts.append(_assign(writer, signature, unpack, targets, before=before))
    return "\n\n".join(parts)


def _index(target) -> str:
    """``i`` or ``i, j``: a target of ``_primitive_parts`` as Python indexing."""
    return ", ".join(map(str, target if isinstance(target, tuple) else (target,)))


def specs(writer, mechanics) -> list:
    """``PRIMITIVES`` as ``systems.llvm_kernels.FunctionSpec``s (the same expressions as
    ``kernel_source``): ``c_saddle`` and ``c_gamma`` set the velocities from the state
    first, by their expressions or, in matrix form, by the velocity solve."""
    from systems.llvm_kernels import FunctionSpec

    scene = mechanics.scene
    state, pairs_bindings = writer.bindings()
    solve = writer._solve_spec()
    qdot = set(mechanics.qdot)
    velocities = tuple(f"v_{name}" for name in scene.velocity_names)
    found = []
    for name, arguments, pairs, first in _primitive_parts(mechanics):
        targets = tuple(t if isinstance(t, tuple) else (t,) for t, _ in pairs)
        exprs = tuple(e for _, e in pairs)
        bindings = pairs_bindings if name == "c_momenta" else state
        pre = None
        if first:
            pre = (velocities, tuple(mechanics.velocities), solve)
        uses = any(as_expr(e).free_symbols & qdot for e in exprs)
        found.append(
            FunctionSpec(
                name, arguments, bindings, exprs, targets=targets, pre=pre,
                solve=solve if uses and not first and name != "c_momenta" else None,
            )
        )  # fmt: skip
    return found


def _velocity_lines(writer, mechanics) -> list[str]:
    """Lines that set ``v_<q>_dot`` from the state (q, p), for functions of (q, qdot);
    for a system in matrix form they solve M(q, t) qdot = p - a(q, t)."""
    temps, values = writer.solved_body(mechanics.velocities)
    names = mechanics.scene.velocity_names
    return temps + [
        f"v_{name} = {value}"
        for name, value in zip(names, values, strict=True)
        if value != f"v_{name}"
    ]


def _function(writer, signature: str, unpack: list[str], exprs: Sequence) -> str:
    targets = [f"out[{i}]" for i in range(len(exprs))]
    return _assign(writer, signature, unpack, list(zip(targets, exprs, strict=True)))


def _assign(
    writer, signature: str, unpack: list[str], pairs: list[tuple[str, object]], before=()
) -> str:
    """A function that assigns each expression of ``pairs`` to its target, after the
    lines ``before`` (which may use the parameters). Without ``before``, a function of the
    state y = (q, p) of a system in matrix form solves for the velocities its expressions
    use (``_body_for``); ``before`` sets them itself."""
    lines = writer.header(signature, unpack) + list(before)
    exprs = [expr for _, expr in pairs]
    temps, values = writer.body(exprs) if before else writer._body_for(signature, exprs)
    lines += temps
    lines += [f"{target} = {value}" for (target, _), value in zip(pairs, values, strict=True)]
    return lines[0] + "\n" + "\n".join("    " + line for line in lines[1:]) + "\n"


# -- numpy, for diagnostics and the initial state -----------------------------------------


@functools.cache
def _numeric_tag() -> str:
    """The tag of ``Numeric``'s remembered functions: what writes their source (the
    expressions are the scene's, whose key names the code that derives them)."""
    from systems import derivation_cache

    code = derivation_cache.code_hash(lambdified)
    return f"numeric {code} sympy {sympy.__version__} numpy {np.__version__}"


class Numeric:
    """The constraints of a compiled system evaluated with numpy, many states at once.

    Parameters
    ----------
    compiled : CompiledSystem
        Of a scene with constraints; its parameter values are used (see ``bound_to``).
    """

    def __init__(self, compiled):
        self.compiled = compiled
        mech = compiled.mechanics
        if not constrained(mech.scene):
            raise ValueError("the scene has no constraints")
        self.n = mech.n
        kinds = np.array(
            [kind for kind, number in counts(mech.scene).items() for _ in range(number)]
        )
        self.k = len(kinds)
        self.holonomic = kinds == "holonomic"
        self.nonholonomic = kinds == "nonholonomic"
        self.unilateral = kinds == "unilateral"
        self._params = tuple(mech.params[name] for name in compiled.parameter_names)
        self._made: dict[str, object] = {}  # shared with ``bound_to``'s copies

    @functools.cached_property
    def pieces(self) -> Rows:
        """The constraints' rows (``rows``): symbolic work (3 ms of the rolling disk's),
        done only where a function is lambdified or an error names a constraint."""
        return rows(self.compiled.mechanics)

    @functools.cached_property
    def _sources(self) -> dict:
        """The expressions of each numpy function, by name, with their arguments (None: no
        expression). Each is lambdified on first use (``_lambdified``), 1-3 ms apiece, and
        remembered on disk: opening a scene again needs two to four of the eight and
        none of these expressions."""
        mech = self.compiled.mechanics
        t, q, qd = mech.t, mech.q, mech.qdot
        positions = [
            sympy.S.Zero if kind == "nonholonomic" else f
            for kind, f in zip(self.pieces.kinds, self.pieces.values, strict=True)
        ]
        form = mech.matrix_form
        return {
            "positions": ((t, q), positions),
            "jacobian": ((t, q), [*self.pieces.jacobian, *self.pieces.time_derivative]),
            "mass": ((t, q, qd), list(mech.mass_matrix)),
            "forcing": ((t, q, qd), list(mech.forcing)),
            "gamma": ((t, q, qd), self.pieces.gamma),
            # in matrix form qdot solves M(q, t) qdot = p - a(q, t): no expression
            "velocities": None if form is not None else ((t, q, mech.p), mech.velocities),
            "shift": ((t, q), list(form.shift)) if form is not None else None,
            "momenta": ((t, q, qd), mech.momenta),
        }

    def _lambdified(self, name: str):
        """The numpy function of the expressions ``name`` of ``_sources`` (None where there
        are none), made once for this system and its copies, and kept on disk with the
        derivation (``derivation_cache.remembered_value``: its source text, compiled again
        in 0.1 ms where sympy's printing took 1-3 ms)."""
        if name not in self._made:
            from systems import derivation_cache

            # the expressions are only looked at (``_sources``) where none is on disk
            matrix_form = self.compiled.mechanics.matrix_form is not None
            absent = name == ("velocities" if matrix_form else "shift")
            self._made[name] = (
                None
                if absent
                else derivation_cache.remembered_value(
                    f"{self._key} {name}", _numeric_tag(), lambda: self._lambdify(name)
                )
            )
        return self._made[name]

    def _lambdify(self, name: str) -> lambdified.Lambdified:
        args, exprs = self._sources[name]
        return lambdified.lambdify(
            (*args, self._params), [as_expr(e) for e in exprs], modules="numpy"
        )

    @functools.cached_property
    def _key(self) -> str:
        """What names this system's functions on disk (the scene's key: a quarter of a
        millisecond, once)."""
        from systems import derivation_cache

        scene = derivation_cache.scene_key(self.compiled.mechanics.scene)
        return f"constraints.Numeric {scene} {' '.join(map(str, self._params))}"

    _positions = property(lambda self: self._lambdified("positions"))
    _jacobian = property(lambda self: self._lambdified("jacobian"))
    _mass = property(lambda self: self._lambdified("mass"))
    _forcing = property(lambda self: self._lambdified("forcing"))
    _gamma = property(lambda self: self._lambdified("gamma"))
    _velocities = property(lambda self: self._lambdified("velocities"))
    _shift = property(lambda self: self._lambdified("shift"))
    _momenta = property(lambda self: self._lambdified("momenta"))

    def bound_to(self, compiled) -> Numeric:
        """The same functions with ``compiled``'s parameter values (nothing is lambdified
        again: a parameter slider costs nothing here)."""
        other = copy.copy(self)
        other.compiled = compiled
        return other

    def _stack(self, f, shape, N, *args) -> np.ndarray:
        """``f`` (a list of expressions) at N states, as an array (N, *shape)."""
        values = f(*args, self.compiled.parameters)
        return np.stack([np.broadcast_to(np.asarray(v, float), (N,)) for v in values], -1).reshape(
            (N, *shape)
        )

    def _split(self, t, Y):
        Y = np.atleast_2d(np.asarray(Y, dtype=float))
        N = len(Y)
        ts = np.broadcast_to(np.asarray(t, dtype=float), (N,))
        return ts, Y, N

    def _rows(self, ts, Q, N) -> tuple[np.ndarray, np.ndarray]:
        """(A (N, k, n), c (N, k)): the velocity rows and their velocity-free parts."""
        n, k = self.n, self.k
        both = self._stack(self._jacobian, ((n + 1) * k,), N, ts, Q)
        return both[:, : n * k].reshape(N, k, n), both[:, n * k :]

    def values(self, t, Y: np.ndarray) -> np.ndarray:
        """Phi, a . qdot + b and g at states Y (N, 2n); returns (N, k)."""
        ts, Y, N = self._split(t, Y)
        Q = Y[:, : self.n].T
        out = self._stack(self._positions, (self.k,), N, ts, Q)
        if self.nonholonomic.any():
            A, c = self._rows(ts, Q, N)
            speeds = np.einsum("akn,an->ak", A, self.qdot(ts, Y)) + c
            out[:, self.nonholonomic] = speeds[:, self.nonholonomic]
        return out

    def violation(self, t, Y: np.ndarray) -> float:
        """The largest violation over the states Y (N, 2n): |Phi_i| of the holonomic
        constraints, |a . qdot + b| of the nonholonomic ones and max(0, -g) of the
        unilateral ones."""
        if not len(np.atleast_2d(Y)):
            return 0.0
        values = self.values(t, Y)
        values[:, self.unilateral] = np.maximum(0.0, -values[:, self.unilateral])
        return float(np.max(np.abs(values)))

    def qdot(self, t, Y: np.ndarray) -> np.ndarray:
        """The velocities (N, n) at states Y (N, 2n)."""
        ts, Y, N = self._split(t, Y)
        n = self.n
        if self._velocities is not None:
            return self._stack(self._velocities, (n,), N, ts, Y[:, :n].T, Y[:, n:].T)
        Q = Y[:, :n].T
        M = self._stack(self._mass, (n, n), N, ts, Q, np.zeros((n, N)))
        a = self._stack(self._shift, (n,), N, ts, Q)
        return np.linalg.solve(M, (Y[:, n:] - a)[..., None])[..., 0]

    def contacts(self, t, Y: np.ndarray) -> np.ndarray:
        """Which rows act at states Y (N, 2n), as the kernels' ``c_contacts`` decides:
        every bilateral row, and the unilateral rows a state touches (g and the normal
        velocity at zero, see ``CONTACT_GAP``) where the contact pushes. Returns a
        boolean array (N, k)."""
        return self.solve(t, Y)[1]

    def multipliers(self, t, Y: np.ndarray) -> np.ndarray:
        """lambda at states Y (N, 2n) from the saddle-point system; returns (N, k). A
        unilateral row's multiplier is 0 where the state is not in contact with it."""
        return self.solve(t, Y)[0]

    def solve(
        self, t, Y: np.ndarray, acting: np.ndarray | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """The multipliers and the acting rows at states Y (N, 2n).

        Parameters
        ----------
        t : float or ndarray, shape (N,)
        Y : ndarray, shape (N, 2n)
        acting : ndarray of bool, shape (N, k) or (k,), optional
            The rows that act; by default the kernels' choice (``contacts``).

        Returns
        -------
        lam : ndarray, shape (N, k)
            0 for a row that does not act; nan where the system is singular.
        acting : ndarray of bool, shape (N, k)
        """
        ts, Y, N = self._split(t, Y)
        n, k = self.n, self.k
        Q, Qd = Y[:, :n].T, self.qdot(ts, Y)
        M = self._stack(self._mass, (n, n), N, ts, Q, Qd.T)
        F = self._stack(self._forcing, (n,), N, ts, Q, Qd.T)
        gamma = self._stack(self._gamma, (k,), N, ts, Q, Qd.T)
        J, c = self._rows(ts, Q, N)
        if acting is not None:
            act = np.broadcast_to(np.asarray(acting, dtype=bool), (N, k))
            return self._saddle(M, F, gamma, J, act), act
        act = np.broadcast_to(~self.unilateral, (N, k)).copy()
        if self.unilateral.any():
            g = self._stack(self._positions, (k,), N, ts, Q)
            speeds = np.einsum("akn,an->ak", J, Qd) + c
            qscale = np.maximum(1.0, np.abs(Y[:, :n]).max(axis=1))[:, None]
            vscale = np.maximum(1.0, np.abs(Qd).max(axis=1))[:, None]
            touching = (np.abs(g) <= CONTACT_GAP * qscale) & (
                np.abs(speeds) <= CONTACT_SPEED * vscale
            )
            act |= touching & self.unilateral
        for _ in range(int(self.unilateral.sum()) + 1):
            lam = self._saddle(M, F, gamma, J, act)
            pulling = act & self.unilateral & (lam > 0.0)
            if not pulling.any():
                break
            # release one pulling contact per state and try again, as the kernel does
            first = np.argmax(pulling, axis=1)
            rows_ = np.flatnonzero(pulling.any(axis=1))
            act[rows_, first[rows_]] = False
        return lam, act

    def _saddle(self, M, F, gamma, J, act) -> np.ndarray:
        """lambda of [[M, A^T], [A, 0]] [qddot; lambda] = [F; gamma] over the rows ``act``
        (the others: lambda = 0), for N states at once; nan where it is singular."""
        N, n, k = len(M), self.n, self.k
        Ja = np.where(act[:, :, None], J, 0.0)
        A = np.zeros((N, n + k, n + k))
        A[:, :n, :n] = M
        A[:, :n, n:] = np.transpose(Ja, (0, 2, 1))
        A[:, n:, :n] = Ja
        A[:, n:, n:] = np.where(act, 0.0, 1.0)[:, :, None] * np.eye(k)
        b = np.concatenate([F, np.where(act, gamma, 0.0)], axis=1)[..., None]
        try:
            return np.linalg.solve(A, b)[:, n:, 0]
        except np.linalg.LinAlgError:  # some state where the rows lose rank: nan there
            out = np.full((N, k), np.nan)
            for row in range(N):
                try:
                    out[row] = np.linalg.solve(A[row], b[row])[n:, 0]
                except np.linalg.LinAlgError:
                    pass
            return out

    def project(self, t: float, y: np.ndarray) -> np.ndarray:
        """One state (2n,) moved onto the constraints (positions onto Phi = 0, then the
        velocities onto the holonomic and nonholonomic rows), as the kernels' ``project``
        does; for an initial state off the constraints.

        Raises
        ------
        DerivationError
            If Newton's iteration does not converge (no nearby point satisfies Phi = 0),
            or the state lies beyond a unilateral constraint (g < 0).
        """
        n = self.n
        y = np.array(y, dtype=float)
        qd = self.qdot(t, y)[0]
        if self.holonomic.any():
            self._project_positions(t, y, qd)
        if self.unilateral.any():
            g = self._stack(self._positions, (self.k,), 1, t, y[:n])[0]
            scale = max(1.0, float(np.max(np.abs(y[:n]))))
            for i in np.flatnonzero(self.unilateral & (g < -CONTACT_GAP * scale)):
                number = int(np.sum(self.unilateral[:i]))
                raise DerivationError(
                    f"the initial state lies beyond the unilateral constraint "
                    f"{self.pieces.values[i]} >= 0 (it is {g[i]:.6g} there): start where "
                    "it holds",
                    source=self.compiled.mechanics.scene.source,
                    field=f"constraints.unilateral[{number}]",
                )
        bilateral = ~self.unilateral
        if bilateral.any():
            try:
                qd = self._metric_step(t, y[:n], qd, bilateral, None)
            except np.linalg.LinAlgError:
                raise self._cannot(y) from None
        p = np.asarray(self._momenta(t, y[:n], qd, self.compiled.parameters), float)
        y[n:] = p.reshape(n)
        return y

    def _project_positions(self, t, y, qd) -> None:
        n = self.n
        previous = math.inf
        for _ in range(4 * PROJECTION_ITERATIONS):
            residual = self._stack(self._positions, (self.k,), 1, t, y[:n])[0]
            try:
                dq = qd - self._metric_step(t, y[:n], qd, self.holonomic, residual)
            except np.linalg.LinAlgError:  # Phi_q (or M) singular here
                break
            y[:n] -= dq
            if not np.all(np.isfinite(y)):
                break
            size, scale = np.max(np.abs(dq)), max(1.0, np.max(np.abs(y[:n])))
            if size <= 1e-14 * scale or (size <= 1e-10 * scale and size > 0.5 * previous):
                return
            previous = size
        raise self._cannot(y)

    def _cannot(self, y) -> DerivationError:
        return DerivationError(
            "the initial state cannot be moved onto the constraints (Newton's iteration "
            f"on Phi(q) = 0 did not converge from q = {list(np.round(y[: self.n], 6))})",
            source=self.compiled.mechanics.scene.source,
            field="initial",
        )

    def _metric_step(self, t, q, qd, use, residual):
        """qd - M^-1 A^T (A M^-1 A^T)^-1 r over the rows ``use``, for r = residual, or
        r = A qdot + c (the velocities' violation)."""
        n, k = self.n, self.k
        P = self.compiled.parameters
        both = np.asarray(self._jacobian(t, q, P), float).reshape(-1)
        J, c = both[: n * k].reshape(k, n)[use], both[n * k :][use]
        M = np.asarray(self._mass(t, q, qd, P), float).reshape(n, n)
        r = J @ qd + c if residual is None else residual[use]
        X = np.linalg.solve(M, J.T)
        return qd - X @ np.linalg.solve(J @ X, r)
