"""Default step sizes and tolerances from the time scales of a compiled system."""

from __future__ import annotations

import math
import threading
import weakref
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from systems.integrators.registry import Stepper


ENERGY_TARGET = 1e-10
"""The relative energy error the default settings aim at over a scene's run."""
STEPS_PER_PERIOD = {1: 2000, 2: 400, 4: 300, 6: 260, 8: 100}
"""Steps per fastest period, by order. Measured on the catalogue and the users' scenes:
order 8 (yoshida8) reaches ENERGY_TARGET by 75 steps in the worst separable scene (the
pendulum from theta = 2), order 6 (gauss_legendre6) by 196 in the worst non-separable one
(the double pendulum); these keep a margin. Orders 1, 2 and 4 cannot reach it at any
sensible cost (implicit midpoint needs 1e4 to 1e6 steps): their steps are for showing
what low orders do."""
TIME_TRANSFORMED_PER_PERIOD = {2: 200, 4: 60, 6: 100, 8: 60}
"""Steps per period of the motion at the start for time-transformed methods, by order: the
transformation shortens the steps at close approaches. logh_yoshida6 at 15 keeps Kepler's
energy to 1e-14 (e = 0.5 and 0.9), but the three-body figure-eight needs 90 (order 6) and
50 (order 8) to reach ENERGY_TARGET; these keep a margin. Orders 2 and 4 (the Gauss
methods' teaching variants) keep their Kepler-measured counts."""
PROBE_STEPS_PER_PERIOD = 30
"""Steps per period of the Runge-Kutta probe that looks for faster motion later on: RK4 at
30 steps per period keeps an orbit to about 1e-4 per period, ample to see where the motion
gets fast (60 took twice as long, most of a ten-link chain's first block)."""
PROBE_SAMPLES = 64
PROBE_JACOBIAN_BUDGET = 640
"""Most Jacobian columns the probe forms along its run: all 64 samples up to 10 state
variables, fewer beyond (a 20-variable system samples every other state)."""

PROBE_MEMORY = 32
"""Probed rates kept per compiled system: a change of method (only the steps per period
differ) or a restart from the same state finds the probe's answer instead of running it
again (tens of ms, in the worker's loop, while a click waits)."""

DEFAULT_TOL = 1e-12
STIFF_TOL = 1e-6


def jacobian(f, y0: np.ndarray, central: bool = True) -> np.ndarray | None:
    """Finite-difference Jacobian of ``f(y) -> (m,)`` at ``y0`` (shape (m,)), shape (m, m).

    Central differences (2m evaluations), or forward ones (m + 1, error of order 1e-6
    relative: ample for a rate that sets a step). None where ``f`` fails (a division by
    zero, a domain error), is complex or is not finite there.
    """
    m = len(y0)
    J = np.empty((m, m))
    try:
        with np.errstate(all="ignore"):
            base = None if central else np.asarray(f(y0), dtype=float)
            for j in range(m):
                h = 1e-6 * max(1.0, abs(y0[j]))
                up = y0.copy()
                up[j] += h
                if central:
                    down = y0.copy()
                    down[j] -= h
                    J[:, j] = (np.asarray(f(up), dtype=float) - np.asarray(f(down), float)) / (
                        2 * h
                    )
                else:
                    J[:, j] = (np.asarray(f(up), dtype=float) - base) / h
    except (ArithmeticError, ValueError, TypeError):  # TypeError: a complex value
        return None
    return J if np.all(np.isfinite(J)) else None


def fastest_rate(compiled, t0: float, y0: np.ndarray, central: bool = True, rhs=None) -> float:
    """Largest |eigenvalue| of the Jacobian of the compiled rhs at ``y0`` (shape (2n,)).

    Finite differences (see ``jacobian``) on ``rhs(t, y)`` (default ``compiled.rhs``);
    0.0 when it is not finite there.
    """
    f = compiled.rhs if rhs is None else rhs
    J = jacobian(lambda y: f(t0, y), y0, central)
    return 0.0 if J is None else float(np.abs(np.linalg.eigvals(J)).max())


