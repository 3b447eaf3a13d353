"""The orbit (bifurcation) diagram of a periodically driven scene (issue 27 item 3).

View > Orbit diagram (a dock tabbed with the conserved quantities, offered where the
drive is periodic: ``systems.chaos.bifurcation.drive_period``): choose a parameter and a
range, Draw, and the state once per period of the drive after a transient is plotted
against the parameter, every value one row of one parallel compiled loop
(``bifurcation.orbit_diagram``) run in a thread of its own (``orbit-diagram``) with a
progress bar and Cancel between chunks. Every orbit starts from the scene's start. The
driven damped pendulum's period-doubling route to chaos: A from 1.0 to 1.5. The method is
``bifurcation.default_strobe_method``'s (taylor where it applies: more accurate and
faster than rk4 at 200 steps a period on every driven scene of the catalogue), named
under the plot.
"""

from __future__ import annotations

import numpy as np
import pyqtgraph as pg
from PySide6.QtCore import QObject, Signal
from PySide6.QtWidgets import (
    QComboBox,
    QDoubleSpinBox,
    QHBoxLayout,
    QLabel,
    QPushButton,
    QSpinBox,
    QVBoxLayout,
    QWidget,
)

from explorer.panels.background import ProgressControls, RelayThread
from explorer.panels.lazy_menu import LazyMenuViewBox
from explorer.panels.offered_dock import OfferedDockLink, attach_hidden
from explorer.session.script import MAX_DIAGRAM_VALUES

DOCK_KEY = "orbit_diagram"
VALUES = 200
TRANSIENT_PERIODS = 200
SAMPLES = 32
CHUNK = 8


class _Relay(QObject):
    """Carries the thread's news to the GUI thread (queued)."""

    progressed = Signal(int, int, int)  # generation, done, total
    finished = Signal(int, object)  # generation, OrbitDiagram
    failed = Signal(int, str)


class DiagramRun(RelayThread):
    """One orbit diagram in its own thread; ``cancel`` ends it between chunks."""

    def __init__(self, compiled, parameter, values, y0, relay: _Relay, generation: int):
        super().__init__("orbit-diagram", relay, generation)
        self.compiled, self.parameter = compiled, parameter
        self.values, self.y0 = np.asarray(values, dtype=float), np.asarray(y0, dtype=float)

    def run(self) -> None:
        from systems.chaos import bifurcation as bf

        try:
            period = bf.drive_period(self.compiled)
            kernel = bf.strobe_kernel(
                self.compiled, self.parameter, transient=TRANSIENT_PERIODS * period,
                samples=SAMPLES,
            )  # fmt: skip
            diagram = bf.orbit_diagram(
                kernel, self.values, y0=self.y0, chunk=bf.chunk_values(kernel, CHUNK),
                cancelled=self.stopping.is_set,
                progress=lambda done, total: self._emit("progressed", done, total),
            )  # fmt: skip
        except Exception as exc:  # noqa: BLE001 - said in the view, never lost
            self._emit("failed", f"The orbit diagram failed: {exc}")
            return
        if diagram.complete:
            self._emit("finished", diagram)


