"""Level sets of H(q, p) for one-degree autonomous systems, with the separatrix.

H is evaluated on a grid with the compiled Hamiltonian (one batched call); saddle points
are found from the grid's small-gradient cells, refined with Newton's method on finite
differences of H, and kept when the Hessian determinant is negative (centres, where it is
positive, are kept apart). The separatrix is the level set through a saddle.

``fit_window`` chooses the phase plane's ranges before anything is integrated: it grows a
first guess until the closed level sets that matter (the main orbit's energy, the
separatrix) and the equilibria lie inside, so the view fits them at once.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import contourpy
import numpy as np
from scipy.optimize import root


@dataclass(frozen=True)
class EnergyGrid:
    """H on a grid: ``values[i, j] = H(qs[i], ps[j])`` for the coordinate pair shown."""

    qs: np.ndarray
    ps: np.ndarray
    values: np.ndarray


@dataclass(frozen=True)
class Saddle:
    q: float
    p: float
    energy: float


def energy_grid(
    compiled, q_range, p_range, size: int = 201, base_state=None, index: int = 0, t: float = 0.0
) -> EnergyGrid:
    """H over ``q_range x p_range`` for coordinate ``index`` (others from ``base_state``)."""
    n = compiled.n
    qs = np.linspace(*q_range, size)
    ps = np.linspace(*p_range, size)
    Q, P = np.meshgrid(qs, ps, indexing="ij")
    base = np.zeros(2 * n) if base_state is None else np.asarray(base_state, dtype=float)
    Y = np.repeat(base[None, :], Q.size, axis=0)
    Y[:, index] = Q.ravel()
    Y[:, n + index] = P.ravel()
    with np.errstate(all="ignore"):
        values = compiled.hamiltonian(t, Y).reshape(Q.shape)
    return EnergyGrid(qs, ps, values)


def _h(compiled, q: float, p: float, t: float = 0.0) -> float:
    return float(compiled.hamiltonian(t, np.array([[q, p]]))[0])


def _gradient(compiled, x: np.ndarray, step: np.ndarray) -> np.ndarray:
    q, p = x
    hq, hp = step
    Y = np.array([[q + hq, p], [q - hq, p], [q, p + hp], [q, p - hp]])
    H = compiled.hamiltonian(0.0, Y)
    return np.array([(H[0] - H[1]) / (2 * hq), (H[2] - H[3]) / (2 * hp)])


def find_saddles(compiled, grid: EnergyGrid, limit: int = 8) -> list[Saddle]:
    """Saddle points of H inside the grid (1-degree systems only)."""
    return find_stationary(compiled, grid, limit)[0]


def find_stationary(
    compiled, grid: EnergyGrid, limit: int = 8
) -> tuple[list[Saddle], list[tuple[float, float]]]:
    """Saddles and centres (extrema) of H inside the grid (1-degree systems only).

    Returns
    -------
    saddles : list of Saddle
    centres : list of (q, p)
    """
    if compiled.n != 1:
        return [], []
    values = grid.values
    if not np.isfinite(values).any():
        return [], []
    dq = grid.qs[1] - grid.qs[0]
    dp = grid.ps[1] - grid.ps[0]
    with np.errstate(all="ignore"):
        gq, gp = np.gradient(values, dq, dp)
        scale = np.nanmax(np.abs(values)) or 1.0
        magnitude = np.hypot(gq * dq, gp * dp) / scale
    magnitude = np.where(np.isfinite(magnitude), magnitude, np.inf)
    # local minima of |grad H| over each 3x3 neighbourhood
    padded = np.pad(magnitude, 1, constant_values=np.inf)
    neighbours = np.stack(
        [
            padded[1 + a : padded.shape[0] - 1 + a, 1 + b : padded.shape[1] - 1 + b]
            for a in (-1, 0, 1)
            for b in (-1, 0, 1)
            if (a, b) != (0, 0)
        ]
    )
    candidates = np.argwhere((magnitude <= neighbours.min(axis=0)) & (magnitude < 0.05))
    order = np.argsort(magnitude[tuple(candidates.T)])
    step = np.array([dq, dp]) * 1e-3
    saddles: list[Saddle] = []
    centres: list[tuple[float, float]] = []
    for i, j in candidates[order][: 4 * limit]:
        x0 = np.array([grid.qs[i], grid.ps[j]])
        with np.errstate(all="ignore"):
            solution = root(lambda x: _gradient(compiled, x, step), x0, method="hybr")
        if not solution.success:
            continue
        q, p = solution.x
        inside = (
            grid.qs[0] - dq <= q <= grid.qs[-1] + dq and grid.ps[0] - dp <= p <= grid.ps[-1] + dp
        )
        if not inside:
            continue
        hess = np.array(
            [
                (_gradient(compiled, solution.x + [step[0], 0], step)
                 - _gradient(compiled, solution.x - [step[0], 0], step)) / (2 * step[0]),
                (_gradient(compiled, solution.x + [0, step[1]], step)
                 - _gradient(compiled, solution.x - [0, step[1]], step)) / (2 * step[1]),
            ]
        )  # fmt: skip
        det = np.linalg.det(hess)
        if det > 0 and np.isfinite(det):
            if not any(abs(c[0] - q) < 2 * dq and abs(c[1] - p) < 2 * dp for c in centres):
                centres.append((float(q), float(p)))
            continue
        if not det < 0:
            continue
        if any(abs(s.q - q) < 2 * dq and abs(s.p - p) < 2 * dp for s in saddles):
            continue
        saddles.append(Saddle(float(q), float(p), _h(compiled, q, p)))
        if len(saddles) >= limit:
            break
    return saddles, centres


def spread_levels(grid: EnergyGrid, count: int = 12) -> np.ndarray:
    """``count`` energies spread over the grid's range (between its 2% and 90% quantiles)."""
    finite = grid.values[np.isfinite(grid.values)]
    if not finite.size:
        return np.array([])
    lo, hi = np.quantile(finite, [0.02, 0.9])
    if hi <= lo:
        return np.array([lo])
    return np.linspace(lo, hi, count + 2)[1:-1]


