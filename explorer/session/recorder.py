"""The recorder: what the user does in the window, one session line per action.

``Recorder(window)`` listens to the widgets' own signals (the run controls, the phase
view, the editor, the parameter table) and to ``window.acted``, which the window emits
for the actions it handles itself (open, new, save, export, delete, tab, energy guard).
``text()`` is the script; File > Save session writes it.

Two kinds of line are not a signal's:

- **Time.** Before an action taken while the simulation plays, at least
  ``TIME_MARK_SECONDS`` of wall time after the previous line, a ``run-until T`` line is
  written with the time the main orbit had reached (rounded down), so that a replay acts
  at the same point of the run.
- **Replayed script lines.** While a ``Player`` replays a script (``replaying``), no time
  is marked; the player hands over the lines that are no user action (``run-until``,
  ``wait``) through ``note``. A replayed session therefore records the same script again.

Lines that follow each other and set the same thing (a dragged slider, a field typed
letter by letter) are kept as the last one only.

A build that fails is marked: ``did-not-build REASON`` goes right after the line that asked
for it (``open``, ``new``, an edit...), even if other lines were written while it was
being derived. A replay then knows which builds must fail, and that every other one
must succeed.
"""

from __future__ import annotations

import math
import time

import numpy as np
from PySide6.QtCore import QObject, QTimer, Signal

from explorer.session.edits import edit_lines, form
from explorer.session.script import BUILDING_VERBS, line, number, time_mark

TIME_MARK_SECONDS = 1.0
HEADER = "# Phase Explorer session: replay with `python main.py open --session FILE`"


