"""Driven systems by Floquet theory: constant solutions and their multipliers.

Where L (or H) depends on t, and t enters only through sines and cosines of ``w t +
phase`` whose frequencies are commensurate, the equations are periodic in t with the
common period T (``periodicity``). A *constant solution* q* is a configuration at rest
that stays at rest: Lagrange's ``M(q, t) qdd = F(q, qdot, t)`` holds with qdot = qdd = 0
for every t, that is ``F(q*, 0, t) = 0`` for all t (``constant_solutions`` solves it at
several times of one period at once, then checks it at others). The Kapitza pendulum's
hanging and inverted positions are such solutions, although its pivot moves.

The stability of a constant solution (or of any periodic orbit, ``periodic_orbits``) is
read from the monodromy matrix M: the solution over one period of the variational
equations ``Phi' = J(y(t), t) Phi``, ``Phi(0) = 1``, with J the Jacobian of Hamilton's
equations along the solution (``monodromy``). Its eigenvalues are the Floquet multipliers.
Without effects Hamilton's flow is symplectic: det M = 1 (Liouville), multipliers come in
pairs mu, 1/mu, and the solution is linearly stable exactly when every multiplier lies on
the unit circle and none is repeated (for one degree of freedom: |tr M| < 2). A repeated
multiplier on the circle (tr M = +-2) is the boundary between stability and parametric
resonance: ``marginal``. Damping makes det M < 1; the solution is then asymptotically
stable when every |mu| < 1. The determinant is compared with exp(integral of tr J) (the
Liouville formula) as a check of the integration.

The multipliers are integrated with scipy's DOP853 at ``RTOL`` (1e-11). Numeric work only
after the symbolic set-up (``VariationalSystem.build``: Jacobian and lambdified
functions, picklable), so a stability chart over two parameters (``stability_chart``)
needs no sympy.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from fractions import Fraction

import numpy as np
import sympy

from systems.cpu_limit import TimeLimitExceeded, cpu_limit
from systems.expressions import as_expr
from systems.mechanics import Mechanics
from systems.textbook._numeric import fold_angle, periodic_symbols, vectorize

RTOL = 1e-11
"""DOP853's relative tolerance for the multipliers (the absolute one is ``ATOL``)."""
ATOL = 1e-13
UNIT_TOLERANCE = 1e-6
"""|mu| within this of 1 is on the unit circle; |tr M| within it of 2 is marginal."""
SAMPLE_TIMES = 7
"""Times in one period at which F(q, 0, t) = 0 is solved together."""
SECONDS = 15.0
"""CPU seconds the analysis of one system may take (like the equilibrium search)."""
MAX_DENOMINATOR = 64
"""Frequency ratios are commensurate when a fraction with at most this denominator fits."""
MAX_EVALUATIONS = 20_000
"""Right-hand side evaluations one monodromy matrix may take (a regular constant solution
needs a few thousand): beyond them the equations are stiff or singular near the solution,
which is then reported undecided, leaving the others their share of ``SECONDS``."""


class NotPeriodic(ValueError):
    """The explicit time dependence is not periodic; ``str()`` says why, for a person."""


# -- periodicity --------------------------------------------------------------------------


def time_harmonics(
    exprs: Sequence[sympy.Expr], t: sympy.Symbol, constants: Sequence[sympy.Symbol] | None = None
) -> list[sympy.Expr]:
    """The angular frequencies w of the sin(w t + phase) and cos(w t + phase) through
    which alone ``exprs`` depend on t (w free of t and of the state; may hold
    parameters), distinct, in order of appearance.

    Raises
    ------
    NotPeriodic
        When t appears anywhere else (``t``, ``exp(t)``, ``cos(t**2)``), or in a frequency.
    """
    omegas: list[sympy.Expr] = []
    replaced = {}
    for expr in exprs:
        expr = as_expr(expr)
        for atom in sorted(expr.atoms(sympy.Function), key=sympy.default_sort_key):
            if not atom.has(t):
                continue
            if not isinstance(atom, (sympy.sin, sympy.cos)):
                raise NotPeriodic(f"t appears in {atom}, not only in sines and cosines")
            argument = atom.args[0]
            omega = sympy.diff(argument, t)
            if omega.has(t) or sympy.diff(argument - omega * t, t) != 0:
                raise NotPeriodic(f"the argument of {atom} is not linear in t")
            if constants is not None and not omega.free_symbols <= set(constants):
                raise NotPeriodic(f"the frequency of {atom} depends on the state")
            if omega.could_extract_minus_sign():
                omega = -omega
            if all(sympy.simplify(omega - known) != 0 for known in omegas):
                omegas.append(omega)
            replaced[atom] = sympy.Dummy()
    for expr in exprs:
        rest = as_expr(expr).xreplace(replaced)
        if rest.has(t):
            raise NotPeriodic("t appears outside the sines and cosines of w·t + phase")
    return omegas


