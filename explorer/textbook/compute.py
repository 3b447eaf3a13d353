"""What the Textbook tabs show, computed without Qt (these run in the task pool).

Each function takes a ``CompiledSystem`` (its ``.mechanics`` and parameter values) and
returns a small frozen value that a tab draws as it is. Long loops check a ``Cancel``
token so a superseded or shut-down job stops early.
"""

from __future__ import annotations

import math
import threading
from dataclasses import dataclass, field

import numpy as np
import scipy.integrate
import scipy.special
import sympy

from systems.display import pretty_name


class Cancelled(Exception):
    """Raised inside a job whose result is no longer wanted."""


class Cancel:
    """A flag a job checks between steps: ``check()`` raises ``Cancelled`` once set."""

    def __init__(self) -> None:
        self._event = threading.Event()

    def set(self) -> None:
        self._event.set()

    @property
    def is_set(self) -> bool:
        return self._event.is_set()

    def check(self) -> None:
        if self._event.is_set():
            raise Cancelled


NEVER = Cancel()


def parameters_of(compiled) -> dict[str, float]:
    """The compiled system's parameter values by name (sliders included)."""
    return {
        name: float(value)
        for name, value in zip(compiled.parameter_names, compiled.parameters, strict=True)
    }


def names_of(compiled) -> tuple[str, ...]:
    return tuple(compiled.mechanics.scene.coordinates)


# -- a run of the current system --------------------------------------------------------------


@dataclass(frozen=True)
class Run:
    """The current system integrated from its initial state on a uniform grid.

    Attributes
    ----------
    t : ndarray, shape (K,)
    y : ndarray, shape (K, 2n)
        Canonical states.
    qdot : ndarray, shape (K, n)
    complete : bool
        False if the integration stopped early (``t`` then ends where it stopped).
    message : str
    """

    t: np.ndarray
    y: np.ndarray
    qdot: np.ndarray
    complete: bool
    message: str


def integrate(
    compiled,
    duration: float,
    samples: int = 801,
    *,
    y0: np.ndarray | None = None,
    t0: float = 0.0,
    cancel: Cancel = NEVER,
    rtol: float = 1e-10,
) -> Run:
    """Integrate Hamilton's equations (``compiled.rhs``) with DOP853.

    From ``y0`` (default: the scene's initial state) at ``t0`` over [t0, t0 + duration],
    sampled at ``samples`` uniform times.
    """
    start = compiled.initial_state() if y0 is None else np.asarray(y0, dtype=float)

    def rhs(t, y):
        cancel.check()
        return compiled.rhs(t, y)

    t1 = float(t0) + float(duration)
    t_eval = np.linspace(float(t0), t1, int(samples))
    with np.errstate(all="ignore"):
        result = scipy.integrate.solve_ivp(
            rhs,
            (float(t0), t1),
            start,
            method="DOP853",
            t_eval=t_eval,
            rtol=rtol,
            atol=rtol * 1e-2,
        )
    y = np.asarray(result.y.T, dtype=float)
    t = np.asarray(result.t, dtype=float)
    complete = result.status == 0 and len(t) == len(t_eval)
    qdot = compiled.velocities(t, y) if len(t) else np.empty((0, compiled.n))
    return Run(t, y, qdot, complete, str(result.message))


# -- equilibria ------------------------------------------------------------------------------


@dataclass(frozen=True)
class EquilibriaResult:
    """``search_equilibria`` on the current system (see ``systems.textbook.equilibria``)."""

    search: object
    names: tuple[str, ...]


def equilibria(compiled, cancel: Cancel = NEVER) -> EquilibriaResult:
    from systems.textbook import search_equilibria

    cancel.check()
    search = search_equilibria(compiled.mechanics, parameters=parameters_of(compiled))
    return EquilibriaResult(search, names_of(compiled))


# -- Hamilton's principle ------------------------------------------------------------------------


@dataclass(frozen=True)
class PrincipleResult:
    """S(eps) along the sine variation ``k`` of coordinate ``index`` over [0, duration].

    Attributes
    ----------
    run : Run
        The true path.
    eps, action : ndarray
        The sampled amplitudes and S(eps).
    slope, curvature : float
        dS/deps and d2S/deps2 at eps = 0.
    nature : str
        From ``second_variation``: ``"minimum"``, ``"saddle"``, ``"maximum"``, ``"degenerate"``.
    eigenvalues : ndarray
        The second variation's eigenvalues (ascending).
    eta : ndarray, shape (K, n)
        The variation (for drawing a varied path).
    """

    run: Run
    index: int
    k: int
    eps: np.ndarray
    action: np.ndarray
    slope: float
    curvature: float
    nature: str
    eigenvalues: np.ndarray
    eta: np.ndarray
    lagrangian_only: bool


