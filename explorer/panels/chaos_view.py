"""Chaos view: the Lyapunov exponents, MEGNO and SALI/GALI of the main orbit's start,
as running estimates that converge while the run plays.

The variational equations are written in a worker process (``systems.processes``:
``systems.chaos.variational.tangent_code``, symbolic work the window never does itself),
turned into machine code and integrated in a thread of the view's own
(``ChaosRun``: ``systems.chaos.lyapunov.LyapunovRun``, DOP853 at tolerance 1e-12 from
the scene's start), which follows the main orbit's time: it computes up to the time
the main orbit has reached (``refresh``), so the estimates grow with the run and stop
when it is paused or the dock is hidden. Nothing starts before the view is first shown
for a system. The thread is ended (an event, then joined) when another system comes or
the window closes; nothing is raised into it.

``attach(window)`` adds the view's dock (tabbed with the conserved quantities, hidden),
offered where the variational equations can be written (``variational.refusal``).
"""

from __future__ import annotations

import math
import threading
import time

import numpy as np
import pyqtgraph as pg
from PySide6.QtCore import QObject, Qt, Signal
from PySide6.QtWidgets import (
    QDockWidget,
    QLabel,
    QMainWindow,
    QSizePolicy,
    QStackedWidget,
    QVBoxLayout,
    QWidget,
)

from explorer.panels.curves import set_title, style_plot
from explorer.panels.lazy_menu import add_plot
from explorer.panels.offered_dock import OfferedDockLink, attach_hidden
from systems import processes

DOCK_KEY = "chaos"
CPU_SECONDS = 30.0
"""CPU seconds the worker writing the variational equations may take."""
SLICE_SECONDS = 0.05
"""Computing between two reports of the running estimates, about."""
DUTY = 0.25
"""The share of the time the estimates' thread computes while it is behind the main orbit:
its bookkeeping between compiled steps holds the GIL, and computing all the time made
the GUI thread's median event latency 140 ms instead of 11-23 ms (the double pendulum at
full speed)."""
MEGNO_REGULAR = 2.0
INTERVAL_SCALES = 2.0
"""The longest interval between two estimates, in the fastest motion's time (1/|J|'s
largest eigenvalue at the start): estimates follow the main orbit that closely."""


def submit_tangent_code(mechanics, signal, generation: int, cpu_seconds: float):
    """Write the variational equations of ``mechanics`` in a worker process
    (``systems.processes``); ``signal.emit(generation, code)`` when done, the
    ``TangentCode`` or the error's message (also when no worker can start). Returns the
    job (None without a worker), whose ``cancel`` drops the result."""
    from systems.chaos.variational import tangent_code

    def report(job: processes.Job) -> None:  # in the thread that waited for the worker
        try:
            result = job.result(0)
        except processes.Cancelled:
            return
        except Exception as exc:  # noqa: BLE001 - shown in the view
            result = str(exc)
        try:
            signal.emit(generation, result)
        except RuntimeError:  # the relay's C++ side is gone: nobody is left to tell
            pass

    try:
        return processes.submit(
            tangent_code, mechanics, cpu_seconds=cpu_seconds,
            what="the variational equations", on_done=report,
        )  # fmt: skip
    except Exception as exc:  # noqa: BLE001 - no worker: said in the view
        signal.emit(generation, str(exc))
        return None


class _Relay(QObject):
    """Carries results from the view's threads to the GUI thread (queued)."""

    coded = Signal(int, object)  # generation, TangentCode or an error message
    estimated = Signal(int, object, object)  # generation, Estimate, history arrays
    failed = Signal(int, str)


