"""The player: a session script replayed in a window, one command at a time.

``Player(window, commands)`` runs on a ``QTimer`` (``POLL_MS``) and never blocks the GUI
thread. Before each command it waits until the window is idle: no build under way
(``window.builder.busy_changed``, ``window._opening``), no debounced edit or parameter
change pending (``window.editor.debounce``, ``window.parameter_timer``). ``run-until``
and ``wait`` then hold the script until the simulation time, or the wall clock, has
come.

Every command goes through the widget or window method a user's action goes through
(the method combo's index, the parameter table's cell, ``window.open_scene``...), so a
replay exercises the real paths and a ``Recorder`` records the same lines again.

The outcome is ``status`` (emitted as ``finished``): ``OK`` when the script ran through,
``FAILED`` when the application raised an exception meanwhile (reported by the window's
``ErrorReporter``; its traceback went to stderr), ``SCRIPT_ERROR`` for a line that does
not apply to the window's state (``demo.session:4: unknown parameter 'k' (parameters: m,
g, l)``); ``message`` says which.
"""

from __future__ import annotations

import math
import time
from pathlib import Path

import numpy as np
from PySide6.QtCore import QEvent, QObject, QTimer, Signal
from PySide6.QtGui import QValidator

from explorer.session.script import MAX_WAIT, Command, ScriptError

POLL_MS = 20
SETTLE_SECONDS = 120.0
"""How long a command may keep the window busy (derivation, compilation) before it is an error."""
RUN_UNTIL_SECONDS = 60.0
"""Wall time ``run-until`` allows beyond twice the simulated time over the speed."""
PROJECT_SECONDS = 10.0
"""How long ``run-until`` watches the run advance before it judges whether ``T`` can be
reached in the time allowed."""
STOP_SECONDS = 0.5
"""How long a run must stay stopped before ``run-until`` gives up on it: Play continues a
Poincaré run that reached its end, and the first new block takes a moment to arrive."""
OK, FAILED, SCRIPT_ERROR = 0, 1, 2