class Recorder(QObject):
    """Turns a window's user actions into session lines.

    Signals
    -------
    recorded(str)   a line was added (or replaced the last one); its text

    Attributes
    ----------
    lines : list of str
        The script so far, without the header.
    replaying : bool
        Set by a ``Player`` while it replays: no time marks (it notes its own).
    """

    recorded = Signal(str)

    def __init__(self, window, parent: QObject | None = None):
        super().__init__(parent if parent is not None else window)
        self.window = window
        self.lines: list[str] = []
        self.replaying = False
        self._key: tuple | None = None  # what the last line sets, if a new one may replace it
        self._last_wall = -math.inf
        self._mark_store: int | None = None  # id of the store the last time mark was for
        self._mark_t = 0.0
        self._values: dict[str, float] = {}
        self._step = window.controls.step_value
        self._form: dict | None = None
        self._asked: int | None = None  # the index of the last line that may ask for a build
        self._reset_form()
        controls = window.controls
        controls.method_changed.connect(self._on_method_changed)
        controls.step_changed.connect(self._on_step_changed)
        controls.speed_changed.connect(self._on_speed_changed)
        controls.play_toggled.connect(self._on_play_toggled)
        controls.single_step_requested.connect(self._on_single_step_requested)
        controls.reset_requested.connect(self._on_reset_requested)
        controls.clear_requested.connect(self._on_clear_requested)
        phase = window.phase_view
        phase.mode_changed.connect(self._on_phase_mode_changed)
        phase.pair_combo.currentIndexChanged.connect(self._on_pair_index_changed)
        phase.launch_requested.connect(self._on_launch_requested)
        phase.map_layer.started.connect(self._on_chaos_map_started)
        phase.fill_layer.started.connect(self._on_section_fill_started)
        window.orbit_diagram_view.started.connect(self._on_orbit_diagram_started)
        editor = window.editor
        editor.parameters_changed.connect(self._on_parameters_changed)
        editor.scene_edited.connect(self._on_scene_edited)
        window.builder.build_failed.connect(self._on_build_failed)
        window.builder.built.connect(self._on_built)
        window.system_started.connect(self._on_system_started)
        acted = getattr(window, "acted", None)
        if acted is not None:
            acted.connect(self._on_window_acted)

    # -- the script -------------------------------------------------------------------------

    def text(self) -> str:
        """The session script: a header comment and one line per action."""
        return "\n".join([HEADER, *self.lines]) + "\n"

    def record(self, text: str, key: tuple | None = None, timed: bool | None = None) -> None:
        """Add a line (or replace the last one if it has the same non-None ``key``).

        ``timed``: whether the run was playing until this action (default: whether it
        plays now); then a ``run-until`` may be marked before the line.
        """
        if timed is None:
            timed = self.window.controls.playing
        if timed and not self.replaying:
            self._mark_time()
        if key is not None and key == self._key and self.lines:
            self.lines[-1] = text
        else:
            self.lines.append(text)
        if text.split(" ", 1)[0] in BUILDING_VERBS and not text.startswith("set "):
            self._asked = len(self.lines) - 1  # (a `set` asks only to retry a failed build)
        self._key = key
        self._last_wall = time.monotonic()
        self.recorded.emit(text)

    def note(self, text: str) -> None:
        """A line of a replayed script that is no user action (``run-until``, ``wait``)."""
        self.lines.append(text)
        self._key = None
        self._last_wall = time.monotonic()
        self.recorded.emit(text)

    def _mark_time(self) -> None:
        store = self.window.store
        main = store.main
        if main is None or time.monotonic() - self._last_wall < TIME_MARK_SECONDS:
            return
        t = main.last_t
        if not math.isfinite(t) or t <= 0:
            return
        mark = time_mark(t)
        same_run = self._mark_store == id(store)
        if float(mark) <= 0 or (same_run and float(mark) <= self._mark_t):
            return
        self._mark_store, self._mark_t = id(store), float(mark)
        self.lines.append(line("run-until", mark))
        self._key = None
        self.recorded.emit(self.lines[-1])

    # -- the editor's document ----------------------------------------------------------------

    def _editor_form(self, data: dict | None = None, previous: dict | None = None) -> dict:
        editor = self.window.editor
        if data is None:
            data = editor.data()
        kind = editor.kind_combo.currentData() if hasattr(editor, "kind_combo") else None
        return form(data, kind, previous)

    def _reset_form(self) -> None:
        """Take what the editor shows now as the state edits are compared with."""
        self._form = self._editor_form()

    def _on_scene_edited(self, data: dict) -> None:
        after = self._editor_form(data, self._form)
        before, self._form = self._form, after
        if before is None or getattr(self.window, "_fresh_next", False):
            return  # a scene opened or a new one fills the editor: its line says so
        for key, text in edit_lines(before, after):
            self.record(text, key)

    def _on_build_failed(self, failure) -> None:
        # an opened file that did not build puts the editor back as it was; an edit that
        # did not build leaves it as typed: either way what it shows is the state now
        debounce = getattr(self.window.editor, "debounce", None)
        if debounce is None or not debounce.isActive():
            self._reset_form()
        if self._asked is None:
            return  # a build no line asked for (the scene a replay starts on)
        at, self._asked = self._asked + 1, None
        self.lines.insert(at, line("did-not-build", failure.message))
        if at == len(self.lines) - 1:
            self._key = None  # the next edit of the same field is a line of its own
        self.recorded.emit(self.lines[at])

    def _on_built(self, _built) -> None:
        self._asked = None

    # -- window and widget signals --------------------------------------------------------------

    def _on_window_acted(self, text: str) -> None:
        verb = text.split(" ", 1)[0]
        self.record(text)
        if verb in ("open", "new"):
            # the window says so before it fills the editor, or (File > Open) after, while
            # ``_fresh_next`` marks the filling: what the editor shows then is no edit of
            # the user's, only what later edits are compared with
            self._form = None
            QTimer.singleShot(0, self, self._reset_form)

    def _on_system_started(self, built) -> None:
        compiled = built.compiled
        names, values = compiled.parameter_names, map(float, compiled.parameters)
        self._values = dict(zip(names, values, strict=True))
        self._step = self.window.controls.step_value

    def _on_method_changed(self, name) -> None:
        self.record(line("method", name or "auto"))
        self._step = self.window.controls.step_value  # a new kind of step clears the field

    def _on_step_changed(self, value) -> None:
        if value == self._step:
            return  # the field lost focus without a change
        self._step = value
        self.record(line("dt", "auto" if value is None else float(value)))

    def _on_speed_changed(self, speed: float) -> None:
        self.record(line("speed", "max" if math.isinf(speed) else float(speed)))

    def _on_play_toggled(self, playing: bool) -> None:
        self.record("play" if playing else "pause", timed=not playing)

    def _on_single_step_requested(self) -> None:
        self.record("step")

    def _on_reset_requested(self) -> None:
        self.record("reset")

    def _on_clear_requested(self) -> None:
        self.record("clear")

    def _on_phase_mode_changed(self, mode: str) -> None:
        self.record(line("section", "on" if mode == "poincare" else "off"))

    def _on_pair_index_changed(self, index: int) -> None:
        scene = self.window.phase_view.scene
        if scene is None or not 0 <= index < len(scene.coordinates):
            return
        q = scene.coordinates[index]
        self.record(line("pair", f"{q},p_{q}"))

    def _on_launch_requested(self, state) -> None:
        compiled = self.window.phase_view.compiled
        if compiled is None:
            return
        coordinates = compiled.mechanics.scene.coordinates
        names = [*coordinates, *(f"p_{q}" for q in coordinates)]
        values = np.asarray(state, dtype=float)
        words = [f"{name}={number(v)}" for name, v in zip(names, values, strict=True)]
        self.record(line("launch", *words))

    def _on_chaos_map_started(self) -> None:
        self.record("chaos-map")

    def _on_section_fill_started(self, count: int) -> None:
        self.record(line("section-fill", count))

    def _on_orbit_diagram_started(self, parameter: str, low: float, high: float, count: int):
        self.record(line("orbit-diagram", parameter, number(low), number(high), count))

    def _on_parameters_changed(self, values: dict) -> None:
        for name, value in values.items():
            if self._values.get(name) != value:
                self._values[name] = float(value)
                self.record(line("set", name, float(value)), key=("set", name))
                if self.window.editor.build_status == "failed":
                    self._asked = len(self.lines) - 1  # the editor builds it again
