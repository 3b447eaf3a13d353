"""Locating section crossings between two steps by cubic Hermite interpolation."""

from __future__ import annotations

import numpy as np


def locate_crossings(
    compiled, brackets_t: np.ndarray, brackets_y: np.ndarray, index: int, value: float
) -> tuple[np.ndarray, np.ndarray]:
    """Crossings of ``y[index] = value`` inside bracketing steps, by cubic Hermite.

    Parameters
    ----------
    brackets_t : ndarray, shape (e, 2)
        Times before and after each crossing step.
    brackets_y : ndarray, shape (e, 2, 2n)
        States before and after.

    Returns
    -------
    t : ndarray, shape (e,)
    y : ndarray, shape (e, 2n)
        The Hermite interpolant (from the states and rhs at both ends, error O(h^4)) at
        the root of its ``index`` component, found by safeguarded Newton/bisection.
    """
    e = len(brackets_t)
    m = brackets_y.shape[-1] if e else 0
    ts, ys = np.empty(e), np.empty((e, m))
    for i in range(e):
        t0, t1 = brackets_t[i]
        y0, y1 = brackets_y[i]
        h = t1 - t0
        f0 = compiled.rhs(t0, y0) * h
        f1 = compiled.rhs(t1, y1) * h

        def at(s, y0=y0, y1=y1, f0=f0, f1=f1):
            h00 = 2 * s**3 - 3 * s**2 + 1
            h10 = s**3 - 2 * s**2 + s
            h01 = -2 * s**3 + 3 * s**2
            h11 = s**3 - s**2
            return h00 * y0 + h10 * f0 + h01 * y1 + h11 * f1

        lo, hi = 0.0, 1.0
        g_lo = y0[index] - value
        s = g_lo / (g_lo - (y1[index] - value)) if y1[index] != y0[index] else 0.5
        for _ in range(60):
            g = at(s)[index] - value
            if g == 0.0:
                break
            if (g < 0) == (g_lo < 0):
                lo, g_lo = s, g
            else:
                hi = s
            if hi - lo < 1e-15:
                break
            s = 0.5 * (lo + hi)
        ts[i] = t0 + s * h
        ys[i] = at(s)
    return ts, ys
