"""Work-precision panel: what accuracy costs in time, one curve per method.

"Run" sweeps every suitable method over its step sizes or tolerances for the current
scene (``systems.workprecision.sweep``) in a background thread, with a progress bar and
cancel; the result is drawn as error against wall time, log-log, for the final state and
for the energy.
"""

from __future__ import annotations

import threading

import numpy as np
import pyqtgraph as pg
from PySide6.QtCore import QObject, QThread, Signal, Slot
from PySide6.QtWidgets import (
    QDoubleSpinBox,
    QHBoxLayout,
    QLabel,
    QProgressBar,
    QPushButton,
    QVBoxLayout,
    QWidget,
)

from explorer.panels.curves import LEGEND_BRUSH, style_plot
from explorer.panels.lazy_menu import add_plot
from explorer.panels.log_axis import SparseLogAxis

SYMBOLS = ("o", "s", "t", "d", "+", "x", "star", "p", "h")
COLOURS = ("#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#17becf", "#e377c2", "#8c564b")


def run_workprecision(scene, t_end: float | None = None, progress=None, cancelled=None):
    """Build ``scene`` and sweep its default methods (synchronously); returns the result.

    Raises ``ValueError`` (``systems.workprecision.sweep_problem``) for an end time the
    sweep would take far too long to reach.
    """
    from explorer.builder import build
    from systems.workprecision import default_methods, sweep, sweep_problem

    built = build(scene)
    if t_end is None:
        t_end = float(scene.view.get("t_end", 20.0))
    methods = default_methods(built.compiled.mechanics)
    problem = sweep_problem(built.compiled, methods, t_end=t_end, levels=6)
    if problem:
        raise ValueError(problem)
    return sweep(built.compiled, methods, t_end=t_end, progress=progress, cancelled=cancelled)


class _SweepWorker(QObject):
    progressed = Signal(int, int, str)
    finished = Signal(object)
    failed = Signal(str)

    def __init__(self, compiled, t_end: float):
        super().__init__()
        self.compiled = compiled
        self.t_end = t_end
        self.cancel_event = threading.Event()

    @Slot()
    def work(self) -> None:
        from systems.workprecision import sweep

        try:
            result = sweep(
                self.compiled,
                t_end=self.t_end,
                progress=lambda done, total, text: self.progressed.emit(done, total, text),
                cancelled=self.cancel_event.is_set,
            )
        except Exception as exc:  # noqa: BLE001 - shown in the panel
            self.failed.emit(f"{type(exc).__name__}: {exc}")
        else:
            self.finished.emit(result)


