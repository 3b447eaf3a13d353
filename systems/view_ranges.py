"""Plot ranges for a scene: the ``[view] ranges`` table, or a guess from the initial state.

Shared by the window (``explorer.panels.ranges`` re-exports it), the chaos maps and the
Python API (``phase_explorer``)."""

from __future__ import annotations

import math

import numpy as np


def axis_range(scene, name: str, value: float) -> tuple[float, float]:
    """The range of ``name`` (``theta``, ``p_theta``...) from ``[view] ranges`` or a guess."""
    ranges = dict(scene.view.get("ranges", {}) or {})
    if name in ranges:
        lo, hi = ranges[name]
        return float(lo), float(hi)
    half = max(2.0 * abs(value), 1.0)
    if not name.startswith("p_") and half < math.pi and abs(value) <= math.pi:
        half = math.pi
    return value - half, value + half


def phase_ranges(scene, y0: np.ndarray, index: int) -> tuple[tuple, tuple]:
    """(q range, p range) for coordinate ``index`` of the scene."""
    n = len(scene.coordinates)
    q = scene.coordinates[index]
    return axis_range(scene, q, float(y0[index])), axis_range(scene, f"p_{q}", float(y0[n + index]))