def default_step(
    compiled,
    stepper: Stepper,
    t0: float,
    y0: np.ndarray,
    t_end: float,
    probe: bool = True,
    per_period: int | None = None,
    probe_start: tuple[float, np.ndarray] | None = None,
    aim: bool = True,
) -> float:
    """A fixed step for ``stepper``: ``STEPS_PER_PERIOD`` steps per fastest period, then
    (with ``aim``) aimed at the energy target by pilot runs (``aimed_step``).

    The fastest rate is the largest |eigenvalue| of the Jacobian at ``y0`` and, with
    ``probe``, at states sampled along a short Runge-Kutta run (about 20 periods
    of the initial motion): a pendulum released at rest moves much faster later. A probe
    that fails (the state stops being finite) is repeated with half the step.
    Falls back to 0.01 when the linearisation has no rate (free motion); never more than
    a tenth of a finite run. For time-transformed steppers see ``fictitious_step``.

    ``probe_start`` (t, y): where the probe runs from instead (a run restarted part way
    along an orbit with another method probes from where the orbit began, so the probe
    already run there is found again, not run once more).
    """
    if per_period is None:
        per_period = STEPS_PER_PERIOD.get(stepper.order, 300)
    rate = fastest_rate(compiled, t0, y0)
    dt = 2.0 * math.pi / rate / per_period if rate > 0.0 else 0.01
    if math.isfinite(t_end) and t_end > t0:
        dt = min(dt, (t_end - t0) / 10.0)
    if not probe or rate <= 0.0 or stepper.setting != "dt" or stepper.family.adaptive:
        return dt
    start = (t0, y0) if probe_start is None else probe_start
    rate = max(rate, _probed_rate(compiled, float(start[0]), np.asarray(start[1], float), t_end))
    dt = min(dt, 2.0 * math.pi / rate / per_period)
    if not aim:
        return dt
    return aimed_step(compiled, stepper, float(t0), np.asarray(y0, dtype=float), t_end, dt)


AIMED_ORDERS = (6, 8)
"""Orders whose default step is aimed at ``ENERGY_TARGET`` by pilot runs (``aimed_step``)
on a conservative system: the orders the automatic choice uses there. Lower orders keep
``STEPS_PER_PERIOD`` (their energy plot shows what low orders do)."""
STATE_AIMED_ORDERS = (4, 6, 8)
"""Orders whose default step is aimed at the same target through the error of the state
(Richardson's estimate from pilots at the step and half of it) where H is not conserved
(damping, driving): nothing on screen shows their error there. Orders 1 and 2 would need
10^4 to 10^6 steps a period; ``systems.run_check`` says plainly when they are off."""
AIM = 0.1
"""The error aimed at, as a fraction of ``ENERGY_TARGET`` (a margin for the part of the
run the pilot does not cover)."""
AIM_GROWTH = (0.25, 3.0)
"""The aimed step stays within these factors of ``STEPS_PER_PERIOD``'s."""
STATE_AIM_GROWTH = (1.0 / 16.0, 3.0)
"""The same where the state's error is aimed at: RK4 and Gauss-Legendre 4 at 300 steps a
period end 4.7e-9 and 7.9e-10 from a damped oscillator's exact state at t = 10 and need
a fifth and a third of that step; a lower order or a larger error hits the bound."""
AIM_PILOT_STEPS = 8000
"""Steps of a pilot run at most (the whole run when it is shorter)."""

