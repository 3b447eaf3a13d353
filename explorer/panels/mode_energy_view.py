"""Normal-mode energy view: the energy in each linear normal mode of a lattice over time,
and the energies against the mode number now (the Fermi-Pasta-Ulam-Tsingou picture).

``set_system`` rebuilds the view for a new system: the modes are computed by
``systems.normal_modes`` in a worker process (``systems.processes``; about 0.1 s for a
64-particle chain, ended when another system comes or the window closes) and the view
shows them when they arrive, or the reason there are none. ``refresh(store)``
(the window's redraw timer) and ``update(t, Y)`` take the new states of the main orbit.

Drawing stays cheap however long the run: the curves are kept as the minimum and maximum
of each mode's energy per time bucket (``PeakBuckets``, O(new rows) a frame), with
buckets merged pairwise so that there are about as many as half the plot's pixel columns,
i.e. two points per column. Pens are 1 px cosmetic, without antialiasing. A view zoomed by
hand is drawn from the stored rows in the visible interval, bucketed the same way.

``attach(window)`` puts the view in a dock of the main window (tabbed with the conserved
quantities) that is offered only where modes apply: two or more coordinates and a stable
equilibrium with every frequency positive. It is shown, in front, for a new system of
``SHOWN_FROM`` or more coordinates, and hidden otherwise (View > Normal modes).
"""

from __future__ import annotations

import numpy as np
import pyqtgraph as pg
from PySide6.QtCore import QObject, Qt, Signal
from PySide6.QtWidgets import (
    QCheckBox,
    QDockWidget,
    QHBoxLayout,
    QLabel,
    QMainWindow,
    QSizePolicy,
    QStackedWidget,
    QVBoxLayout,
    QWidget,
)

from explorer.buffers import GrowingArray
from explorer.panels.curves import OutsideLegend, RangeKeeper, set_title, style_plot
from explorer.panels.lazy_menu import add_plot
from explorer.panels.log_axis import SparseLogAxis
from explorer.panels.offered_dock import OfferedDockLink, attach_hidden
from explorer.trajectories import is_gap
from systems import processes
from systems.display import pretty_name
from systems.normal_modes import ModeAnalysis, analyse

MAX_CURVES = 8
"""Modes drawn against time (the lowest ones); the spectrum shows them all."""
SHOWN_FROM = 6
"""A new system with at least this many coordinates shows the view at once."""
LOG_FLOOR = 1e-10
"""On a log scale, energies below this fraction of the total are drawn at it."""
COLOURS = (
    "#1f77b4",
    "#d62728",
    "#2ca02c",
    "#ff7f0e",
    "#9467bd",
    "#8c564b",
    "#e377c2",
    "#17becf",
)
DOCK_KEY = "modes"
CPU_SECONDS = 60.0
"""CPU seconds the analysis may take in its worker (its symbolic part stops itself at 10)."""