def common_period(omegas: Sequence[float]) -> float | None:
    """The smallest T > 0 with every w T a multiple of 2 pi (frequencies of either sign;
    zeros ignored); None when the ratios are not rational with a denominator of at most
    ``MAX_DENOMINATOR`` (quasi-periodic), or every w is 0."""
    values = [abs(float(w)) for w in omegas if abs(float(w)) > 1e-14]
    if not values:
        return None
    base = values[0]
    ratios = []
    for w in values:
        fraction = Fraction(w / base).limit_denominator(MAX_DENOMINATOR)
        if abs(float(fraction) - w / base) > 1e-9 * max(1.0, w / base):
            return None
        ratios.append(fraction)
    lcm = 1
    for r in ratios:
        lcm = lcm * r.denominator // math.gcd(lcm, r.denominator)
    integers = [int(r * lcm) for r in ratios]
    divisor = 0
    for k in integers:
        divisor = math.gcd(divisor, k)
    fundamental = base * divisor / lcm
    return 2.0 * math.pi / fundamental


@dataclass(frozen=True)
class Periodicity:
    """How the equations depend on t.

    Attributes
    ----------
    periodic : bool
        True when t enters only through sin/cos of commensurate frequencies (at these
        parameter values) that are not all 0.
    period : float or None
        The common period T at these parameter values.
    frequencies : tuple of str
        The angular frequencies, as written in the scene's symbols.
    reason : str
        One sentence for a person: the period and where it comes from, or why there is no
        Floquet analysis.
    """

    periodic: bool
    period: float | None
    frequencies: tuple[str, ...]
    reason: str


def _equations(mechanics: Mechanics) -> list[sympy.Expr]:
    """The equations the constant solutions and multipliers come from: Lagrange's M and F
    where there is a Lagrangian, and Hamilton's equations (which integrate them)."""
    exprs = list(mechanics.hamilton_equations)
    if mechanics.mass_matrix is not None and mechanics.forcing is not None:
        exprs += list(mechanics.mass_matrix) + list(mechanics.forcing)
    return exprs


def periodicity(mechanics: Mechanics, parameters: Mapping[str, float] | None = None) -> Periodicity:
    """Whether the explicit time dependence of ``mechanics`` is periodic, and its period."""
    t = mechanics.t
    try:
        omegas = time_harmonics(_equations(mechanics), t, list(mechanics.params.values()))
    except NotPeriodic as exc:
        return Periodicity(False, None, (), f"not periodic ({exc}): no Floquet analysis")
    if not omegas:
        return Periodicity(False, None, (), "the equations do not contain t")
    values = _parameter_values(mechanics, parameters)
    numbers = [float(w.xreplace(values)) for w in omegas]
    shown = tuple(str(w) for w in omegas)
    period = common_period(numbers)
    if period is None:
        if all(abs(w) <= 1e-14 for w in numbers):
            why = "every frequency of the drive is 0 at these parameter values"
        else:
            why = f"the frequencies {', '.join(shown)} are incommensurate (quasi-periodic)"
        return Periodicity(False, None, shown, f"not periodic ({why}): no Floquet analysis")
    through = ", ".join("t" if w == "1" else f"{w}·t" for w in shown)
    return Periodicity(
        True,
        period,
        shown,
        f"t enters only through sines and cosines of {through}: period T = {period:.6g}",
    )


def _parameter_values(mechanics, parameters) -> dict:
    values = dict(mechanics.scene.parameter_values)
    values.update(parameters or {})
    return {mechanics.params[k]: sympy.Float(float(v)) for k, v in values.items()}


def explicit_time(mechanics: Mechanics) -> bool:
    """True when L (or H without L) depends on t beyond a total time derivative: the
    systems the equilibrium search leaves to this module."""
    from systems.symmetries import ENERGY

    if ENERGY in mechanics.conserved or mechanics.classification.gauge_time:
        return False
    expression = mechanics.lagrangian if mechanics.lagrangian is not None else None
    if expression is None:
        expression = mechanics.hamiltonian
    return bool(as_expr(expression).has(mechanics.t))


# -- the variational system -----------------------------------------------------------------