_aimed: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def aimed_step(compiled, stepper, t0: float, y0: np.ndarray, t_end: float, dt: float) -> float:
    """``dt`` scaled so that the run's error lands near ``AIM * ENERGY_TARGET`` instead of
    far below it (or above it).

    For a fixed-step method: on a conservative system (orders ``AIMED_ORDERS``) the error
    is the largest relative energy error of a pilot run of the method itself at ``dt``
    (``AIM_PILOT_STEPS`` steps at most, over the run or the scene's ``[view] t_end`` for
    an endless one); where H is not conserved (orders ``STATE_AIMED_ORDERS``) it is the
    final state's error relative to its size (at least 1), by Richardson's estimate from
    a second pilot at half the step. The step is scaled by (AIM * ENERGY_TARGET /
    e)^(1 / order), within ``AIM_GROWTH`` (``STATE_AIM_GROWTH``), and a pilot at the new
    step must keep the error within ``ENERGY_TARGET`` (else the step shrinks by 1.5 at
    most twice more, and otherwise stays ``dt``: chaotic motion, whose error no
    affordable step bounds). Counted in errors, never timed: the same system and start
    always get the same step. Remembered per compiled system, start and method.
    """
    order = stepper.order
    if stepper.setting != "dt" or stepper.family.adaptive:
        return dt
    c = compiled.mechanics.classification
    if c.conservative and c.hamiltonian_conserved:
        if order not in AIMED_ORDERS or "hamiltonian" not in getattr(compiled, "wanted", ()):
            return dt
        error, growth = _pilot_error, AIM_GROWTH
    elif order in STATE_AIMED_ORDERS:
        error, growth = _state_error, STATE_AIM_GROWTH
    else:
        return dt
    horizon = t_end - t0
    if not math.isfinite(horizon) or horizon <= 0.0:
        horizon = float(compiled.mechanics.scene.view.get("t_end", 10.0) or 10.0)
    parameters = np.asarray(getattr(compiled, "parameters", ()), dtype=float)
    key = (stepper.name, t0, y0.tobytes(), parameters.tobytes(), horizon, dt)
    with _probed_lock:
        try:
            memory = _aimed.setdefault(compiled, {})
        except TypeError:
            memory = {}
        if key in memory:
            return memory[key]
    aimed = _aim(lambda step: error(compiled, stepper, t0, y0, horizon, step), order, dt, growth)
    with _probed_lock:
        if len(memory) >= PROBE_MEMORY:
            memory.pop(next(iter(memory)))
        memory[key] = aimed
    return aimed


def _aim(error_at, order: int, dt: float, growth: tuple[float, float]) -> float:
    error = error_at(dt)
    if error is None:
        return dt
    low, high = growth
    target = AIM * ENERGY_TARGET
    factor = high if error <= 0.0 else (target / error) ** (1.0 / order)
    factor = min(max(factor, low), high)
    if abs(factor - 1.0) < 0.05:
        return dt
    for _ in range(3):
        trial = dt * factor
        error = error_at(trial)
        if error is not None and error <= ENERGY_TARGET:
            return trial
        factor /= 1.5
        if factor < low:
            break
    return dt


def _pilot_error(compiled, stepper, t0, y0, horizon, dt) -> float | None:
    """The largest relative |H - H0| of a run of ``stepper`` at ``dt`` over ``horizon``
    (``AIM_PILOT_STEPS`` steps at most); None where the run fails."""
    end = t0 + min(horizon, AIM_PILOT_STEPS * dt)
    outcome = pilot_run(compiled, stepper.name, t0, y0, end, AIM_PILOT_STEPS, dt=dt)
    return None if outcome is None else outcome[0]


def _state_error(compiled, stepper, t0, y0, horizon, dt) -> float | None:
    """Richardson's estimate of the error of the state a run of ``stepper`` at ``dt``
    reaches over ``horizon`` (``AIM_PILOT_STEPS`` steps at most), relative to the
    state's size (at least 1), from a run at ``dt / 2``; None where a run fails."""
    from systems.simulation import Run

    end = t0 + min(horizon, AIM_PILOT_STEPS * dt)
    finals = []
    for step, steps in ((dt, AIM_PILOT_STEPS), (dt / 2, 2 * AIM_PILOT_STEPS)):
        try:
            run = Run(
                compiled, method=stepper.name, y0=y0, t0=t0, t_end=end, dt=step,
                max_points=2, energy_tolerance=None, max_steps=steps + 2,
            )  # fmt: skip
        except (ValueError, ArithmeticError):
            return None
        if run.runner is None:
            return None
        last = run.advance(math.inf)
        while not run.finished and last.status in ("ok", "running"):
            last = run.advance(math.inf)
        if last.status != "ok" or not len(last.y) or not np.all(np.isfinite(last.y[-1])):
            return None
        finals.append(np.asarray(last.y[-1], dtype=float))
    coarse, fine = finals
    scale = max(1.0, float(np.max(np.abs(y0))), float(np.max(np.abs(coarse))))
    p = stepper.order
    return float(np.max(np.abs(coarse - fine))) * 2**p / (2**p - 1) / scale