class PeakBuckets:
    """The minimum and maximum of each column of a time series per time bucket.

    Buckets are ``width`` long from ``t0``; when there are more than ``2 * target`` of
    them, neighbours are merged pairwise and ``width`` doubles, so a series of any length
    keeps between ``target`` and ``2 * target`` buckets. Adding rows costs O(rows).

    Parameters
    ----------
    columns : int
    target : int
        Half the number of buckets kept at most.
    t0, width : float, optional
        A fixed start and bucket width (no merging); by default the start is the first
        row's time and the width follows the data.
    """

    def __init__(self, columns: int, target: int = 300, t0=None, width=None):
        self.columns = columns
        self.target = max(int(target), 8)
        self.fixed = width is not None
        self.t0 = t0
        self.width = width
        self.last_t = -np.inf
        self._index = GrowingArray((), capacity=256)
        self._lo = GrowingArray((columns,), capacity=256)
        self._hi = GrowingArray((columns,), capacity=256)

    def __len__(self) -> int:
        return len(self._index)

    def add(self, t: np.ndarray, values: np.ndarray) -> None:
        """Fold rows ``values`` (k, columns) at times ``t`` (k,), never decreasing."""
        if not len(t):
            return
        if self.t0 is None:
            self.t0 = float(t[0])
        if self.width is None:
            span = float(t[-1]) - self.t0
            if span <= 0:
                self._fold(np.zeros(len(t), dtype=np.int64), values)
                self.last_t = float(t[-1])
                return
            self.width = span / self.target
        index = np.floor((t - self.t0) / self.width).astype(np.int64)
        self._fold(index, values)
        self.last_t = float(t[-1])
        while not self.fixed and len(self._index) and self._index.data[-1] >= 2 * self.target:
            self._merge()

    def _fold(self, index: np.ndarray, values: np.ndarray) -> None:
        starts = np.concatenate([[0], np.flatnonzero(np.diff(index)) + 1])
        lo = np.fmin.reduceat(values, starts, axis=0)
        hi = np.fmax.reduceat(values, starts, axis=0)
        index = index[starts]
        if len(self._index) and index[0] == self._index.data[-1]:
            self._lo.data[-1] = np.fmin(self._lo.data[-1], lo[0])
            self._hi.data[-1] = np.fmax(self._hi.data[-1], hi[0])
            index, lo, hi = index[1:], lo[1:], hi[1:]
        if len(index):
            self._index.extend(index.astype(float))
            self._lo.extend(lo)
            self._hi.extend(hi)

    def _merge(self) -> None:
        index = (self._index.data // 2).astype(np.int64)
        lo, hi = self._lo.data.copy(), self._hi.data.copy()
        starts = np.concatenate([[0], np.flatnonzero(np.diff(index)) + 1])
        self._index.clear()
        self._lo.clear()
        self._hi.clear()
        self._index.extend(index[starts].astype(float))
        self._lo.extend(np.fmin.reduceat(lo, starts, axis=0))
        self._hi.extend(np.fmax.reduceat(hi, starts, axis=0))
        self.width *= 2

    def points(self, column: int) -> tuple[np.ndarray, np.ndarray]:
        """A polyline through each bucket's minimum and maximum: x (2b,), y (2b,)."""
        if not len(self._index):
            return np.empty(0), np.empty(0)
        width = self.width or 0.0
        x = np.minimum(self.t0 + (self._index.data + 0.5) * width, self.last_t)
        y = np.empty(2 * len(x))
        y[0::2] = self._lo.data[:, column]
        y[1::2] = self._hi.data[:, column]
        return np.repeat(x, 2), y

    def extent(self) -> tuple[float, float] | None:
        """The smallest and largest value held, or None."""
        if not len(self._index):
            return None
        with np.errstate(all="ignore"):
            lo, hi = np.nanmin(self._lo.data), np.nanmax(self._hi.data)
        return (float(lo), float(hi)) if np.isfinite(lo) and np.isfinite(hi) else None


class GridLegend(OutsideLegend):
    """An ``OutsideLegend`` whose width is the sum of its columns' widest entries.

    ``OutsideLegend.updateSize`` takes the widest row, which is narrower than the grid
    when the widest entries of two columns sit in different rows; the legend then ran
    under the spectrum's axis.
    """

    def updateSize(self) -> None:  # noqa: N802 - pyqtgraph override
        super().updateSize()
        widths: dict[int, float] = {}
        for row in range(self.layout.rowCount()):
            for col in range(self.layout.columnCount()):
                item = self.layout.itemAt(row, col)
                if item:
                    size = item.effectiveSizeHint(Qt.SizeHint.PreferredSize)
                    widths[col] = max(widths.get(col, 0.0), size.width() + 3)
        if self.side == "right" and widths:
            width = sum(widths.values()) + 6
            self.setMinimumWidth(width)
            self.setMaximumWidth(width)
            self.updateGeometry()


class _Relay(QObject):
    """Carries an analysis from the thread that waits for its worker to the GUI thread
    (queued). It has no parent and that thread holds it, so it is alive whenever the
    thread emits."""

    delivered = Signal(int, object)


def _subscript(k: int) -> str:
    return f"<sub>{k}</sub>"


class ModeEnergyView(QWidget):
    """Mode energies E_k(t) of the main orbit for the lowest modes, and E_k against k now.

    Signals
    -------
    analysed(object)  the ``ModeAnalysis`` of the current system, once computed
    """

    analysed = Signal(object)

    def __init__(self, parent: QWidget | None = None):
        super().__init__(parent)
        self.compiled = None
        self.analysis: ModeAnalysis | None = None
        self._generation = 0
        self._closed = False
        self._job: processes.Job | None = None
        self._relay = _Relay()
        self._relay.delivered.connect(self._on_relay_delivered, Qt.ConnectionType.QueuedConnection)
        self._store = None
        self._seen_t = -np.inf
        self._buckets: PeakBuckets | None = None
        self._total = 0.0
        self._current: np.ndarray | None = None
        self._curves: list[pg.PlotCurveItem] = []
        self._brushes: list = []
        self._zoomed_at = None

        self.info = QLabel("")
        self.info.setTextFormat(Qt.TextFormat.RichText)
        self.info.setSizePolicy(QSizePolicy.Policy.Ignored, QSizePolicy.Policy.Preferred)
        self.log_box = QCheckBox("log scale")
        self.log_box.setToolTip("Energies on a logarithmic scale (small modes become visible)")
        self.log_box.toggled.connect(self._on_log_box_toggled)
        top = QHBoxLayout()
        top.setContentsMargins(4, 0, 4, 0)
        top.addWidget(self.info, 1)
        top.addWidget(self.log_box)

        self.layout_widget = pg.GraphicsLayoutWidget()
        self.layout_widget.setBackground("w")
        self.time_plot = add_plot(
            self.layout_widget, row=0, col=0, axisItems={"left": SparseLogAxis("left")}
        )
        style_plot(self.time_plot)
        self.time_plot.setLabel("bottom", "t")
        self.time_plot.setLabel("left", "E" + _subscript("k"))
        set_title(self.time_plot, "Energy in each normal mode (main orbit)")
        self.legend = GridLegend(columns=2, side="right")
        self.layout_widget.ci.addItem(self.legend, row=0, col=1)
        self.layout_widget.ci.layout.setAlignment(self.legend, Qt.AlignmentFlag.AlignTop)
        self.spectrum_plot = add_plot(
            self.layout_widget, row=0, col=2, axisItems={"left": SparseLogAxis("left")}
        )
        style_plot(self.spectrum_plot)
        self.spectrum_plot.setLabel("bottom", "mode k")
        set_title(self.spectrum_plot, "E" + _subscript("k") + " now")
        self.spectrum_plot.setMouseEnabled(x=False, y=True)
        self.layout_widget.ci.layout.setColumnStretchFactor(0, 3)
        self.layout_widget.ci.layout.setColumnStretchFactor(2, 1)
        # curve and scatter items, not PlotDataItems (which take eight times as long to
        # update, ten times with per-point brushes); they know nothing of log scales, so
        # they are given log10 values there (``_shown``)
        self._stems = pg.PlotCurveItem(pen=pg.mkPen("#888888", width=1), connect="pairs")
        self._dots = pg.ScatterPlotItem(size=6, pen=None)
        self.spectrum_plot.addItem(self._stems)
        self.spectrum_plot.addItem(self._dots)
        self.time_range = RangeKeeper(self.time_plot, time_axis=True)
        self.spectrum_range = RangeKeeper(self.spectrum_plot)
        self.time_plot.getViewBox().sigXRangeChanged.connect(self._on_time_range_changed)

        self.message = QLabel("")
        self.message.setWordWrap(True)
        self.message.setAlignment(Qt.AlignmentFlag.AlignCenter)
        self.message.setMargin(12)
        self.stack = QStackedWidget()
        self.stack.addWidget(self.layout_widget)
        self.stack.addWidget(self.message)
        layout = QVBoxLayout(self)
        layout.setContentsMargins(2, 2, 2, 2)
        layout.setSpacing(2)
        layout.addLayout(top)
        layout.addWidget(self.stack, 1)
        self._show_message("No system yet.")

    # -- the system -----------------------------------------------------------------------

    @property
    def modes(self):
        return None if self.analysis is None else self.analysis.modes

    @property
    def log_y(self) -> bool:
        return self.log_box.isChecked()

    def set_system(self, compiled, y0: np.ndarray | None = None) -> None:
        """Show a newly compiled system: the modes are found again (in a worker process)
        about the stable equilibrium nearest ``y0`` (the scene's start by default)."""
        self._end_job()
        self.compiled = compiled
        self.analysis = None
        self._generation += 1
        self._store = None
        self._clear()
        if self.stack.currentWidget() is self.message:  # plots stay, emptied, until then
            self._show_message("Finding the normal modes…")
        if y0 is None:
            y0 = compiled.initial_state()
        start = np.array(y0, dtype=float)[: compiled.n]
        generation, relay = self._generation, self._relay

        def report(job: processes.Job) -> None:  # in the thread that waited for the worker
            try:
                result = job.result(0)
            except processes.Cancelled:  # another system came, or the window closed
                return
            except Exception as exc:  # noqa: BLE001 - shown in the view, never lost
                result = ModeAnalysis(None, f"the normal-mode analysis failed: {exc}")
            try:
                relay.delivered.emit(generation, result)
            except RuntimeError:  # the relay's C++ side is gone: nobody is left to tell
                pass

        try:
            self._job = processes.submit(
                analyse,
                compiled.mechanics,
                np.asarray(compiled.parameters, dtype=float),
                start,
                cpu_seconds=CPU_SECONDS,
                what="the normal-mode analysis",
                on_done=report,
            )
        except Exception as exc:  # noqa: BLE001 - no worker: said in the view
            failed = ModeAnalysis(None, f"the normal-mode analysis failed: {exc}")
            relay.delivered.emit(generation, failed)

    def shutdown(self) -> None:
        """End any analysis still under way (the window is closing)."""
        self._closed = True
        self._generation += 1
        self._end_job()

    def _end_job(self) -> None:
        """End the worker of an analysis nobody waits for any more."""
        job, self._job = self._job, None
        if job is not None:
            job.cancel()

    def _on_relay_delivered(self, generation: int, analysis: ModeAnalysis) -> None:
        if self._closed or generation != self._generation:
            return  # a system replaced meanwhile
        self.analysis = analysis
        if analysis.applies:
            self._build(analysis.modes)
        else:
            self._show_message(f"No normal modes for this system: {analysis.reason}.")
        self.analysed.emit(analysis)
        if analysis.applies and self._store is not None:
            self.refresh(self._store)

    def _show_message(self, text: str) -> None:
        self.message.setText(text)
        self.info.setText("")
        self.log_box.setEnabled(False)
        self.stack.setCurrentWidget(self.message)

    def _clear(self) -> None:
        for curve in self._curves:
            self.time_plot.removeItem(curve)
        self._curves = []
        self.legend.clear()
        self._buckets = None
        self._seen_t = -np.inf
        self._total = 0.0
        self._current = None
        self._zoomed_at = None
        self._stems.setData([], [])
        self._dots.setData([], [])
        self._reset_ranges()

    def _reset_ranges(self) -> None:
        self.time_range.log_y = self.spectrum_range.log_y = self.log_y
        for plot in (self.time_plot, self.spectrum_plot):
            plot.setLogMode(y=self.log_y)
            plot.disableAutoRange()  # setLogMode turned it on; the keepers set the ranges
        self.time_range.reset()
        n = self.modes.n if self.modes is not None else 1
        self.spectrum_range.reset(x=(0.4, n + 0.6), fixed=("x",))

    def _build(self, modes) -> None:
        self._clear()
        shown = min(modes.n, MAX_CURVES)
        for k in range(shown):
            pen = pg.mkPen(COLOURS[k % len(COLOURS)], width=1)
            curve = pg.PlotCurveItem(pen=pen, antialias=False, connect="finite")
            self.time_plot.addItem(curve)
            self._curves.append(curve)
            self.legend.addItem(curve, f"E{_subscript(k + 1)} ω={modes.omega[k]:.3g}")
        self.legend.updateSize()
        self._buckets = PeakBuckets(shown, self._bucket_target())
        self._reset_ranges()
        self._brushes = [pg.mkBrush(COLOURS[k] if k < shown else "#888888") for k in range(modes.n)]
        names = modes.coordinates
        where = "q = 0" if not np.any(modes.q0) else _where(names, modes.q0)
        omega = f"ω{_subscript(1)} = {modes.omega[0]:.4g}"
        if modes.n > 1:
            omega += f" … ω{_subscript(modes.n)} = {modes.omega[-1]:.4g}"
        more = f"; the lowest {shown} drawn against t" if modes.n > shown else ""
        note = f"; {modes.note}" if modes.note else ""
        self.info.setText(f"{modes.n} linear modes about {where}: {omega}{more}{note}")
        self.info.setToolTip(
            "E_k = (P_k² + ω_k² Q_k²)/2 with Q = Vᵀ M (q − q₀), P = Vᵀ p, where K v = ω² M v "
            "at the stable equilibrium nearest the start. The E_k add up to H for a harmonic "
            "system and each is constant there; energy moving between them is the anharmonic "
            "coupling (the Fermi–Pasta–Ulam–Tsingou recurrence)."
        )
        # whole mode numbers on the spectrum's axis
        major = 1 if modes.n <= 10 else 5 if modes.n <= 50 else 10
        self.spectrum_plot.getAxis("bottom").setTickSpacing(major, 1)
        self.log_box.setEnabled(True)
        self.stack.setCurrentWidget(self.layout_widget)

    def _bucket_target(self) -> int:
        """Half the time plot's width in pixels: two points per pixel column at most."""
        width = self.time_plot.getViewBox().width()
        return max(int(width / 2), 100) if width > 0 else 300

    # -- data -----------------------------------------------------------------------------

    def refresh(self, store) -> None:
        """Take the main orbit's rows not seen yet from ``store`` and redraw."""
        self._store = store
        main = store.main
        if self.modes is None or main is None or main.y.data.shape[1] != 2 * len(self.modes.q0):
            return
        t = main.t.data
        start = int(np.searchsorted(t, self._seen_t, side="right"))
        if start < len(t):
            self.update(t[start:], main.y.data[start:])

    def update(self, t: np.ndarray, Y: np.ndarray) -> None:
        """Add the new states ``Y`` (k, 2n) of the main orbit at times ``t`` (k,) and redraw."""
        modes = self.modes
        if modes is None or self._buckets is None or not len(t):
            return
        keep = ~is_gap(Y) & (t > self._seen_t)
        t, Y = t[keep], Y[keep]
        if not len(t):
            return
        self._seen_t = float(t[-1])
        energies = modes.energies(Y, len(self._curves))
        if self._total == 0.0:
            self._total = float(np.sum(modes.energies(Y[:1]))) or 1.0
        self._buckets.add(t, energies)
        self._current = modes.energies(Y[-1:])[0]
        self._draw(t, energies)

    def _draw(self, t: np.ndarray, energies: np.ndarray) -> None:
        floor = LOG_FLOOR * self._total if self.log_y else None
        if self.time_range.manual:
            (x0, x1), _ = self.time_plot.getViewBox().viewRange()
            if t[0] <= x1 and t[-1] >= x0:  # new rows in sight
                self._draw_zoomed()
        else:
            for k, curve in enumerate(self._curves):
                x, y = self._buckets.points(k)
                curve.setData(x, _shown(y, floor))
            low, high = float(np.nanmin(energies)), float(np.nanmax(energies))
            if floor is not None:
                low, high = max(low, floor), max(high, floor)
            self.time_range.include(np.array([t[0], t[-1]]), np.array([low, high]))
        self._draw_spectrum(floor)

    def _draw_spectrum(self, floor) -> None:
        if self._current is None:
            return
        k = np.arange(1, len(self._current) + 1, dtype=float)
        values = self._current if floor is None else np.maximum(self._current, floor)
        base = np.full_like(values, floor if floor is not None else 0.0)
        stems_y = np.empty(2 * len(k))
        stems_y[0::2], stems_y[1::2] = base, values
        self._stems.setData(np.repeat(k, 2), _shown(stems_y, floor))
        self._dots.setData(k, _shown(values, floor), brush=self._brushes)
        self.spectrum_range.include(k, np.concatenate([values, base[:1]]))

    def _draw_zoomed(self) -> None:
        """The visible interval of a view zoomed by hand, bucketed from the stored rows."""
        store, modes = self._store, self.modes
        main = store.main if store is not None else None
        if main is None or modes is None:
            return
        (x0, x1), _ = self.time_plot.getViewBox().viewRange()
        t = main.t.data
        a, b = np.searchsorted(t, [x0, x1])
        a, b = max(a - 1, 0), min(b + 1, len(t))
        rows = main.y.data[a:b]
        keep = ~is_gap(rows)
        t, rows = t[a:b][keep], rows[keep]
        target = self._bucket_target()
        buckets = PeakBuckets(len(self._curves), target, t0=x0, width=(x1 - x0) / (2 * target))
        if len(t):
            buckets.add(t, modes.energies(rows, len(self._curves)))
        floor = LOG_FLOOR * self._total if self.log_y else None
        for k, curve in enumerate(self._curves):
            x, y = buckets.points(k)
            curve.setData(x, _shown(y, floor))
        self._zoomed_at = (x0, x1)

    def _on_time_range_changed(self, *_args) -> None:
        if not self.time_range.manual or self._buckets is None:
            return
        (x0, x1), _ = self.time_plot.getViewBox().viewRange()
        if self._zoomed_at != (x0, x1):
            self._draw_zoomed()

    def _on_log_box_toggled(self, _checked: bool) -> None:
        """Redraw everything on the other scale (the ranges start again, zoom included)."""
        self._reset_ranges()
        if self._buckets is None or self._current is None:
            return
        floor = LOG_FLOOR * self._total if self.log_y else None
        extent = self._buckets.extent()
        for k, curve in enumerate(self._curves):
            x, y = self._buckets.points(k)
            curve.setData(x, _shown(y, floor))
        if extent is not None:
            low, high = extent
            if floor is not None:
                low, high = max(low, floor), max(high, floor)
            self.time_range.include(
                np.array([self._buckets.t0, self._buckets.last_t]), np.array([low, high])
            )
        self._draw_spectrum(floor)

    def export_target(self) -> QWidget:
        return self.layout_widget


def _shown(values: np.ndarray, floor: float | None) -> np.ndarray:
    """What an item that knows no log scale is given: the values, or on a log scale
    (``floor`` set) log10 of the values raised to ``floor``."""
    if floor is None:
        return values
    with np.errstate(all="ignore"):
        return np.log10(np.maximum(values, floor))


def _where(names, q0: np.ndarray) -> str:
    if len(names) > 4:
        return "the equilibrium nearest the start"
    return ", ".join(f"{pretty_name(n)} = {v:.4g}" for n, v in zip(names, q0, strict=True))


class ModeDockLink(OfferedDockLink):
    """Offers the mode view in a window's dock where modes apply (see the module)."""

    def __init__(self, window: QMainWindow, view: ModeEnergyView, dock: QDockWidget):
        self._coordinates: tuple | None = None
        self._fresh = False
        super().__init__(
            window,
            view,
            dock,
            "The energy in each linear normal mode over time",
            "No normal modes for this system: {why}",
        )
        window.system_started.connect(self._on_system_started)
        view.analysed.connect(self._on_view_analysed)

    def _on_system_started(self, built) -> None:
        coordinates = tuple(built.scene.coordinates)
        self._fresh = self._fresh or coordinates != self._coordinates
        self._coordinates = coordinates

    def _on_view_analysed(self, analysis: ModeAnalysis) -> None:
        n = self.view.compiled.n if self.view.compiled is not None else 0
        offered = analysis.applies and n >= 2
        why = analysis.reason if not analysis.applies else "a single coordinate"
        self._offer(offered, why)
        self.wanted = offered and n >= SHOWN_FROM
        if self._fresh:
            self._fresh = False
            if offered and n >= SHOWN_FROM:
                self.dock.show()
                self.dock.raise_()
            else:
                self.dock.hide()


def attach(window, key: str = DOCK_KEY) -> ModeEnergyView:
    """Add the mode view to ``window`` (a ``MainWindow``) in a dock tabbed with the
    conserved quantities, hidden until a system with modes opens; returns the view."""
    return attach_hidden(window, key, "Normal modes", ModeEnergyView(), ModeDockLink)
