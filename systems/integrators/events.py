"""Section crossings located between two steps, and DOP853's dense output.

The compiled loops only bracket a crossing of ``y[index] = value`` by the states before
and after a step. Here the crossing is found on an interpolant of that step: DOP853's own
7th-order dense output for DOP853 runs (``dop853_interpolant``), the step's own series
for Taylor runs (``taylor_interpolant``), a cubic Hermite interpolant from the states
and derivatives at both ends otherwise (error O(h^4)).

A section on an angle coordinate is crossed at ``value + 2 pi j`` for every integer j:
``periodic_brackets`` finds those steps among consecutive states (the compiled loop only
knows one level), and ``locate_crossings`` takes one level per bracket.
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
    from systems.integrators.tableaux import dop853_coefficients

    dc = dop853_coefficients()
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


def taylor_interpolant(compiled, t0, y0, t1, y1, order: int = 20) -> Callable[[float], np.ndarray]:
    """The Taylor family's dense output over the step from ``(t0, y0)`` to ``(t1, y1)``:
    the step's own polynomial (the coefficients to ``order`` through ``(t0, y0)``,
    computed again by the scene's compiled coefficient function), as accurate as the
    step at every point of it. Returns ``u(s)``, s in [0, 1] -> state (2n,)."""
    h = t1 - t0
    y0 = np.ascontiguousarray(y0, dtype=float)
    C = compiled.taylor().coefficients(t0, y0, compiled.parameters, order)[:, : len(y0)]

    def u(s: float) -> np.ndarray:
        x = s * h
        total = C[order].copy()
        for k in range(order - 1, 0, -1):
            total = total * x + C[k]
        return y0 + total * x

    return u


def periodic_brackets(
    t: np.ndarray,
    y: np.ndarray,
    index: int,
    value: float,
    direction: float,
    period: float = 2.0 * np.pi,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Steps between consecutive states that cross ``y[index] = value + period * j``.

    The test is the compiled loop's (``before < level <= after`` upward, ``before > level
    >= after`` downward), for every level j at once: with ``k = floor((y - value) /
    period)`` an upward step crosses the levels ``j`` in ``(k_before, k_after]``, and with
    ``c = ceil(...)`` a downward one those in ``[c_after, c_before)``. A step that turns
    more than once yields one bracket per level.

    Parameters
    ----------
    t : ndarray, shape (k,)
        Times of consecutive accepted steps (every step, not a thinned output); two rows
        at one time (an impact, before and after) bracket nothing.
    y : ndarray, shape (k, m)
    index : int
    value : float
    direction : float
        +1 upward, -1 downward, 0 both.
    period : float

    Returns
    -------
    brackets_t : ndarray, shape (e, 2)
    brackets_y : ndarray, shape (e, 2, m)
    levels : ndarray, shape (e,)
        The level ``value + period * j`` each bracket crosses, in time order.
    """
    t = np.asarray(t, dtype=float)
    y = np.asarray(y, dtype=float)
    m = y.shape[1] if y.ndim == 2 else 0
    empty = (np.empty((0, 2)), np.empty((0, 2, m)), np.empty(0))
    if len(t) < 2:
        return empty
    u = (y[:, index] - value) / period
    with np.errstate(invalid="ignore"):
        k = np.floor(u)
        c = np.ceil(u)
    rows: list[int] = []
    levels: list[float] = []
    # an impact's two rows share a time: a jump of the velocities, not the flow crossing
    finite = np.isfinite(u[:-1]) & np.isfinite(u[1:]) & (t[1:] > t[:-1])
    if direction >= 0:
        for i in np.flatnonzero(finite & (k[1:] > k[:-1])):
            for j in np.arange(k[i] + 1, k[i + 1] + 1):
                rows.append(i)
                levels.append(value + period * j)
    if direction <= 0:
        for i in np.flatnonzero(finite & (c[1:] < c[:-1])):
            for j in np.arange(c[i] - 1, c[i + 1] - 1, -1):
                rows.append(i)
                levels.append(value + period * j)
    if not rows:
        return empty
    order = np.argsort(np.array(rows), kind="stable")
    rows_sorted = np.array(rows)[order]
    brackets_t = np.stack([t[rows_sorted], t[rows_sorted + 1]], axis=1)
    brackets_y = np.stack([y[rows_sorted], y[rows_sorted + 1]], axis=1)
    return brackets_t, brackets_y, np.array(levels)[order]


def locate_crossings(
    compiled,
    brackets_t: np.ndarray,
    brackets_y: np.ndarray,
    index: int,
    value: float | np.ndarray,
    *,
    dense: bool | str = False,
    order: int = 20,
) -> tuple[np.ndarray, np.ndarray]:
    """Crossings of ``y[index] = value`` inside bracketing steps.

    Parameters
    ----------
    brackets_t : ndarray, shape (e, 2)
        Times before and after each crossing step.
    brackets_y : ndarray, shape (e, 2, 2n)
        States before and after.
    value : float or ndarray, shape (e,)
        The level, or one level per bracket (a section on an angle).
    dense : bool or "taylor"
        The steps are DOP853 steps (True): use its dense output instead of cubic
        Hermite; "taylor": Taylor steps of ``order``, whose dense output is the series.
    order : int
        The Taylor steps' order.

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
    if dense == "taylor":

        def make(compiled, t0, y0, t1, y1):
            return taylor_interpolant(compiled, t0, y0, t1, y1, order)

    levels = np.broadcast_to(np.asarray(value, dtype=float), (e,))
    for i in range(e):
        t0, t1 = brackets_t[i]
        y0, y1 = brackets_y[i]
        level = float(levels[i])
        u = make(compiled, t0, y0, t1, y1)
        s = _root(lambda s, u=u, c=level: u(s)[index] - c, y0[index] - level, y1[index] - level)
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