class Player(QObject):
    """Replays commands in a ``MainWindow``; ``start()``, then wait for ``finished``.

    Parameters
    ----------
    window : MainWindow
        The window to act in.
    commands : list of Command
        A parsed script (``explorer.session.parse``).
    source : str
        The script's name for messages (``demo.session``).
    folder : path, optional
        Where relative paths of ``open``, ``export`` and ``save`` start (the script's
        folder); the working directory if None.
    recorder : Recorder, optional
        The recorder to tell about the replay (default: ``window.recorder`` if any).

    Signals
    -------
    finished(int)   ``OK``, ``FAILED`` or ``SCRIPT_ERROR``; ``message`` says why
    noted(str)      something worth telling that is no error (a build that failed)
    """

    finished = Signal(int)
    noted = Signal(str)

    def __init__(
        self,
        window,
        commands: list[Command],
        *,
        source: str = "<session>",
        folder: str | Path | None = None,
        recorder=None,
        parent: QObject | None = None,
    ):
        super().__init__(parent if parent is not None else window)
        self.window = window
        self.commands = list(commands)
        self.source = source
        self.folder = Path(folder) if folder is not None else None
        self.recorder = recorder if recorder is not None else getattr(window, "recorder", None)
        self.status: int | None = None
        self.message = ""
        self.command: Command | None = None  # the command running, or the last one run
        self._index = 0
        self._started = False
        self._wait: _RunUntil | _Pause | None = None
        self._settle_deadline = math.inf
        busy_bar = getattr(window, "busy_bar", None)
        self._busy = busy_bar is not None and not busy_bar.isHidden()
        self._timer = QTimer(self)
        self._timer.setInterval(POLL_MS)
        self._timer.timeout.connect(self._on_timer_timeout)
        window.builder.busy_changed.connect(self._on_builder_busy_changed)
        window.builder.build_failed.connect(self._on_builder_build_failed)
        window.error_reporter.reported.connect(self._on_error_reported)
        window.installEventFilter(self)

    # -- running ------------------------------------------------------------------------------

    @property
    def running(self) -> bool:
        """Whether the replay has started and not finished."""
        return self._started and self.status is None

    def start(self) -> None:
        """Start replaying (returns at once; the event loop runs the commands)."""
        if self._started:
            return
        self._started = True
        if self.recorder is not None:
            self.recorder.replaying = True
        self._settle_deadline = time.monotonic() + SETTLE_SECONDS
        self._timer.start()

    def stop(self) -> None:
        """Stop the replay where it is (``status`` stays None if it had not finished)."""
        self._timer.stop()
        if self.recorder is not None:
            self.recorder.replaying = False

    def _finish(self, status: int, message: str = "") -> None:
        if self.status is not None:
            return
        self.stop()
        self.status, self.message = status, message
        if message:
            try:
                self.window.statusBar().showMessage(message)
            except RuntimeError:  # the window's C++ side is gone
                pass
        self.finished.emit(status)

    def _error(self, reason: str) -> ScriptError:
        return ScriptError(reason, self.command.line if self.command else 0, self.source)

    def _where(self) -> str:
        if self.command is None or not self.command.line:
            return self.source
        return f"{self.source}:{self.command.line}"

    def _on_timer_timeout(self) -> None:
        try:
            self._advance()
        except ScriptError as exc:
            self._finish(SCRIPT_ERROR, str(exc))

    def _advance(self) -> None:
        now = time.monotonic()
        if not self._idle():
            if now > self._settle_deadline:
                raise self._error(
                    f"the window was still busy (deriving or compiling) {SETTLE_SECONDS:.0f} s "
                    "after this line"
                )
            return
        if self._wait is not None:
            if not self._wait.poll(now):
                return
            self._wait = None
        if self._index >= len(self.commands):
            self._finish(OK)
            return
        command = self.commands[self._index]
        self._index += 1
        self.command = command
        self._settle_deadline = now + SETTLE_SECONDS
        getattr(self, "_do_" + command.verb.replace("-", "_"))(command)

    def _idle(self) -> bool:
        window = self.window
        if self._busy or getattr(window, "_opening", 0):
            return False
        timers = (
            getattr(window, "parameter_timer", None),
            getattr(window.editor, "debounce", None),
        )
        return not any(timer is not None and timer.isActive() for timer in timers)

    # -- what the window reports ------------------------------------------------------------

    def _on_builder_busy_changed(self, busy: bool) -> None:
        self._busy = busy

    def _on_builder_build_failed(self, failure) -> None:
        if self.running:
            self.noted.emit(f"{self._where()}: note: did not build: {failure.message}")

    def _on_error_reported(self, summary: str, _details: str) -> None:
        if self.running:
            when = "while this line ran (or just after)" if self.command else "before line 1"
            self._finish(
                FAILED, f"{self._where()}: the application raised an exception {when}: {summary}"
            )

    def eventFilter(self, watched: QObject, event: QEvent) -> bool:  # noqa: N802 - Qt override
        if watched is self.window and event.type() == QEvent.Type.Close and self.running:
            self._finish(FAILED, f"{self._where()}: the window closed before the script ended")
        return False

    # -- helpers -----------------------------------------------------------------------------------

    def _path(self, text: str) -> str:
        path = Path(text).expanduser()
        if not path.is_absolute() and self.folder is not None:
            path = self.folder / path
        return str(path)

    def _note(self, command: Command) -> None:
        if self.recorder is not None:
            self.recorder.note(command.text())

    def _refusals_during(self, action) -> list[str]:
        """Run ``action``; the parameter refusals the editor announced meanwhile."""
        refusals: list[str] = []

        def refused(message: str) -> None:
            refusals.append(message)

        editor = self.window.editor
        editor.parameter_refused.connect(refused)
        try:
            action()
        finally:
            editor.parameter_refused.disconnect(refused)
        return refusals

    @staticmethod
    def _rows(table, column: int = 0) -> dict[str, int]:
        rows = {}
        for row in range(table.rowCount()):
            item = table.item(row, column)
            if item is not None and item.text().strip():
                rows.setdefault(item.text().strip(), row)
        return rows

    # -- the commands ------------------------------------------------------------------------------

    def _do_open(self, command: Command) -> None:
        scene, window = command.value, self.window
        if scene.endswith(".toml") or "/" in scene or "\\" in scene:
            # a file of the user's: File > Open's path where the window has one
            scene = self._path(scene)
            opened = getattr(window, "open_file", window.open_scene)(scene)
        else:
            opened = window.open_scene(scene)  # the catalogue's path
        if not opened:
            shown = window.statusBar().currentMessage()
            raise self._error(shown or f"{scene} could not be opened")

    def _do_new(self, _command: Command) -> None:
        self.window.new_scene()

    def _do_set(self, command: Command) -> None:
        from explorer.editor.parameters_table import NAME, VALUE

        name, _value = command.value
        table = self.window.editor.parameter_table
        rows = self._rows(table, NAME)
        if name not in rows:
            names = ", ".join(rows) or "none"
            raise self._error(f"unknown parameter {name!r} (parameters: {names})")
        item = table.item(rows[name], VALUE)
        refusals = self._refusals_during(lambda: item.setText(command.args[1]))
        if refusals:
            raise self._error(refusals[-1])

    def _do_parameters(self, command: Command) -> None:
        table = self.window.editor.parameter_table
        table.set_parameters(list(command.value), table.ranges())
        table.structure_changed.emit()

    def _do_initial(self, command: Command) -> None:
        table = self.window.editor.initial_table
        rows = self._rows(table)
        for name, _ in command.value:
            if name not in rows or table.item(rows[name], 1) is None:
                names = ", ".join(rows) or "none"
                raise self._error(f"unknown initial value {name!r} (initial values: {names})")
        for name, text in command.value:
            table.item(rows[name], 1).setText(text)

    def _do_edit(self, command: Command) -> None:
        field, text = command.value
        editor = self.window.editor
        if field == "title":
            editor.title_edit.setText(text)
            editor.title_edit.textEdited.emit(text)
            return
        if field == "given-by":
            editor.kind_combo.setCurrentIndex(editor.kind_combo.findData(text))
            return
        if field == "coordinates":
            target = editor.coordinates
        elif field == "dissipation":
            target = editor.dissipation
        elif field.startswith("forces."):
            target = editor.force_fields.get(field.removeprefix("forces."))
            if target is None:
                names = ", ".join(editor.force_fields) or "none"
                raise self._error(f"no generalized force on {field[7:]!r} (coordinates: {names})")
        else:
            target = editor.fields[field]
        target.set_text(text)
        target.edited.emit()

    def _do_effect(self, command: Command) -> None:
        key, on = command.value
        editor = self.window.editor
        if key == "dissipation":
            switch = editor.dissipation_switch
        else:
            switch = editor.force_switches.get(key.removeprefix("forces."))
            if switch is None:
                names = ", ".join(f"forces.{q}" for q in editor.force_switches)
                raise self._error(f"no effect {key!r} (effects: dissipation, {names})")
        switch.setChecked(on)

    def _do_method(self, command: Command) -> None:
        controls = self.window.controls
        combo = controls.method_combo
        index = 0
        if command.value is not None:
            index = combo.findData(command.value)
            if index <= 0:
                names = [combo.itemData(i) for i in range(1, combo.count())]
                raise self._error(
                    f"unknown method {command.value!r} (methods: auto, {', '.join(names)})"
                )
            refusal = controls.refusal(command.value)
            if refusal:
                raise self._error(f"{command.value} does not apply to this system: {refusal}")
        combo.setCurrentIndex(index)

    def _do_dt(self, command: Command) -> None:
        edit = self.window.controls.step_edit
        text = "" if command.value is None else command.args[0]
        validator = edit.validator()
        if text and validator is not None:
            state = validator.validate(text, len(text))
            state = state[0] if isinstance(state, tuple) else state
            if state != QValidator.State.Acceptable:
                span = ""
                if hasattr(validator, "bottom"):
                    span = f" (from {validator.bottom():g} to {validator.top():g})"
                raise self._error(f"the step field does not take {text}{span}")
        edit.setText(text)
        edit.editingFinished.emit()

    def _do_speed(self, command: Command) -> None:
        from explorer.controls import SPEEDS

        for index, (_label, speed) in enumerate(SPEEDS):
            if speed == command.value or math.isclose(speed, command.value, rel_tol=1e-9):
                self.window.controls.speed_combo.setCurrentIndex(index)
                return
        offered = ", ".join("max" if math.isinf(s) else f"{s:g}" for _, s in SPEEDS)
        raise self._error(f"speed {command.args[0]} is not offered (speeds: {offered})")

    def _do_energy_guard(self, command: Command) -> None:
        self.window.set_energy_tolerance(command.value)

    def _do_section(self, command: Command) -> None:
        box = self.window.phase_view.poincare_box
        if command.value and not box.isEnabled():
            raise self._error(
                "this system has no Poincaré section (it needs two coordinates, no "
                "explicit time dependence and a conserved H)"
            )
        box.setChecked(command.value)

    def _do_pair(self, command: Command) -> None:
        q, p = command.value
        view = self.window.phase_view
        coordinates = tuple(view.scene.coordinates) if view.scene is not None else ()
        if q not in coordinates or p != f"p_{q}":
            pairs = "; ".join(f"{c},p_{c}" for c in coordinates) or "none"
            raise self._error(f"the phase view has no pair {q},{p} (pairs: {pairs})")
        index = coordinates.index(q)
        combo = view.pair_combo
        if combo.currentIndex() == index:
            return
        if not combo.isEnabled():
            raise self._error("the pair cannot change while the Poincaré section is on")
        combo.setCurrentIndex(index)

    def _do_launch(self, command: Command) -> None:
        window = self.window
        view = window.phase_view
        if view.compiled is None or window.worker is None:
            raise self._error("no system is running to launch an orbit in")
        coordinates = view.compiled.mechanics.scene.coordinates
        names = [*coordinates, *(f"p_{q}" for q in coordinates)]
        state = np.array(view.y0, dtype=float)
        for name, value in command.value:
            if name not in names:
                hint = " (give the momentum p_q, not the velocity)" if name.endswith("_dot") else ""
                raise self._error(
                    f"{name!r} is not a coordinate or momentum of this system "
                    f"(names: {', '.join(names)}){hint}"
                )
            state[names.index(name)] = value
        view.launch_requested.emit(state)

    def _do_delete(self, command: Command) -> None:
        keys = [trajectory.key for trajectory in self.window.store if trajectory.key != 0]
        if command.value not in keys:
            shown = ", ".join(map(str, keys)) or "none"
            raise self._error(f"no launched orbit {command.value} (launched orbits: {shown})")
        self.window.delete_orbit(command.value)

    def _do_clear(self, _command: Command) -> None:
        self.window.controls.clear_button.click()

    def _do_reset(self, _command: Command) -> None:
        self.window.controls.reset_button.click()

    def _do_pause(self, _command: Command) -> None:
        self.window.controls.play_button.setChecked(False)

    def _do_play(self, _command: Command) -> None:
        self.window.controls.play_button.setChecked(True)

    def _do_step(self, _command: Command) -> None:
        controls = self.window.controls
        if controls.playing:
            controls.play_button.setChecked(False)
        controls.step_button.click()

    def _do_run_until(self, command: Command) -> None:
        self._note(command)
        t, timeout = command.value
        self._wait = _RunUntil(self, t, timeout)

    def _do_wait(self, command: Command) -> None:
        self._note(command)
        self._wait = _Pause(command.value)

    def _do_tab(self, command: Command) -> None:
        try:
            self.window.show_tab(command.value)
        except KeyError as exc:
            raise self._error(exc.args[0] if exc.args else f"no tab {command.value!r}") from None

    def _do_export(self, command: Command) -> None:
        panel, path = command.value
        window = self.window
        if panel != "csv" and panel not in window.panels:
            names = ", ".join([*window.panels, "csv"])
            raise self._error(f"unknown panel {panel!r} (panels: {names})")
        path = self._path(path)
        try:
            if panel == "csv":
                window.export_csv(path)
            else:
                window.export_panel(panel, path)
        except (OSError, ValueError, RuntimeError) as exc:
            raise self._error(f"could not export {path}: {exc}") from None

    def _do_save(self, command: Command) -> None:
        path = self._path(command.value)
        if self.window.save_scene(path) is False:
            shown = self.window.statusBar().currentMessage()
            raise self._error(shown or f"could not save {path}")