def principle(
    compiled,
    duration: float,
    k: int,
    index: int,
    amplitude: float,
    start: float = 0.0,
    cancel: Cancel = NEVER,
) -> PrincipleResult:
    """S(eps) and the second variation on the stretch [start, start + duration] of the run."""
    from systems.textbook import action_curve, second_variation, sine_variation

    mechanics = compiled.mechanics
    if mechanics.lagrangian is None:
        raise ValueError("the scene gives only a Hamiltonian: the action needs a Lagrangian")
    y0 = None
    if start > 0:
        before = integrate(compiled, start, 2, cancel=cancel)
        if not before.complete:
            raise ValueError(f"the run to t = {start:g} did not complete: {before.message}")
        y0 = before.y[-1]
    run = integrate(compiled, duration, 801, y0=y0, t0=start, cancel=cancel)
    if not run.complete or len(run.t) < 5:
        raise ValueError(
            f"the run over [{start:g}, {start + duration:g}] did not complete: {run.message}"
        )
    cancel.check()
    parameters = parameters_of(compiled)
    q = run.y[:, : compiled.n]
    eps = np.linspace(-amplitude, amplitude, 41)
    curve = action_curve(
        mechanics,
        run.t,
        q,
        run.qdot,
        eps,
        k=k,
        direction=index,
        parameters=parameters,
        step=amplitude * 1e-3,
    )
    cancel.check()
    second = second_variation(mechanics, run.t, q, run.qdot, parameters=parameters)
    eta, _ = sine_variation(run.t, k, index, n=compiled.n)
    return PrincipleResult(
        run=run,
        index=index,
        k=k,
        eps=curve.eps,
        action=curve.action,
        slope=float(curve.slope),
        curvature=float(curve.curvature),
        nature=second.nature,
        eigenvalues=second.eigenvalues,
        eta=eta,
        lagrangian_only=any(f != 0 for f in mechanics.generalized_forces),
    )


@dataclass(frozen=True)
class TwoPointResult:
    """The path from A to B in time T, by the stationary discrete action and by shooting."""

    action_path: object
    shooting_path: object | None
    shooting_error: str


def two_point(
    compiled, qa, qb, duration: float, t0: float = 0.0, cancel: Cancel = NEVER
) -> TwoPointResult:
    """From configuration ``qa`` at t0 to ``qb`` at t0 + duration, both ways."""
    from systems.textbook import shoot_two_point, solve_two_point

    parameters = parameters_of(compiled)
    path = solve_two_point(compiled.mechanics, qa, qb, duration, t0=t0, parameters=parameters)
    cancel.check()
    try:
        shot = shoot_two_point(
            compiled.mechanics,
            qa,
            qb,
            duration,
            t0=t0,
            parameters=parameters,
            velocity_guess=path.qdot[0],
        )
        error = ""
    except (ValueError, RuntimeError, np.linalg.LinAlgError) as exc:
        shot, error = None, str(exc)
    return TwoPointResult(path, shot, error)


# -- Routhian reduction -------------------------------------------------------------------------


@dataclass(frozen=True)
class ReductionSetup:
    """The reduction of the current system, or why there is none.

    Attributes
    ----------
    reduction : Reduction or None
    reason : str
        Why there is no reduction (no cyclic coordinate...), empty otherwise.
    state : ndarray, shape (2n,)
        The initial state.
    p_cyclic : ndarray, shape (c,)
        The conserved momenta of that state.
    cyclic_index, rest_index : tuple[int, ...]
        Indices of the cyclic and remaining coordinates in the scene's order.
    q_range, p_range : (float, float)
        Plot ranges of the first remaining coordinate and its momentum.
    expression : str
        V_eff in textbook notation.
    quadratic : callable or None
        ``(q (K,), p_cyclic (c,)) -> (A, B, C)``, each (K,): H_red = A p² + B p + C in the
        first remaining momentum p (the other remaining coordinates and momenta at the
        state's values), so level sets are solved for p exactly; None if H_red is not
        quadratic in p.
    """

    reduction: object | None
    reason: str
    state: np.ndarray = field(default_factory=lambda: np.empty(0))
    p_cyclic: np.ndarray = field(default_factory=lambda: np.empty(0))
    cyclic_index: tuple[int, ...] = ()
    rest_index: tuple[int, ...] = ()
    q_range: tuple[float, float] = (0.0, 1.0)
    p_range: tuple[float, float] = (-1.0, 1.0)
    expression: str = ""
    quadratic: object | None = None


