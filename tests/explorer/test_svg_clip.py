"""Polylines are clipped to the plot rectangle before they go into an SVG."""

import numpy as np
from PySide6.QtCore import QRectF

from explorer.svg import clip_segments


def test_segments_are_cut_at_the_rectangle():
    rect = QRectF(0, 0, 10, 10)
    x = np.array([-5.0, 5.0, 5.0, 15.0, np.nan, 20.0, 30.0])
    y = np.array([5.0, 5.0, 5.0, 5.0, np.nan, 20.0, 30.0])
    x0, y0, x1, y1 = clip_segments(x, y, rect)
    # (-5,5)-(5,5) -> (0,5)-(5,5); (5,5)-(5,5) kept; (5,5)-(15,5) -> (5,5)-(10,5);
    # segments touching NaN or wholly outside are dropped
    assert np.allclose(x0, [0, 5, 5]) and np.allclose(x1, [5, 5, 10])
    assert np.allclose(y0, 5) and np.allclose(y1, 5)


def test_diagonal_through_a_corner_region():
    rect = QRectF(0, 0, 1, 1)
    x0, y0, x1, y1 = clip_segments(np.array([-1.0, 2.0]), np.array([-1.0, 2.0]), rect)
    assert np.allclose([x0[0], y0[0], x1[0], y1[0]], [0, 0, 1, 1])
