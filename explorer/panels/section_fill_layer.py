"""Fill the section: many orbits' crossings at the section's energy (issue 28 item 3).

"Fill section…" (the phase view's header, and Run > Fill section…) asks for a number of
orbits (``DEFAULT_ORBITS``, as the CLI's ``export --poincare --orbits``) and draws the
section portrait of ``systems.section_orbits`` at the section's energy (the energy a
click on the section starts orbits at): starts spread over the allowed interval of the
line p = 0 (``default_starts``), each orbit to ``T_END`` in the taylor family's SIMD
batches (``kernels.taylor_batch_section_parallel``, compiled ``nogil``), in a thread of
its own (``section-fill``) that asks ``stopping`` between chunks of one batch a thread
and reports progress through a queued relay, as the chaos map does. Each orbit's
crossings are drawn in its own colour (``orbit_colour``, the CLI's) as one scatter item
under the launched orbits' points; an orbit whose energy check fails
(``Portrait.trusted``) is left out and the status says how many and why.

Cancel, Esc (Run > Stop filling the section), another system, mode, energy or pair (the
view rebuilt) and closing the window stop the thread at its next checkpoint and remove
the layer. Where the section is not defined or taylor does not apply, the action is
disabled and its tooltip says why (``refusal``).
"""

from __future__ import annotations

import numpy as np
import pyqtgraph as pg
from PySide6.QtCore import QObject, Signal
from PySide6.QtGui import QAction
from PySide6.QtWidgets import QGraphicsItem, QInputDialog, QPushButton

from explorer.orbit_colours import orbit_colour
from explorer.panels.background import ProgressControls, RelayThread
from explorer.session.script import MAX_SECTION_ORBITS as MAX_ORBITS
from systems.angles import wrap

DEFAULT_ORBITS = 30
T_END = 2000.0
"""Each orbit's end time (the CLI's ``PORTRAIT_T_END``: a few hundred crossings each)."""
CROSSINGS = 2000
"""The most crossings kept per orbit (the CLI's ``PORTRAIT_CROSSINGS``)."""
Z_VALUE = -15
"""Over the forbidden region (-20) and the chaos map (-25), under the launched orbits."""
POINT_SIZE = 3
MESSAGE_MS = 10_000
REFUSED_HINT = "Cannot fill the section here (the Fill button's tip says why)"


class _Relay(QObject):
    """Carries results from the fill's thread to the GUI thread (queued)."""

    progressed = Signal(int, int, int)  # generation, orbits done, total
    finished = Signal(int, object)  # generation, Portrait
    failed = Signal(int, str)


class FillRun(RelayThread):
    """One portrait of one section, in its own thread; ``cancel`` ends it between chunks."""

    def __init__(self, compiled, section, energy: float, count: int, relay, generation: int):
        super().__init__("section-fill", relay, generation)
        self.compiled, self.section = compiled, section
        self.energy, self.count = float(energy), int(count)

    def run(self) -> None:
        from systems.section_orbits import default_starts, section_portrait

        try:
            starts = default_starts(self.compiled, self.section, self.energy, self.count)
            portrait = section_portrait(
                self.compiled, self.section, self.energy, starts, t_end=T_END,
                crossings=CROSSINGS, cancelled=self.stopping.is_set,
                progress=lambda done, total: self._emit("progressed", done, total),
            )  # fmt: skip
        except ValueError as exc:  # no start reaches the energy, taylor refused
            self._emit("failed", f"No section fill: {exc}")
            return
        except Exception as exc:  # noqa: BLE001 - said in the view, never lost
            self._emit("failed", f"The section fill failed: {exc}")
            return
        if portrait is not None:
            self._emit("finished", portrait)


