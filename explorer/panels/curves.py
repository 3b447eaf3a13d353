"""A long curve drawn as frozen chunks plus a live tail, so a redraw costs O(new points).

pyqtgraph re-processes the whole array on ``setData``, and an antialiased path of a million
points takes seconds to stroke; neither may happen every frame. ``TrailCurve`` hands each
completed chunk to a static item once (drawn without antialiasing and cached as pixels by
Qt until the view changes) and only updates the short tail. Curves against time also get
``clipToView`` and ``autoDownsample``; phase-space curves cannot (pyqtgraph's clipping
and downsampling assume sorted x and would drop or distort parts of a closed orbit).
"""

from __future__ import annotations

import math
import weakref
from collections.abc import Callable, Iterable

import numpy as np
import pyqtgraph as pg
from PySide6.QtCore import Qt
from PySide6.QtWidgets import QGraphicsGridLayout, QGraphicsItem

from explorer.buffers import GrowingArray
from systems.angles import break_at_wraps

CHUNK = 16384
ANGLE_RANGE = (-1.06 * math.pi, 1.06 * math.pi)
"""The axis of an angle coordinate: (-pi, pi] with a little room to see the edges."""


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


class FlexibleLabel(pg.LabelItem):
    """A plot title that does not set the plot's minimum width (a long one is clipped).

    pyqtgraph's ``LabelItem`` makes its text's width its minimum at every change and
    resize, so in a narrow dock a long title pushes the plot's right part out of sight.
    """

    def updateMin(self) -> None:  # noqa: N802 - pyqtgraph override
        super().updateMin()
        self.setMinimumWidth(0)


def set_title(plot: pg.PlotItem, text: str) -> None:
    """``plot.setTitle(text)`` with a ``FlexibleLabel`` (put in place the first time)."""
    if not isinstance(plot.titleLabel, FlexibleLabel):
        old = plot.titleLabel
        plot.layout.removeItem(old)
        if old.scene() is not None:
            old.scene().removeItem(old)
        plot.titleLabel = FlexibleLabel("", size="11pt", parent=plot)
        plot.layout.addItem(plot.titleLabel, 0, 1)
    plot.setTitle(text)