class WorkPrecisionView(QWidget):
    """Sweep controls and the two log-log plots (final-state and energy error)."""

    result_ready = Signal(object)

    def __init__(self, parent: QWidget | None = None):
        super().__init__(parent)
        self.compiled = None
        self.result = None
        self._thread: QThread | None = None
        self._worker: _SweepWorker | None = None
        self.run_button = QPushButton("Run sweep")
        self.run_button.clicked.connect(self._on_run_button_clicked)
        self.cancel_button = QPushButton("Cancel")
        self.cancel_button.setEnabled(False)
        self.cancel_button.clicked.connect(self.cancel)
        self.t_end_box = QDoubleSpinBox()
        self.t_end_box.setRange(0.01, 1e6)
        self.t_end_box.setDecimals(2)
        self.progress = QProgressBar()
        self.progress.setTextVisible(True)
        self.status = QLabel("Run a sweep to see error against time for each method.")
        self.status.setStyleSheet("color: #555")
        header = QHBoxLayout()
        header.addWidget(self.run_button)
        header.addWidget(self.cancel_button)
        header.addWidget(QLabel("to t ="))
        header.addWidget(self.t_end_box)
        header.addWidget(self.progress, 1)
        header.addWidget(self.status, 2)
        self.plot_area = pg.GraphicsLayoutWidget()
        self.plot_area.setBackground("w")
        self.error_plot = style_plot(
            add_plot(
                self.plot_area,
                row=0,
                col=0,
                axisItems={"bottom": SparseLogAxis("bottom"), "left": SparseLogAxis("left")},
            )
        )
        self.energy_plot = style_plot(
            add_plot(
                self.plot_area,
                row=0,
                col=1,
                axisItems={"bottom": SparseLogAxis("bottom"), "left": SparseLogAxis("left")},
            )
        )
        for plot, what in (
            (self.error_plot, "final-state error"),
            (self.energy_plot, "max |ΔH/H₀|"),
        ):
            plot.setLogMode(x=True, y=True)
            plot.setLabel("bottom", "wall time of the integration [s]")
            plot.setLabel("left", what)
        self.error_plot.setTitle("Final-state error against time")
        self.energy_plot.setTitle("Energy error against time")
        self.legend = self.error_plot.addLegend(offset=(-10, 10), brush=LEGEND_BRUSH)
        layout = QVBoxLayout(self)
        layout.setContentsMargins(2, 2, 2, 2)
        layout.addLayout(header)
        layout.addWidget(self.plot_area)

    def set_system(self, compiled) -> None:
        """A new system: forget the old result (a sweep in progress is cancelled)."""
        self.cancel()
        self.compiled = compiled
        self.t_end_box.setValue(float(compiled.mechanics.scene.view.get("t_end", 20.0)))
        self._clear()
        self.status.setText("Run a sweep to see error against time for each method.")
        self.progress.setValue(0)

    @property
    def running(self) -> bool:
        return self._thread is not None and self._thread.isRunning()

    def start(self) -> None:
        """Sweep the current system in the background."""
        if self.compiled is None or self.running:
            return
        self._finish_thread()
        self._worker = _SweepWorker(self.compiled, self.t_end_box.value())
        self._thread = QThread()
        self._thread.setObjectName("workprecision")
        self._worker.moveToThread(self._thread)
        self._thread.started.connect(self._worker.work)
        self._worker.progressed.connect(self._on_worker_progressed)
        self._worker.finished.connect(self._on_worker_finished)
        self._worker.failed.connect(self._on_worker_failed)
        self._worker.finished.connect(self._thread.quit)
        self._worker.failed.connect(self._thread.quit)
        self.run_button.setEnabled(False)
        self.cancel_button.setEnabled(True)
        self.status.setText("compiling and sweeping…")
        self._thread.start()

    def cancel(self) -> None:
        if self._worker is not None:
            self._worker.cancel_event.set()
        self._finish_thread()

    def _finish_thread(self) -> None:
        if self._thread is not None:
            self._thread.quit()
            self._thread.wait()
            self._thread = None
            self._worker = None
        self.run_button.setEnabled(True)
        self.cancel_button.setEnabled(False)

    def shutdown(self) -> None:
        self.cancel()

    def _on_run_button_clicked(self) -> None:
        self.start()

    def _on_worker_progressed(self, done: int, total: int, text: str) -> None:
        self.progress.setRange(0, max(total, 1))
        self.progress.setValue(done)
        self.status.setText(text)

    def _on_worker_finished(self, result) -> None:
        self._finish_thread()
        self.show_result(result)
        self.result_ready.emit(result)

    def _on_worker_failed(self, message: str) -> None:
        self._finish_thread()
        self.status.setText(f"the sweep failed: {message}")

    # -- drawing ---------------------------------------------------------------------------

    def _clear(self) -> None:
        self.error_plot.clear()
        self.energy_plot.clear()
        self.legend.clear()

    def show_result(self, result) -> None:
        """Draw a ``systems.workprecision.WorkPrecision``."""
        self.result = result
        self._clear()
        for k, method in enumerate(result.methods):
            points = result.curve(method)
            if not points:
                continue
            colour = COLOURS[k % len(COLOURS)]
            style = dict(
                pen=pg.mkPen(colour, width=1.5),
                symbol=SYMBOLS[k % len(SYMBOLS)],
                symbolBrush=colour,
                symbolPen=colour,
                symbolSize=7,
            )
            wall = np.array([p.wall_s for p in points])
            error = np.array([max(p.final_error, 1e-17) for p in points])
            order = np.argsort(wall)
            self.error_plot.plot(wall[order], error[order], name=method, **style)
            energy = [(p.wall_s, p.energy_error) for p in points if p.energy_error is not None]
            if energy:
                w, e = np.array(energy).T
                order = np.argsort(w)
                self.energy_plot.plot(w[order], np.maximum(e[order], 1e-17), **style)
        state = " (cancelled: partial)" if result.cancelled else ""
        self.error_plot.setTitle(f"Final-state error against time{state}")
        self.energy_plot.setTitle(f"Energy error; reference: {result.reference}")
        self.status.setText(f"{result.title}, t = {result.t_end:g}; reference: {result.reference}")
        self.progress.setValue(self.progress.maximum())

    def export_target(self) -> QWidget:
        return self.plot_area
