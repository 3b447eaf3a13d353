"""Colours of the many orbits of a section portrait (the CLI's ``export --poincare
--orbits`` and the window's Fill section…): Qt-free, so that the CLI's modules and the
window's panels share it."""

from __future__ import annotations

import colorsys


def orbit_colour(index: int, count: int) -> str:
    """A colour of its own for orbit ``index`` of ``count``: hues evenly around the
    circle, alternately darker and lighter so that neighbours differ."""
    hue = (index / max(count, 1)) % 1.0
    r, g, b = colorsys.hls_to_rgb(hue, 0.38 if index % 2 else 0.5, 0.85)
    return f"#{round(255 * r):02x}{round(255 * g):02x}{round(255 * b):02x}"