def contour(grid: EnergyGrid, level: float) -> tuple[np.ndarray, np.ndarray]:
    """The level set ``H = level`` as (q, p) arrays with NaN between separate pieces.

    Marching squares by contourpy (matplotlib's contour engine, about 10 times faster
    than pyqtgraph's ``isocurve``, which held the GUI thread 0.2 to 0.7 s on each scene's
    twelve levels); cells with a non-finite corner are left out, not closed off.

    Returns
    -------
    q, p : ndarray, shape (k,)
    """
    finite = np.isfinite(grid.values)
    if not finite.any():
        return np.array([]), np.array([])
    z = np.ma.masked_array(np.where(finite, grid.values, 0.0), mask=~finite).T
    generator = contourpy.contour_generator(
        grid.qs, grid.ps, z, line_type=contourpy.LineType.Separate
    )
    xs: list[np.ndarray] = []
    ys: list[np.ndarray] = []
    for points in generator.lines(float(level)):
        if len(points) < 2:
            continue
        xs += [points[:, 0], [np.nan]]
        ys += [points[:, 1], [np.nan]]
    if not xs:
        return np.array([]), np.array([])
    return np.concatenate(xs), np.concatenate(ys)


def level_mask(grid: EnergyGrid, level: float) -> np.ndarray:
    """Grid nodes next to the level set ``H = level``: shape (len(qs), len(ps)), bool."""
    with np.errstate(invalid="ignore"):
        above = grid.values > level
    finite = np.isfinite(grid.values)
    mask = np.zeros(grid.values.shape, dtype=bool)
    across_q = (above[1:] != above[:-1]) & finite[1:] & finite[:-1]
    across_p = (above[:, 1:] != above[:, :-1]) & finite[:, 1:] & finite[:, :-1]
    mask[1:] |= across_q
    mask[:-1] |= across_q
    mask[:, 1:] |= across_p
    mask[:, :-1] |= across_p
    return mask


def fit_window(
    features: Callable[[tuple, tuple], tuple[np.ndarray, np.ndarray, list[np.ndarray]]],
    q_range: tuple[float, float],
    p_range: tuple[float, float],
    *,
    q_fixed: bool = False,
    p_fixed: bool = False,
    rounds: int = 4,
) -> tuple[tuple[float, float], tuple[float, float]] | None:
    """The smallest box around the bounded features, searched by growing a first guess.

    ``features(q_range, p_range) -> (qs, ps, masks)`` marks on a grid the nodes each
    feature (a level set, a region) occupies. While a feature touches a side that may
    move, that side moves out by the current span (the window doubles), at most
    ``rounds`` times; features still touching a movable side then are unbounded and left
    out (the data will grow the view as an orbit goes there).

    Parameters
    ----------
    features : callable
        ``(q_range, p_range) -> (qs (a,), ps (b,), list of bool arrays (a, b))``.
    q_range, p_range : (float, float)
        The first guess.
    q_fixed, p_fixed : bool
        Sides that never move (an angle's (-pi, pi], a declared range).

    Returns
    -------
    ((q_lo, q_hi), (p_lo, p_hi)) or None
        The bounding box of the bounded features' nodes; None if there are none.
    """
    q_range, p_range = tuple(map(float, q_range)), tuple(map(float, p_range))
    for round_ in range(rounds + 1):
        qs, ps, masks = features(q_range, p_range)
        touched: list[set[str]] = []
        for mask in masks:
            sides = set()
            if not q_fixed:
                sides |= {"q-"} if mask[0].any() else set()
                sides |= {"q+"} if mask[-1].any() else set()
            if not p_fixed:
                sides |= {"p-"} if mask[:, 0].any() else set()
                sides |= {"p+"} if mask[:, -1].any() else set()
            touched.append(sides)
        every = set().union(*touched) if touched else set()
        if not every or round_ == rounds:
            break
        q_span, p_span = q_range[1] - q_range[0], p_range[1] - p_range[0]
        q_range = (
            q_range[0] - q_span * ("q-" in every),
            q_range[1] + q_span * ("q+" in every),
        )
        p_range = (
            p_range[0] - p_span * ("p-" in every),
            p_range[1] + p_span * ("p+" in every),
        )
    bounded = [mask for mask, sides in zip(masks, touched, strict=True) if not sides]
    if not bounded:
        return None
    union = np.logical_or.reduce(bounded)
    rows, cols = np.flatnonzero(union.any(axis=1)), np.flatnonzero(union.any(axis=0))
    if not len(rows) or not len(cols):
        return None
    return (float(qs[rows[0]]), float(qs[rows[-1]])), (float(ps[cols[0]]), float(ps[cols[-1]]))
