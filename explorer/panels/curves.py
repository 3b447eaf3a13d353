"""A long curve drawn as frozen chunks plus a live tail, so a redraw costs O(new points).

pyqtgraph re-processes the whole array on ``setData``; for a trace of a million points
that is too slow for every frame. ``TrailCurve`` hands completed chunks to static items
once and only updates the tail, with ``clipToView`` and ``autoDownsample`` on every item.
"""

from __future__ import annotations

import numpy as np
import pyqtgraph as pg

CHUNK = 65536


class TrailCurve:
    """A polyline in ``plot`` that follows growing ``x``/``y`` arrays."""

    def __init__(self, plot: pg.PlotItem, pen, name: str | None = None, chunk: int = CHUNK):
        self.plot = plot
        self.pen = pen
        self.chunk = chunk
        self._frozen: list[pg.PlotDataItem] = []
        self._frozen_until = 0
        self.tail = self._item(name)
        self.plot.addItem(self.tail)

    def _item(self, name=None) -> pg.PlotDataItem:
        item = pg.PlotDataItem(pen=self.pen, name=name, connect="finite")
        item.setClipToView(True)
        item.setDownsampling(auto=True, method="peak")
        return item

    @property
    def items(self) -> list[pg.PlotDataItem]:
        return [*self._frozen, self.tail]

    def update(self, x: np.ndarray, y: np.ndarray) -> None:
        """Show ``x[i], y[i]`` for all i; only rows past the frozen chunks are re-sent."""
        size = len(x)
        if size < self._frozen_until:  # the data was replaced: start over
            self.reset()
        while size - self._frozen_until > self.chunk:
            start, stop = self._frozen_until, self._frozen_until + self.chunk
            item = self._item()
            item.setData(x[start : stop + 1].copy(), y[start : stop + 1].copy())
            self.plot.addItem(item)
            self._frozen.append(item)
            self._frozen_until = stop
        self.tail.setData(x[self._frozen_until :], y[self._frozen_until :])

    def reset(self) -> None:
        for item in self._frozen:
            self.plot.removeItem(item)
        self._frozen.clear()
        self._frozen_until = 0
        self.tail.setData([], [])

    def remove(self) -> None:
        self.reset()
        self.plot.removeItem(self.tail)

    def point_count(self) -> int:
        return sum(len(item.xData) for item in self.items if item.xData is not None)


def style_plot(plot: pg.PlotItem) -> pg.PlotItem:
    """House style: a light grid, no SI-prefix rescaling of the axes (it hides the units)."""
    plot.showGrid(x=True, y=True, alpha=0.15)
    for name in ("left", "bottom"):
        plot.getAxis(name).enableAutoSIPrefix(False)
    return plot