class RangeKeeper:
    """Grow-only axis ranges, updated from new data only.

    pyqtgraph's auto-range scans every item's whole data each frame, which is O(N) for a
    million-point trace and invalidates every cached chunk. Instead the range grows when
    new data leave it, by ``margin`` of the new span on each side (so growing is rare and
    the view does not jitter), and otherwise stays put. A time axis starts at the data and
    ends ``time_margin`` of the span past it. An axis in ``fixed`` (``"x"``, ``"y"``) is
    left alone (a declared range, or an angle's (-pi, pi]); once the user pans or zooms
    with the mouse the keeper stops until ``reset``.

    Parameters
    ----------
    plot : pyqtgraph.PlotItem
    log_y : bool
        The y axis is logarithmic: data are included as log10.
    margin : float
        Fraction of the span added on each side when an axis grows.
    time_axis : bool
        x is time: fitted to the data, ``time_margin`` ahead.
    on_grow : callable, optional
        Called after a range changed because of data (redraw what depends on the view).
    """

    def __init__(
        self,
        plot: pg.PlotItem,
        log_y: bool = False,
        margin: float = 0.1,
        time_axis: bool = False,
        time_margin: float = 0.05,
        on_grow: Callable[[], None] | None = None,
    ):
        self.plot = plot
        self.log_y = log_y
        self.time_axis = time_axis
        self.margin = margin
        self.time_margin = time_margin
        # a weak reference: the owner holds the keeper, and a cycle through a Qt object's
        # wrapper could let the garbage collector clear it while Qt still draws it
        self._on_grow = None
        if on_grow is not None:
            self._on_grow = (
                weakref.WeakMethod(on_grow) if hasattr(on_grow, "__self__") else lambda: on_grow
            )
        self.fixed: set[str] = set()
        self.manual = False
        plot.disableAutoRange()
        plot.getViewBox().sigRangeChangedManually.connect(self._on_manual)
        self.reset()

    def _on_manual(self, *_args) -> None:
        self.manual = True

    def reset(
        self,
        x: tuple[float, float] | None = None,
        y: tuple[float, float] | None = None,
        fixed: tuple[str, ...] = (),
    ) -> None:
        """Forget the data seen; start from ranges ``x``, ``y`` (None: from the first
        data), with the axes in ``fixed`` never changed by data."""
        self.x: list[float] | None = None if x is None else [float(x[0]), float(x[1])]
        self.y: list[float] | None = None if y is None else [float(y[0]), float(y[1])]
        self.fixed = set(fixed)
        self.manual = False
        self.apply()

    def apply(self) -> None:
        """Show the kept ranges (both axes in one call: an aspect-locked view then keeps
        the whole box visible instead of cutting one axis)."""
        changes = {}
        if self.x is not None:
            changes["xRange"] = self.x
        if self.y is not None:
            changes["yRange"] = self.y
        if changes:
            self.plot.getViewBox().setRange(**changes, padding=0)

    def include(self, x: np.ndarray, y: np.ndarray) -> bool:
        """Grow to show the points (x, y), shape (k,) each; True if a range changed."""
        x = np.asarray(x, dtype=float)
        y = np.asarray(y, dtype=float)
        if self.log_y:
            with np.errstate(all="ignore"):
                y = np.log10(y)
        x, y = x[np.isfinite(x)], y[np.isfinite(y)]
        if not len(x) and not len(y):
            return False
        return self.include_box(
            (float(x.min()), float(x.max())) if len(x) else None,
            (float(y.min()), float(y.max())) if len(y) else None,
        )

    def include_box(self, x: tuple | None, y: tuple | None) -> bool:
        """Grow to show the ranges ``x = (lo, hi)`` and ``y`` (None: no change)."""
        if self.manual:
            return False
        new_x, new_y = self.x, self.y
        if x is not None and "x" not in self.fixed:
            new_x = self._grow(self.x, *x, time=self.time_axis)
        if y is not None and "y" not in self.fixed:
            new_y = self._grow(self.y, *y)
        if new_x == self.x and new_y == self.y:
            return False
        self.x, self.y = new_x, new_y
        self.apply()
        callback = self._on_grow() if self._on_grow is not None else None
        if callback is not None:
            callback()
        return True

    def _grow(self, current, lo: float, hi: float, time: bool = False):
        if current is not None and current[0] <= lo and hi <= current[1]:
            return current
        if current is not None:
            lo, hi = min(lo, current[0]), max(hi, current[1])
        span = hi - lo if hi > lo else max(abs(hi), 1.0) * 0.1
        if time:  # a time axis: the data from their start, a little room ahead
            return [lo, hi + self.time_margin * span]
        return [lo - self.margin * span, hi + self.margin * span]


class OutsideLegend(pg.LegendItem):
    """A legend in its own cell of a ``GraphicsLayout``, below or beside its plot: it never
    covers data. Entries flow into ``columns`` columns; it cannot be dragged away.

    ``LegendItem`` sizes itself by setting its geometry, which a layout would override;
    here its size is handed to the layout instead: its height when it sits below the plot
    (``side="below"``), its width when beside it (``side="right"``).
    """

    def __init__(self, columns: int = 4, side: str = "below"):
        super().__init__(offset=None, colCount=columns, labelTextColor="#222", verSpacing=0)
        self.side = side

    def updateSize(self) -> None:  # noqa: N802 - pyqtgraph override
        height, width = 0.0, 0.0
        for row in range(self.layout.rowCount()):
            row_height, row_width = 0.0, 0.0
            for col in range(self.layout.columnCount()):
                item = self.layout.itemAt(row, col)
                if item:
                    size = item.effectiveSizeHint(Qt.SizeHint.PreferredSize)
                    row_height = max(row_height, size.height())
                    row_width += size.width() + 3
            height += row_height
            width = max(width, row_width)
        if self.side == "right":
            self.setMinimumWidth(width)
            self.setMaximumWidth(width)
        self.setMinimumHeight(height)
        self.setMaximumHeight(height)
        self.setVisible(bool(self.items))
        self.updateGeometry()

    def mouseDragEvent(self, ev) -> None:  # noqa: N802 - pyqtgraph override
        ev.ignore()

    def clear(self) -> None:
        """Remove every entry. The grid is replaced too: pyqtgraph places a new entry by
        the grid's row and column counts, which removing items does not lower, so entries
        added after a ``clear`` would land on top of each other."""
        for sample, label in self.items:
            self._removeItemFromLayout(sample, label)
        self.items = []
        self.rowCount = 1
        spacing = (self.layout.horizontalSpacing(), self.layout.verticalSpacing())
        self.layout = QGraphicsGridLayout()
        self.layout.setHorizontalSpacing(spacing[0])
        self.layout.setVerticalSpacing(spacing[1])
        self.setLayout(self.layout)
        self.updateSize()

    def set_entries(self, entries: Iterable[tuple[object, str]]) -> None:
        """Show exactly ``entries``, a list of (item, name), in order (nothing is redone
        when they are what is shown)."""
        entries = list(entries)
        if [(s.item, label.text) for s, label in self.items] == entries:
            return
        self.clear()
        for item, name in entries:
            self.addItem(item, name)
        self.updateSize()

    def entries(self) -> list[str]:
        """The entries' texts, in order."""
        return [label.text for _, label in self.items]