def reduction_setup(compiled, cancel: Cancel = NEVER) -> ReductionSetup:
    """Reduce the current system by its cyclic coordinates (symbolic work: off the GUI)."""
    from explorer.textbook.plots import readable
    from systems.display import for_display
    from systems.textbook import reduce

    mechanics = compiled.mechanics
    try:
        reduction = reduce(mechanics)
    except ValueError as exc:
        return ReductionSetup(None, str(exc))
    cancel.check()
    names = names_of(compiled)
    state = compiled.initial_state()
    n = compiled.n
    cyclic_index = tuple(names.index(c) for c in reduction.cyclic)
    rest_index = tuple(names.index(r) for r in reduction.rest)
    p_cyclic = np.array([state[n + i] for i in cyclic_index])
    i = rest_index[0]
    q_range = _view_range(mechanics.scene, names[i], state[i])
    p_range = _view_range(mechanics.scene, f"p_{names[i]}", state[n + i])
    try:
        text = readable(for_display(reduction.effective_potential, mechanics.scene))
    except Exception:  # noqa: BLE001 - only a caption
        text = str(reduction.effective_potential)
    quadratic = _quadratic_in_momentum(compiled, reduction, state, rest_index)
    return ReductionSetup(
        reduction,
        "",
        state,
        p_cyclic,
        cyclic_index,
        rest_index,
        q_range,
        p_range,
        text,
        quadratic,
    )


def _quadratic_in_momentum(compiled, reduction, state, rest_index):
    """H_red = A p² + B p + C in the first remaining momentum, as numeric functions."""
    mechanics = compiled.mechanics
    n = compiled.n
    values = {mechanics.params[k]: v for k, v in parameters_of(compiled).items()}
    q_sym, p_sym = reduction.rest_symbols[0], reduction.rest_momenta[0]
    held = {mechanics.t: sympy.S.Zero}
    for j, index in enumerate(rest_index[1:], start=1):
        held[reduction.rest_symbols[j]] = sympy.Float(state[index])
        held[reduction.rest_momenta[j]] = sympy.Float(state[n + index])
    H = sympy.expand(reduction.reduced_hamiltonian.xreplace(values).xreplace(held))
    try:
        poly = sympy.Poly(H, p_sym)
    except sympy.PolynomialError:
        return None
    if poly.degree() != 2:
        return None
    coefficients = [poly.coeff_monomial(p_sym**k) for k in (2, 1, 0)]
    if any(c.has(p_sym) for c in coefficients):
        return None
    args = [q_sym, *reduction.cyclic_momenta]
    functions = [sympy.lambdify(args, c, modules="numpy") for c in coefficients]

    def abc(q: np.ndarray, p_cyclic) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        q = np.asarray(q, dtype=float)
        pc = np.asarray(p_cyclic, dtype=float).ravel()
        with np.errstate(all="ignore"):
            return tuple(
                np.broadcast_to(np.asarray(f(q, *pc), dtype=float), q.shape) for f in functions
            )

    return abc


