"""Linear normal modes about the stable equilibrium nearest a scene's start, and the energy
each mode carries along a trajectory (the Fermi-Pasta-Ulam-Tsingou view of a lattice).

Small oscillations about a minimum ``q0`` of the potential ``U`` obey ``M qddot = -K dq``
with ``M`` the mass matrix and ``K`` the Hessian of ``U`` at ``q0``. The generalized
symmetric eigenproblem ``K v = w**2 M v`` (``scipy.linalg.eigh``) gives the frequencies
``w_k`` (ascending) and the mode shapes, normalized so that ``V^T M V = 1``. The point
transformation ``q = q0 + V Q`` has the conjugate momenta ``P = V^T p``, so

    E_k = (P_k**2 + w_k**2 Q_k**2) / 2,    Q = V^T M (q - q0),    P = V^T p,

and ``sum_k E_k`` is the quadratic part of H about ``(q0, 0)``: exactly H - U(q0) for a
harmonic system, and constant mode by mode there. For a lattice with weak anharmonic
terms the energies are nearly constant between exchanges (the FPU recurrence).

``U`` is ``-L`` at zero velocities (the potential energy, less any velocity-free part of
T), or ``H`` at zero momenta for a scene given by a Hamiltonian without a Lagrangian. The
minimum is found by a damped Newton descent on ``U`` from the scene's start (and from
q = 0), so it is the minimum whose basin holds the start; the expressions for the
gradient, the Hessian (only its structurally non-zero entries) and ``M`` are formed
symbolically once per derivation (by symengine, sympy where it cannot) and evaluated
with numbers for the current parameters: a 64-particle chain takes about 0.1 s.

When modes do not apply, ``analyse`` says why in one sentence (``ModeAnalysis.reason``)
instead of returning numbers: a rheonomic system, a potential that does not depend on
some coordinate (the Kepler problem's angle), terms of L linear in the velocities
(gyroscopic or magnetic: the modes of ``K v = w**2 M v`` are not its small oscillations;
so do effects that do no work, the same force given as a force),
no minimum reached from the start, or a zero frequency (a free translation of a ring).
Dissipation and driving forces are ignored: the modes are those of the conservative part.

With holonomic constraints ``Phi(q) = 0`` (and unilateral ones in contact) the small
oscillations keep to the constraints: the equilibrium and its modes come from
``systems.textbook.equilibria`` (the stable isolated equilibrium nearest the start), where
``K v = w**2 M v`` is solved on the tangent space ``ker Phi_q`` with the stiffness
``U_qq + sum_i lambda_i Phi_i,qq``. There are then d = n - k modes, and the mode shapes
(n, d) are displacements that keep the constraints to first order; ``Q = V^T M (q - q0)``
is the M-orthogonal projection onto them and ``P = V^T p`` their momenta (the point
transformation ``q = q0 + V Q`` restricted to the constraints). Nonholonomic constraints
are refused (see ``equilibria.not_computed``).

Headless (sympy, symengine, numpy, scipy); nothing is cached on disk. The symbolic preparation is
kept in memory as long as its ``Mechanics`` lives.
"""

from __future__ import annotations

import math
import weakref
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
import scipy.linalg
import sympy

from systems.angles import angle_flags
from systems.calculus import to_symengine
from systems.classification import does_no_work
from systems.cpu_limit import TimeLimitExceeded, cpu_limit
from systems.derivation_cache import remembered_job
from systems.mechanics import Mechanics
from systems.symmetries import ENERGY

PREPARE_SECONDS = 10.0
"""Limit on the symbolic preparation (gradient, Hessian, mass matrix) of one derivation."""
DESCENT_STEPS = 80
RELATIVE_GRADIENT = 1e-11
"""The descent stops when |dU/dq| falls below this fraction of the Hessian's scale."""
POSITIVE = 1e-9
"""A frequency squared counts as zero below this fraction of the largest one."""

_PREPARED: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