@dataclass(frozen=True)
class VariationalSystem:
    """Hamilton's equations and their Jacobian as numpy functions, picklable.

    Every function takes ``(t, *q, *p, *parameters)`` (``rest`` and ``rest_momenta``:
    ``(t, *q, *parameters)``) as broadcasting arrays and returns an array of shape
    ``(count, *shape)``.

    Attributes
    ----------
    names : tuple of str
        Coordinates.
    parameter_names : tuple of str
    n : int
    rhs : Vectorized
        (qdot, pdot), 2n entries.
    jacobian : Vectorized
        d(rhs)/d(q, p), (2n)^2 entries row by row.
    rest : Vectorized or None
        F(q, qdot = 0, t), n entries: zero for all t at a constant solution (None for a
        scene given by H alone: Hamilton's equations themselves, in (q, p), are used).
    rest_momenta : Vectorized or None
        p(q, qdot = 0, t), n entries.
    frequencies : Vectorized or None
        The drive's angular frequencies as functions of the parameters.
    symplectic : bool
        No effects: the flow is Hamiltonian, det M = 1.
    searched : tuple of int
        The coordinates the constant solutions depend on (the others are free, set to 0).
    angles : tuple of int
        Coordinates in which the equations are 2 pi-periodic (folded into (-pi, pi]).
    """

    names: tuple[str, ...]
    parameter_names: tuple[str, ...]
    n: int
    rhs: object
    jacobian: object
    rest: object | None
    rest_momenta: object | None
    frequencies: object | None
    symplectic: bool
    searched: tuple[int, ...]
    angles: tuple[int, ...]
    parameters: tuple[float, ...] = field(default=())
    """The scene's parameter values."""
    hamiltonian: object | None = None
    """H(t, q, p, parameters), one entry."""

    @classmethod
    def build(cls, mechanics: Mechanics) -> VariationalSystem:
        """The variational system of a derived scene (not in matrix form, no constraints).

        Raises
        ------
        ValueError
            For a system in matrix form or with ``[constraints]``: why, for a person.
        """
        from systems.constraints import constrained

        if mechanics.matrix_form is not None:
            raise ValueError(
                "the velocities are solved numerically at every step (matrix form), so "
                "the Jacobian of Hamilton's equations is not formed"
            )
        if constrained(mechanics.scene):
            raise ValueError("systems with [constraints] are not analysed by Floquet theory")
        t, q, p = mechanics.t, list(mechanics.q), list(mechanics.p)
        names = tuple(mechanics.scene.coordinates)
        parameter_names = tuple(name for name, _ in mechanics.scene.parameters)
        P = [mechanics.params[name] for name in parameter_names]
        equations = [as_expr(e) for e in mechanics.hamilton_equations]
        state = [*q, *p]
        J = [sympy.diff(e, s) for e in equations for s in state]
        args = [t, *state, *P]
        rest = rest_momenta = None
        if mechanics.forcing is not None and mechanics.momenta is not None:
            at_rest = dict.fromkeys(mechanics.qdot, sympy.S.Zero)
            rest_exprs = [as_expr(f).xreplace(at_rest) for f in mechanics.forcing]
            rest = vectorize(rest_exprs, [t, *q, *P])
            rest_momenta = vectorize(
                [as_expr(m).xreplace(at_rest) for m in mechanics.momenta], [t, *q, *P]
            )
            depends = [any(e.has(qi) for e in rest_exprs) for qi in q]
            everything = [t, *mechanics.q, *mechanics.qdot, *mechanics.p]
            numeric = sum(rest_exprs, sympy.S.Zero).xreplace(_parameter_values(mechanics, None))
        else:
            depends = [
                any(e.has(qi) or e.has(pi) for e in equations) for qi, pi in zip(q, p, strict=True)
            ]
            everything = [t, *mechanics.q, *mechanics.p]
            numeric = sum(equations, sympy.S.Zero).xreplace(_parameter_values(mechanics, None))
        angles_found = periodic_symbols(numeric, q, everything)
        try:
            omegas = time_harmonics(_equations(mechanics), t, list(mechanics.params.values()))
        except NotPeriodic:
            omegas = []
        frequencies = vectorize(omegas, P) if omegas else None
        symplectic = all(as_expr(f) == 0 for f in mechanics.generalized_forces)
        return cls(
            names=names,
            parameter_names=parameter_names,
            n=len(q),
            rhs=vectorize(equations, args),
            jacobian=vectorize(J, args),
            rest=rest,
            rest_momenta=rest_momenta,
            frequencies=frequencies,
            symplectic=symplectic,
            searched=tuple(i for i, d in enumerate(depends) if d),
            angles=tuple(i for i, qi in enumerate(q) if qi in angles_found),
            parameters=tuple(float(v) for _, v in mechanics.scene.parameters),
            hamiltonian=vectorize([as_expr(mechanics.hamiltonian)], args),
        )

    def parameter_vector(self, parameters: Mapping[str, float] | None = None) -> np.ndarray:
        """The parameter values in order, the scene's with ``parameters`` overriding."""
        values = dict(zip(self.parameter_names, self.parameters, strict=True))
        values.update(parameters or {})
        return np.array([float(values[name]) for name in self.parameter_names])

    def period(self, P: np.ndarray) -> float | None:
        """The drive's period at parameter values ``P`` (None: not periodic there)."""
        if self.frequencies is None:
            return None
        return common_period(np.atleast_1d(self.frequencies(*P)).ravel().tolist())

    def state_at_rest(self, q: np.ndarray, P: np.ndarray, t: float = 0.0) -> np.ndarray:
        """(q, p) at rest at q and time t."""
        if self.rest_momenta is None:
            raise ValueError("a scene given by H alone has no state at rest")
        p = np.asarray(self.rest_momenta(t, *q, *P), dtype=float).ravel()
        return np.concatenate([np.asarray(q, dtype=float), p])