class OrbitDiagramView(QWidget):
    """Parameter, range, Draw and Cancel over a plot of the stroboscopic samples.

    Signals
    -------
    applies(object)
        None where the scene's drive is periodic, else the reason it is not.
    started(str, float, float, int)
        A diagram was started: the parameter, the range's ends and the number of values
        (a session's ``orbit-diagram`` line).
    """

    applies = Signal(object)
    started = Signal(str, float, float, int)

    def __init__(self, parent: QWidget | None = None):
        super().__init__(parent)
        self.compiled = None
        self.y0 = None
        self.diagram = None
        self.reason: str | None = "no system yet"
        self._thread: DiagramRun | None = None
        self._generation = 0
        self._closed = False
        self._relay = _Relay()
        self._relay.progressed.connect(self._on_relay_progressed)
        self._relay.finished.connect(self._on_relay_finished)
        self._relay.failed.connect(self._on_relay_failed)
        self.parameter_combo = QComboBox()
        self.parameter_combo.currentIndexChanged.connect(self._on_parameter_changed)
        self.low, self.high = QDoubleSpinBox(), QDoubleSpinBox()
        for box in (self.low, self.high):
            box.setDecimals(4)
            box.setRange(-1e6, 1e6)
            box.setSingleStep(0.01)
        self.count = QSpinBox()
        self.count.setRange(2, MAX_DIAGRAM_VALUES)
        self.count.setValue(VALUES)
        self.draw_button = QPushButton("Draw")
        self.draw_button.clicked.connect(self.start)
        self.controls = ProgressControls(self.cancel)
        self.progress, self.cancel_button = self.controls.progress, self.controls.cancel_button
        controls = QHBoxLayout()
        for widget in (QLabel("Parameter:"), self.parameter_combo, QLabel("from"), self.low,
                       QLabel("to"), self.high, QLabel("values:"), self.count,
                       self.draw_button, self.cancel_button, self.progress):  # fmt: skip
            controls.addWidget(widget)
        controls.addStretch(1)
        self.plot_widget = pg.PlotWidget(background="w", viewBox=LazyMenuViewBox())
        self.plot = self.plot_widget.getPlotItem()
        self.plot.showGrid(x=True, y=True, alpha=0.2)
        self.scatter = pg.ScatterPlotItem(size=2, pen=None, brush=pg.mkBrush(20, 20, 90, 170))
        self.plot.addItem(self.scatter)
        self.info = QLabel("")
        self.info.setStyleSheet("color: #555")
        layout = QVBoxLayout(self)
        layout.setContentsMargins(2, 2, 2, 2)
        layout.addLayout(controls)
        layout.addWidget(self.plot_widget)
        layout.addWidget(self.info)
        self._update_enabled()

    def set_system(self, compiled, y0: np.ndarray | None = None) -> None:
        """A new system: whatever was computed or drawn is dropped."""
        self.cancel()
        self.compiled = compiled
        self.y0 = None if y0 is None else np.array(y0, dtype=float)
        self.diagram = None
        self.scatter.setData([], [])
        self.reason = self._reason(compiled)
        self.parameter_combo.blockSignals(True)
        self.parameter_combo.clear()
        if self.reason is None:
            self.parameter_combo.addItems(list(compiled.parameter_names))
            names = list(compiled.parameter_names)
            self.parameter_combo.setCurrentIndex(names.index("A") if "A" in names else 0)
        self.parameter_combo.blockSignals(False)
        self._on_parameter_changed()
        self.info.setText(self.reason or "Choose a parameter and a range, then Draw.")
        self._update_enabled()
        self.applies.emit(self.reason)

    @staticmethod
    def _reason(compiled) -> str | None:
        from systems.chaos.bifurcation import drive_period

        if not compiled.parameter_names:
            return "the scene has no parameters to scan"
        if drive_period(compiled) is None:
            return "its time dependence is not a periodic drive (no stroboscopic section)"
        return None

    def _on_parameter_changed(self, _index: int = 0) -> None:
        name = self.parameter_combo.currentText()
        if self.compiled is None or not name:
            return
        value = float(self.compiled.parameters[list(self.compiled.parameter_names).index(name)])
        low, high = (2 * value / 3, value) if value > 0 else (value - 1, value + 1)
        self.low.setValue(low)
        self.high.setValue(high)

    def start(self) -> None:
        """Draw the diagram over the chosen parameter and range."""
        if self._closed or self.compiled is None or self.reason is not None:
            return
        self.cancel()
        lo, hi = self.low.value(), self.high.value()
        if not lo < hi:
            self.info.setText("The range's low end must be below its high end.")
            return
        self._generation += 1
        values = np.linspace(lo, hi, self.count.value())
        y0 = self.compiled.initial_state() if self.y0 is None else self.y0
        parameter = self.parameter_combo.currentText()
        self._thread = DiagramRun(
            self.compiled, parameter, values, y0, self._relay, self._generation
        )
        self._thread.start()
        self._show_running(True)
        self.info.setText(f"Integrating {len(values)} orbits…")
        self.started.emit(parameter, float(lo), float(hi), len(values))

    @property
    def running(self) -> bool:
        """Whether a diagram is being computed."""
        return self._thread is not None

    def cancel(self) -> None:
        """Stop the diagram being computed."""
        self._generation += 1
        thread, self._thread = self._thread, None
        if thread is not None:
            thread.cancel()
        self._show_running(False)

    def shutdown(self) -> None:
        """The window is closing."""
        self._closed = True
        self.cancel()

    def _show_running(self, running: bool) -> None:
        self.controls.show_running(running)
        self._update_enabled()

    def _update_enabled(self) -> None:
        usable = self.reason is None and not self._closed
        for widget in (self.parameter_combo, self.low, self.high, self.count):
            widget.setEnabled(usable)
        self.draw_button.setEnabled(usable and self._thread is None)

    def _on_relay_progressed(self, generation: int, done: int, total: int) -> None:
        if generation == self._generation:
            self.controls.set_progress(done, total)

    def _on_relay_finished(self, generation: int, diagram) -> None:
        if self._closed or generation != self._generation:
            return
        from systems.angles import angle_coordinates
        from systems.chaos.bifurcation import periods

        thread, self._thread = self._thread, None
        if thread is not None:
            thread.join(1.0)
        self._show_running(False)
        self.diagram = diagram
        mechanics = self.compiled.mechanics
        angles = [
            i
            for i, q in enumerate(mechanics.scene.coordinates)
            if q in angle_coordinates(mechanics)
        ]
        n = self.compiled.n
        index = n if 0 in angles else 0  # an angle's momentum: no wrapping needed
        column = diagram.samples[:, :, index]
        x = np.repeat(diagram.values, column.shape[1])
        keep = np.isfinite(column.ravel())
        self.scatter.setData(x[keep], column.ravel()[keep])
        self.plot.setLabel("bottom", diagram.parameter)
        self.plot.setLabel("left", diagram.names[index])
        found = periods(diagram, angles=tuple(angles))
        chaotic = int((found == 0).sum())
        self.info.setText(
            f"{diagram.names[index]} once per period of the drive after "
            f"{diagram.transient_periods} periods, {SAMPLES} periods a value; no period "
            f"within {SAMPLES // 2} at {chaotic} of {len(found)} values ({diagram.method}, "
            f"{diagram.wall_s:.1f} s)."
        )

    def _on_relay_failed(self, generation: int, message: str) -> None:
        if generation != self._generation:
            return
        self._thread = None
        self._show_running(False)
        self.info.setText(message)

    def export_target(self) -> QWidget:
        return self.plot_widget


class OrbitDiagramDockLink(OfferedDockLink):
    """Offers the orbit diagram where the scene's drive is periodic."""

    def __init__(self, window, view: OrbitDiagramView, dock):
        super().__init__(
            window, view, dock,
            "The state once per period of the drive over one parameter: period doubling, chaos",
            "No orbit diagram for this system: {why}",
        )  # fmt: skip
        view.applies.connect(self._on_view_applies)

    def _on_view_applies(self, reason) -> None:
        self._offer(reason is None, reason or "")


def attach(window, key: str = DOCK_KEY) -> OrbitDiagramView:
    """Add the orbit diagram to ``window`` (a ``MainWindow``) in a dock tabbed with the
    conserved quantities, hidden (View > Orbit diagram); returns the view."""
    return attach_hidden(window, key, "Orbit diagram", OrbitDiagramView(), OrbitDiagramDockLink)
