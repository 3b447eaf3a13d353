"""A log-scale axis whose labels never crowd: only 1, 2 and 5 times a power of ten.

pyqtgraph labels every minor tick (2, 3, ... 9 times 10^k) when an axis spans less than
a decade or so, and the labels then run into each other.
"""

from __future__ import annotations

import math

import pyqtgraph as pg

LABELLED_MANTISSAS = (1, 2, 5)


def _label(value: float) -> str:
    exponent = math.floor(math.log10(value) + 1e-9)
    mantissa = round(value / 10**exponent)
    if -3 <= exponent <= 3:
        return f"{value:g}"
    return f"{mantissa}e{exponent}" if mantissa != 1 else f"1e{exponent}"


class SparseLogAxis(pg.AxisItem):
    """Labels ticks at 1, 2 and 5 times a power of ten; the others stay unlabelled."""

    def logTickStrings(self, values, scale, spacing):  # noqa: N802 - pyqtgraph override
        strings = []
        for v in values:
            value = 10 ** float(v) * scale
            if not math.isfinite(value) or value <= 0:
                strings.append("")
                continue
            mantissa = value / 10 ** math.floor(math.log10(value) + 1e-9)
            wanted = any(abs(mantissa - m) < 1e-6 * m for m in LABELLED_MANTISSAS)
            strings.append(_label(value) if wanted else "")
        return strings