# -- monodromy ------------------------------------------------------------------------------


@dataclass(frozen=True)
class Monodromy:
    """The monodromy matrix over one period and what it says.

    Attributes
    ----------
    matrix : ndarray (2n, 2n)
    multipliers : ndarray (2n,) complex
        Its eigenvalues, largest modulus first.
    determinant : float
        det M (1 for a Hamiltonian flow).
    liouville : float
        exp(integral of tr J dt) over the period: what det M must equal.
    closure : float
        |y(T) - y(0)| of the reference solution (0 for a periodic one).
    final : ndarray (2n,)
        y(T).
    evaluations : int
        Right-hand side evaluations of DOP853.
    """

    matrix: np.ndarray
    multipliers: np.ndarray
    determinant: float
    liouville: float
    closure: float
    final: np.ndarray
    evaluations: int


def monodromy(
    system: VariationalSystem,
    y0: np.ndarray,
    period: float,
    P: np.ndarray,
    *,
    t0: float = 0.0,
    rtol: float = RTOL,
    atol: float = ATOL,
    cancel=None,
    max_evaluations: int | None = None,
) -> Monodromy:
    """Integrate the solution from ``y0`` and its variational equations over one period
    (``RuntimeError`` if that fails, or takes more than ``max_evaluations``)."""
    m = 2 * system.n
    y0 = np.asarray(y0, dtype=float)
    P = np.asarray(P, dtype=float)

    def rhs(t, z):
        if cancel is not None:
            cancel.check()
        y = z[:m]
        phi = z[m : m + m * m].reshape(m, m)
        f = np.asarray(system.rhs(t, *y, *P), dtype=float).ravel()
        J = np.asarray(system.jacobian(t, *y, *P), dtype=float).reshape(m, m)
        return np.concatenate([f, (J @ phi).ravel(), [np.trace(J)]])

    evaluations = 0

    def counted(t, z):
        nonlocal evaluations
        evaluations += 1
        if max_evaluations is not None and evaluations > max_evaluations:
            raise RuntimeError(
                f"the variational equations took more than {max_evaluations} evaluations "
                "over one period (stiff or singular near the solution)"
            )
        return rhs(t, z)

    import scipy.integrate  # here: derive --json of an autonomous system never needs it

    z0 = np.concatenate([y0, np.eye(m).ravel(), [0.0]])
    solution = scipy.integrate.solve_ivp(
        counted, (t0, t0 + period), z0, method="DOP853", rtol=rtol, atol=atol
    )
    if not solution.success:
        raise RuntimeError(f"the variational equations could not be integrated: {solution.message}")
    z = solution.y[:, -1]
    matrix = z[m : m + m * m].reshape(m, m)
    multipliers = np.linalg.eigvals(matrix)
    multipliers = multipliers[np.argsort(-np.abs(multipliers), kind="stable")]
    final = z[:m]
    difference = final - y0
    for i in system.angles:
        difference[i] = fold_angle(difference[i])
    return Monodromy(
        matrix=matrix,
        multipliers=multipliers,
        determinant=float(np.linalg.det(matrix)),
        liouville=float(np.exp(z[-1])),
        closure=float(np.linalg.norm(difference)),
        final=final,
        evaluations=int(solution.nfev),
    )


@dataclass(frozen=True)
class Verdict:
    """``word``: ``"stable"``, ``"asymptotically stable"``, ``"unstable"`` or
    ``"marginal"``; ``sentence``: why, for a person."""

    word: str
    sentence: str