def level_curve(q, A, B, C, energy: float) -> tuple[np.ndarray, np.ndarray]:
    """The level set A p² + B p + C = E over the samples q, as closed loops or arcs.

    Both roots p = (−B ± √D)/(2A), D = B² − 4A(C − E), are joined where D crosses zero
    (the turning points, found by linear interpolation of D), so librations close up.
    Pieces are separated by NaN.
    """
    with np.errstate(all="ignore"):
        D = B * B - 4 * A * (C - energy)
    valid = np.isfinite(D) & np.isfinite(A) & (A != 0)
    inside = valid & (D >= 0)
    xs: list[np.ndarray] = []
    ys: list[np.ndarray] = []
    k, K = 0, len(q)
    while k < K:
        if not inside[k]:
            k += 1
            continue
        start = k
        while k < K and inside[k]:
            k += 1
        stop = k  # inside[start:stop]
        qq = q[start:stop]
        root = np.sqrt(D[start:stop])
        upper = (-B[start:stop] + root) / (2 * A[start:stop])
        lower = (-B[start:stop] - root) / (2 * A[start:stop])
        head_x, head_y, tail_x, tail_y = [], [], [], []
        if start > 0 and valid[start - 1]:  # a turning point between start - 1 and start
            x = _zero_between(q[start - 1], q[start], D[start - 1], D[start])
            head_x, head_y = [x], [float(-B[start] / (2 * A[start]))]
        if stop < K and valid[stop]:
            x = _zero_between(q[stop - 1], q[stop], D[stop - 1], D[stop])
            tail_x, tail_y = [x], [float(-B[stop - 1] / (2 * A[stop - 1]))]
        if head_x and tail_x:  # a closed loop between two turning points
            x = np.concatenate([head_x, qq, tail_x, qq[::-1], head_x])
            y = np.concatenate([head_y, upper, tail_y, lower[::-1], head_y])
        elif head_x:  # open to the right
            x = np.concatenate([qq[::-1], head_x, qq])
            y = np.concatenate([upper[::-1], head_y, lower])
        elif tail_x:  # open to the left
            x = np.concatenate([qq, tail_x, qq[::-1]])
            y = np.concatenate([upper, tail_y, lower[::-1]])
        else:
            x = np.concatenate([qq, [np.nan], qq])
            y = np.concatenate([upper, [np.nan], lower])
        xs += [x, [np.nan]]
        ys += [y, [np.nan]]
    if not xs:
        return np.array([]), np.array([])
    return np.concatenate(xs), np.concatenate(ys)


def _zero_between(x0: float, x1: float, f0: float, f1: float) -> float:
    if f1 == f0:
        return float(x0)
    return float(x0 - f0 * (x1 - x0) / (f1 - f0))


def _view_range(scene, name: str, value: float) -> tuple[float, float]:
    ranges = scene.view.get("ranges", {}) if isinstance(scene.view, dict) else {}
    if name in ranges:
        lo, hi = (float(v) for v in ranges[name])
        if lo < hi:
            return lo, hi
    half = max(1.0, 2.0 * abs(value))
    return value - half, value + half


@dataclass(frozen=True)
class ReductionCurves:
    """V_eff, the energy of the current state, turning points and the reduced portrait.

    Attributes
    ----------
    p_cyclic : ndarray, shape (c,)
    q, v_eff : ndarray, shape (K,)
        V_eff along the first remaining coordinate.
    energy : float
        H of the state with these conserved momenta.
    turning : ndarray
        Where V_eff = energy.
    minimum : float or None
        The sample where V_eff is least (inside the range).
    levels : ndarray
        Energies of the portrait's other level sets.
    lines : list of (x, y)
        The level sets of H_red at ``levels`` in (q, p).
    orbit : (x, y)
        The level set through the state.
    q0, p0 : float
        The state.
    """

    p_cyclic: np.ndarray
    q: np.ndarray
    v_eff: np.ndarray
    energy: float
    turning: np.ndarray
    minimum: float | None
    levels: np.ndarray
    lines: list
    orbit: tuple
    q0: float
    p0: float


def reduction_curves(
    setup: ReductionSetup, parameters: dict[str, float], p_cyclic, size: int = 1200
) -> ReductionCurves:
    """Everything the Reduction tab draws for one value of the conserved momenta (fast)."""
    from systems.textbook import turning_points

    reduction = setup.reduction
    n = len(setup.state) // 2
    p_cyclic = np.asarray(p_cyclic, dtype=float).ravel()
    q_lo, q_hi = setup.q_range
    if q_lo <= 0.0 <= q_hi and q_hi > 0:
        q_lo = max(q_lo, 1e-3 * (q_hi - q_lo))  # a radius: V_eff blows up at 0
    q = np.linspace(q_lo, q_hi, size)
    q_state = setup.state[list(setup.rest_index)]
    p_state = setup.state[[n + j for j in setup.rest_index]]
    rest_values = np.repeat(q_state[None, :], len(q), axis=0)
    rest_values[:, 0] = q
    V = reduction.effective_potential_function(parameters)
    H = reduction.reduced_hamiltonian_function(parameters)
    with np.errstate(all="ignore"):
        v_eff = np.asarray(V(rest_values, p_cyclic), dtype=float)
        energy = float(H(q_state[None, :], p_state[None, :], p_cyclic)[0])
    turning = np.empty(0)
    if len(setup.rest_index) == 1:
        try:
            with np.errstate(all="ignore"):
                turning = turning_points(
                    reduction, energy, p_cyclic, q_lo, q_hi, parameters=parameters, samples=801
                )
        except (ValueError, RuntimeError):
            turning = np.empty(0)
    finite = np.isfinite(v_eff)
    minimum = None
    if finite.any():
        k = int(np.argmin(np.where(finite, v_eff, np.inf)))
        if 0 < k < len(q) - 1:
            minimum = float(q[k])
    levels = _portrait_levels(v_eff[finite], energy)
    lines: list = []
    orbit: tuple = (np.array([]), np.array([]))
    if setup.quadratic is not None:
        A, B, C = setup.quadratic(q, p_cyclic)
        lines = [level_curve(q, A, B, C, float(level)) for level in levels]
        orbit = level_curve(q, A, B, C, energy)
    return ReductionCurves(
        p_cyclic,
        q,
        v_eff,
        energy,
        np.asarray(turning),
        minimum,
        levels,
        lines,
        orbit,
        float(q_state[0]),
        float(p_state[0]),
    )


