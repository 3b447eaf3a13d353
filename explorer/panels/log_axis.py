"""A log-scale axis whose labels never crowd or overlap.

pyqtgraph labels every minor tick (2, 3, ... 9 times 10^k) when an axis spans less than
a decade or so, and the labels then run into each other: its check is on the density of
the text, not on where each label lands. Here only 1, 2 and 5 times a power of ten are
labelled (every tick where fewer than two of those are in view, so a short span keeps
its labels), and of labels that would still overlap (a short axis, a large font) the
later ones are left out: major ticks first, then in order along the axis.
"""

from __future__ import annotations

import math

import pyqtgraph as pg

LABELLED_MANTISSAS = (1, 2, 5)
LABEL_GAP_PIXELS = 2.0
"""Room kept free between two labels, at least."""


def _label(value: float) -> str:
    exponent = math.floor(math.log10(value) + 1e-9)
    mantissa = round(value / 10**exponent)
    if -3 <= exponent <= 3:
        return f"{value:g}"
    return f"{mantissa}e{exponent}" if mantissa != 1 else f"1e{exponent}"


def _wanted(value: float) -> bool:
    mantissa = value / 10 ** math.floor(math.log10(value) + 1e-9)
    return any(abs(mantissa - m) < 1e-6 * m for m in LABELLED_MANTISSAS)


def apart(rects, gap: float = LABEL_GAP_PIXELS) -> list[int]:
    """Indices of the rectangles (QRectF) kept, in order, each at least ``gap`` pixels
    away from every one kept before it."""
    kept: list[int] = []
    for k, rect in enumerate(rects):
        grown = rect.adjusted(-gap / 2, -gap / 2, gap / 2, gap / 2)
        if not any(grown.intersects(rects[j]) for j in kept):
            kept.append(k)
    return kept


class SparseLogAxis(pg.AxisItem):
    """Labels ticks at 1, 2 and 5 times a power of ten (all of them where fewer than two
    of those are in view); labels that would overlap are left out."""

    def logTickStrings(self, values, scale, spacing):  # noqa: N802 - pyqtgraph override
        numbers = [10 ** float(v) * scale for v in values]
        good = [math.isfinite(x) and x > 0 for x in numbers]
        low, high = 10 ** self.range[0] * scale, 10 ** self.range[1] * scale
        shown = [
            ok and low <= x <= high and _wanted(x) for x, ok in zip(numbers, good, strict=True)
        ]
        every = sum(shown) < 2
        return [
            _label(x) if ok and (every or _wanted(x)) else ""
            for x, ok in zip(numbers, good, strict=True)
        ]

    def generateDrawSpecs(self, p):  # noqa: N802 - pyqtgraph override
        specs = super().generateDrawSpecs(p)
        if specs is None:
            return None
        axis, ticks, texts = specs
        texts = [spec for spec in texts if spec[2]]
        return axis, ticks, [texts[k] for k in apart([rect for rect, _, _ in texts])]
