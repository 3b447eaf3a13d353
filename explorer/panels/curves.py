"""Long curves drawn so that a frame costs about the same however long they have grown.

pyqtgraph re-processes the whole array on ``setData``, and Qt strokes an antialiased or
wide pen along a long path slowly (a pen wider than a pixel along a self-crossing path
of thousands of rows takes hundreds of ms); neither may happen every frame.

- ``TrailCurve`` (orbits, paths: any shape) hands completed rows to frozen items, drawn
  without antialiasing and cached as pixels by Qt until the view changes, and redraws
  only a short tail (``TAIL_POINTS``) every frame. Phase-space curves are never clipped
  or downsampled (pyqtgraph's clipping and downsampling assume sorted x and would drop
  or distort parts of a closed orbit).
- ``EnvelopeCurve`` (curves against time) draws at most four rows per pixel column
  (``column_envelope``), which covers the same pixels as every row; a NaN row is a break
  (``connect="finite"``): no line joins the rows on either side of it.
"""

from __future__ import annotations

import math
import time
import weakref
from collections.abc import Callable, Iterable

import numpy as np
import pyqtgraph as pg
from PySide6.QtCore import Qt, QTimer
from PySide6.QtGui import QPixmapCache
from PySide6.QtWidgets import QGraphicsGridLayout, QGraphicsItem, QGraphicsView

from explorer.buffers import GrowingArray
from systems.angles import break_at_wraps

TAIL_POINTS = 1024
"""Rows of a curve's live tail, at most: redrawn (antialiased) at every frame."""
FROZEN_POINTS = 16384
"""Rows of one frozen item, at most: it grows by whole tails, each time drawn once more."""
PIXMAP_CACHE_KB = 64 * 1024
"""Room for the pixels Qt keeps of cached items (frozen chunks, settled curves, axes): its
default, 10 MB, holds a few plots' worth, and an item whose pixels were evicted is drawn
again at every frame."""
SETTLE_POINTS = 128
"""Rows of an ``EnvelopeCurve``'s live item, about, before they go to its settled item."""
REPAINT_GAP_SECONDS = 0.025
"""Time a live plot leaves free after each of its paints before it paints again."""
ANGLE_RANGE = (-1.06 * math.pi, 1.06 * math.pi)
"""The axis of an angle coordinate: (-pi, pi] with a little room to see the edges."""