def verdict(
    multipliers: np.ndarray, symplectic: bool, *, trivial: int = 0, tol: float = UNIT_TOLERANCE
) -> Verdict:
    """The stability the multipliers state.

    Parameters
    ----------
    multipliers : complex array
    symplectic : bool
        A Hamiltonian flow (multipliers in pairs mu, 1/mu).
    trivial : int
        Multipliers that are 1 whatever the stability (2 for a periodic orbit of an
        autonomous system: along the orbit and across the energy levels): the ones
        closest to 1 are set aside.
    """
    mu = np.asarray(multipliers, dtype=complex)
    if trivial:
        order = np.argsort(np.abs(mu - 1.0), kind="stable")
        mu = mu[order[trivial:]]
    if mu.size == 0:
        return Verdict(
            "marginal", "only the trivial multipliers 1: the linearisation cannot decide"
        )
    largest = float(np.max(np.abs(mu)))
    if largest > 1.0 + tol:
        return Verdict(
            "unstable",
            f"a multiplier has |μ| = {largest:.6g} > 1: small deviations grow by that factor "
            "every period",
        )
    if not symplectic and largest < 1.0 - tol:
        return Verdict(
            "asymptotically stable",
            f"every |μ| ≤ {largest:.6g} < 1: small deviations die out",
        )
    if mu.size == 2 and symplectic:
        trace = float(np.real(mu.sum()))
        if abs(abs(trace) - 2.0) <= tol:
            return Verdict(
                "marginal",
                f"tr M = {trace:.8g}: on the boundary of a resonance tongue (|tr M| = 2); "
                "the linearisation cannot decide",
            )
        return Verdict(
            "stable", f"both multipliers on the unit circle, |tr M| = {abs(trace):.6g} < 2"
        )
    close = [
        (i, j)
        for i in range(mu.size)
        for j in range(i + 1, mu.size)
        if abs(mu[i] - mu[j]) <= math.sqrt(tol)
    ]
    if close or np.any(np.abs(np.abs(mu) - 1.0) > tol) and symplectic:
        return Verdict(
            "marginal",
            "multipliers on the unit circle coincide (or sit at ±1): the linearisation "
            "cannot decide",
        )
    if not symplectic:
        return Verdict("marginal", "a multiplier has |μ| = 1 and the flow is not Hamiltonian")
    return Verdict("stable", "every multiplier on the unit circle, none repeated")


# -- constant solutions ---------------------------------------------------------------------


def _box(system: VariationalSystem, ranges: Mapping[str, Sequence[float]] | None):
    lows, highs = [], []
    for i in system.searched:
        name = system.names[i]
        if i in system.angles:
            lows.append(-math.pi)
            highs.append(math.pi)
        elif ranges and name in ranges:
            lo, hi = (float(v) for v in ranges[name])
            middle, half = (lo + hi) / 2, 1.5 * (hi - lo)
            lows.append(min(middle - half, -10.0))
            highs.append(max(middle + half, 10.0))
        else:
            lows.append(-10.0)
            highs.append(10.0)
    return np.array(lows), np.array(highs)