class SectionFillLayer(QObject):
    """The fill's button, actions, progress bar and points for one ``PhaseView``.

    Signals
    -------
    started(int)
        A fill of this many orbits was started (a session's ``section-fill N`` line).
    message(str, int)
        A status-bar message and how long to show it (ms; 0 until the next).
    """

    started = Signal(int)
    message = Signal(str, int)

    def __init__(self, view):
        super().__init__(view)
        self.view = view
        self.portrait = None
        self.item: pg.ScatterPlotItem | None = None
        self.kept = np.zeros(0, dtype=int)  # the orbits drawn (trusted), indices of portrait
        self._generation = 0
        self._thread: FillRun | None = None
        self._count = 0
        self._last = ""  # what the last fill gave (its button's tip says it)
        self._closed = False
        self._relay = _Relay()
        self._relay.progressed.connect(self._on_relay_progressed)
        self._relay.finished.connect(self._on_relay_finished)
        self._relay.failed.connect(self._on_relay_failed)
        self.button = QPushButton("Fill section…")
        self.button.clicked.connect(self.ask)
        self.fill_action = QAction("&Fill section…", self)
        self.fill_action.triggered.connect(self.ask)
        self.stop_action = QAction("Stop filling the section", self)
        self.stop_action.setShortcut("Esc")
        self.stop_action.setStatusTip("Stop computing the section fill (Esc)")
        self.stop_action.triggered.connect(self.stop)
        self.controls = ProgressControls(self.stop)
        self.controls.cancel_button.setToolTip("Stop filling the section (Esc)")
        self.progress, self.cancel_button = self.controls.progress, self.controls.cancel_button
        self.update_enabled()

    # -- state ---------------------------------------------------------------------------------

    def refusal(self) -> str | None:
        """None when the section can be filled now, else why not and what to change."""
        view = self.view
        if view.compiled is None:
            return "no system is open"
        if not view.poincare_available:
            return view._poincare_refusal()
        if view.section is None:
            return (
                "this scene's section is stroboscopic (a periodic drive): filling needs the "
                "section of an autonomous system at one energy"
            )
        if view.mode != "poincare":
            return "turn on the Poincaré section first (the check box above the plot)"
        from systems.integrators.registry import get_stepper

        reason = get_stepper("taylor").applies_to(view.compiled.mechanics)
        if reason is not None:
            return f"the fill runs the taylor family in batch, and {reason}"
        return None

    @property
    def available(self) -> bool:
        return self.refusal() is None

    @property
    def running(self) -> bool:
        return self._thread is not None

    def widgets(self) -> tuple:
        """What goes in the view's header."""
        return (self.button, self.progress, self.cancel_button)

    def update_enabled(self) -> None:
        reason = self.refusal()
        enabled = reason is None and not self.running and not self._closed
        tip = (
            f"Draw the crossings of many orbits (default {DEFAULT_ORBITS}) started on the "
            f"section at its energy, each to t = {T_END:g}, in a colour of its own"
            if reason is None
            else f"Fill section: not here: {reason}"
        )
        if self._last:
            tip += f"\n\nLast fill: {self._last}"
        for widget in (self.button, self.fill_action):
            widget.setEnabled(enabled)
            widget.setToolTip(tip)
        self.fill_action.setStatusTip(tip)
        self.stop_action.setEnabled(self.running)

    # -- actions -------------------------------------------------------------------------------

    def ask(self) -> None:
        """Ask for the number of orbits, then ``start``."""
        reason = self.refusal()
        if reason is not None:
            self._say(f"Cannot fill the section: {reason}", hint=REFUSED_HINT)
            return
        count, ok = QInputDialog.getInt(
            self.view, "Fill section", "Orbits to start on the section:",
            DEFAULT_ORBITS, 1, MAX_ORBITS,
        )  # fmt: skip
        if ok:
            self.start(count)

    def start(self, count: int) -> None:
        """Fill the section with ``count`` orbits at the section's energy."""
        if self.running or self._closed:
            return
        reason = self.refusal()
        if reason is not None:
            self._say(f"Cannot fill the section: {reason}", hint=REFUSED_HINT)
            return
        self.clear()
        view = self.view
        self._generation += 1
        self._count = int(count)
        self._thread = FillRun(
            view.compiled, view.section, view.section_energy, count, self._relay,
            self._generation,
        )  # fmt: skip
        self._show_running(True)
        self._say(f"filling section: {count} orbits at H = {view.section_energy:.6g}…", 0)
        self.started.emit(int(count))
        self._thread.start()

    def stop(self) -> None:
        """Stop a fill under way (Cancel, Esc); nothing of it is drawn."""
        if self.running:
            self.cancel()
            self._say("section fill stopped")

    def cancel(self) -> None:
        """Stop the fill being computed (its thread ends at its next checkpoint)."""
        self._generation += 1
        thread, self._thread = self._thread, None
        if thread is not None:
            thread.cancel()
        self._show_running(False)

    def clear(self) -> None:
        """Cancel and remove the fill (the view was rebuilt: another system, mode, energy
        or pair)."""
        was_running = self.running
        self.cancel()
        if self.item is not None:
            self.view.plot.removeItem(self.item)
            self.item = None
            self.view.set_layer_legend([], key="section-fill")
        self.portrait = None
        self.kept = np.zeros(0, dtype=int)
        self._last = ""
        if was_running:
            # the status bar only: the rebuilt view's header has its own hint
            self._say("section fill stopped: the section changed", hint=None)
        self.update_enabled()

    def shutdown(self) -> None:
        """The window is closing: end the thread."""
        self._closed = True
        self.cancel()

    def points(self) -> np.ndarray:
        """The drawn crossings' states, shape (k, 2n) (the trusted orbits' only)."""
        if self.portrait is None or not len(self.kept):
            width = 2 * self.view.compiled.n if self.view.compiled is not None else 2
            return np.empty((0, width))
        return np.concatenate([self.portrait.y[r] for r in self.kept])

    # -- the thread's reports ------------------------------------------------------------------

    def _say(self, text: str, ms: int = MESSAGE_MS, hint: str | None = "") -> None:
        """Show ``text`` in the status bar (``message``) and ``hint`` in the view's header
        ("": ``text`` itself; None: the header keeps its own). The header's text stays
        short: a label's text is its minimum width, and the header's the window's."""
        if hint is not None:
            self.view.hint.setText(hint or text)
        self.message.emit(text, ms)

    def _show_running(self, running: bool) -> None:
        self.controls.show_running(running)
        self.update_enabled()

    def _on_relay_progressed(self, generation: int, done: int, total: int) -> None:
        if self._closed or generation != self._generation:
            return
        self.controls.set_progress(done, total)
        self._say(f"filling section: {done} of {total} orbits…", 0)

    def _on_relay_finished(self, generation: int, portrait) -> None:
        if self._closed or generation != self._generation:
            return
        thread, self._thread = self._thread, None
        if thread is not None:
            thread.join(1.0)
        self._show_running(False)
        self.portrait = portrait
        self._draw(portrait)

    def _on_relay_failed(self, generation: int, message: str) -> None:
        if self._closed or generation != self._generation:
            return
        self._thread = None
        self._last = message
        self._show_running(False)
        self._say(message, hint="The section fill failed (its button's tip says why)")

    def _draw(self, portrait) -> None:
        view = self.view
        count = len(portrait.starts)
        self.kept = np.flatnonzero(portrait.trusted)
        n, s = view.compiled.n, portrait.section.shown
        xs, ys, brushes = [], [], []
        for r in self.kept:
            y = portrait.y[r]
            if not len(y):
                continue
            q = y[:, s]
            xs.append(wrap(q) if view.angles[s] else q)
            ys.append(y[:, n + s])
            brushes += [pg.mkBrush(orbit_colour(int(r), count))] * len(y)
        x = np.concatenate(xs) if xs else np.empty(0)
        y = np.concatenate(ys) if ys else np.empty(0)
        item = pg.ScatterPlotItem(x, y, size=POINT_SIZE, pen=None, brush=brushes or None)
        item.setZValue(Z_VALUE)
        # thousands of points: kept as pixels until the view moves
        item.setCacheMode(QGraphicsItem.CacheMode.DeviceCoordinateCache)
        view.plot.addItem(item)
        self.item = item
        if len(x):
            view.ranges.include(x, y)
        left_out = count - len(self.kept)
        sample = pg.ScatterPlotItem(size=6, pen=None, brush=pg.mkBrush(orbit_colour(0, count)))
        view.set_layer_legend(
            [(sample, f"section fill: {len(self.kept)} orbits at H = {portrait.energy:.4g}")],
            key="section-fill",
        )
        text = (
            f"section filled: {len(self.kept)} of {count} orbits, {len(x)} crossings to "
            f"t = {T_END:g}"
        )
        if len(self.kept):
            text += f"; energy error at most {np.max(portrait.energy_error[self.kept]):.2g}"
        short = f"{len(self.kept)} of {count} orbits filled, {len(x)} crossings"
        if left_out:
            first = next(m for m in portrait.messages if m)
            text += f"; {left_out} left out (energy check failed or stopped): {first}"
            short += f"; {left_out} left out"
        self._last = text
        self.update_enabled()
        self._say(text, hint=short)
