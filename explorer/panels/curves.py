"""A long curve drawn as frozen chunks plus a live tail, so a redraw costs O(new points).

pyqtgraph re-processes the whole array on ``setData``, and an antialiased path of a million
points takes seconds to stroke; neither may happen every frame. ``TrailCurve`` hands each
completed chunk to a static item once (drawn without antialiasing and cached as pixels by
Qt until the view changes) and only updates the short tail. Curves against time also get
``clipToView`` and ``autoDownsample``; phase-space curves cannot (pyqtgraph's clipping
and downsampling assume sorted x and would drop or distort parts of a closed orbit).
"""

from __future__ import annotations

import numpy as np
import pyqtgraph as pg
from PySide6.QtWidgets import QGraphicsItem

CHUNK = 16384


class TrailCurve:
    """A polyline in ``plot`` that follows growing ``x``/``y`` arrays."""

    def __init__(
        self,
        plot: pg.PlotItem,
        pen,
        name: str | None = None,
        chunk: int = CHUNK,
        ranges: RangeKeeper | None = None,
        monotonic_x: bool = False,
    ):
        self.plot = plot
        self.monotonic_x = monotonic_x
        self.ranges = ranges
        self._seen = 0
        self.pen = pen
        self.chunk = chunk
        self._frozen: list[pg.PlotDataItem] = []
        self._frozen_until = 0
        self.tail = self._item(name)

    def _item(self, name=None) -> pg.PlotDataItem:
        """A new item, already in the plot (clip-to-view needs its view box at once)."""
        item = pg.PlotDataItem(pen=self.pen, name=name, connect="finite")
        self.plot.addItem(item)
        if self.monotonic_x:  # pyqtgraph clips and downsamples assuming sorted x
            item.setClipToView(True)
            item.setDownsampling(auto=True, method="peak")
        return item

    @property
    def items(self) -> list[pg.PlotDataItem]:
        return [*self._frozen, self.tail]

    def update(self, x: np.ndarray, y: np.ndarray) -> None:
        """Show ``x[i], y[i]`` for all i; only rows past the frozen chunks are re-sent."""
        size = len(x)
        if size < self._frozen_until or size < self._seen:  # the data was replaced
            self.reset()
        if self.ranges is not None and size > self._seen:
            self.ranges.include(x[self._seen :], y[self._seen :])
        self._seen = size
        while size - self._frozen_until > self.chunk:
            start, stop = self._frozen_until, self._frozen_until + self.chunk
            item = self._item()
            item.setData(x[start : stop + 1].copy(), y[start : stop + 1].copy(), antialias=False)
            # a finished chunk never changes: Qt keeps its pixels until the view moves
            item.curve.setCacheMode(QGraphicsItem.CacheMode.DeviceCoordinateCache)
            self._frozen.append(item)
            self._frozen_until = stop
        self.tail.setData(x[self._frozen_until :], y[self._frozen_until :])

    def reset(self) -> None:
        for item in self._frozen:
            self.plot.removeItem(item)
        self._frozen.clear()
        self._frozen_until = 0
        self._seen = 0
        self.tail.setData([], [])

    def remove(self) -> None:
        self.reset()
        self.plot.removeItem(self.tail)

    def point_count(self) -> int:
        return sum(len(item.xData) for item in self.items if item.xData is not None)


def style_plot(plot: pg.PlotItem) -> pg.PlotItem:
    """House style: a light grid, no SI-prefix rescaling of the axes (it hides the units),
    axes cached as pixels."""
    plot.showGrid(x=True, y=True, alpha=0.15)
    for name in ("left", "bottom"):
        axis = plot.getAxis(name)
        axis.enableAutoSIPrefix(False)
        # an axis (with its grid) only changes with its range: keep its pixels, so a
        # frame that moves a curve does not re-render every tick label
        axis.setCacheMode(QGraphicsItem.CacheMode.DeviceCoordinateCache)
    return plot


class RangeKeeper:
    """Grow-only axis ranges, updated from new data only.

    pyqtgraph's auto-range scans every item's whole data each frame, which is O(N) for a
    million-point trace and invalidates every cached chunk. Instead the range grows by a
    margin when new data leave it and otherwise stays put.
    """

    def __init__(
        self, plot: pg.PlotItem, log_y: bool = False, margin: float = 0.3, time_axis: bool = False
    ):
        self.plot = plot
        self.log_y = log_y
        self.time_axis = time_axis
        self.margin = margin
        plot.disableAutoRange()
        self.reset()

    def reset(self) -> None:
        self.x: list[float] | None = None
        self.y: list[float] | None = None

    def include(self, x: np.ndarray, y: np.ndarray) -> None:
        x = np.asarray(x, dtype=float)
        y = np.asarray(y, dtype=float)
        if self.log_y:
            with np.errstate(all="ignore"):
                y = np.log10(y)
        x, y = x[np.isfinite(x)], y[np.isfinite(y)]
        if len(x):
            self.x = self._grow(self.x, float(x.min()), float(x.max()), self.time_axis)
            self.plot.setXRange(*self.x, padding=0)
        if len(y):
            self.y = self._grow(self.y, float(y.min()), float(y.max()))
            self.plot.setYRange(*self.y, padding=0)

    def _grow(self, current, lo: float, hi: float, lower_fixed: bool = False):
        if current is not None and current[0] <= lo and hi <= current[1]:
            return current
        if current is not None:
            lo, hi = min(lo, current[0]), max(hi, current[1])
        span = hi - lo if hi > lo else max(abs(hi), 1.0) * 0.1
        if lower_fixed:  # a time axis: double it, so redrawing everything is rare
            return [lo, hi + span]
        return [lo - self.margin * span * 0.5, hi + self.margin * span]


LEGEND_BRUSH = pg.mkBrush(255, 255, 255, 215)
"""Legends on a nearly opaque white ground, so curves behind them do not cross the text."""
