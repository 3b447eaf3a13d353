"""Default step sizes and tolerances from the time scales of a compiled system."""

from __future__ import annotations

import math

import numpy as np

from systems.integrators.registry import Stepper

STEPS_PER_PERIOD = {2: 200, 4: 60, 6: 30, 8: 20}
"""Steps per fastest period at the start, by order: about 1e-4 relative error per period."""

DEFAULT_TOL = 1e-10
STIFF_TOL = 1e-6


def fastest_rate(compiled, t0: float, y0: np.ndarray) -> float:
    """Largest |eigenvalue| of the Jacobian of the compiled rhs at ``y0`` (shape (2n,)).

    Central differences on ``compiled.rhs``; 0.0 when it is not finite there.
    """
    m = len(y0)
    J = np.empty((m, m))
    for j in range(m):
        h = 1e-6 * max(1.0, abs(y0[j]))
        up, down = y0.copy(), y0.copy()
        up[j] += h
        down[j] -= h
        try:
            J[:, j] = (compiled.rhs(t0, up) - compiled.rhs(t0, down)) / (2 * h)
        except ZeroDivisionError:
            return 0.0
    if not np.all(np.isfinite(J)):
        return 0.0
    return float(np.abs(np.linalg.eigvals(J)).max())


def default_step(compiled, stepper: Stepper, t0: float, y0: np.ndarray, t_end: float) -> float:
    """A fixed step for ``stepper``: a fixed number of steps per fastest period at ``y0``.

    Falls back to ``(t_end - t0) / 1000`` (or 0.01) when the linearisation has no
    rate (free motion). For time-transformed steppers see ``fictitious_step``.
    """
    rate = fastest_rate(compiled, t0, y0)
    per_period = STEPS_PER_PERIOD.get(stepper.order, 60)
    if rate > 0.0:
        dt = 2.0 * math.pi / rate / per_period
    else:
        dt = 0.01
    if math.isfinite(t_end) and t_end > t0:
        dt = min(dt, (t_end - t0) / 10.0)
    return dt


def fictitious_step(compiled, stepper: Stepper, t0: float, y0: np.ndarray, t_end: float) -> float:
    """Fictitious-time step ``ds`` of a log-H stepper: ``dt * |V(q0)|`` for the default dt.

    In log-H stepping dt = ds / (-V), so ``ds`` matches ``dt`` where the motion starts.
    """
    dt = default_step(compiled, stepper, t0, y0, t_end)
    n = compiled.n
    V = compiled.kernels.potential(float(t0), np.ascontiguousarray(y0[:n]), compiled.parameters)
    return dt * max(abs(V), 1e-300)