class ChaosRun(threading.Thread):
    """The tangent run of one system, in its own thread, up to ``target`` (the main
    orbit's time); reports each slice's estimate through ``relay``."""

    def __init__(self, compiled, code, y0: np.ndarray, relay: _Relay, generation: int):
        super().__init__(name="chaos-estimates", daemon=True)
        self.compiled, self.code, self.y0 = compiled, code, np.array(y0, dtype=float)
        self.relay, self.generation = relay, generation
        self.target = 0.0
        self.stopping = threading.Event()
        self.wake = threading.Event()

    def follow(self, t: float) -> None:
        """Compute up to the time ``t`` (never back)."""
        if t > self.target:
            self.target = t
            self.wake.set()

    def stop(self, timeout: float = 1.0) -> None:
        self.stopping.set()
        self.wake.set()
        if self.is_alive() and threading.current_thread() is not self:
            self.join(timeout)

    def run(self) -> None:
        from systems.chaos.lyapunov import LyapunovRun
        from systems.chaos.variational import Tangent

        try:
            tangent = Tangent(self.compiled, self.code)
            chaos = LyapunovRun(tangent, y0=self.y0)
            # estimates close behind the main orbit: intervals of a fraction of a period
            chaos.max_interval = chaos.tau = min(chaos.tau, INTERVAL_SCALES * chaos.time_scale)
        except Exception as exc:  # noqa: BLE001 - said in the view, never lost
            self._emit("failed", f"the variational equations could not be run: {exc}")
            return
        while not self.stopping.is_set():
            if chaos.done:
                self._emit("failed", f"the tangent run stopped: {chaos.message}")
                return
            if chaos.t >= self.target:
                self.wake.wait(0.2)
                self.wake.clear()
                continue
            start = time.perf_counter()
            try:
                estimate = chaos.advance(SLICE_SECONDS, until=self.target)
            except Exception as exc:  # noqa: BLE001
                self._emit("failed", f"the tangent run failed: {exc}")
                return
            self._emit("estimated", estimate, chaos.history.arrays())
            # the intervals' bookkeeping holds the GIL: leave the window most of the time
            self.stopping.wait((time.perf_counter() - start) * (1 / DUTY - 1))

    def _emit(self, signal: str, *values) -> None:
        try:
            getattr(self.relay, signal).emit(self.generation, *values)
        except RuntimeError:  # the relay's C++ side is gone: nobody is left to tell
            pass