class _RunUntil:
    """Waits until the main orbit reaches ``t``; a stop or a timeout is a script error."""

    def __init__(self, player: Player, t: float, timeout: float | None):
        self.player, self.t, self.timeout = player, t, timeout
        self.deadline: float | None = None
        self.allowed = 0.0
        self.start = (0.0, 0.0)  # (when, at which t) the wait began
        self.stopped: tuple[float, float] | None = None  # (since when, at which t)

    def poll(self, now: float) -> bool:
        window = self.player.window
        main = window.store.main
        if main is not None and main.last_t >= self.t:
            return True
        reached = main.last_t if main is not None else 0.0
        if self.deadline is None:
            if not window.controls.playing:
                raise self.player._error(
                    f"the simulation is paused at t = {reached:.6g}: run-until {self.t:g} "
                    "would wait for ever (add `play` before it)"
                )
            speed = window.controls.speed
            self.allowed = self.timeout or min(
                RUN_UNTIL_SECONDS + MAX_WAIT,
                RUN_UNTIL_SECONDS
                + (2.0 * (self.t - reached) / speed if math.isfinite(speed) else 0.0),
            )
            self.deadline = now + self.allowed
            self.start = (now, reached)
        if main is None or main.status == "running":
            self.stopped = None
        elif self.stopped is None or self.stopped[1] != reached:
            self.stopped = (now, reached)
        elif now - self.stopped[0] > STOP_SECONDS:
            why = "it reached its end" if main.status == "ok" else f"{main.status}: {main.message}"
            raise self.player._error(
                f"the run stopped at t = {reached:.6g}, before t = {self.t:g}: {why}"
            )
        self._project(now, reached)
        if now > self.deadline:
            raise self.player._error(
                f"t = {reached:.6g} after waiting {self.allowed:.3g} s for t = {self.t:g} "
                "(give run-until a longer timeout=SECONDS, or a higher speed)"
            )
        return False

    def _project(self, now: float, reached: float) -> None:
        """A script error now if, at the rate the run has advanced for
        ``PROJECT_SECONDS``, ``t`` would come only after the time allowed (``run-until
        1e308`` would otherwise wait the whole hour)."""
        since, start = self.start
        if now - since < PROJECT_SECONDS or reached <= start:
            return
        rate = (reached - start) / (now - since)
        needed = (self.t - reached) / rate
        if needed > self.deadline - now:
            raise self.player._error(
                f"the run advances about {rate:.3g} time units a second (t = {reached:.6g} "
                f"now): t = {self.t:g} would take about {needed:.3g} s more, beyond the "
                f"{self.allowed:.3g} s allowed (a higher speed, a smaller T, or a longer "
                "timeout=SECONDS)"
            )


class _Pause:
    """Waits ``seconds`` of wall time."""

    def __init__(self, seconds: float):
        self.seconds = seconds
        self.deadline: float | None = None

    def poll(self, now: float) -> bool:
        if self.deadline is None:
            self.deadline = now + self.seconds
        return now >= self.deadline
