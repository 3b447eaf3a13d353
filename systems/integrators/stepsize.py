"""Default step sizes and tolerances from the time scales of a compiled system."""

from __future__ import annotations

import math

import numpy as np

from systems.integrators.registry import Stepper

STEPS_PER_PERIOD = {2: 200, 4: 60, 6: 30, 8: 20}
"""Steps per fastest period at the start, by order: about 1e-4 relative error per period."""

DEFAULT_TOL = 1e-10
STIFF_TOL = 1e-6


def jacobian(f, y0: np.ndarray) -> np.ndarray | None:
    """Central-difference Jacobian of ``f(y) -> (m,)`` at ``y0`` (shape (m,)), shape (m, m).

    None where ``f`` fails (a division by zero, a domain error) or is not finite there.
    """
    m = len(y0)
    J = np.empty((m, m))
    for j in range(m):
        h = 1e-6 * max(1.0, abs(y0[j]))
        up, down = y0.copy(), y0.copy()
        up[j] += h
        down[j] -= h
        try:
            J[:, j] = (np.asarray(f(up), dtype=float) - np.asarray(f(down), dtype=float)) / (2 * h)
        except (ZeroDivisionError, ValueError, OverflowError):
            return None
    return J if np.all(np.isfinite(J)) else None


def fastest_rate(compiled, t0: float, y0: np.ndarray) -> float:
    """Largest |eigenvalue| of the Jacobian of the compiled rhs at ``y0`` (shape (2n,)).

    Central differences on ``compiled.rhs``; 0.0 when it is not finite there.
    """
    J = jacobian(lambda y: compiled.rhs(t0, y), y0)
    return 0.0 if J is None else float(np.abs(np.linalg.eigvals(J)).max())


def default_step(
    compiled, stepper: Stepper, t0: float, y0: np.ndarray, t_end: float, probe: bool = True
) -> float:
    """A fixed step for ``stepper``: ``STEPS_PER_PERIOD`` steps per fastest period.

    The fastest rate is the largest |eigenvalue| of the Jacobian at ``y0`` and, with
    ``probe``, at states sampled along a short Runge-Kutta run (about 20 periods
    of the initial motion): a pendulum released at rest moves much faster later. A probe
    that fails (the state stops being finite) is repeated with half the step.
    Falls back to 0.01 when the linearisation has no rate (free motion); never more than
    a tenth of a finite run. For time-transformed steppers see ``fictitious_step``.
    """
    per_period = STEPS_PER_PERIOD.get(stepper.order, 60)
    rate = fastest_rate(compiled, t0, y0)
    dt = 2.0 * math.pi / rate / per_period if rate > 0.0 else 0.01
    if math.isfinite(t_end) and t_end > t0:
        dt = min(dt, (t_end - t0) / 10.0)
    if not probe or rate <= 0.0 or stepper.family not in ("composition", "gauss"):
        return dt
    for _ in range(6):
        states = _probe(compiled, t0, y0, dt, 20 * per_period)
        if states is not None:
            break
        dt /= 2.0
    else:
        return dt
    for t, y in states:
        rate = max(rate, fastest_rate(compiled, t, y))
    return min(dt, 2.0 * math.pi / rate / per_period)


def _probe(compiled, t0, y0, dt, nsteps, samples=24):
    """States ``(t, y)`` along ``nsteps`` classical Runge-Kutta steps of ``dt``, or None.

    RK4 on ``compiled.rhs`` rather than the method itself: the states only show where the
    motion gets fast, and this loop costs the same (a few ms) whether the kernels are
    compiled yet or still interpreted (``systems.interpreted``), so the step chosen never
    depends on how far numba has got. None when the state stops being finite.
    """
    f = compiled.rhs
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


def fictitious_step(compiled, stepper: Stepper, t0: float, y0: np.ndarray, t_end: float) -> float:
    """Fictitious-time step ``ds`` of a log-H stepper: ``dt * |V(q0)|`` for the default dt.

    In log-H stepping dt = ds / (-V), so ``ds`` matches ``dt`` where the motion starts.
    """
    dt = default_step(compiled, stepper, t0, y0, t_end)
    n = compiled.n
    V = compiled.kernels.potential(float(t0), np.ascontiguousarray(y0[:n]), compiled.parameters)
    return dt * max(abs(V), 1e-300)