class ChaosView(QWidget):
    """The running estimates of the maximal Lyapunov exponent, MEGNO and SALI (GALI).

    Signals
    -------
    estimated(object)  each new ``Estimate`` shown
    applies(object)  None when the system's chaos can be measured, else the reason
    """

    estimated = Signal(object)
    applies = Signal(object)

    def __init__(self, parent: QWidget | None = None):
        super().__init__(parent)
        self.compiled = None
        self.estimate = None
        self._y0 = None
        self._generation = 0
        self._closed = False
        self._job: processes.Job | None = None
        self._thread: ChaosRun | None = None
        self._started = False
        self._pending_t = 0.0  # the main orbit's time, for a thread not started yet
        self._reason: str | None = "no system yet"
        self._relay = _Relay()
        queued = Qt.ConnectionType.QueuedConnection
        self._relay.coded.connect(self._on_relay_coded, queued)
        self._relay.estimated.connect(self._on_relay_estimated, queued)
        self._relay.failed.connect(self._on_relay_failed, queued)

        self.info = QLabel("")
        self.info.setTextFormat(Qt.TextFormat.RichText)
        self.info.setSizePolicy(QSizePolicy.Policy.Ignored, QSizePolicy.Policy.Preferred)
        self.info.setToolTip(
            "Running estimates from the scene's start, integrated with the variational "
            "equations (DOP853, tolerance 1e-12) up to the main orbit's time. MEGNO ⟨Y⟩ "
            "tends to 2 on a regular (quasi-periodic) orbit, to 0 on a periodic orbit of "
            "an isochronous system, and grows like λ t / 2 on a chaotic one; SALI tends "
            "to 0 on a chaotic orbit (GALI_k likewise, k = max(2, n))."
        )
        self.layout_widget = pg.GraphicsLayoutWidget()
        self.layout_widget.setBackground("w")
        self.plots = {}
        self.curves = {}
        for col, (key, title, label) in enumerate(
            (
                ("maximal", "Maximal Lyapunov exponent", "λ<sub>max</sub>"),
                ("megno", "MEGNO ⟨Y⟩ (2: regular)", "⟨Y⟩"),
                ("sali", "SALI and GALI (log)", "index"),
            )
        ):
            plot = add_plot(self.layout_widget, row=0, col=col)
            style_plot(plot)
            set_title(plot, title)
            plot.setLabel("bottom", "t")
            plot.setLabel("left", label)
            self.plots[key] = plot
            self.curves[key] = plot.plot(pen=pg.mkPen("#1f77b4", width=1))
        self.curves["gali"] = self.plots["sali"].plot(pen=pg.mkPen("#d62728", width=1))
        self.plots["sali"].setLogMode(y=True)
        self.plots["megno"].addItem(
            pg.InfiniteLine(MEGNO_REGULAR, angle=0, pen=pg.mkPen("#888888", style=Qt.DashLine))
        )
        self.plots["maximal"].addItem(pg.InfiniteLine(0.0, angle=0, pen=pg.mkPen("#888888")))
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
        layout.addWidget(self.info)
        layout.addWidget(self.stack, 1)
        self._show_message("No system yet.")

    # -- the system -----------------------------------------------------------------------

    @property
    def reason(self) -> str | None:
        """Why this system's chaos is not measured (None: it is)."""
        return self._reason

    def set_system(self, compiled, y0: np.ndarray | None = None) -> None:
        """Show a new system (or new parameters): the estimates start again from ``y0``
        (its start) once the view is shown and the main orbit moves."""
        from systems.chaos.variational import refusal

        self._end()
        self._generation += 1
        self.compiled = compiled
        self.estimate = None
        self._y0 = None if y0 is None else np.array(y0, dtype=float)
        self._started = False
        self._reason = refusal(compiled.mechanics)
        for curve in self.curves.values():
            curve.setData([], [])
        self.info.setText("")
        if self._reason is None:
            self._show_message("The estimates start when the run plays with this panel shown.")
        else:
            self._show_message(f"Chaos is not measured for this system: {self._reason}.")
        self.applies.emit(self._reason)

    def refresh(self, store) -> None:
        """The main orbit's time from ``store``: the estimates follow it."""
        if self._closed or self.compiled is None or self._reason is not None:
            return
        main = store.main
        if main is None or not len(main.t.data):
            return
        t = float(main.t.data[-1])
        if not self._started:
            self._start()
        if self._thread is not None and math.isfinite(t):
            self._thread.follow(t)
        self._pending_t = t

    def _start(self) -> None:
        self._started = True
        self._show_message("Writing the variational equations…")
        self._job = submit_tangent_code(
            self.compiled.mechanics, self._relay.coded, self._generation, CPU_SECONDS
        )

    def _on_relay_coded(self, generation: int, code) -> None:
        if self._closed or generation != self._generation:
            return
        self._job = None
        if isinstance(code, str):
            self._show_message(f"Chaos is not measured: {code}")
            return
        y0 = self._y0 if self._y0 is not None else self.compiled.initial_state()
        self._thread = ChaosRun(self.compiled, code, y0, self._relay, generation)
        self._thread.follow(self._pending_t)
        self._thread.start()
        self._show_message("Measuring…")

    def _on_relay_estimated(self, generation: int, estimate, history: dict) -> None:
        if self._closed or generation != self._generation:
            return
        from systems.chaos.lyapunov import megno_verdict

        self.estimate = estimate
        if self.stack.currentWidget() is not self.layout_widget:
            self.stack.setCurrentWidget(self.layout_widget)
        t = history["t"]
        self.curves["maximal"].setData(t, history["maximal"])
        self.curves["megno"].setData(t, history["megno"])
        floor = 1e-17  # round-off: a log scale shows zero there
        self.curves["sali"].setData(t, np.maximum(history["sali"], floor))
        if estimate.gali_order > 2:
            self.curves["gali"].setData(t, np.maximum(history["gali"], floor))
        gali = (
            f" · GALI<sub>{estimate.gali_order}</sub> = {estimate.gali:.3g}"
            if estimate.gali_order > 2
            else ""
        )
        self.info.setText(
            f"t = {estimate.t:.6g}: λ<sub>max</sub> = {estimate.maximal:.4g} · "
            f"MEGNO ⟨Y⟩ = {estimate.megno:.4g} ({megno_verdict(estimate.megno)}) · "
            f"SALI = {estimate.sali:.3g}{gali} · exponents "
            + ", ".join(f"{x:.3g}" for x in estimate.exponents)
        )
        self.estimated.emit(estimate)

    def _on_relay_failed(self, generation: int, message: str) -> None:
        if self._closed or generation != self._generation:
            return
        self.info.setText(message)

    def _show_message(self, text: str) -> None:
        self.message.setText(text)
        self.stack.setCurrentWidget(self.message)

    def _end(self) -> None:
        job, self._job = self._job, None
        if job is not None:
            job.cancel()
        thread, self._thread = self._thread, None
        if thread is not None:
            thread.stop()
        self._pending_t = 0.0

    def shutdown(self) -> None:
        """End the worker and the thread (the window is closing)."""
        self._closed = True
        self._generation += 1
        self._end()

    def export_target(self) -> QWidget:
        return self.layout_widget


class ChaosDockLink(OfferedDockLink):
    """Offers the chaos view where the variational equations can be written."""

    def __init__(self, window: QMainWindow, view: ChaosView, dock: QDockWidget):
        super().__init__(
            window,
            view,
            dock,
            "Lyapunov exponents, MEGNO and SALI of the scene's start, as the run plays",
            "Chaos is not measured for this system: {why}",
        )
        view.applies.connect(self._on_view_applies)

    def _on_view_applies(self, reason) -> None:
        self._offer(reason is None, reason or "")


def attach(window, key: str = DOCK_KEY) -> ChaosView:
    """Add the chaos view to ``window`` (a ``MainWindow``) in a dock tabbed with the
    conserved quantities, hidden (View > Chaos); returns the view."""
    return attach_hidden(window, key, "Chaos", ChaosView(), ChaosDockLink)
