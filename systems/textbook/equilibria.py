"""Equilibria by virtual work, their stability, and small oscillations about them.

For a scleronomic system the equilibria (constant q, zero velocities) solve
``dU/dq = 0`` with ``U(q) = -L(q, qdot=0)``: the potential energy, less any velocity-free
part of the kinetic energy (a bead on a spinning hoop has ``U = V - m w^2 R^2 sin^2/2``).
A scene given only by a Hamiltonian that cannot be turned into a Lagrangian uses
``U = H(q, p=0)``. The Hessian ``K = d2U/dq2`` at an equilibrium decides its kind, and the
generalized eigenproblem ``K v = w^2 M v`` (``scipy.linalg.eigh``) gives the normal modes
(terms of L linear in the velocities, gyroscopic or magnetic, are not part of it).

Coordinates that ``U`` does not depend on (cyclic ones such as the angle of planetary
motion) are not searched: every value is an equilibrium value. They are reported as
``free`` and set to 0; their momenta are held at zero, so the mass matrix used for the
remaining coordinates is the Schur complement ``M_rr - M_rf M_ff^-1 M_fr``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np
import scipy.linalg
import scipy.optimize
import sympy

from systems.calculus import Calculus, Unsupported
from systems.deadline import TimeLimitExceeded, time_limit
from systems.mechanics import EXPANSION_LIMIT, Mechanics, expanded_terms
from systems.textbook._numeric import (
    cache_for,
    fold_angle,
    parameter_values,
    periodic_symbols,
    run_bounded,
    vectorize,
    with_parameters,
)

DEFAULT_HALF_WIDTH = 10.0
SYMBOLIC_TIMEOUT = 2.0
SYMBOLIC_MAX_COORDINATES = 3
SYMBOLIC_MAX_OPS = 200
Box = Mapping[str, tuple[float, float]]


@dataclass(frozen=True)
class Equilibrium:
    """One equilibrium configuration, with its stability and normal modes.

    Attributes
    ----------
    q : dict[str, float]
        Every coordinate's value (free coordinates at 0, periodic angles in (-pi, pi]).
    stable : bool
        True for a strict minimum of U (all Hessian eigenvalues positive).
    kind : str
        ``"minimum"``, ``"saddle"``, ``"maximum"`` or ``"degenerate"`` (a zero eigenvalue).
    frequencies : list[float]
        Normal-mode angular frequencies w (ascending) for a stable equilibrium, else [].
    omega_squared : ndarray, shape (m,)
        Eigenvalues w^2 of ``K v = w^2 M v`` over the m searched coordinates, ascending;
        a negative one is the square of a growth rate.
    modes : ndarray, shape (n, m)
        Column j is the mode shape of ``omega_squared[j]`` in all n coordinates,
        normalized so that ``v^T M v = 1``.
    hessian : ndarray, shape (m, m)
        K = d2U/dq2 over the searched coordinates.
    potential : float
        U at the equilibrium, which is also H there: the energy of the level set through
        it (a saddle's level set is the separatrix).
    p : dict[str, float]
        The momenta at rest there (zero unless L has terms linear in the velocities),
        for markers in a phase view.
    exact : dict[str, str]
        Closed forms found by sympy (coordinate -> expression text in the parameters);
        empty when the equilibrium was found numerically.
    """

    q: dict[str, float]
    stable: bool
    kind: str
    frequencies: list[float]
    omega_squared: np.ndarray
    modes: np.ndarray
    hessian: np.ndarray
    potential: float
    p: dict[str, float] = field(default_factory=dict)
    exact: dict[str, str] = field(default_factory=dict)

    def as_json(self) -> dict:
        """``{"q": {name: value}, "stable": bool, "frequencies": [...]}``."""
        return {
            "q": {name: _clean(value) for name, value in self.q.items()},
            "stable": bool(self.stable),
            "frequencies": [float(w) for w in self.frequencies] if self.stable else [],
        }


@dataclass(frozen=True)
class EquilibriumSearch:
    """The result of a search: the equilibria and how they were found.

    Attributes
    ----------
    equilibria : list[Equilibrium]
        Sorted by U, then by coordinates.
    method : str
        ``"symbolic"`` (sympy solved dU/dq = 0 and a numeric scan found nothing more),
        ``"symbolic+numeric"``, ``"numeric"``, or ``"none"`` (not searched: see reason).
    reason : str
        One sentence for the user: why there are none, or what was assumed.
    searched, free, periodic : tuple[str, ...]
        Coordinates solved for; coordinates U does not depend on (set to 0); coordinates
        folded into (-pi, pi] because the system is 2 pi-periodic in them.
    box : dict[str, tuple[float, float]]
        The numeric search box of each searched coordinate.
    potential : sympy.Expr or None
        The U(q) used, in the scene's symbols (parameters left symbolic).
    """

    equilibria: list[Equilibrium]
    method: str
    reason: str
    searched: tuple[str, ...] = ()
    free: tuple[str, ...] = ()
    periodic: tuple[str, ...] = ()
    box: dict[str, tuple[float, float]] = field(default_factory=dict)
    potential: sympy.Expr | None = None


SEARCH_SECONDS = 15.0
"""Longest an equilibrium search may take (the symbolic part has its own ``timeout``)."""


def find_equilibria(
    mechanics: Mechanics,
    box: Box | None = None,
    *,
    parameters: Mapping[str, float] | None = None,
    symbolic: bool = True,
    timeout: float = SYMBOLIC_TIMEOUT,
) -> list[Equilibrium]:
    """The equilibria of a scleronomic system (see ``search_equilibria``)."""
    return search_equilibria(
        mechanics, box, parameters=parameters, symbolic=symbolic, timeout=timeout
    ).equilibria


def equilibria_json(
    mechanics: Mechanics, box: Box | None = None, *, parameters: Mapping[str, float] | None = None
) -> list[dict]:
    """The equilibria for ``derive --json``: a list of ``{"q", "stable", "frequencies"}``."""
    return [e.as_json() for e in find_equilibria(mechanics, box, parameters=parameters)]


def equilibrium_potential(mechanics: Mechanics) -> tuple[sympy.Expr, str]:
    """U(q) (parameters symbolic) whose stationary points are the equilibria, and its origin.

    Returns ``(U, source)`` with source ``"lagrangian"`` (U = -L at zero velocities) or
    ``"hamiltonian"`` (U = H at zero momenta).
    """
    if mechanics.lagrangian is not None:
        zero = dict.fromkeys(mechanics.qdot, sympy.S.Zero)
        return _expand(-mechanics.lagrangian.xreplace(zero)), "lagrangian"
    zero = dict.fromkeys(mechanics.p, sympy.S.Zero)
    return _expand(mechanics.hamiltonian.xreplace(zero)), "hamiltonian"


def _expand(expr: sympy.Expr) -> sympy.Expr:
    """``expand(expr)``, unless it would have more terms than anyone would read."""
    return expr if expanded_terms(expr) > EXPANSION_LIMIT else sympy.expand(expr)


def search_equilibria(
    mechanics: Mechanics,
    box: Box | None = None,
    *,
    parameters: Mapping[str, float] | None = None,
    symbolic: bool = True,
    timeout: float = SYMBOLIC_TIMEOUT,
) -> EquilibriumSearch:
    """Solve dU/dq = 0 symbolically where sympy can, and numerically within a box.

    Parameters
    ----------
    mechanics : Mechanics
        From ``systems.mechanics.derive``. Effects (dissipation, forces) are ignored: the
        equilibria are those of the conservative part.
    box : mapping of coordinate name to (low, high), optional
        The region scanned numerically (the view). Defaults: (-pi, pi] for a periodic
        coordinate; otherwise (-10, 10), widened to cover three times the scene's view
        range of the coordinate (``[view] ranges``) if it has one. When a box is given,
        symbolic solutions outside it are dropped too; without one they are all kept.
    parameters : mapping of name to float, optional
        Parameter values overriding the scene's.
    symbolic : bool
        Try ``sympy.solve`` first (in a child process stopped after ``timeout`` seconds).

    Returns
    -------
    EquilibriumSearch
        Never raises for a scene that derived; ``reason`` explains an empty result. A
        search that runs past ``SEARCH_SECONDS`` is stopped and says so.
    """
    try:
        with time_limit(SEARCH_SECONDS, "the equilibrium search"):
            return _search_equilibria(mechanics, box, parameters, symbolic, timeout)
    except TimeLimitExceeded as exc:
        return EquilibriumSearch([], "none", f"{exc} (the potential is too large to scan)")


def _search_equilibria(mechanics, box, parameters, symbolic, timeout) -> EquilibriumSearch:
    names = mechanics.scene.coordinates
    U, source = equilibrium_potential(mechanics)
    expression = mechanics.lagrangian if source == "lagrangian" else mechanics.hamiltonian
    if expression.has(mechanics.t):
        return EquilibriumSearch(
            [],
            "none",
            "the system is rheonomic (its Lagrangian depends explicitly on t), so it has "
            "no equilibria in these coordinates",
            potential=U,
        )
    notes = []
    if any(f != 0 for f in mechanics.generalized_forces):
        notes.append("equilibria of the conservative part (dissipation and forces ignored)")
    if source == "hamiltonian":
        notes.append("U = H(q, p = 0), as the Hamiltonian has no Lagrangian")
    free = tuple(name for name, qi in zip(names, mechanics.q, strict=True) if not U.has(qi))
    searched = tuple(name for name in names if name not in free)
    if free:
        notes.append(f"U does not depend on {', '.join(free)}: free (any value), shown at 0")
    if not searched:
        return EquilibriumSearch(
            [],
            "none",
            "U is constant: every configuration is a (neutral) equilibrium",
            free=free,
            potential=U,
        )
    symbol_of = dict(zip(names, mechanics.q, strict=True))
    unknowns = [symbol_of[name] for name in searched]
    everything = [*mechanics.q, *mechanics.qdot, *mechanics.p]
    numeric_expression = with_parameters(expression, mechanics, parameters)
    angles = periodic_symbols(numeric_expression, unknowns, everything)
    periodic = tuple(name for name in searched if symbol_of[name] in angles)
    region = _region(searched, periodic, box, mechanics.scene.view)
    U_numeric = with_parameters(U, mechanics, parameters)
    problem = _Problem(mechanics, U_numeric, unknowns, searched, free, periodic, region, parameters)

    found: list[tuple[np.ndarray, dict[str, str]]] = []
    method = "numeric"
    if symbolic and len(unknowns) <= SYMBOLIC_MAX_COORDINATES:
        # Parameters stay symbolic, so one solve serves every slider position.
        cache = cache_for(mechanics)
        key = ("equilibria.symbolic", tuple(unknowns))
        if key not in cache:
            cache[key] = _symbolic_solutions(mechanics, U, unknowns, timeout)
        exact = cache[key]
        if exact is not None:
            method = "symbolic"
            for solution in exact:
                point = problem.evaluate_exact(solution, keep_outside=box is None)
                if point is not None:
                    found.append(
                        (
                            point,
                            {n: str(solution[s]) for n, s in zip(searched, unknowns, strict=True)},
                        )
                    )
    numeric = problem.scan()
    added = False
    known = [point for point, _ in found]
    for point in numeric:
        if problem.index(point, known) < 0:
            found.append((point, {}))
            added = True
    if method == "symbolic" and added:
        method = "symbolic+numeric"
    found = _unique(found, problem)
    equilibria = [problem.equilibrium(point, exact) for point, exact in found]
    equilibria.sort(key=lambda e: (round(e.potential, 9), tuple(e.q.values())))
    if not equilibria:
        notes.insert(0, "dU/dq vanishes nowhere in the search box")
    return EquilibriumSearch(
        equilibria,
        method,
        "; ".join(notes),
        searched=searched,
        free=free,
        periodic=periodic,
        box=region,
        potential=U,
    )


# -- the pieces -------------------------------------------------------------------------------


def _region(searched, periodic, box: Box | None, view: Mapping) -> dict[str, tuple[float, float]]:
    ranges = view.get("ranges", {}) if isinstance(view, Mapping) else {}
    region = {}
    for name in searched:
        if box is not None and name in box:
            lo, hi = (float(v) for v in box[name])
            if not lo < hi:
                raise ValueError(f"the box of {name!r} is empty: ({lo}, {hi})")
        elif name in periodic:
            lo, hi = -math.pi, math.pi
        else:
            lo, hi = -DEFAULT_HALF_WIDTH, DEFAULT_HALF_WIDTH
            try:  # a scene's view range, widened three times about its centre
                a, b = (float(v) for v in ranges[name])
                centre, width = (a + b) / 2, abs(b - a)
                lo, hi = min(lo, centre - 1.5 * width), max(hi, centre + 1.5 * width)
            except (KeyError, TypeError, ValueError):
                pass
        region[name] = (lo, hi)
    return region


def _symbolic_solutions(mechanics: Mechanics, U, unknowns, timeout: float):
    """sympy's solutions of dU/dq = 0 (dicts symbol -> expression), or None."""
    # Positive parameters as positive symbols, so that sqrt and acos come out simply.
    values = mechanics.scene.parameter_values
    positive = {
        s: sympy.Symbol(name, positive=True)
        for name, s in mechanics.params.items()
        if values.get(name, 0.0) > 0
    }
    gradient = [sympy.diff(U.xreplace(positive), u) for u in unknowns]
    if sum(g.count_ops() for g in gradient) > SYMBOLIC_MAX_OPS:
        return None
    solutions = run_bounded(_solve, (gradient, unknowns), timeout)
    if solutions is None:
        return None
    back = {v: k for k, v in positive.items()}
    return [{k: v.xreplace(back) for k, v in s.items()} for s in solutions]


def _solve(gradient, unknowns):
    """Runs in the child process. One unknown: solve each factor of dU/dq on its own
    (faster, and sympy then finds both sin = 0 roots); several: ``sympy.solve``."""
    if len(unknowns) == 1:
        (u,) = unknowns
        numerator, _ = sympy.fraction(sympy.together(gradient[0]))
        try:
            factors = [f for f, _ in sympy.factor_list(numerator)[1] if f.has(u)]
        except sympy.PolynomialError:
            factors = [numerator]
        return [{u: value} for factor in factors for value in sympy.solve(factor, u)]
    solutions = sympy.solve(gradient, unknowns, dict=True)
    complete = [s for s in solutions if all(u in s for u in unknowns)]
    if len(complete) != len(solutions):  # a continuum of equilibria: leave it to numerics
        return None
    return complete


class _Problem:
    """dU/dq = 0 over the searched coordinates, with numbers for the parameters."""

    def __init__(self, mechanics, U, unknowns, searched, free, periodic, region, parameters):
        self.mechanics = mechanics
        self.names = mechanics.scene.coordinates
        self.searched, self.free, self.periodic = searched, free, periodic
        self.region = region
        self.parameters = parameters
        self.unknowns = unknowns
        m = len(unknowns)
        self.is_periodic = np.array([name in periodic for name in searched])
        gradient, hessian = _derivatives(mechanics, U, unknowns)
        self.gradient = vectorize(gradient, unknowns)
        self._hessian = vectorize(hessian, unknowns)
        self.U = vectorize([U], unknowns)
        self.m = m
        grid = self.starts()
        with np.errstate(all="ignore"):
            g = np.linalg.norm(self.gradient(*grid.T), axis=0)
            h = np.abs(self._hessian(*grid.T))
        self.gradient_scale = _typical(g)
        self.hessian_scale = _typical(h)
        self.mass = _mass_function(mechanics, parameters)
        zero = {**dict.fromkeys(mechanics.qdot, 0), mechanics.t: 0}
        if mechanics.matrix_form is not None:  # a = p at zero velocity, already formed
            momenta = [
                with_parameters(e, mechanics, parameters).xreplace(zero)
                for e in mechanics.matrix_form.shift
            ]
        elif mechanics.momenta is not None:
            momenta = [
                with_parameters(e, mechanics, parameters).xreplace(zero) for e in mechanics.momenta
            ]
        else:
            momenta = [sympy.S.Zero] * len(self.names)
        momenta_function = vectorize(momenta, mechanics.q)
        self.rest_momenta = lambda q: momenta_function(*q)

    def hessian(self, x: np.ndarray) -> np.ndarray:
        return self._hessian(*x).reshape(self.m, self.m)

    def starts(self) -> np.ndarray:
        """Starting points, shape (s, m): a grid for m <= 3, a Halton set beyond."""
        m = self.m
        lows = np.array([self.region[n][0] for n in self.searched])
        highs = np.array([self.region[n][1] for n in self.searched])
        if m <= 3:
            count = {1: 41, 2: 15, 3: 8}[m]
            axes = [np.linspace(0.0, 1.0, count) for _ in range(m)]
            unit = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, m)
        else:
            from scipy.stats import qmc

            unit = qmc.Halton(d=m, seed=3).random(400)
        # Keep starting points off the box edges (and off 0 exactly, often singular).
        unit = 0.01 + 0.98 * unit
        return lows + (highs - lows) * unit

    def scan(self) -> list[np.ndarray]:
        found: list[np.ndarray] = []

        def fun(x):
            return self.gradient(*x)

        for x0 in self.starts():
            with np.errstate(all="ignore"):
                try:
                    sol = scipy.optimize.root(
                        fun, x0, jac=self.hessian, method="hybr", options={"xtol": 1e-13}
                    )
                except (ValueError, np.linalg.LinAlgError, FloatingPointError):
                    continue
            x = self.accept(sol.x, inside_only=True)
            if x is not None and self.index(x, found) < 0:
                found.append(x)
        return found

    def accept(self, x: np.ndarray, *, inside_only: bool) -> np.ndarray | None:
        x = np.asarray(x, dtype=float)
        if not np.all(np.isfinite(x)):
            return None
        x = np.where(self.is_periodic, fold_angle(x), x)
        with np.errstate(all="ignore"):
            residual = float(np.linalg.norm(self.gradient(*x)))
        if not np.isfinite(residual) or residual > 1e-7 * self.gradient_scale:
            return None
        if inside_only:
            for value, name, periodic in zip(x, self.searched, self.is_periodic, strict=True):
                lo, hi = self.region[name]
                margin = 1e-9 * (hi - lo)
                if not periodic and not lo - margin <= value <= hi + margin:
                    return None
                if periodic and not lo - margin <= value <= hi + margin:
                    return None
        return x

    def evaluate_exact(self, solution: dict, *, keep_outside: bool) -> np.ndarray | None:
        values = parameter_values(self.mechanics, self.parameters)
        point = []
        for u in self.unknowns:
            try:
                value = complex(sympy.N(solution[u].xreplace(values), 17))
            except (TypeError, ValueError, ZeroDivisionError):
                return None
            if abs(value.imag) > 1e-10 * max(1.0, abs(value.real)):
                return None
            point.append(value.real)
        return self.accept(np.array(point), inside_only=not keep_outside)

    def same(self, a: np.ndarray, b: np.ndarray) -> bool:
        d = np.abs(a - b)
        d = np.where(self.is_periodic, np.minimum(d, 2 * math.pi - d), d)
        return bool(np.all(d <= 1e-6 * (1.0 + np.abs(a))))

    def index(self, a: np.ndarray, points) -> int:
        """The first ``i`` with ``same(a, points[i])``, or -1; one array operation (a
        chain of ten links has hundreds of equilibria, and pairwise calls cost seconds)."""
        if len(points) == 0:
            return -1
        d = np.abs(np.asarray(points, dtype=float).reshape(len(points), -1) - a)
        d = np.where(self.is_periodic, np.minimum(d, 2 * math.pi - d), d)
        hits = np.flatnonzero(np.all(d <= 1e-6 * (1.0 + np.abs(a)), axis=1))
        return int(hits[0]) if hits.size else -1

    def equilibrium(self, x: np.ndarray, exact: dict[str, str]) -> Equilibrium:
        n, m = len(self.names), self.m
        full = dict.fromkeys(self.names, 0.0)
        full.update({name: float(v) for name, v in zip(self.searched, x, strict=True)})
        q = np.array([full[name] for name in self.names])
        K = self.hessian(x)
        K = (K + K.T) / 2
        M = self.mass(q)
        index_r = [self.names.index(name) for name in self.searched]
        index_f = [self.names.index(name) for name in self.free]
        Mrr = M[np.ix_(index_r, index_r)]
        back = np.zeros((len(index_f), m))
        if index_f:
            Mff = M[np.ix_(index_f, index_f)]
            Mfr = M[np.ix_(index_f, index_r)]
            back = -np.linalg.pinv(Mff) @ Mfr  # pinv: M_ff may vanish (spherical pendulum)
            Mrr = Mrr + Mfr.T @ back
        eig_K = np.linalg.eigvalsh(K)
        tol = 1e-8 * max(self.hessian_scale, float(np.max(np.abs(eig_K))), 1e-300)
        if np.any(np.abs(eig_K) <= tol):
            kind = "degenerate"
        elif np.all(eig_K > 0):
            kind = "minimum"
        elif np.all(eig_K < 0):
            kind = "maximum"
        else:
            kind = "saddle"
        if _regular(Mrr):
            try:
                w2, vectors = scipy.linalg.eigh(K, Mrr)
            except (np.linalg.LinAlgError, ValueError):
                w2, vectors = scipy.linalg.eig(K, Mrr)
                order = np.argsort(w2.real)
                w2, vectors = w2.real[order], vectors.real[:, order]
        else:  # no inertia, or infinite: no small oscillations (H = p**4/4 at p = 0, m = 0)
            w2, vectors = np.full(m, np.nan), np.zeros((m, m))
        modes = np.zeros((n, m))
        modes[index_r] = vectors
        if index_f:
            modes[index_f] = back @ vectors
        stable = kind == "minimum"
        frequencies = [float(math.sqrt(max(v, 0.0))) for v in w2 if math.isfinite(v)]
        frequencies = frequencies if stable else []
        return Equilibrium(
            q=full,
            stable=stable,
            kind=kind,
            frequencies=frequencies,
            omega_squared=np.asarray(w2, dtype=float),
            modes=modes,
            hessian=K,
            potential=float(self.U(*x)[0]),
            p={
                f"p_{name}": _clean(v)
                for name, v in zip(self.names, self.rest_momenta(q), strict=True)
            },
            exact=exact,
        )