def pilot_run(
    compiled, method: str, t0: float, y0: np.ndarray, t_end: float, steps: int, **setting
) -> tuple[float, int, float] | None:
    """A short run that measures: (the largest relative |H - H0|, the right-hand-side
    evaluations, the time covered) of ``method`` from ``(t0, y0)`` (y0 of shape (2n,))
    towards ``t_end``, ``steps`` steps at most, at ``setting`` (``dt=`` or ``tol=``;
    none: the method's default). H is checked at every step: a thinned output misses
    the peaks of the error. None where the run fails or covers no time."""
    from systems.simulation import Run

    try:
        run = Run(
            compiled, method=method, y0=y0, t0=t0, t_end=t_end, diagnostics=("H",),
            max_points=steps + 2, energy_tolerance=None, max_steps=steps + 1, **setting,
        )  # fmt: skip
    except (ValueError, ArithmeticError):
        return None
    if run.runner is None:
        return None
    H0 = float(compiled.hamiltonian(t0, y0[None, :])[0])
    scale = abs(H0) if abs(H0) > 1e-8 else 1.0
    worst = 0.0
    evaluations = 0
    while not run.finished:
        block = run.advance(1.0)
        evaluations = block.rhs_evaluations  # totals since the start
        if block.status not in ("ok", "running", "budget"):
            return None
        H = block.diagnostics.get("H")
        if H is not None and len(H):
            with np.errstate(all="ignore"):
                worst = max(worst, float(np.max(np.abs(H - H0))) / scale)
        if block.status == "budget":
            break
    covered = run.t - t0
    if not covered > 0.0 or not math.isfinite(worst):
        return None
    return worst, evaluations, covered


DRAWN_PER_PERIOD = 64
"""Steps per period of the fastest linear motion at the start, at least, in a drawing."""
DRAWN_PER_RUN = 256
"""Steps over a finite run, at least, in a drawing."""
DRAWN_PER_TRAVERSE = 16
"""Without a linear rate: steps while the state moves by its own size, at least."""


def drawing_step(compiled, t0: float, y0: np.ndarray, t_end: float) -> float:
    """The longest step an adaptive method may take in a run that is drawn.

    ``DRAWN_PER_PERIOD`` steps per fastest period at ``y0`` (``fastest_rate``); where the
    linearisation has no rate (a free flight, a ball between bounces), ``y0``'s size over
    its rate of change, divided by ``DRAWN_PER_TRAVERSE``; never more than
    ``1 / DRAWN_PER_RUN`` of a finite run. inf when none of these gives a scale.
    """
    rate = fastest_rate(compiled, t0, y0)
    h = math.inf
    if rate > 0.0:
        h = 2.0 * math.pi / rate / DRAWN_PER_PERIOD
    else:
        try:
            with np.errstate(all="ignore"):
                speed = float(np.linalg.norm(np.asarray(compiled.rhs(t0, y0), dtype=float)))
        except (ArithmeticError, ValueError, TypeError):
            speed = math.nan
        size = float(np.linalg.norm(y0))
        if math.isfinite(speed) and speed > 0.0 and size > 0.0:
            h = size / speed / DRAWN_PER_TRAVERSE
    if math.isfinite(t_end) and t_end > t0:
        h = min(h, (t_end - t0) / DRAWN_PER_RUN)
    return h


_probed: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()
_probed_lock = threading.Lock()  # runs are made in the worker, the GUI and job threads