def _portrait_levels(v_eff: np.ndarray, energy: float, count: int = 11) -> np.ndarray:
    """Energies from just above the bottom of V_eff to well past the state's energy."""
    if not v_eff.size:
        return np.empty(0)
    bottom = float(np.min(v_eff))
    span = energy - bottom
    if not span > 0:
        span = max(float(np.quantile(v_eff, 0.5)) - bottom, 1e-6)
    return bottom + span * np.linspace(0.0, 2.5, count + 1)[1:]


# -- action-angle -----------------------------------------------------------------------------


@dataclass(frozen=True)
class ActionAngleResult:
    """J(E) and T(E) of a one-degree system, with the separatrix and an exact check.

    Attributes
    ----------
    energies, action, period : ndarray
        NaN where there is no bounded motion through ``q0``.
    motion : list[str]
    q0 : float
        The stable equilibrium the motions pass through.
    minimum : float
        U at that equilibrium.
    separatrix : float or None
        The lowest U of an unstable equilibrium above the minimum.
    small_period : float or None
        2 pi / omega of small oscillations.
    exact : ndarray or None
        For U = u0 - c cos(q) with constant mass: the exact libration period
        ``4 sqrt(M/c) K(k^2)``, ``k^2 = (E - U_min) / (2c)`` (NaN above the separatrix).
    current : float
        The energy of the initial state.
    current_action, current_period : float or None
        J and T of the initial state's own orbit (None if it is not periodic).
    """

    energies: np.ndarray
    action: np.ndarray
    period: np.ndarray
    motion: list[str]
    q0: float
    minimum: float
    separatrix: float | None
    small_period: float | None
    exact: np.ndarray | None
    exact_formula: str
    current: float
    current_action: float | None = None
    current_period: float | None = None


def action_angle_reason(compiled) -> str:
    """Why the action-angle tab does not apply to this system ("" if it does)."""
    mechanics = compiled.mechanics
    if compiled.n != 1:
        return (
            f"action–angle variables are shown for one-degree systems; this one has {compiled.n} "
            "coordinates"
        )
    if mechanics.hamiltonian.has(mechanics.t):
        return "H depends explicitly on t: there are no fixed level sets H = E to integrate over"
    if any(f != 0 for f in mechanics.generalized_forces):
        return "effects (dissipation or forces) are switched on: the motion is not on H = E"
    return ""