class TrailCurve:
    """A polyline in ``plot`` that follows growing ``x``/``y`` arrays.

    The newest rows (up to ``chunk``) are the tail, redrawn at every frame with ``pen``
    antialiased; older rows go into frozen items of up to ``FROZEN_POINTS`` rows, drawn
    without antialiasing and kept as pixels until the view changes. A frozen item grows
    by whole tails (each growth draws it once more), so a long trace is a few items.

    Parameters
    ----------
    plot : pyqtgraph.PlotItem
    pen : QPen
    name : str, optional
        The tail's name (legends).
    chunk : int
        Rows of the tail, at most.
    ranges : RangeKeeper, optional
        Grown to show every new row.
    frozen : int
        Rows of one frozen item, at most.
    """

    def __init__(
        self,
        plot: pg.PlotItem,
        pen,
        name: str | None = None,
        chunk: int = TAIL_POINTS,
        ranges: RangeKeeper | None = None,
        frozen: int = FROZEN_POINTS,
    ):
        self.plot = plot
        self.ranges = ranges
        self._seen = 0
        self.pen = pen
        self.chunk = max(int(chunk), 1)
        self.frozen = max(int(frozen), self.chunk)
        self._frozen: list[pg.PlotDataItem] = []
        self._frozen_from = 0  # the first row of the last frozen item
        self._frozen_until = 0
        self.tail = self._item(name)
        reserve_pixmap_cache()

    def _item(self, name=None) -> pg.PlotDataItem:
        item = pg.PlotDataItem(pen=self.pen, name=name, connect="finite")
        self.plot.addItem(item)
        return item

    @property
    def items(self) -> list[pg.PlotDataItem]:
        return [*self._frozen, self.tail]

    def update(self, x: np.ndarray, y: np.ndarray) -> None:
        """Show ``x[i], y[i]`` for all i; only rows past the frozen items are re-sent."""
        size = len(x)
        if size < self._frozen_until or size < self._seen:  # the data was replaced
            self.reset()
        if self.ranges is not None and size > self._seen:
            self.ranges.include(x[self._seen :], y[self._seen :])
        self._seen = size
        unfrozen = size - self._frozen_until
        if unfrozen > self.chunk:
            # whole tails are frozen: the tail keeps 1 to ``chunk`` rows
            self._freeze(x, y, self._frozen_until + self.chunk * ((unfrozen - 1) // self.chunk))
        self.tail.setData(x[self._frozen_until :], y[self._frozen_until :])

    def _freeze(self, x: np.ndarray, y: np.ndarray, until: int) -> None:
        """Move rows up to ``until`` into frozen items, each set once."""
        start = self._frozen_from
        if not self._frozen or self._frozen_until - start >= self.frozen:
            start = self._frozen_until  # a new item
        while start < until:
            stop = min(until, start + self.frozen)
            if self._frozen and start == self._frozen_from:
                item = self._frozen[-1]
            else:
                item = self._item()
                self._frozen.append(item)
            # one row more: the next item (or the tail) starts where this one ends
            item.setData(x[start : stop + 1].copy(), y[start : stop + 1].copy(), antialias=False)
            # a frozen item only changes when it grows: Qt keeps its pixels until then or
            # until the view moves
            item.curve.setCacheMode(QGraphicsItem.CacheMode.DeviceCoordinateCache)
            self._frozen_from, self._frozen_until = start, stop
            start = stop

    def reset(self) -> None:
        for item in self._frozen:
            self.plot.removeItem(item)
        self._frozen.clear()
        self._frozen_from = self._frozen_until = 0
        self._seen = 0
        self.tail.setData([], [])

    def remove(self) -> None:
        self.reset()
        self.plot.removeItem(self.tail)

    def point_count(self) -> int:
        return sum(len(item.xData) for item in self.items if item.xData is not None)


def reserve_pixmap_cache() -> None:
    """Let Qt's pixmap cache hold ``PIXMAP_CACHE_KB`` (never lowered)."""
    if QPixmapCache.cacheLimit() < PIXMAP_CACHE_KB:
        QPixmapCache.setCacheLimit(PIXMAP_CACHE_KB)


def column_envelope(
    x: np.ndarray, y: np.ndarray, x0: float, x1: float, columns: int, start: int = 0
) -> tuple[np.ndarray, int]:
    """The rows to draw of a curve against time, at most four per pixel column.

    The view ``[x0, x1]`` is cut into ``columns`` columns; of the rows in one column the
    first, the lowest, the highest and the last are kept, in their order. A polyline
    through them covers the same pixels as through every row: within a column it spans
    the same heights, and the lines between columns join the same rows. Of the rows left
    of the view only the last is kept, of those right of it only the first (the lines
    into the view). A row whose ``y`` is NaN (a break) is kept, and ends its column's
    group: the rows before and after it are taken apart.

    Parameters
    ----------
    x, y : ndarray, shape (k,)
        ``x`` finite and nondecreasing; ``y`` finite or NaN (a break).
    x0, x1 : float
        The view, ``x0 < x1``.
    columns : int
        Pixel columns of the view.
    start : int
        The first row to look at (rows before it were drawn already).

    Returns
    -------
    rows : ndarray of int
        Increasing indices of the rows to draw, all ``>= start``.
    open_start : int
        The first row of the last column drawn: rows after it may still join that
        column, so the next call starts there (``len(x)`` if no row was drawn).
    """
    k = len(x)
    first = max(start, int(np.searchsorted(x, x0, side="left")) - 1)
    stop = min(k, int(np.searchsorted(x, x1, side="right")) + 1)
    if first >= stop:
        return np.empty(0, dtype=np.intp), max(start, min(first, k))
    scale = columns / (x1 - x0)
    column = np.floor((x[first:stop] - x0) * scale)
    np.clip(column, -1, columns, out=column)
    values = y[first:stop]
    breaks = np.isnan(values)
    # a new group where the column changes, at a break and after it
    new = np.diff(column) != 0
    if breaks.any():
        new |= breaks[1:] | breaks[:-1]
    starts = np.concatenate([[0], np.flatnonzero(new) + 1])
    lows = np.minimum.reduceat(values, starts)
    highs = np.maximum.reduceat(values, starts)
    group = np.repeat(np.arange(len(starts)), np.diff(np.append(starts, len(values))))
    index = np.arange(len(values))
    beyond = len(values)
    low_at = np.minimum.reduceat(np.where(values == lows[group], index, beyond), starts)
    high_at = np.minimum.reduceat(np.where(values == highs[group], index, beyond), starts)
    low_at = np.where(low_at == beyond, starts, low_at)  # a break: its own row
    high_at = np.where(high_at == beyond, starts, high_at)
    ends = np.append(starts[1:], len(values)) - 1
    kept = np.sort(np.stack([starts, low_at, high_at, ends], axis=1), axis=1).ravel()
    rows = kept[np.append(True, kept[1:] != kept[:-1])]
    return first + rows, first + int(starts[-1])


class EnvelopeCurve:
    """A curve against time (x nondecreasing and finite; y finite, or NaN for a break)
    drawn at the view's resolution.

    What is handed to pyqtgraph is ``column_envelope`` of the data: at most four rows per
    pixel column, however many rows the curve has. New rows redo only the last column; a
    change of the view's x range or width redoes the whole envelope (O(rows), a few ms).
    The columns that no longer change go to a settled item, kept as pixels by Qt until
    the view moves (or ``SETTLE_POINTS`` more rows of the envelope have settled); only the
    live item, the last columns, is drawn at every frame. The pen is drawn as separate
    line segments: Qt strokes a pen wider than a pixel along a self-crossing path (a
    dense curve's zigzag) in time that grows much faster than the path, the segments in
    linear time.

    Parameters
    ----------
    plot : pyqtgraph.PlotItem
    pen : QPen
    name : str, optional
        The live item's name (legends).
    ranges : RangeKeeper, optional
        Grown to show every new row.
    """

    def __init__(
        self,
        plot: pg.PlotItem,
        pen,
        name: str | None = None,
        ranges: RangeKeeper | None = None,
    ):
        self.plot = plot
        self.pen = pen
        self.ranges = ranges
        self.settled = pg.PlotDataItem(pen=pen, connect="finite")
        self.settled.curve.setCacheMode(QGraphicsItem.CacheMode.DeviceCoordinateCache)
        reserve_pixmap_cache()
        self.tail = pg.PlotDataItem(pen=pen, name=name, connect="finite")
        for item in self.items:
            item.curve.opts["segmentedLineMode"] = "on"
            plot.addItem(item)
        self._x = np.empty(0)
        self._y = np.empty(0)
        self._grid: tuple[float, float, int] | None = None
        self._rows = np.empty(0, dtype=np.intp)  # the rows drawn
        self._open_row = 0  # the first row of the last column drawn
        self._open_at = 0  # where that column's rows begin in ``_rows``
        self._settled = 0  # rows of ``_rows`` in the settled item
        self._updating = False
        self._view = plot.getViewBox()
        self._view.sigXRangeChanged.connect(self._on_view_changed)
        self._view.sigResized.connect(self._on_view_changed)

    @property
    def items(self) -> list[pg.PlotDataItem]:
        return [self.settled, self.tail]

    def _current_grid(self) -> tuple[float, float, int] | None:
        (x0, x1), _ = self._view.viewRange()
        columns = int(round(self._view.width()))
        if not (math.isfinite(x0) and math.isfinite(x1) and x1 > x0) or columns < 1:
            return None
        return (float(x0), float(x1), columns)

    def _on_view_changed(self, *_args) -> None:
        if not self._updating and self._current_grid() != self._grid:
            self._redo(0)

    def update(self, x: np.ndarray, y: np.ndarray, revised: bool = False) -> None:
        """Show ``x[i], y[i]`` for all i (``x`` nondecreasing and finite, ``y`` finite or
        NaN: a break). ``revised``: the last rows changed in place (those of the last
        column drawn)."""
        size = len(x)
        seen = len(self._x)
        replaced = size < seen
        self._updating = True  # a range grown here is taken below, not redone twice
        try:
            if self.ranges is not None:
                if replaced:
                    self.ranges.include(x, y)
                elif size > seen:
                    self.ranges.include(x[seen:], y[seen:])
        finally:
            self._updating = False
        self._x, self._y = x, y
        if replaced or self._current_grid() != self._grid:
            self._redo(0)
        elif size > seen or revised:
            self._redo(self._open_row)

    def _redo(self, start: int) -> None:
        """Draw the envelope again from row ``start`` (0: all of it, for a new grid)."""
        grid = self._current_grid()
        if grid != self._grid:
            start = 0
        self._grid = grid
        x, y = self._x, self._y
        kept = self._rows[: self._open_at] if start else self._rows[:0]  # the open column is redone
        if grid is None:
            rows, open_row = np.arange(start, len(x)), len(x)
        else:
            rows, open_row = column_envelope(x, y, *grid, start=start)
        self._open_at = len(kept) + int(np.searchsorted(rows, open_row))
        self._open_row = open_row
        self._rows = np.concatenate([kept, rows])
        if not start or len(self._rows) - self._settled > SETTLE_POINTS:
            # the columns before the open one never change again (until the view does)
            self._settled = self._open_at
            shown = self._rows[: self._settled] if self._settled > 1 else self._rows[:0]
            self.settled.setData(x[shown], y[shown])
        # one row back: the live item goes on from the settled item's last row
        live = self._rows[max(self._settled - 1, 0) :]
        self.tail.setData(x[live], y[live])

    def reset(self) -> None:
        self._x = self._y = np.empty(0)
        self._rows = np.empty(0, dtype=np.intp)
        self._open_row = self._open_at = self._settled = 0
        self._grid = None
        for item in self.items:
            item.setData([], [])

    def remove(self) -> None:
        self.reset()
        self._view.sigXRangeChanged.disconnect(self._on_view_changed)
        self._view.sigResized.disconnect(self._on_view_changed)
        for item in self.items:
            self.plot.removeItem(item)

    def point_count(self) -> int:
        """Rows of data the curve shows (drawn: ``column_envelope`` of them)."""
        return len(self._x)


class PacedLayoutWidget(pg.GraphicsLayoutWidget):
    """A ``GraphicsLayoutWidget`` that paints at most once per ``gap`` after its last paint.

    Every change to its scene (new data, a pan with the mouse, a range grown) asks for a
    repaint; those that come within ``gap`` seconds of the end of the last paint are
    gathered into one, painted when the gap is over. So a plot fed frames at full speed
    leaves the GUI thread free for ``gap`` between two paints, however long a paint takes
    (a slower machine paints less often instead of never catching up). Rendering it
    (export, ``grab``) is not delayed.

    Parameters
    ----------
    gap : float
        Seconds between the end of a paint and the next, at least.
    """

    def __init__(self, *args, gap: float = REPAINT_GAP_SECONDS, **kwargs):
        super().__init__(*args, **kwargs)
        self.gap = float(gap)
        self._painted = -math.inf
        self._later = QTimer(self)
        self._later.setSingleShot(True)
        self._later.timeout.connect(self._on_later_timeout)
        # Qt then leaves every repaint to this widget: changes arrive as scene.changed
        self.setViewportUpdateMode(QGraphicsView.ViewportUpdateMode.NoViewportUpdate)
        self.scene().changed.connect(self._on_scene_changed)

    def _on_scene_changed(self, _regions) -> None:
        if self._later.isActive():
            return
        wait = self._painted + self.gap - time.perf_counter()
        if wait <= 0:
            self.viewport().update()
        else:
            self._later.start(max(1, math.ceil(1000 * wait)))

    def _on_later_timeout(self) -> None:
        self.viewport().update()

    def paintEvent(self, event) -> None:  # noqa: N802 - Qt override
        super().paintEvent(event)
        self._painted = time.perf_counter()
        self._later.stop()  # what it waited for is painted; later changes ask again


LEGEND_ORBITS = 6
"""Orbits named in a legend (their colours tell the others apart)."""


def legend_orbit_names(keys, main: str = "orbit") -> list[tuple[int, str]]:
    """(key, name) of the orbits a legend names: the first ``LEGEND_ORBITS`` of ``keys``
    (ascending; 0 the main orbit, called ``main``), the last saying how many more there
    are (a section of 30 orbits listed six and said nothing of the rest)."""
    keys = sorted(keys)
    named = [(key, main if key == 0 else f"orbit {key}") for key in keys[:LEGEND_ORBITS]]
    if len(keys) > LEGEND_ORBITS:
        key, name = named[-1]
        named[-1] = (key, f"{name} and {len(keys) - LEGEND_ORBITS} more")
    return named


def style_plot(plot: pg.PlotItem) -> pg.PlotItem:
    """House style: a light grid, no SI-prefix rescaling of the axes (it hides the units),
    axes cached as pixels."""
    plot.showGrid(x=True, y=True, alpha=0.15)
    for name in ("left", "bottom", "right", "top"):
        # with the prefix on, every change of range sets the axis label's HTML again,
        # hidden axes' too (pyqtgraph's AxisItem.updateAutoSIPrefix): 28 a second
        plot.getAxis(name).enableAutoSIPrefix(False)
    for name in ("left", "bottom"):
        # an axis (with its grid) only changes with its range: keep its pixels, so a
        # frame that moves a curve does not re-render every tick label
        plot.getAxis(name).setCacheMode(QGraphicsItem.CacheMode.DeviceCoordinateCache)
    return plot


class FlexibleLabel(pg.LabelItem):
    """A plot title that does not set the plot's minimum width, and is set smaller where
    it would not fit (down to ``LEAST`` of its size; only past that is it clipped).

    pyqtgraph's ``LabelItem`` makes its text's width its minimum at every change and
    resize, so in a narrow dock a long title pushes the plot's right part out of sight;
    presentation mode's large titles were cut ("Double pendulum: configurat").
    """

    LEAST = 0.5

    def updateMin(self) -> None:  # noqa: N802 - pyqtgraph override
        super().updateMin()
        self.setMinimumWidth(0)

    def resizeEvent(self, event) -> None:  # noqa: N802 - Qt override
        super().resizeEvent(event)
        self._fit()

    def setText(self, text, **args) -> None:  # noqa: N802 - pyqtgraph's name
        self.shown_points = None
        super().setText(text, **args)
        self._fit()

    def _fit(self) -> None:
        """Set the text smaller while it is wider than the label (sizes in points)."""
        width = self.width()
        wanted = str(self.opts.get("size") or "")
        if width <= 0 or not wanted.endswith("pt") or getattr(self, "_fitting", False):
            return
        points = float(wanted[:-2])
        for _ in range(4):  # a font's width is not quite in proportion to its size
            shown = getattr(self, "shown_points", None) or points
            natural = self.item.document().idealWidth() * points / shown
            fitted = max(min(points, points * (width - 1) / max(natural, 1.0)), points * self.LEAST)
            if fitted >= shown - 0.05 and (fitted - shown < 0.25 or shown >= points):
                return
            self._fitting = True
            try:
                super().setText(self.text, size=f"{fitted:.2f}pt")
                self.opts["size"] = wanted
            finally:
                self._fitting = False
            self.shown_points = fitted


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
        if not all(math.isfinite(v) for box in (new_x, new_y) if box is not None for v in box):
            return False  # data near the float limit (an unbounded motion followed): as is
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
        self._new_grid()
        self.updateSize()

    def _new_grid(self) -> None:
        self.rowCount = 1
        spacing = (self.layout.horizontalSpacing(), self.layout.verticalSpacing())
        self.layout = QGraphicsGridLayout()
        self.layout.setHorizontalSpacing(spacing[0])
        self.layout.setVerticalSpacing(spacing[1])
        self.setLayout(self.layout)

    def set_entries(self, entries: Iterable[tuple[object, str]]) -> None:
        """Show exactly ``entries``, a list of (item, name), in order (nothing is redone
        when they are what is shown).

        Entries already shown keep their sample and label (laying out a label's text
        takes ms), laid out again in a new grid as ``clear`` and ``addItem`` would.
        """
        entries = list(entries)
        if [(s.item, label.text) for s, label in self.items] == entries:
            return
        shown = {(sample.item, label.text): (sample, label) for sample, label in self.items}
        kept = [shown.pop(entry, None) for entry in entries]
        for sample, label in shown.values():
            self._removeItemFromLayout(sample, label)
        for pair in kept:
            for part in pair or ():
                self.layout.removeItem(part)
        self.items = []
        self._new_grid()
        for (item, name), pair in zip(entries, kept, strict=True):
            if pair is None:
                self.addItem(item, name)
            else:
                self.items.append(pair)
                self._addItemToLayout(*pair)
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