def _probed_rate(compiled, t0: float, y0: np.ndarray, t_end: float) -> float:
    """The fastest rate at ``(t0, y0)`` and along the probe's run from there (0.0: none).

    Remembered per compiled system (its parameters, the start and ``t_end`` are the
    key), since it does not depend on the method.
    """
    parameters = np.asarray(getattr(compiled, "parameters", ()), dtype=float)
    key = (t0, y0.tobytes(), parameters.tobytes(), t_end)
    with _probed_lock:
        try:
            memory = _probed.setdefault(compiled, {})
        except TypeError:  # not weakly referenceable: nothing is remembered
            memory = {}
        if key in memory:
            return memory[key]
    rate = fastest_rate(compiled, t0, y0)
    if rate <= 0.0:
        return rate
    probe_dt = 2.0 * math.pi / rate / PROBE_STEPS_PER_PERIOD
    if math.isfinite(t_end) and t_end > t0:
        probe_dt = min(probe_dt, (t_end - t0) / 10.0)
    found = rate
    for _ in range(6):
        states = _probe(compiled.rhs, t0, y0, probe_dt, 20 * PROBE_STEPS_PER_PERIOD)
        if states is not None:
            break
        probe_dt /= 2.0
    else:
        states = []
    # a Jacobian costs 2 * len(y) evaluations: fewer samples for large systems keep the
    # probe's cost bounded
    every = max(1, len(y0) * max(len(states), 1) // PROBE_JACOBIAN_BUDGET)
    for t, y in states[every - 1 :: every]:  # forward differences: half the evaluations
        found = max(found, fastest_rate(compiled, t, y, central=False))
    with _probed_lock:
        if len(memory) >= PROBE_MEMORY:
            memory.pop(next(iter(memory)))
        memory[key] = found
    return found


def _probe(f, t0, y0, dt, nsteps, samples=PROBE_SAMPLES):
    """States ``(t, y)`` along ``nsteps`` classical Runge-Kutta steps of ``dt`` on
    ``f(t, y)``, or None.

    RK4 on the compiled ``rhs`` rather than the method itself: the states only show
    where the motion gets fast (a few ms for the whole loop). None when the state stops
    being finite.
    """
    y = np.array(y0, dtype=float)
    stride = max(1, nsteps // samples)
    states = []
    half = 0.5 * dt
    try:
        with np.errstate(all="ignore"):
            for k in range(1, nsteps + 1):
                t = t0 + (k - 1) * dt
                k1 = f(t, y)
                k2 = f(t + half, y + half * k1)
                k3 = f(t + half, y + half * k2)
                k4 = f(t + dt, y + dt * k3)
                y = y + (dt / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
                if k % stride == 0:
                    if not np.all(np.isfinite(y)):
                        return None
                    states.append((t0 + k * dt, y))
    except ArithmeticError:
        return None
    return states


def fictitious_step(
    compiled, stepper: Stepper, t0: float, y0: np.ndarray, t_end: float, probe_start=None
) -> float:
    """Fictitious-time step ``ds`` of a log-H stepper: ``dt * |V(q0)|`` for the default dt.
    (No probe: ``probe_start`` is not used.)

    In log-H stepping dt = ds / (-V), so ``ds`` matches ``dt`` where the motion starts.
    """
    dt = time_transformed_step(compiled, stepper, t0, y0, t_end)
    V = compiled.kernels.potential(float(t0), np.ascontiguousarray(y0), compiled.parameters)
    return dt * max(abs(V), 1e-300)


def time_transformed_step(
    compiled, stepper: Stepper, t0: float, y0, t_end: float, probe_start=None
) -> float:
    """Fictitious-time step of a Sundman-transformed method (g = 1 at the start; no probe,
    ``probe_start`` is not used)."""
    per_period = TIME_TRANSFORMED_PER_PERIOD.get(stepper.order, 60)
    return default_step(compiled, stepper, t0, y0, t_end, probe=False, per_period=per_period)