def _derivatives(mechanics: Mechanics, U: sympy.Expr, unknowns) -> tuple[list, list]:
    """dU/dq and d2U/dq2 (row major) over ``unknowns``, by symengine where it can (sympy's
    diff took half a second for a five-link chain's 25 second derivatives)."""
    engine = Calculus(mechanics.scene.symbols.values())
    try:
        e = engine.to_engine(U)
        xs = [engine.variable(u) for u in unknowns]
        first = [e.diff(x) for x in xs]
        second = [g.diff(x) for g in first for x in xs]
        return [engine.to_sympy(g) for g in first], [engine.to_sympy(h) for h in second]
    except Unsupported:
        gradient = [sympy.diff(U, u) for u in unknowns]
        return gradient, [sympy.diff(g, u) for g in gradient for u in unknowns]


def _unique(found, problem: _Problem):
    unique = []
    points = []
    for point, exact in found:
        i = problem.index(point, points)
        if i >= 0:
            if exact and not unique[i][1]:
                unique[i] = (point, exact)
                points[i] = point
        else:
            unique.append((point, exact))
            points.append(point)
    return unique


def _mass_function(mechanics: Mechanics, parameters):
    """M(q) at zero velocities and t = 0, as ``f(q (n,)) -> ndarray (n, n)``."""
    key = ("equilibria.mass", tuple(sorted((parameters or {}).items())))
    cache = cache_for(mechanics)
    if key in cache:
        return cache[key]
    n = mechanics.n
    zero = {**dict.fromkeys(mechanics.qdot, 0), **dict.fromkeys(mechanics.p, 0), mechanics.t: 0}
    if mechanics.mass_matrix is not None:
        entries = [
            with_parameters(e, mechanics, parameters).xreplace(zero) for e in mechanics.mass_matrix
        ]
        f = vectorize(entries, mechanics.q)

        def mass(q):
            return f(*q).reshape(n, n)

    else:  # M = (d2H/dp2)^-1 at p = 0
        H = with_parameters(mechanics.hamiltonian, mechanics, parameters)
        W = [sympy.diff(H, a, b).xreplace(zero) for a in mechanics.p for b in mechanics.p]
        f = vectorize(W, mechanics.q)

        def mass(q):
            try:
                return np.linalg.inv(f(*q).reshape(n, n))
            except np.linalg.LinAlgError:
                return np.full((n, n), np.nan)

    cache[key] = mass
    return mass


def _regular(M: np.ndarray) -> bool:
    """True if the mass matrix ``M`` is finite and invertible (not merely numerically)."""
    if M.size == 0 or not np.all(np.isfinite(M)):
        return False
    singular = np.linalg.svd(M, compute_uv=False)
    return bool(singular[-1] > 1e-13 * singular[0])


def _typical(values: np.ndarray) -> float:
    values = np.asarray(values, dtype=float).ravel()
    values = values[np.isfinite(values) & (values > 0)]
    return float(np.median(values)) if values.size else 1.0


def _clean(value: float) -> float:
    value = float(value)
    return 0.0 if abs(value) < 1e-12 else value