def constant_solutions(
    system: VariationalSystem,
    P: np.ndarray,
    period: float,
    *,
    ranges: Mapping[str, Sequence[float]] | None = None,
    cancel=None,
) -> list[np.ndarray]:
    """The configurations q* with F(q*, 0, t) = 0 for all t (coordinates the equations do
    not depend on at 0), angles folded into (-pi, pi], sorted.

    F is solved at ``SAMPLE_TIMES`` times of one period together (least squares from a
    grid of starts), and every root is checked at other times.
    """
    if system.rest is None:
        raise ValueError("a scene given by H alone: constant solutions are sought in (q, p)")
    n, searched = system.n, list(system.searched)
    P = np.asarray(P, dtype=float)
    times = period * (np.arange(SAMPLE_TIMES) + 0.137) / SAMPLE_TIMES
    checks = period * np.array([0.05, 0.311, 0.529, 0.77, 0.93])

    def full(z):
        q = np.zeros(n)
        q[searched] = z
        return q

    def residual(z, at=times):
        values = system.rest(at, *full(z), *P)
        return np.asarray(values, dtype=float).reshape(n, -1).ravel()

    if not searched:
        return [np.zeros(n)] if np.max(np.abs(residual(np.zeros(0)))) <= 1e-12 else []
    lows, highs = _box(system, ranges)
    k = len(searched)
    per_axis = {1: 41, 2: 13, 3: 7}.get(k, 4)
    axes = [np.linspace(lo, hi, per_axis) for lo, hi in zip(lows, highs, strict=True)]
    grid = np.array(np.meshgrid(*axes, indexing="ij")).reshape(k, -1).T
    scale = float(
        np.median([np.max(np.abs(residual(z))) for z in grid[:: max(1, len(grid) // 50)]])
    )
    scale = max(scale, 1e-300)
    import scipy.optimize

    found: list[np.ndarray] = []
    for z in grid:
        if cancel is not None:
            cancel.check()
        try:
            solution = scipy.optimize.least_squares(
                residual, z, method="lm", xtol=1e-15, ftol=1e-15, gtol=1e-15, max_nfev=400
            )
        except (ValueError, FloatingPointError):
            continue
        root = solution.x
        if not np.all(np.isfinite(root)):
            continue
        if np.max(np.abs(residual(root))) > 1e-9 * scale:
            continue
        if np.max(np.abs(residual(root, checks))) > 1e-9 * scale:
            continue
        q = full(root)
        for i in system.angles:
            q[i] = fold_angle(q[i])
        if _inside(q, searched, lows, highs, system.angles) and not any(
            _same(q, other, system.angles) for other in found
        ):
            found.append(q)
    return sorted(found, key=lambda q: tuple(np.round(q, 9)))


def _inside(q, searched, lows, highs, angles) -> bool:
    """Whether the searched coordinates of q lie in the box (angles always do)."""
    for j, i in enumerate(searched):
        if i in angles:
            continue
        if not lows[j] - 1e-9 <= q[i] <= highs[j] + 1e-9:
            return False
    return True


def _same(a, b, angles) -> bool:
    difference = np.asarray(a, dtype=float) - np.asarray(b, dtype=float)
    for i in angles:
        difference[i] = fold_angle(difference[i])
    return bool(np.max(np.abs(difference)) <= 1e-6 * max(1.0, float(np.max(np.abs(a)))))


# -- the analysis ---------------------------------------------------------------------------


@dataclass(frozen=True)
class ConstantSolution:
    """One constant solution q* of a periodically driven system and its Floquet data."""

    q: dict[str, float]
    multipliers: tuple[complex, ...]
    determinant: float
    liouville: float
    closure: float
    verdict: Verdict

    def as_json(self) -> dict:
        return {
            "q": dict(self.q),
            "multipliers": [[float(m.real), float(m.imag)] for m in self.multipliers],
            "abs_multipliers": [float(abs(m)) for m in self.multipliers],
            "trace": float(np.real(sum(self.multipliers))),
            "determinant": self.determinant,
            "liouville": self.liouville,
            "stability": self.verdict.word,
            "stable": self.verdict.word in ("stable", "asymptotically stable"),
        }


@dataclass(frozen=True)
class FloquetAnalysis:
    """The Floquet analysis of an explicitly time-dependent system.

    Attributes
    ----------
    periodicity : Periodicity
    solutions : tuple of ConstantSolution
    note : str
        Why there are none, or what was assumed; "" if nothing to say.
    symplectic : bool
    system : VariationalSystem or None
        For a stability chart (None where the analysis did not get that far).
    undecided : tuple of (q, reason)
        Constant solutions whose multipliers could not be computed (at a singular point
        of the coordinates, or too stiff), with the reason.
    """

    periodicity: Periodicity
    solutions: tuple[ConstantSolution, ...]
    note: str
    symplectic: bool = True
    system: VariationalSystem | None = None
    undecided: tuple[tuple[dict[str, float], str], ...] = ()

    def as_json(self) -> dict:
        """``derive --json``'s ``floquet``."""
        return {
            "periodic": self.periodicity.periodic,
            "period": self.periodicity.period,
            "frequencies": list(self.periodicity.frequencies),
            "hamiltonian_flow": self.symplectic,
            "constant_solutions": [s.as_json() for s in self.solutions],
            "undecided_solutions": [
                {"q": dict(q), "stability": "undecided", "reason": reason}
                for q, reason in self.undecided
            ],
            "note": self.note or self.periodicity.reason,
        }

    def sentences(self, shown: Mapping[str, str] | None = None, digits: int = 6) -> list[str]:
        """One line per constant solution: where, its multipliers and the verdict."""
        shown = shown or {}
        lines = []
        for s in self.solutions:
            where = ", ".join(f"{shown.get(k, k)} = {v:.{digits}g}" for k, v in s.q.items())
            mus = ", ".join(_complex_text(m, digits) for m in s.multipliers)
            trace = float(np.real(sum(s.multipliers)))
            extra = f", tr M = {trace:.{digits}g}" if len(s.multipliers) == 2 else ""
            check = f"det M = {s.determinant:.12f}"
            check += (
                " (Liouville: 1 for a Hamiltonian flow)"
                if self.symplectic
                else f" (Liouville: exp ∫tr J dt = {s.liouville:.{digits}g})"
            )
            lines.append(f"{where}: {s.verdict.word}; multipliers {mus}{extra}; {check}")
        for q, reason in self.undecided:
            where = ", ".join(f"{shown.get(k, k)} = {v:.{digits}g}" for k, v in q.items())
            lines.append(f"{where}: stability undecided; {reason}")
        return lines


def _complex_text(m: complex, digits: int) -> str:
    if abs(m.imag) <= 1e-12 * max(1.0, abs(m)):
        return f"{m.real:.{digits}g}"
    sign = "+" if m.imag >= 0 else "−"
    return f"{m.real:.{digits}g} {sign} {abs(m.imag):.{digits}g}i"


def analyse(
    mechanics: Mechanics, parameters: Mapping[str, float] | None = None, *, cancel=None
) -> FloquetAnalysis:
    """The constant solutions of a periodically time-dependent system and their multipliers.

    Never raises for a scene that derived: a system that is not periodic, in matrix form
    or too slow (``SECONDS`` of CPU) gets an analysis with no solution and a ``note``.
    """
    period_info = periodicity(mechanics, parameters)
    if not period_info.periodic:
        return FloquetAnalysis(period_info, (), period_info.reason)
    try:
        with cpu_limit(SECONDS, "the Floquet analysis"):
            return _analyse(mechanics, parameters, period_info, cancel)
    except TimeLimitExceeded as exc:
        return FloquetAnalysis(period_info, (), str(exc))


def _analyse(mechanics, parameters, period_info, cancel) -> FloquetAnalysis:
    try:
        system = VariationalSystem.build(mechanics)
    except ValueError as exc:
        return FloquetAnalysis(period_info, (), str(exc))
    if system.rest is None:
        return FloquetAnalysis(
            period_info,
            (),
            "a scene given by H alone has no Lagrangian to say what rest is: constant "
            "solutions are not sought",
            system.symplectic,
            system,
        )
    P = system.parameter_vector(parameters)
    period = float(period_info.period)
    ranges = mechanics.scene.view.get("ranges") if mechanics.scene.view else None
    roots = constant_solutions(system, P, period, ranges=ranges, cancel=cancel)
    solutions, undecided = [], []
    for q in roots:
        y0 = system.state_at_rest(q, P)
        reason = _singular_at(mechanics, parameters, system, q, y0, P)
        if reason is None:
            try:
                result = monodromy(
                    system, y0, period, P, cancel=cancel, max_evaluations=MAX_EVALUATIONS
                )
                if not np.all(np.isfinite(result.multipliers)):
                    reason = "the monodromy matrix is not finite"
            except (RuntimeError, ValueError, np.linalg.LinAlgError) as exc:
                reason = str(exc)
        if reason is not None:  # reported undecided, the others still analysed
            where = {name: float(v) for name, v in zip(system.names, q, strict=True)}
            undecided.append((where, reason))
            continue
        solutions.append(
            ConstantSolution(
                q={name: float(v) for name, v in zip(system.names, q, strict=True)},
                multipliers=tuple(complex(m) for m in result.multipliers),
                determinant=result.determinant,
                liouville=result.liouville,
                closure=result.closure,
                verdict=verdict(result.multipliers, system.symplectic),
            )
        )
    notes = [period_info.reason]
    free = [system.names[i] for i in range(system.n) if i not in system.searched]
    if free:
        notes.append(f"the equations do not depend on {', '.join(free)}: free, shown at 0")
    if not solutions and not undecided:
        notes.append("no constant solution: rest at any q is pushed away at some t")
    if not system.symplectic:
        notes.append("effects act: the flow is not Hamiltonian, det M < 1 under damping")
    return FloquetAnalysis(
        period_info,
        tuple(solutions),
        "; ".join(notes),
        system.symplectic,
        system,
        tuple(undecided),
    )


def _singular_at(mechanics, parameters, system, q, y0, P) -> str | None:
    """Why the multipliers of the constant solution ``q`` cannot be computed in these
    coordinates (None: they can): the equations not finite there, or the chart failing
    (the mass matrix singular, as at a pole of polar angles)."""
    from systems.textbook.equilibria import _mass_function, _regular

    with np.errstate(all="ignore"):
        f = np.asarray(system.rhs(0.0, *y0, *P), dtype=float)
        J = np.asarray(system.jacobian(0.0, *y0, *P), dtype=float)
        M = _mass_function(mechanics, parameters)(np.asarray(q, dtype=float))
    if not _regular(np.asarray(M, dtype=float)):
        return (
            "the mass matrix is singular there (a singular point of the coordinates, "
            "like the pole of polar angles): the multipliers are not computed in this chart"
        )
    if not (np.all(np.isfinite(f)) and np.all(np.isfinite(J))):
        return "the equations of motion are not finite there"
    return None


# -- stability charts -----------------------------------------------------------------------

STABLE, UNSTABLE, MARGINAL, UNKNOWN = 0, 1, 2, 3


def chart_rows(
    system: VariationalSystem,
    q_star: np.ndarray,
    base: Mapping[str, float],
    x_name: str,
    x_values: np.ndarray,
    y_name: str,
    y_values: np.ndarray,
    *,
    rtol: float = 1e-9,
    cancel=None,
) -> tuple[np.ndarray, np.ndarray]:
    """Stability of the constant solution ``q_star`` over a grid of two parameters.

    Every row (one value of ``y_name``) is integrated as one vectorised system over the
    row's points (each over its own period, in the scaled time s = t/T).

    Returns
    -------
    codes : ndarray (len(y_values), len(x_values)) of int
        ``STABLE``, ``UNSTABLE``, ``MARGINAL`` (within 1e-6 of |tr| = 2 for one degree
        of freedom) or ``UNKNOWN`` (not periodic or not a solution there).
    growth : ndarray, same shape
        The largest |mu| (NaN where unknown).
    """
    codes = np.full((len(y_values), len(x_values)), UNKNOWN, dtype=int)
    growth = np.full(codes.shape, np.nan)
    for row, y_value in enumerate(y_values):
        if cancel is not None:
            cancel.check()
        values = dict(base)
        values[y_name] = float(y_value)
        Ps, periods, columns = [], [], []
        for column, x_value in enumerate(x_values):
            values[x_name] = float(x_value)
            P = system.parameter_vector(values)
            period = system.period(P)
            if period is None:
                continue
            residual = np.asarray(system.rest(np.linspace(0, period, 5), *q_star, *P))
            if not np.all(np.abs(residual) <= 1e-9 * max(1.0, float(np.max(np.abs(P))))):
                continue
            Ps.append(P)
            periods.append(period)
            columns.append(column)
        if not columns:
            continue
        mus = _row_multipliers(system, q_star, np.array(Ps), np.array(periods), rtol, cancel)
        for column, mu in zip(columns, mus, strict=True):
            largest = float(np.max(np.abs(mu)))
            growth[row, column] = largest
            word = verdict(mu, system.symplectic, tol=UNIT_TOLERANCE).word
            codes[row, column] = {
                "stable": STABLE,
                "asymptotically stable": STABLE,
                "unstable": UNSTABLE,
            }.get(word, MARGINAL)
    return codes, growth


def _row_multipliers(system, q_star, Ps, periods, rtol, cancel) -> list[np.ndarray]:
    """The multipliers of ``q_star`` at each parameter vector of ``Ps`` (N, k)."""
    N, m = len(Ps), 2 * system.n
    columns = Ps.T  # (k, N)
    y0 = np.array([system.state_at_rest(q_star, P) for P in Ps])  # (N, m)

    def rhs(s, z):
        if cancel is not None:
            cancel.check()
        z = z.reshape(N, m + m * m)
        y = z[:, :m]
        phi = z[:, m:].reshape(N, m, m)
        t = s * periods
        f = system.rhs(t, *y.T, *columns).T  # (N, m)
        J = system.jacobian(t, *y.T, *columns).T.reshape(N, m, m)
        dphi = np.einsum("nij,njk->nik", J, phi)
        return (np.concatenate([f, dphi.reshape(N, m * m)], axis=1) * periods[:, None]).ravel()

    import scipy.integrate

    z0 = np.concatenate([y0, np.tile(np.eye(m).ravel(), (N, 1))], axis=1).ravel()
    solution = scipy.integrate.solve_ivp(
        rhs, (0.0, 1.0), z0, method="DOP853", rtol=rtol, atol=rtol * 1e-2
    )
    z = solution.y[:, -1].reshape(N, m + m * m)
    return [np.linalg.eigvals(z[i, m:].reshape(m, m)) for i in range(N)]


# -- words for the derivation -------------------------------------------------------------

HEADING = "Equilibria of the driven system (constant solutions; stability by Floquet theory)"


def time_dependence_note(mechanics: Mechanics) -> str:
    """Why a system whose L (or H) contains t is not searched by virtual work, and where
    its constant solutions are: one sentence, the same wherever it is shown."""
    info = periodicity(mechanics)
    if info.periodic:
        return (
            f"the equations of motion depend explicitly on t, periodically ({info.reason}): "
            "rest at a constant q is a constant solution of the driven system, and Floquet "
            "theory decides its stability (the Floquet tab, and derive)"
        )
    return (
        f"the equations of motion depend explicitly on t, {info.reason}: constant "
        "solutions are not sought"
    )


def report(
    mechanics: Mechanics, shown: Mapping[str, str] | None = None, digits: int = 6
) -> tuple[list[str], str]:
    """The constant solutions with their multipliers and verdicts, one sentence each, and
    a note (the period, or why there are none) for ``systems.report``."""
    analysis = analyse(mechanics)
    if not analysis.periodicity.periodic:
        return [], time_dependence_note(mechanics)
    return analysis.sentences(shown, digits), analysis.note


def derive_json(mechanics: Mechanics) -> dict | None:
    """``derive --json``'s ``floquet``: None for a system without explicit t."""
    return analyse(mechanics).as_json() if explicit_time(mechanics) else None