def action_angle_data(
    compiled, equilibria_search, count: int = 160, cancel: Cancel = NEVER
) -> ActionAngleResult:
    """J and T over energies from the bottom of the well to past the separatrix."""
    from systems.textbook import action_angle

    reason = action_angle_reason(compiled)
    if reason:
        raise ValueError(reason)
    mechanics = compiled.mechanics
    parameters = parameters_of(compiled)
    name = names_of(compiled)[0]
    stable = [e for e in equilibria_search.equilibria if e.stable]
    state = compiled.initial_state()
    current = float(compiled.hamiltonian(0.0, state[None, :])[0])
    if not stable:
        raise ValueError("there is no stable equilibrium, so no librations to measure")
    # the well the current state is in, if it is in one; else the lowest
    well = min(stable, key=lambda e: (abs(e.q[name] - state[0]), e.potential))
    q0, minimum = float(well.q[name]), float(well.potential)
    above = [e.potential for e in equilibria_search.equilibria if not e.stable]
    above = [u for u in above if u > minimum + 1e-12]
    separatrix = min(above) if above else None
    scale = (separatrix - minimum) if separatrix is not None else max(current - minimum, 1.0)
    top = minimum + (2.0 if separatrix is not None else 1.5) * scale
    # below the separatrix: cluster samples towards it (T grows like log there)
    s = np.linspace(0.0, 1.0, count // 2 + 1)[1:]
    below = minimum + scale * (1.0 - (1.0 - s) ** 2 * 0.999 - 1e-4 * (1.0 - s))
    if separatrix is not None:
        after = (
            separatrix + (top - separatrix) * np.linspace(0.0, 1.0, count - count // 2 + 1)[1:] ** 2
        )
        after = np.maximum(after, separatrix + 1e-6 * scale)
        energies = np.concatenate([below, after])
    else:
        energies = minimum + (top - minimum) * np.linspace(0.0, 1.0, count + 1)[1:]
    J, T, motion = np.full(len(energies), np.nan), np.full(len(energies), np.nan), []
    for j, E in enumerate(energies):
        cancel.check()
        try:
            with np.errstate(all="ignore"):
                result = action_angle(mechanics, E, q0=q0, parameters=parameters)
        except (ValueError, ArithmeticError):
            motion.append("")
            continue
        J[j], T[j] = result.action, result.period
        motion.append(result.motion)
    small = None
    if well.frequencies:
        small = 2 * math.pi / float(well.frequencies[0])
    exact, formula = _pendulum_exact(mechanics, parameters, energies, minimum)
    own_action = own_period = None
    for through in (q0, float(state[0])):  # the state itself may sit at a turning point
        try:
            with np.errstate(all="ignore"):
                own = action_angle(mechanics, current, q0=through, parameters=parameters)
        except (ValueError, ArithmeticError):
            continue
        own_action, own_period = float(own.action), float(own.period)
        break
    return ActionAngleResult(
        energies,
        J,
        T,
        motion,
        q0,
        minimum,
        separatrix,
        small,
        exact,
        formula,
        current,
        own_action,
        own_period,
    )


def _pendulum_exact(mechanics, parameters, energies, minimum):
    """The exact libration period when U = u0 - c cos(q + phase) and M is constant."""
    from systems.textbook import equilibrium_potential

    q = mechanics.q[0]
    values = {mechanics.params[k]: v for k, v in parameters.items() if k in mechanics.params}
    U = sympy.expand(equilibrium_potential(mechanics)[0].xreplace(values))
    M = sympy.simplify(mechanics.mass_matrix[0, 0].xreplace(values))
    if M.free_symbols:
        return None, ""
    a = U.coeff(sympy.cos(q))
    rest = sympy.simplify(U - a * sympy.cos(q))
    if rest.has(q) or a.free_symbols or not a.is_number or float(a) >= 0:
        return None, ""
    c, mass = -float(a), float(M)
    k2 = (np.asarray(energies) - minimum) / (2 * c)
    with np.errstate(all="ignore"):
        exact = np.where(
            (k2 > 0) & (k2 < 1),
            4 * math.sqrt(mass / c) * scipy.special.ellipk(np.clip(k2, 0, 1 - 1e-16)),
            np.nan,
        )
    qname = pretty_name(mechanics.scene.coordinates[0])
    formula = f"4·√(M/c)·K(k²), U = −c cos {qname}, k² = (E − U_min)/(2c)"
    return exact, formula


# -- the energy theorem ------------------------------------------------------------------------


@dataclass(frozen=True)
class EnergyResult:
    """Both sides of dH/dt = -dL/dt (partial) + power of the effects, along a run."""

    balance: object
    run: Run
    rheonomic: bool
    explicit_time: bool
    effects: bool
    hamiltonian_is_energy: bool


def energy(compiled, duration: float, cancel: Cancel = NEVER) -> EnergyResult:
    from systems.textbook import energy_balance

    samples = int(min(20001, max(2001, 100 * duration)))  # dH/dt from samples: keep them dense
    run = integrate(compiled, duration, samples, cancel=cancel)
    if len(run.t) < 5:
        raise ValueError(f"the run stopped at once: {run.message}")
    cancel.check()
    balance = energy_balance(compiled.mechanics, run.t, run.y, parameters=parameters_of(compiled))
    cls = compiled.mechanics.classification
    effects = any(f != 0 for f in compiled.mechanics.generalized_forces)
    mechanics = compiled.mechanics
    expression = mechanics.lagrangian if mechanics.lagrangian is not None else mechanics.hamiltonian
    return EnergyResult(
        balance,
        run,
        bool(cls.time_dependent),
        bool(expression.has(mechanics.t)),
        effects,
        bool(cls.hamiltonian_is_energy),
    )