def add_outside_legend(
    layout: pg.GraphicsLayout, row: int, col: int, columns: int = 4, side: str = "below"
) -> OutsideLegend:
    """An ``OutsideLegend`` in cell (row, col) of a ``GraphicsLayout``."""
    legend = OutsideLegend(columns, side)
    layout.addItem(legend, row=row, col=col)
    where = Qt.AlignmentFlag.AlignTop if side == "right" else Qt.AlignmentFlag.AlignLeft
    layout.layout.setAlignment(legend, where)
    legend.updateSize()
    return legend


class WrappedSeries:
    """A growing polyline with some coordinates wrapped to (-pi, pi] and broken at wraps.

    Fed the whole source arrays each frame (``feed``), it converts only the rows it has
    not seen (plus the last seen one, to catch a wrap between frames), so a frame costs
    O(new rows). Source arrays that got shorter (replaced data) start it afresh.

    Parameters
    ----------
    angles : sequence of bool
        Which of the columns are angles.
    """

    def __init__(self, angles: Iterable[bool]):
        self.angles = tuple(bool(a) for a in angles)
        self._out = GrowingArray((len(self.angles),))
        self._seen = 0

    def reset(self) -> None:
        self._out.clear()
        self._seen = 0

    def feed(self, *columns: np.ndarray) -> tuple[np.ndarray, ...]:
        """The display columns for the source ``columns`` (each shape (k,)): views of
        shape (k + breaks,)."""
        size = len(columns[0])
        if size < self._seen:
            self.reset()
        if size > self._seen:
            first = max(self._seen - 1, 0)
            part = [np.asarray(c[first:], dtype=float) for c in columns]
            shown = break_at_wraps(part, self.angles)
            rows = np.stack(shown, axis=1)
            if self._seen:
                rows = rows[1:]  # the last seen row is already in
            self._out.extend(rows)
            self._seen = size
        data = self._out.data
        return tuple(data[:, k] for k in range(len(self.angles)))


def nearest_distance(
    x: np.ndarray, y: np.ndarray, px: float, py: float, scale: tuple[float, float]
) -> float:
    """Distance in pixels from (px, py) to the polyline (x, y), each shape (k,) (NaN
    breaks it).

    ``scale`` is the data size of one pixel in x and y. Every segment is measured, so a
    sparsely sampled fast orbit is found along its chords too; a single point is a point.
    """
    sx, sy = scale
    x = (np.asarray(x, dtype=float) - px) / sx
    y = (np.asarray(y, dtype=float) - py) / sy
    if not len(x):
        return math.inf
    with np.errstate(all="ignore"):
        best = np.nanmin(np.hypot(x, y)) if np.isfinite(x).any() else math.inf
        if len(x) > 1:
            x0, y0, dx, dy = x[:-1], y[:-1], np.diff(x), np.diff(y)
            length = dx * dx + dy * dy
            s = np.clip(-(x0 * dx + y0 * dy) / np.where(length > 0, length, 1.0), 0.0, 1.0)
            d = np.hypot(x0 + s * dx, y0 + s * dy)
            d = d[np.isfinite(d)]
            if len(d):
                best = min(best, float(d.min()))
    return float(best)


LEGEND_BRUSH = pg.mkBrush(255, 255, 255, 215)
"""Legends on a nearly opaque white ground, so curves behind them do not cross the text."""
