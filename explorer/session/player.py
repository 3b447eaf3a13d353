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

Consecutive edit lines (``edit``, ``parameters``, ``effect``, ``initial``) are typed in
one go, as a user types several fields before the editor rebuilds, and built once. Every
build a line asks for (``open``, ``new``, edits, a ``set`` that retries a failed build)
must succeed unless the next line is ``did-not-build`` (the recorder writes it after a
build that failed): a build that fails otherwise stops the replay there, so that
nothing after it (a ``save``, an ``export``) acts on the wrong system.

The outcome is ``status`` (emitted as ``finished``): ``OK`` when the script ran through,
``FAILED`` when the application raised an exception meanwhile (reported by the window's
``ErrorReporter``; its traceback went to stderr) or when the replay could not do what
the script says (a build that failed where the session expects it to build),
``SCRIPT_ERROR`` for a line that does not apply to the window's state
(``demo.session:4: unknown parameter 'k' (parameters: m, g, l)``); ``message`` says which.
"""

from __future__ import annotations

import math
import time
from pathlib import Path

import numpy as np
from PySide6.QtCore import QEvent, QObject, QTimer, Signal
from PySide6.QtGui import QValidator

from explorer.session.script import (
    BUILDING_VERBS,
    MAX_WAIT,
    TABLE_FIELDS,
    Command,
    ScriptError,
)

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
TYPED_TOGETHER = ("edit", "parameters", "effect", "initial")
"""Verbs whose consecutive lines are applied together, then built once."""


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
        self._asked: tuple[Command, Command] | None = None  # lines whose build to check
        # the last build's ("built"|"failed", message) since those lines began, if any
        self._outcome: tuple[str, str] | None = None
        busy_bar = getattr(window, "busy_bar", None)
        self._busy = busy_bar is not None and not busy_bar.isHidden()
        self._timer = QTimer(self)
        self._timer.setInterval(POLL_MS)
        self._timer.timeout.connect(self._on_timer_timeout)
        window.builder.busy_changed.connect(self._on_builder_busy_changed)
        window.builder.build_failed.connect(self._on_builder_build_failed)
        window.builder.built.connect(self._on_builder_built)
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
        if self._drawing():
            self._settle_deadline = now + SETTLE_SECONDS  # a map ends by itself, however long
            return
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
        if self._asked is not None:
            self._check_build()
            if self.status is not None:
                return
        if self._index >= len(self.commands):
            self._finish(OK)
            return
        first = command = self._next()
        self._settle_deadline = now + SETTLE_SECONDS
        self._outcome = None
        self._run(command)
        while command.verb in TYPED_TOGETHER and self._following() in TYPED_TOGETHER:
            command = self._next()
            self.window.editor.follow_coordinates()  # the rows of new coordinates
            self._run(command)
        if first.verb in BUILDING_VERBS:
            self._asked = (first, command)

    def _next(self) -> Command:
        command = self.commands[self._index]
        self._index += 1
        self.command = command
        return command

    def _following(self) -> str | None:
        """The verb of the next command, or None at the end."""
        return self.commands[self._index].verb if self._index < len(self.commands) else None

    def _run(self, command: Command) -> None:
        getattr(self, "_do_" + command.verb.replace("-", "_"))(command)

    def _check_build(self) -> None:
        """The lines just run asked for a build, which has ended (or none was needed):
        it must have succeeded, unless the next line says it did not."""
        first, last = self._asked
        self._asked = None
        expected = self._following() == "did-not-build"
        lines = f"line {first.line}" if first is last else f"lines {first.line}-{last.line}"
        if self._outcome is None:  # nothing new to build: the document was built before
            failed = self.window.editor.build_status == "failed"
            self._outcome = ("failed", self.window.editor.build_problem) if failed else None
        if self._outcome is None:
            return
        state, message = self._outcome
        if state == "failed" and expected:
            self.noted.emit(f"{self._where()}: note: did not build, as recorded: {message}")
        elif state == "failed":
            self._finish(
                FAILED,
                f"{self._where()}: did not build: {message} (the session expects {lines} to "
                "build: no `did-not-build` line follows; the replay stops here and runs, "
                "saves and exports nothing after it)",
            )
        elif expected:
            self.noted.emit(
                f"{self.source}:{self.commands[self._index].line}: note: {lines} built in this "
                "replay, though the build failed when the session was recorded"
            )

    def _drawing(self) -> bool:
        """Whether a chaos map, a section fill or an orbit diagram is being computed: the
        next line waits for it (a ``chaos-map``'s grid takes seconds to minutes: no
        settling deadline)."""
        phase = self.window.phase_view
        layers = (phase.map_layer, phase.fill_layer, self.window.orbit_diagram_view)
        return any(layer.running for layer in layers)

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
        self._outcome = ("failed", failure.message)

    def _on_builder_built(self, _built) -> None:
        self._outcome = ("built", "")

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
        try:
            path = Path(text).expanduser()
        except RuntimeError as exc:  # ~user of no user
            raise self._error(f"{text!r} cannot be a path: {exc}") from None
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
        rows = {name: row for name, row in self._rows(table).items() if table.item(row, 1)}
        typed: list[tuple[int, str, str]] = []  # (row, its name, value)
        for name, text in command.value:
            # q_dot where the table has p_q (or the other way round): the row is renamed,
            # as a user retypes its name; scene files take either
            row = rows.get(name, rows.get(_counterpart(name, rows)))
            if row is None and text:
                names = ", ".join(rows) or "none"
                raise self._error(
                    f"unknown initial value {name!r} (initial values: {names}; a velocity "
                    "q_dot may stand for the momentum p_q and the other way round)"
                )
            if row is not None:
                typed.append((row, name, text))
        for row, name, text in typed:
            if table.item(row, 0).text().strip() != name:
                table.item(row, 0).setText(name)
            table.item(row, 1).setText(text)

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
        if field in TABLE_FIELDS or field == "gravity":
            editor.replace_table(field, text)
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
        compiled = view.compiled
        if compiled is None or window.worker is None:
            raise self._error("no system is running to launch an orbit in")
        coordinates = list(compiled.mechanics.scene.coordinates)
        names = [*coordinates, *(f"p_{q}" for q in coordinates)]
        velocities = [f"{q}_dot" for q in coordinates]
        state = np.array(view.y0, dtype=float)
        qdot: dict[int, float] = {}
        momenta = False
        for name, value in command.value:
            if name in velocities:
                qdot[velocities.index(name)] = value
            elif name in names:
                state[names.index(name)] = value
                momenta = momenta or names.index(name) >= len(coordinates)
            else:
                raise self._error(
                    f"{name!r} is not a coordinate, velocity or momentum of this system "
                    f"(names: {', '.join([*names, *velocities])})"
                )
        if qdot:
            if momenta:
                raise self._error(
                    "give the velocities q_dot or the momenta p_q of a launch, not both"
                )
            state = self._with_velocities(state, qdot)
        view.launch_requested.emit(state)

    def _with_velocities(self, state: np.ndarray, given: dict[int, float]) -> np.ndarray:
        """``state`` with its momenta for the velocities ``given`` (index -> q_dot) and,
        for the other coordinates, the velocities of the initial state."""
        window = self.window
        compiled = window.phase_view.compiled
        n = compiled.n
        t0 = 0.0  # where the window starts a launched orbit
        main = window.store.main
        if main is not None and compiled.mechanics.classification.time_dependent:
            t0 = main.last_t
        y0 = np.array(window.phase_view.y0, dtype=float)
        qdot = np.array(compiled.velocities(t0, y0[None, :])[0], dtype=float)
        for i, value in given.items():
            qdot[i] = value
        try:
            p = compiled.momenta_from_velocities(t0, state[:n], qdot)
        except (ValueError, ArithmeticError) as exc:
            raise self._error(f"no momenta for these velocities: {exc}") from None
        if not np.all(np.isfinite(p)):
            raise self._error("the momenta for these velocities are not finite numbers")
        return np.concatenate([state[:n], p])

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

    def _do_did_not_build(self, _command: Command) -> None:
        pass  # checked with the lines before it (``_check_build``)

    def _do_tab(self, command: Command) -> None:
        try:
            self.window.show_tab(command.value)
        except KeyError as exc:
            raise self._error(exc.args[0] if exc.args else f"no tab {command.value!r}") from None

    def _do_chaos_map(self, _command: Command) -> None:
        layer = self.window.phase_view.map_layer
        if not layer.available:
            raise self._error(
                "a chaos map colours the Poincaré section: turn it on first (`section on`)"
            )
        layer.button.click()

    def _do_section_fill(self, command: Command) -> None:
        layer = self.window.phase_view.fill_layer
        reason = layer.refusal()
        if reason is not None:
            raise self._error(f"cannot fill the section: {reason}")
        layer.start(command.value)

    def _do_orbit_diagram(self, command: Command) -> None:
        parameter, low, high, count = command.value
        view = self.window.orbit_diagram_view
        if view.reason is not None:
            raise self._error(f"no orbit diagram here: {view.reason}")
        names = [view.parameter_combo.itemText(i) for i in range(view.parameter_combo.count())]
        if parameter not in names:
            raise self._error(
                f"no parameter {parameter!r} to scan (parameters: {', '.join(names)})"
            )
        view.parameter_combo.setCurrentIndex(names.index(parameter))
        view.low.setValue(low)
        view.high.setValue(high)
        view.count.setValue(count)
        if (view.low.value(), view.high.value()) != (low, high):
            raise self._error(
                f"the range {low:g} to {high:g} does not fit the Orbit diagram's boxes "
                f"({view.low.minimum():g} to {view.low.maximum():g}, "
                f"{view.low.decimals()} decimals)"
            )
        view.draw_button.click()

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


def _counterpart(name: str, rows) -> str | None:
    """Among ``rows``, the momentum ``p_q`` of a velocity ``q_dot``, or the other way round."""
    candidates = []
    if name.endswith("_dot"):
        candidates.append(f"p_{name[:-4]}")
    if name.startswith("p_"):
        candidates.append(f"{name[2:]}_dot")
    return next((c for c in candidates if c in rows), None)


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
            if main is not None and main.status not in ("running", "ok"):
                raise self.player._error(  # stopped (the button then says Play): why
                    f"the run stopped at t = {reached:.6g}, before t = {self.t:g}: "
                    f"{main.status}: {main.message}"
                )
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
            self._reachable(window, reached)
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

    def _reachable(self, window, reached: float) -> None:
        """A script error now if ``t`` cannot come in the time allowed: beyond the end of
        the run (a Poincaré section's), or, at a finite speed, further away than the
        speed covers in the time allowed (the run never goes faster than its speed)."""
        settings = getattr(window, "settings", None)
        t_end = getattr(settings, "t_end", math.inf)
        if self.t > t_end:
            raise self.player._error(
                f"the run ends at t = {t_end:g} (the Poincaré section's run; `play` after "
                f"its end goes on): run-until {self.t:g} waits for a time it does not reach "
                "(run-until the end, then `play`)"
            )
        speed = getattr(settings, "speed", window.controls.speed)  # a section runs at max
        needed = (self.t - reached) / speed
        if math.isfinite(speed) and needed > self.allowed:
            raise self.player._error(
                f"at speed {speed:g}, t = {self.t:g} is {needed:.3g} s of wall time away "
                f"(t = {reached:.6g} now), beyond the {self.allowed:.3g} s allowed (a higher "
                "speed or `speed max`, a smaller T, or a longer timeout=SECONDS)"
            )

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
