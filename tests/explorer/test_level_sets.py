"""The level sets of H drawn in the phase plane (``explorer.level_sets.contour``), on the
pendulum H = p^2/2 - cos(q), whose level sets are known in closed form: each point lies
on its level (to the grid's interpolation error), librations are closed curves inside the
separatrix and rotations two open ones, pieces are separated by NaN, and cells where H is
not finite are left out."""

from __future__ import annotations

import numpy as np

from explorer.level_sets import EnergyGrid, contour


def _pendulum(size: int = 201) -> EnergyGrid:
    qs = np.linspace(-np.pi, np.pi, size)
    ps = np.linspace(-3.0, 3.0, size)
    Q, P = np.meshgrid(qs, ps, indexing="ij")
    return EnergyGrid(qs, ps, P**2 / 2 - np.cos(Q))


def _pieces(q: np.ndarray, p: np.ndarray) -> list[np.ndarray]:
    """The NaN-separated pieces, each shape (k, 2)."""
    cuts = np.flatnonzero(np.isnan(q))
    pieces = zip(np.split(q, cuts), np.split(p, cuts), strict=True)
    return [np.column_stack([a, b])[~np.isnan(a)] for a, b in pieces if (~np.isnan(a)).any()]


def test_points_lie_on_their_level_and_pieces_are_separated():
    grid = _pendulum()
    for level, count in [(-0.5, 1), (2.0, 2)]:
        q, p = contour(grid, level)
        real = ~np.isnan(q)
        assert np.isnan(q).sum() == count and np.isnan(p[~real]).all()
        error = np.abs(p[real] ** 2 / 2 - np.cos(q[real]) - level)
        assert error.max() < 1e-3, level  # linear interpolation on a 0.03 grid
        pieces = _pieces(q, p)
        assert len(pieces) == count
        if level < 1:  # a libration: one closed curve about the centre
            (loop,) = pieces
            assert np.allclose(loop[0], loop[-1])
            assert np.arccos(-level) - 1e-3 < loop[:, 0].max() < np.arccos(-level) + 1e-3
        else:  # rotations: one above, one below, across the whole range of q
            assert sorted(np.sign(piece[:, 1].mean()) for piece in pieces) == [-1, 1]
            for piece in pieces:
                assert np.ptp(piece[:, 0]) > 2 * np.pi - 0.1


def test_a_level_outside_the_range_is_empty():
    q, p = contour(_pendulum(), 10.0)
    assert len(q) == len(p) == 0


def test_cells_where_h_is_not_finite_are_left_out():
    grid = _pendulum()
    values = grid.values.copy()
    values[grid.qs > 0] = np.inf  # right half: no H (a singular region)
    q, p = contour(EnergyGrid(grid.qs, grid.ps, values), -0.5)
    real = ~np.isnan(q)
    assert real.any() and q[real].max() <= grid.qs[grid.qs <= 0].max() + 1e-12
    assert np.abs(p[real] ** 2 / 2 - np.cos(q[real]) + 0.5).max() < 1e-3
    empty = EnergyGrid(grid.qs, grid.ps, np.full_like(values, np.nan))
    assert len(contour(empty, 0.0)[0]) == 0