@dataclass(frozen=True, eq=False)
class NormalModes:
    """The linear normal modes of a system about a stable equilibrium.

    Attributes
    ----------
    coordinates : tuple of str
        The scene's coordinate names.
    q0 : ndarray, shape (n,)
        The equilibrium (a strict minimum of U, on the constraints if there are any).
    omega : ndarray, shape (d,)
        Angular frequencies, ascending, all > 0; d = n without constraints, the degrees of
        freedom n - k with k acting constraints.
    shapes : ndarray, shape (n, d)
        Column k is the shape of mode k + 1, normalized so that ``shapes.T @ M @ shapes``
        is the identity.
    mass, stiffness : ndarray, shape (n, n)
        M and K at ``q0``, with ``K v = w**2 M v`` for every mode: d2U/dq2 without
        constraints; with them, the stiffness on the tangent space,
        ``M V diag(w**2) V^T M`` (zero across the constraints).
    angles : ndarray of bool, shape (n,)
        Angle coordinates: their displacement from ``q0`` is wrapped to (-pi, pi].
    potential : float
        U(q0), the energy of the equilibrium.
    note : str
        Anything the numbers leave out (dissipation or forces ignored), or "".
    """

    coordinates: tuple[str, ...]
    q0: np.ndarray
    omega: np.ndarray
    shapes: np.ndarray
    mass: np.ndarray
    stiffness: np.ndarray
    angles: np.ndarray
    potential: float
    note: str = ""

    @property
    def n(self) -> int:
        """The number of modes d (the number of coordinates without constraints)."""
        return len(self.omega)

    def amplitudes(self, Y: np.ndarray, modes: int | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Modal coordinates and momenta ``(Q, P)``, each shape (N, d), of states ``Y``
        (shape (N, 2n) or (2n,), canonical ``(q, p)``); (N, modes) for the first
        ``modes`` only."""
        Y = np.atleast_2d(np.asarray(Y, dtype=float))
        n = len(self.q0)
        dq = Y[:, :n] - self.q0
        if self.angles.any():
            wrapped = np.mod(dq + math.pi, 2 * math.pi) - math.pi
            dq = np.where(self.angles, wrapped, dq)
        shapes = self.shapes if modes is None else self.shapes[:, :modes]
        Q = dq @ (self.mass @ shapes)
        P = Y[:, n:] @ shapes
        return Q, P

    def energies(self, Y: np.ndarray, modes: int | None = None) -> np.ndarray:
        """The energy in each mode, ``E_k = (P_k**2 + w_k**2 Q_k**2) / 2``: shape (N, d)
        for states ``Y`` of shape (N, 2n), or (N, modes) for the first ``modes`` only.
        Non-finite states give NaN rows."""
        Q, P = self.amplitudes(Y, modes)
        w = self.omega[: Q.shape[1]]
        return 0.5 * (P * P + (w * w) * (Q * Q))


@dataclass(frozen=True, eq=False)
class ModeAnalysis:
    """The outcome of ``analyse``: the modes, or the reason there are none."""

    modes: NormalModes | None
    reason: str = ""

    @property
    def applies(self) -> bool:
        return self.modes is not None


class _Prepared:
    """The symbolic part of the analysis of one derivation: U, its gradient and Hessian,
    the mass matrix and the momenta at rest, in one function of (q, parameters).

    The derivatives are taken by symengine (milliseconds for a 64-particle chain, where
    sympy's ``diff`` took seconds) and evaluated by its ``Lambdify``; sympy takes over
    for whatever symengine cannot represent.
    """

    def __init__(self, mechanics: Mechanics):
        self.reason = ""
        self.note = ""
        q = list(mechanics.q)
        self.n = n = len(q)
        self.parameter_names = [name for name, _ in mechanics.scene.parameters]
        self.args = [*q, *(mechanics.params[name] for name in self.parameter_names)]
        zero_qdot = dict.fromkeys(mechanics.qdot, sympy.S.Zero)
        zero_p = dict.fromkeys(mechanics.p, sympy.S.Zero)
        if ENERGY in mechanics.conserved:
            # L contains t only through a total time derivative dF/dt: U is the energy E
            # at rest (the potential of L without dF/dt); the momenta at rest are read
            # from L at t = 0, which adds F_q(q, 0) to them
            U = mechanics.conserved[ENERGY].xreplace(zero_qdot)
            kinetic = mechanics.lagrangian.xreplace({mechanics.t: sympy.S.Zero})
            velocities, zero = mechanics.qdot, zero_qdot
        elif mechanics.lagrangian is not None:
            U = -mechanics.lagrangian.xreplace(zero_qdot)
            kinetic, velocities, zero = mechanics.lagrangian, mechanics.qdot, zero_qdot
        elif mechanics.separable_parts is not None:
            U = mechanics.separable_parts[1]
            kinetic, velocities, zero = mechanics.separable_parts[0], mechanics.p, zero_p
        else:
            U = mechanics.hamiltonian.xreplace(zero_p)
            kinetic, velocities, zero = mechanics.hamiltonian, mechanics.p, zero_p
        # M itself, or (d2H/dp2 at p = 0)^-1 for a Hamiltonian without a Lagrangian
        self.inverse_mass = mechanics.mass_matrix is None
        mass = None if self.inverse_mass else mechanics.mass_matrix.xreplace(zero_qdot)
        t = mechanics.t
        if U.has(t) or (mass.has(t) if mass is not None else kinetic.has(t)):
            self.reason = (
                "the system is rheonomic (it depends explicitly on t), so it has no "
                "equilibrium to oscillate about"
            )
            return
        free = [
            name for name, qi in zip(mechanics.scene.coordinates, q, strict=True) if not U.has(qi)
        ]
        if free:
            self.reason = (
                f"the potential does not depend on {', '.join(free)}: "
                f"{'that coordinate moves' if len(free) == 1 else 'those coordinates move'} "
                "freely (a zero frequency), so there are no normal modes of small oscillation"
            )
            return
        forces = mechanics.generalized_forces
        if any(force != 0 for force in forces) and does_no_work(forces, mechanics.qdot):
            self.reason = (
                "the effects do no work but turn the velocities (a gyroscopic or magnetic "
                "force), so the small oscillations are not the normal modes of "
                "K v = \u03c9\u00b2 M v"
            )
            return
        if any(force != 0 for force in forces):
            self.note = "modes of the conservative part (dissipation and forces ignored)"
        # a natural T is quadratic in the velocities: no terms linear in them, no momenta
        # at rest; otherwise they are checked at the equilibrium
        self.check_rest = not mechanics.classification.natural
        problem = (U, kinetic, velocities, zero, mass, list(mechanics.p), zero_p)
        try:
            parts = _engine_parts(self.args, q, *problem, check_rest=self.check_rest)
        except _Unsupported:
            parts = _sympy_parts(self.args, q, *problem, check_rest=self.check_rest)
        self._evaluate, entries, self.hessian_index, self.mass_index = parts
        sizes = np.cumsum([0, 1, n, len(self.hessian_index[0]), len(self.mass_index[0])])
        self._slices = [slice(a, b) for a, b in zip(sizes[:-1], sizes[1:], strict=True)]
        self._slices.append(slice(sizes[-1], entries))
        self.angles = angle_flags(mechanics)

    def evaluate(self, x: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
        """U, dU/dq (n,) and K = d2U/dq2 (n, n) at ``x = (q, parameters)``."""
        values = self._evaluate(x)
        U, g, h = (values[s] for s in self._slices[:3])
        return float(U[0]), g, _symmetric(self.n, self.hessian_index, h)

    def potential(self, x: np.ndarray) -> float:
        return float(self._evaluate(x)[0])

    def mass(self, x: np.ndarray) -> np.ndarray:
        """M at ``x``; NaN where d2H/dp2 (for a scene given by H alone) is singular."""
        matrix = _symmetric(self.n, self.mass_index, self._evaluate(x)[self._slices[3]])
        if self.inverse_mass:
            if not _regular(matrix):
                return np.full((self.n, self.n), np.nan)
            return np.linalg.inv(matrix)
        return matrix

    def rest(self, x: np.ndarray) -> np.ndarray:
        """The momenta at zero velocity (or dH/dp at p = 0), shape (n,) or (0,)."""
        return self._evaluate(x)[self._slices[4]]


class _Unsupported(Exception):
    """symengine cannot represent or differentiate an expression: use sympy."""


def _upper_entries(n: int, matrix) -> tuple[list, np.ndarray, np.ndarray]:
    """The structurally non-zero entries of a symmetric matrix's upper triangle."""
    entries, rows, cols = [], [], []
    for i in range(n):
        for j in range(i, n):
            if matrix(i, j) != 0:
                entries.append(matrix(i, j))
                rows.append(i)
                cols.append(j)
    return entries, (np.array(rows, dtype=int), np.array(cols, dtype=int))


def _engine_parts(args, q, U, kinetic, velocities, zero, mass, p, zero_p, *, check_rest):
    """(evaluate, count, hessian index, mass index) by symengine; ``_Unsupported`` if not."""
    try:
        import symengine
    except ImportError:  # a dependency; sympy alone is only slower
        raise _Unsupported("symengine is not installed") from None
    try:
        plain = {s: symengine.Symbol(s.name) for s in {*args, *velocities, *p}}
        qs = [plain[s] for s in q]
        EU = to_symengine(U)
        gradient = [EU.diff(x) for x in qs]
        hessian = {}
        for i, g in enumerate(gradient):
            holds = g.free_symbols
            for j in range(i, len(qs)):
                if qs[j] in holds:
                    hessian[i, j] = g.diff(qs[j])
        h_entries, h_index = _upper_entries(len(q), lambda i, j: hessian.get((i, j), 0))
        if mass is not None:
            m_entries, m_index = _upper_entries(len(q), lambda i, j: to_symengine(mass[i, j]))
        else:
            T = to_symengine(kinetic)
            at_rest = {plain[s]: 0 for s in p}
            first = [T.diff(plain[s]) for s in p]
            W = {}
            for i in range(len(p)):
                for j in range(i, len(p)):
                    W[i, j] = first[i].diff(plain[p[j]]).subs(at_rest)
            m_entries, m_index = _upper_entries(len(q), lambda i, j: W[i, j])
        rest = []
        if check_rest:
            T = to_symengine(kinetic)
            stop = {plain[s]: 0 for s in zero}
            rest = [T.diff(plain[v]).subs(stop) for v in velocities]
        expressions = [EU, *gradient, *h_entries, *m_entries, *rest]
        function = symengine.Lambdify(
            [plain[s] for s in args], expressions, real=True, backend="lambda", cse=True
        )
    except (RuntimeError, TypeError, ValueError, NotImplementedError, AttributeError) as exc:
        raise _Unsupported(str(exc)) from None
    count = len(expressions)

    def evaluate(x: np.ndarray) -> np.ndarray:
        with np.errstate(all="ignore"):
            return np.asarray(function(np.asarray(x, dtype=float)), dtype=float).reshape(count)

    return evaluate, count, h_index, m_index


def _sympy_parts(args, q, U, kinetic, velocities, zero, mass, p, zero_p, *, check_rest):
    """``_engine_parts`` by sympy alone (slower, for what symengine cannot do)."""
    position = {qi: i for i, qi in enumerate(q)}
    gradient = [sympy.S.Zero] * len(q)
    for qi, derivative in _partials(U, q).items():
        gradient[position[qi]] = derivative
    hessian = {}
    for i, g in enumerate(gradient):
        for qj, derivative in _partials(g, q[i:]).items():
            hessian[i, position[qj]] = derivative
    h_entries, h_index = _upper_entries(len(q), lambda i, j: hessian.get((i, j), 0))
    if mass is not None:
        m_entries, m_index = _upper_entries(len(q), lambda i, j: mass[i, j])
    else:
        first = _partials(kinetic, p)
        W = {}
        for i, a in enumerate(p):
            column = _partials(first.get(a, sympy.S.Zero), p[i:])
            for j in range(i, len(p)):
                W[i, j] = column.get(p[j], sympy.S.Zero).xreplace(zero_p)
        m_entries, m_index = _upper_entries(len(q), lambda i, j: W[i, j])
    rest = []
    if check_rest:
        found = _partials(kinetic, velocities)
        rest = [found.get(v, sympy.S.Zero).xreplace(zero) for v in velocities]
    expressions = [U, *gradient, *h_entries, *m_entries, *rest]
    raw = sympy.lambdify(args, expressions, modules="numpy", cse=True)
    count = len(expressions)

    def evaluate(x: np.ndarray) -> np.ndarray:
        with np.errstate(all="ignore"):
            values = [np.asarray(v, dtype=float) for v in raw(*x)]
        return np.array([float(v) for v in values]).reshape(count)

    return evaluate, count, h_index, m_index


def _partials(expr: sympy.Expr, symbols: Sequence[sympy.Symbol]) -> dict:
    """The non-zero derivatives of ``expr`` by each of ``symbols`` (symbol -> expression),
    term by term: a term of a sum is differentiated only by the symbols it holds, so a
    lattice's potential costs O(terms), not O(terms x coordinates)."""
    wanted = set(symbols)
    parts: dict[sympy.Symbol, list] = {}
    for term in sympy.Add.make_args(expr):
        for symbol in term.free_symbols & wanted:
            parts.setdefault(symbol, []).append(sympy.diff(term, symbol))
    out = {}
    for symbol, terms in parts.items():
        derivative = sympy.Add(*terms)
        if derivative != 0:
            out[symbol] = derivative
    return out


def _symmetric(n: int, index: tuple[np.ndarray, np.ndarray], values: np.ndarray) -> np.ndarray:
    """The symmetric (n, n) matrix with ``values`` at ``index`` (upper triangle)."""
    matrix = np.zeros((n, n))
    matrix[index] = values
    matrix[index[1], index[0]] = values
    return matrix


def prepare(mechanics: Mechanics) -> _Prepared:
    """The symbolic preparation of ``mechanics`` (kept while ``mechanics`` lives).

    Raises ``TimeLimitExceeded`` when it takes longer than ``PREPARE_SECONDS``.
    """
    try:
        return _PREPARED[mechanics]
    except (KeyError, TypeError):
        pass
    with cpu_limit(PREPARE_SECONDS, "the normal-mode analysis"):
        prepared = _Prepared(mechanics)
    try:
        _PREPARED[mechanics] = prepared
    except TypeError:  # not weak-referenceable: no caching
        pass
    return prepared


@remembered_job
def analyse(
    mechanics: Mechanics,
    parameters: Sequence[float] | Mapping[str, float] | None = None,
    start: Sequence[float] | None = None,
) -> ModeAnalysis:
    """The normal modes about the stable equilibrium nearest ``start``, or why there are none.

    Parameters
    ----------
    mechanics : Mechanics
        From ``systems.mechanics.derive``.
    parameters : sequence (scene order) or mapping of name to value, optional
        Parameter values; the scene's by default.
    start : sequence of float, shape (n,), optional
        The configuration q whose nearest minimum is wanted (the scene's start by default,
        missing entries 0).

    Returns
    -------
    ModeAnalysis
        Never raises for a scene that derived.
    """
    from systems.constraints import constrained

    if constrained(mechanics.scene):
        # the free coordinates' U and M would give wrong modes (the Cartesian pendulum's
        # x "moves freely"): small oscillations keep to the constraints' tangent space
        return _constrained_modes(mechanics, parameters, start)
    try:
        prepared = prepare(mechanics)
    except TimeLimitExceeded as exc:
        return ModeAnalysis(None, f"{exc} (the potential is too large)")
    if prepared.reason:
        return ModeAnalysis(None, prepared.reason)
    values = dict(mechanics.scene.parameter_values)
    if isinstance(parameters, Mapping):
        values.update({k: float(v) for k, v in parameters.items()})
    elif parameters is not None:
        values.update(zip(prepared.parameter_names, (float(v) for v in parameters), strict=True))
    p = np.array([values[name] for name in prepared.parameter_names], dtype=float)
    n = prepared.n
    if start is None:
        initial = mechanics.scene.initial_values
        start = [float(initial.get(name, 0.0)) for name in mechanics.scene.coordinates]
    start = np.asarray(start, dtype=float)[:n]
    minima, neutral = [], []
    for origin in (start, np.zeros(n)):
        with np.errstate(all="ignore"):
            found, kind = _descend(prepared, origin, p)
        if kind == "neutral":
            neutral.append(found)
        elif found is not None and not any(np.allclose(found, m, atol=1e-8) for m in minima):
            minima.append(found)
    if not minima and neutral:
        where = _describe(mechanics.scene.coordinates, neutral[0])
        return ModeAnalysis(
            None,
            f"the equilibrium at {where} has a zero frequency (a neutral direction such as a "
            "free translation), so not every mode oscillates",
        )
    if not minima:
        return ModeAnalysis(
            None,
            "no stable equilibrium near the start: a descent of the potential from the start "
            "(and from q = 0) reaches no minimum",
        )
    q0 = min(minima, key=lambda m: float(np.linalg.norm(m - start)))
    return _modes_at(prepared, mechanics, q0, p)


def _constrained_modes(
    mechanics: Mechanics,
    parameters: Sequence[float] | Mapping[str, float] | None,
    start: Sequence[float] | None,
) -> ModeAnalysis:
    """``analyse`` for a scene with ``[constraints]``: the stable isolated equilibrium of
    ``systems.textbook.equilibria`` nearest ``start`` and its modes on the tangent space
    of the constraints acting there."""
    from systems.constraints import counts
    from systems.textbook._numeric import vectorize, with_parameters
    from systems.textbook.equilibria import search_equilibria

    if counts(mechanics.scene)["nonholonomic"]:
        return ModeAnalysis(
            None,
            "normal modes of a system with nonholonomic constraints are not computed: its "
            "equilibria form manifolds, and the linearised motion about them is not a "
            "symmetric eigenproblem K v = \u03c9\u00b2 M v (the reduced stiffness "
            "Z\u1d40(U_qq + \u03a3\u03bb\u1d62 \u2202a\u1d62/\u2202q)Z is not symmetric)",
        )

    names = [name for name, _ in mechanics.scene.parameters]
    if parameters is None:
        values = {}
    elif isinstance(parameters, Mapping):
        values = {k: float(v) for k, v in parameters.items()}
    else:
        values = dict(zip(names, (float(v) for v in parameters), strict=True))
    search = search_equilibria(mechanics, parameters=values, symbolic=False)
    if not search.equilibria:
        reason = search.reason or "the search found none"
        return ModeAnalysis(None, f"no equilibrium to oscillate about ({reason})")
    if search.free:
        free = ", ".join(search.free)
        moves = "that coordinate moves" if len(search.free) == 1 else "those coordinates move"
        return ModeAnalysis(
            None,
            f"neither the potential nor the constraints depend on {free}: {moves} freely "
            "(a zero frequency), so there are no normal modes of small oscillation",
        )
    candidates = [e for e in search.equilibria if e.stable and e.continuum is None]
    if not candidates:
        if any(e.stable for e in search.equilibria):
            return ModeAnalysis(
                None,
                "the stable equilibria form a set (a zero frequency along it), so not every "
                "mode oscillates",
            )
        return ModeAnalysis(None, "no stable equilibrium on the constraints")
    n = mechanics.n
    angles = np.asarray(angle_flags(mechanics), dtype=bool)
    if start is None:
        initial = mechanics.scene.initial_values
        start = [float(initial.get(name, 0.0)) for name in mechanics.scene.coordinates]
    start = np.asarray(start, dtype=float)[:n]

    def distance(e) -> float:
        d = np.array(list(e.q.values())) - start
        d = np.where(angles, np.mod(d + math.pi, 2 * math.pi) - math.pi, d)
        return float(np.linalg.norm(d))

    e = min(candidates, key=distance)
    q0 = np.array(list(e.q.values()), dtype=float)
    where = _describe(mechanics.scene.coordinates, q0)
    if np.any(np.asarray(e.gyroscopic) != 0):
        return ModeAnalysis(
            None,
            "the kinetic energy has terms linear in the velocities (gyroscopic or "
            "magnetic), so the small oscillations are not the normal modes of K v = ω² M v",
        )
    shapes = np.asarray(e.modes, dtype=float)
    if e.kind != "minimum" or not shapes.shape[1] or len(e.frequencies) != shapes.shape[1]:
        if not shapes.shape[1]:
            return ModeAnalysis(
                None,
                f"the constraints acting at {where} leave no motion to oscillate "
                "(no degree of freedom)",
            )
        return ModeAnalysis(
            None,
            f"the equilibrium at {where} has a zero frequency (a neutral direction), so not "
            "every mode oscillates",
        )
    zero = {**dict.fromkeys(mechanics.qdot, 0), mechanics.t: 0}
    entries = [
        with_parameters(entry, mechanics, values).xreplace(zero) for entry in mechanics.mass_matrix
    ]
    M = np.asarray(vectorize(entries, mechanics.q)(*q0), dtype=float).reshape(n, n)
    omega = np.asarray(e.frequencies, dtype=float)
    signs = np.sign(shapes[np.argmax(np.abs(shapes), axis=0), np.arange(shapes.shape[1])])
    shapes = shapes * np.where(signs == 0, 1.0, signs)
    MV = M @ shapes
    notes = []
    if any(force != 0 for force in mechanics.generalized_forces):
        notes.append("modes of the conservative part (dissipation and forces ignored)")
    if e.contacts:
        held = ", ".join(f"{name} = {e.multipliers[name]:.4g}" for name in e.contacts)
        notes.append(f"along a resting contact ({held}), while it holds")
    return ModeAnalysis(
        NormalModes(
            coordinates=tuple(mechanics.scene.coordinates),
            q0=q0,
            omega=omega,
            shapes=shapes,
            mass=M,
            stiffness=MV @ np.diag(omega**2) @ MV.T,
            angles=angles,
            potential=e.potential,
            note="; ".join(notes),
        )
    )


def analyse_compiled(compiled, y0: np.ndarray | None = None) -> ModeAnalysis:
    """``analyse`` for a ``CompiledSystem`` at its current parameters, nearest the
    configuration of ``y0`` (shape (2n,); the scene's start by default)."""
    if y0 is None:
        y0 = compiled.initial_state()
    return analyse(
        compiled.mechanics, np.asarray(compiled.parameters), np.asarray(y0)[: compiled.n]
    )


def _descend(prepared: _Prepared, q: np.ndarray, p: np.ndarray) -> tuple[np.ndarray | None, str]:
    """Damped Newton steps down U from ``q``: ``(q0, "minimum")`` at a strict local
    minimum, ``(q0, "neutral")`` at a minimum with a flat direction, or ``(None, "none")``.

    At a saddle or a maximum (a start exactly on top of an inverted pendulum) it steps
    off along the direction of most negative curvature and goes on down.
    """
    q = q.astype(float).copy()
    reach = 1e6 * (1.0 + np.linalg.norm(q))
    for _ in range(DESCENT_STEPS):
        if not np.linalg.norm(q) < reach:
            return None, "none"  # running off: U keeps decreasing (a linear potential)
        x = np.concatenate([q, p])
        u, g, K = prepared.evaluate(x)
        if not (math.isfinite(u) and np.all(np.isfinite(g)) and np.all(np.isfinite(K))):
            return None, "none"
        eigenvalues, vectors = np.linalg.eigh(K)
        scale = max(float(np.max(np.abs(eigenvalues))), 1e-300)
        lowest = eigenvalues[0] / scale
        if np.linalg.norm(g) <= RELATIVE_GRADIENT * scale * (1.0 + np.linalg.norm(q)):
            if lowest > POSITIVE:
                polished = q - np.linalg.solve(K, g)  # one more Newton step, to round-off
                return (polished if np.all(np.isfinite(polished)) else q), "minimum"
            if lowest >= -POSITIVE:
                return q, "neutral"
            q = q + 1e-3 * (1.0 + np.linalg.norm(q)) * vectors[:, 0]  # off the saddle
            continue
        shift = 0.0 if lowest > POSITIVE else 1e-3 * scale - eigenvalues[0]
        try:
            step = np.linalg.solve(K + shift * np.eye(len(q)), -g)
        except np.linalg.LinAlgError:
            return None, "none"
        slope = float(g @ step)
        alpha = 1.0
        while alpha > 1e-10:
            trial = q + alpha * step
            value = prepared.potential(np.concatenate([trial, p]))
            if math.isfinite(value) and value <= u + 1e-4 * alpha * slope:
                break
            alpha *= 0.5
        else:
            # no decrease is measurable: converged to round-off, if the step is tiny
            if np.linalg.norm(step) <= 1e-9 * (1.0 + np.linalg.norm(q)):
                return q, "minimum" if lowest > POSITIVE else "neutral"
            return None, "none"
        q = trial
    return None, "none"


def _modes_at(prepared: _Prepared, mechanics: Mechanics, q0: np.ndarray, p: np.ndarray):
    x = np.concatenate([q0, p])
    potential, _, K = prepared.evaluate(x)
    M = prepared.mass(x)
    where = _describe(mechanics.scene.coordinates, q0)
    if not np.all(np.isfinite(K)):
        return ModeAnalysis(None, f"the potential's curvature is not finite at {where}")
    if not np.all(np.isfinite(M)):
        return ModeAnalysis(
            None,
            f"the mass matrix at {where} is not finite (d²H/dp² is singular at p = 0: "
            "no inertia for small oscillations)",
        )
    try:
        mass_eigenvalues = np.linalg.eigvalsh(M)
    except np.linalg.LinAlgError:
        return ModeAnalysis(None, f"the mass matrix at {where} has no eigenvalues")
    if mass_eigenvalues[0] <= 1e-13 * max(abs(mass_eigenvalues[-1]), 1e-300):
        return ModeAnalysis(None, f"the mass matrix at {where} is not positive definite")
    if prepared.check_rest and _has_rest_momenta(prepared, q0, p):
        return ModeAnalysis(
            None,
            "the kinetic energy has terms linear in the velocities (gyroscopic or "
            "magnetic), so the small oscillations are not the normal modes of K v = ω² M v",
        )
    try:
        w2, shapes = scipy.linalg.eigh(K, M)
    except (np.linalg.LinAlgError, ValueError) as exc:
        return ModeAnalysis(None, f"the eigenproblem K v = ω² M v failed at {where}: {exc}")
    if w2[0] <= POSITIVE * max(abs(w2[-1]), 1e-300):
        return ModeAnalysis(
            None,
            f"the equilibrium at {where} has a zero frequency (a neutral direction such as a "
            "free translation), so not every mode oscillates",
        )
    # a sign convention, so that mode shapes do not flip between parameter values
    signs = np.sign(shapes[np.argmax(np.abs(shapes), axis=0), np.arange(len(w2))])
    shapes = shapes * np.where(signs == 0, 1.0, signs)
    return ModeAnalysis(
        NormalModes(
            coordinates=tuple(mechanics.scene.coordinates),
            q0=q0,
            omega=np.sqrt(w2),
            shapes=shapes,
            mass=M,
            stiffness=K,
            angles=np.asarray(prepared.angles, dtype=bool),
            potential=potential,
            note=prepared.note,
        )
    )


def _has_rest_momenta(prepared: _Prepared, q0: np.ndarray, p: np.ndarray) -> bool:
    """True if the momenta at zero velocity do not vanish at and around ``q0`` (terms of
    L linear in the velocities; a magnetic term vanishes at the centre but not near it)."""
    rng = np.random.default_rng(5)
    points = [q0, *(q0 + 0.1 * (1.0 + np.abs(q0)) * rng.uniform(-1, 1, len(q0)) for _ in range(2))]
    for q in points:
        rest = prepared.rest(np.concatenate([q, p]))
        if not np.all(np.isfinite(rest)) or np.any(np.abs(rest) > 1e-12):
            return True
    return False


def _regular(matrix: np.ndarray) -> bool:
    """Finite and invertible (not merely numerically)."""
    if not np.all(np.isfinite(matrix)):
        return False
    singular = np.linalg.svd(matrix, compute_uv=False)
    return bool(singular[-1] > 1e-13 * singular[0])


def _describe(names: Sequence[str], q: np.ndarray) -> str:
    """``q = 0`` or ``(x, y) = (0.1, 2)``, short."""
    if np.all(np.abs(q) < 1e-12):
        return "q = 0"
    if len(names) > 4:
        return f"the minimum near |q| = {float(np.linalg.norm(q)):.3g}"
    values = ", ".join(f"{v:.4g}" for v in q)
    return f"({', '.join(names)}) = ({values})" if len(names) > 1 else f"{names[0]} = {values}"
