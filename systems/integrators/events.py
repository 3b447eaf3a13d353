"""Section crossings located between two steps, and DOP853's dense output.

The compiled loops only bracket a crossing of ``y[index] = value`` by the states before
and after a step. Here the crossing is found on an interpolant of that step: DOP853's own
7th-order dense output for DOP853 runs (``dop853_interpolant``), a cubic Hermite
interpolant from the states and derivatives at both ends otherwise (error O(h^4)).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np


def hermite_interpolant(compiled, t0, y0, t1, y1) -> Callable[[float], np.ndarray]:
    """Cubic Hermite interpolant of one step; returns ``u(s)``, s in [0, 1] -> (2n,)."""
    h = t1 - t0
    f0 = compiled.rhs(t0, y0) * h
    f1 = compiled.rhs(t1, y1) * h

    def u(s: float) -> np.ndarray:
        h00 = 2 * s**3 - 3 * s**2 + 1
        h10 = s**3 - 2 * s**2 + s
        h01 = -2 * s**3 + 3 * s**2
        h11 = s**3 - s**2
        return h00 * y0 + h10 * f0 + h01 * y1 + h11 * f1

    return u


def dop853_interpolant(compiled, t0, y0, t1, y1) -> Callable[[float], np.ndarray]:
    """DOP853's dense output over the accepted step from ``(t0, y0)`` to ``(t1, y1)``.

    The step's 12 stages are recomputed (the compiled loop keeps no history), then the
    three extra stages and Hairer's interpolation polynomial of order 7, as in scipy.
    Returns ``u(s)``, s in [0, 1] -> state (2n,).
    """
    from scipy.integrate._ivp import dop853_coefficients as dc

    h = t1 - t0
    m = len(y0)
    K = np.empty((dc.N_STAGES_EXTENDED, m))
    K[0] = compiled.rhs(t0, y0)
    for s in range(1, dc.N_STAGES):
        K[s] = compiled.rhs(t0 + dc.C[s] * h, y0 + h * (dc.A[s, :s] @ K[:s]))
    K[dc.N_STAGES] = compiled.rhs(t1, y1)
    for s in range(dc.N_STAGES + 1, dc.N_STAGES_EXTENDED):
        K[s] = compiled.rhs(t0 + dc.C[s] * h, y0 + h * (dc.A[s, :s] @ K[:s]))
    delta = y1 - y0
    F = np.empty((dc.INTERPOLATOR_POWER, m))
    F[0] = delta
    F[1] = h * K[0] - delta
    F[2] = 2 * delta - h * (K[dc.N_STAGES] + K[0])
    F[3:] = h * (dc.D @ K)

    def u(s: float) -> np.ndarray:
        y = np.zeros(m)
        for i, f in enumerate(reversed(F)):
            y += f
            y *= s if i % 2 == 0 else 1 - s
        return y + y0

    return u


def locate_crossings(
    compiled,
    brackets_t: np.ndarray,
    brackets_y: np.ndarray,
    index: int,
    value: float,
    *,
    dense: bool = False,
) -> tuple[np.ndarray, np.ndarray]:
    """Crossings of ``y[index] = value`` inside bracketing steps.

    Parameters
    ----------
    brackets_t : ndarray, shape (e, 2)
        Times before and after each crossing step.
    brackets_y : ndarray, shape (e, 2, 2n)
        States before and after.
    dense : bool
        The steps are DOP853 steps: use its dense output instead of cubic Hermite.

    Returns
    -------
    t : ndarray, shape (e,)
    y : ndarray, shape (e, 2n)
        The interpolant at the root of its ``index`` component, found by safeguarded
        secant/bisection.
    """
    e = len(brackets_t)
    m = brackets_y.shape[-1] if e else 0
    ts, ys = np.empty(e), np.empty((e, m))
    make = dop853_interpolant if dense else hermite_interpolant
    for i in range(e):
        t0, t1 = brackets_t[i]
        y0, y1 = brackets_y[i]
        u = make(compiled, t0, y0, t1, y1)
        s = _root(lambda s, u=u: u(s)[index] - value, y0[index] - value, y1[index] - value)
        ts[i] = t0 + s * (t1 - t0)
        ys[i] = u(s)
    return ts, ys


def _root(g: Callable[[float], float], g0: float, g1: float) -> float:
    """A root of ``g`` on [0, 1] with g(0) = g0, g(1) = g1 of opposite signs (or zero)."""
    lo, hi, g_lo, g_hi = 0.0, 1.0, g0, g1
    if g_lo == 0.0:
        return 0.0
    if g_hi == 0.0:
        return 1.0
    for _ in range(100):
        s = lo - g_lo * (hi - lo) / (g_hi - g_lo)  # regula falsi (Illinois)
        if not lo < s < hi:
            s = 0.5 * (lo + hi)
        gs = g(s)
        if abs(gs) <= 1e-16 * (abs(g0) + abs(g1)) or hi - lo < 1e-15:
            return s
        if (gs < 0) == (g_lo < 0):
            lo, g_lo = s, gs
            g_hi *= 0.5
        else:
            hi, g_hi = s, gs
            g_lo *= 0.5
    return s
