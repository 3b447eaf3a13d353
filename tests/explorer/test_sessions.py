"""Session scripts (issue 10, deliverable 7): the grammar, the player, the recorder, the CLI.

- ``parse`` reads any text to commands or raises ``ScriptError`` naming a line, never
  anything else (property tests); lines written by ``line``/``quote`` read back exactly;
- every command, replayed offscreen in a window, has its effect (the widget it sets, the
  run it changes, the file it writes), and a line that does not fit the scene is a
  script error at that line;
- ``python main.py open --session F --offscreen --exit`` exits 0, 1 or 2;
- a session recorded from a user's actions replays to the same script;
- the regression scripts in ``tests/explorer/sessions/`` (issue 10's problems) run
  through with the checks listed for each.
"""

from __future__ import annotations

import math
import os
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from explorer.session import Command, ScriptError, line, parse, quote, split, time_mark
from explorer.session.edits import edit_lines, form
from explorer.session.script import GRAMMAR

ROOT = Path(__file__).resolve().parents[2]
SESSIONS = Path(__file__).resolve().parent / "sessions"
SOURCE = "test.session"
REPLAY_MS = 60000


# -- the grammar (no Qt) ------------------------------------------------------------------------

WORDS = st.one_of(
    st.text(max_size=12),
    st.sampled_from(
        ['"', "'", "#", "=", "x=1", "a=", "=2", "\\", '"\\q"', "on", "off", "max", "auto"]
    ),
    st.sampled_from(["1", "-1", "0", "1e400", "nan", "inf", "0.5x", "2×", "p_x,x", "x,p_x"]),
    st.from_regex(r"[a-z_]{1,6}=[-+0-9.e]{0,6}", fullmatch=True),
)
LINES = st.one_of(
    st.text(),
    st.builds(
        lambda verb, words: " ".join([verb, *words]),
        st.sampled_from([*GRAMMAR, "RUN-UNTIL", "lauch", ""]),
        st.lists(WORDS, max_size=4),
    ),
)


@settings(max_examples=400, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(LINES, max_size=6).map("\n".join))
def test_any_text_parses_or_names_a_line(text):
    try:
        commands = parse(text, SOURCE)
    except ScriptError as exc:
        assert 1 <= exc.line <= text.count("\n") + 1
        assert str(exc) == f"{SOURCE}:{exc.line}: {exc.reason}"
        assert exc.reason and "\n" not in exc.reason
        return
    assert all(isinstance(c, Command) and c.verb in GRAMMAR for c in commands)
    assert [c.line for c in commands] == sorted({c.line for c in commands})
    # what a command writes reads back to the same command
    for command in commands:
        (again,) = parse(command.text())
        assert (again.verb, again.args, again.value) == (command.verb, command.args, command.value)


@settings(max_examples=300, deadline=None)
@given(st.lists(st.text(), max_size=5))
def test_quoted_words_read_back_exactly(words):
    assert split(" ".join(quote(w) for w in words)) == words


@settings(max_examples=200, deadline=None)
@given(st.floats(min_value=1e-300, max_value=1e300))
def test_time_marks_are_passed_by_the_time_they_mark(t):
    mark = float(time_mark(t))
    assert mark <= t
    assert mark >= t * (1 - 1e-5)


def test_a_script_with_every_command_reads_as_written():
    text = textwrap.dedent(
        """\
        # a teacher's demo
        open simple_pendulum        # from the catalogue

        set l 1.5
        parameters m=1 g=9.81 l=2*pi
        initial theta=2 theta_dot=0
        edit potential "-m*g*l*cos(theta) + 0.1 * theta**2"
        edit given-by lagrangian
        effect forces.theta off
        method yoshida4
        method auto
        dt 0.01
        dt auto
        speed 2x
        speed max
        energy-guard off
        section on
        pair theta2, p_theta2
        launch theta=0.5 p_theta=-2
        delete 2
        clear
        reset
        pause
        step
        play
        run-until 5 timeout=30
        wait 0.5
        tab "Hamilton's principle"
        export phase 'figures/phase #1.png'
        save out.toml
        new
        """
    )
    commands = parse(text, SOURCE)
    values = {c.verb: c.value for c in commands}
    assert commands[0] == Command("open", ("simple_pendulum",), 2, "simple_pendulum")
    assert values["set"] == ("l", 1.5)
    assert values["parameters"] == (("m", "1"), ("g", "9.81"), ("l", "2*pi"))
    assert values["edit"] == ("given-by", "lagrangian")
    assert values["effect"] == ("forces.theta", False)
    assert values["speed"] == math.inf and commands[11].value == 2.0
    assert values["dt"] is None and values["method"] is None
    assert values["pair"] == ("theta2", "p_theta2")
    assert values["launch"] == (("theta", 0.5), ("p_theta", -2.0))
    assert values["run-until"] == (5.0, 30.0)
    assert values["tab"] == "Hamilton's principle"
    assert values["export"] == ("phase", "figures/phase #1.png")
    assert [c.line for c in commands][-1] == 31


@pytest.mark.parametrize(
    ("text", "line_number", "words"),
    [
        ("open", 1, "usage: open SCENE"),
        ("open x\n\n  set l", 3, "usage: set PARAMETER VALUE"),
        ("set l one", 1, "the value of l must be a number, not 'one'"),
        ("lauch theta=1", 1, "unknown command 'lauch' (did you mean 'launch'?)"),
        ("dt 0", 1, "dt must be positive"),
        ("speed fast", 1, "the speed must be a number, not 'fast'"),
        ("section maybe", 1, "on or off"),
        ("pair theta", 1, "usage: pair Q,p_Q"),
        ("launch theta=1 theta=2", 1, "theta is given twice"),
        ("launch theta", 1, "'theta' is not NAME=VALUE"),
        ("run-until soon", 1, "the time T must be a number"),
        ("run-until 5 forever", 1, "usage: run-until T [timeout=SECONDS]"),
        ("delete 0", 1, "launched orbit's number"),
        ("edit weight 2", 1, "unknown field 'weight'"),
        ("edit given-by newton", 1, "edit given-by takes energies, lagrangian, hamiltonian"),
        ('# fine\nexport phase "a.png', 2, 'a quote " is not closed'),
        ('save "C:\\new\\x.toml"', 1, "unknown escape \\x"),
        ("clear now", 1, "usage: clear"),
        ("chaos-map 100", 1, "usage: chaos-map"),
        ("orbit-diagram A 1.1 1.0 10", 1, "LOW must be below HIGH"),
        ("orbit-diagram A 1 2 1", 1, "VALUES is a whole number from 2 to 5000, not '1'"),
        ("orbit-diagram A 1 2", 1, "usage: orbit-diagram PARAMETER LOW HIGH VALUES"),
    ],
)
def test_grammar_errors_name_the_line_and_the_reason(text, line_number, words):
    with pytest.raises(ScriptError) as caught:
        parse(text, "demo.session")
    assert caught.value.line == line_number
    assert str(caught.value).startswith(f"demo.session:{line_number}: ")
    assert words in caught.value.reason


def test_lines_are_written_for_reading_back():
    assert line("launch", "theta=0.5", "p_theta=2") == "launch theta=0.5 p_theta=2"
    assert line("set", "l", 2.0) == "set l 2"
    assert line("set", "l", 0.1) == "set l 0.1"
    assert line("edit", "title", 'My "best" pendulum') == r'edit title "My \"best\" pendulum"'
    assert line("tab", "#1") == 'tab "#1"'
    assert split(line("edit", "kinetic", "a +\n b")) == ["edit", "kinetic", "a +\n b"]
    # a # inside a word is no comment; one that starts a word is
    assert split("edit title Pendulum#2 # the second") == ["edit", "title", "Pendulum#2"]


def _pendulum_data(**changes) -> dict:
    data = {
        "title": "Simple pendulum",
        "system": {
            "coordinates": ["theta"],
            "parameters": {"m": 1.0, "g": 9.81, "l": 1.0},
            "kinetic": "m*l**2*theta_dot**2/2",
            "potential": "-m*g*l*cos(theta)",
        },
        "effects": {"dissipation": "b*theta_dot**2/2", "disabled": []},
        "initial": {"theta": 1.2, "theta_dot": 0.0},
    }
    for key, value in changes.items():
        target = data["system"] if key in data["system"] else data
        if key in ("dissipation", "disabled"):
            target = data["effects"]
        target[key] = value
    return data


def test_editor_edits_become_edit_initial_and_effect_lines():
    before = form(_pendulum_data())
    after = form(
        _pendulum_data(potential="-m*g*l*cos(theta)**3", initial={"theta": 2.0, "theta_dot": 0.0}),
        previous=before,
    )
    assert [text for _, text in edit_lines(before, after)] == [
        "edit potential -m*g*l*cos(theta)**3",
        "initial theta=2",
    ]
    # a parameter value alone is no edit (it goes out as `set`); a new name is
    renamed = form(_pendulum_data(parameters={"m": 2.0, "g": 9.81, "L": 1.0}), previous=before)
    assert [text for _, text in edit_lines(before, renamed)] == ["parameters m=2 g=9.81 L=1"]
    switched = form(_pendulum_data(disabled=["dissipation"]), previous=before)
    assert [text for _, text in edit_lines(before, switched)] == ["effect dissipation off"]
    # "Given by" switched to L and back: the T and V seen before are no new edit
    system = dict(_pendulum_data()["system"])
    del system["kinetic"], system["potential"]
    as_l = form({**_pendulum_data(), "system": {**system, "lagrangian": "L0"}}, previous=before)
    assert [text for _, text in edit_lines(before, as_l)] == [
        "edit given-by lagrangian",
        "edit lagrangian L0",
    ]
    back = form(_pendulum_data(), previous=as_l)
    assert [text for _, text in edit_lines(as_l, back)] == ["edit given-by energies"]
    drawn = form({**_pendulum_data(), "drawing": {"points": {"bob": ["x", "y"]}}}, previous=before)
    assert [text for _, text in edit_lines(before, drawn)] == [
        """edit drawing '{ points = { bob = ["x", "y"] } }'"""
    ]
    # "Given by" particles: the choice, the particles and gravity are lines a script replays
    bob = {"bob": {"mass": "m", "position": ["L*sin(theta)", "-L*cos(theta)"]}}
    system = dict(_pendulum_data()["system"])
    del system["kinetic"]
    system["gravity"] = ["0", "-g"]
    as_particles = form({**_pendulum_data(), "system": system, "particles": bob}, previous=before)
    assert [text for _, text in edit_lines(before, as_particles)] == [
        "edit given-by particles",
        'edit particles \'{ bob = { mass = "m", position = ["L*sin(theta)", "-L*cos(theta)"] } }\'',
        'edit gravity "[0, -g]"',
    ]


# -- replaying in a window ------------------------------------------------------------------------


def replay(qtbot, window, text: str, folder=None, recorder=None, expect=0):
    """Replay ``text`` in ``window`` until it ends; check its status; return the player."""
    from explorer.session import Player

    player = Player(window, parse(text, SOURCE), source=SOURCE, folder=folder, recorder=recorder)
    player.start()
    qtbot.waitUntil(lambda: player.status is not None, timeout=REPLAY_MS)
    assert player.status == expect, player.message
    return player


def _standing_still(qtbot, window, seconds: float = 5.0) -> float:
    """The main orbit's time once it stays put for 0.4 s (frames under way may land first);
    fails if it keeps moving for ``seconds``."""
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        before = window.store.main.last_t
        qtbot.wait(400)  # playing, a frame comes every 25 ms
        if window.store.main.last_t == before:
            return before
    raise AssertionError(f"the run did not stand still within {seconds} s")


def test_run_controls_replayed(qtbot, window):
    replay(qtbot, window, "method yoshida4\ndt 0.02\nspeed max\nenergy-guard 0.5\nrun-until 3")
    assert window.controls.method == "yoshida4"
    assert window.settings.method == "yoshida4" and window.settings.dt == 0.02
    assert window.settings.speed == math.inf and window.energy_tolerance == 0.5
    assert window.store.main.last_t >= 3 and window.store.main.method == "yoshida4"
    replay(qtbot, window, "speed 1\ndt auto\nmethod auto\nenergy-guard off\npause")
    assert window.settings.speed == 1.0 and window.settings.dt is None
    assert window.controls.method is None and window.energy_tolerance is None
    assert not window.controls.playing
    paused_at = _standing_still(qtbot, window)
    started = time.monotonic()
    replay(qtbot, window, "wait 0.4\nstep")
    assert time.monotonic() - started >= 0.4
    qtbot.waitUntil(lambda: window.store.main.last_t > paused_at, timeout=5000)
    assert not window.controls.playing
    replay(qtbot, window, f"play\nrun-until {window.store.main.last_t + 0.2}")
    assert window.controls.playing


def test_parameters_initial_state_and_fields_replayed(qtbot, window):
    replay(qtbot, window, "set l 1.5\ninitial theta=2 theta_dot=0.5")
    names = list(window.compiled.parameter_names)
    assert window.compiled.parameters[names.index("l")] == 1.5
    # the initial state was edited, so the system was rebuilt from the editor: l stays
    assert window.built.scene.parameter_values["l"] == 1.5
    theta, p_theta = window.store.main.y0
    assert theta == 2.0 and p_theta == pytest.approx(1.5**2 * 0.5)
    replay(qtbot, window, 'edit potential "-m*g*l*cos(theta) + theta**2/10"')
    assert window.built.scene.potential == "-m*g*l*cos(theta) + theta**2/10"
    lagrangian = "m*l**2*theta_dot**2/2 + m*g*l*cos(theta)"
    replay(
        qtbot,
        window,
        f'edit title "My pendulum"\nedit given-by lagrangian\nedit lagrangian "{lagrangian}"',
    )
    assert window.built.scene.title == "My pendulum"
    assert window.built.scene.lagrangian == lagrangian and window.built.scene.kinetic is None
    replay(qtbot, window, "parameters m=1 g=9.81 l=1.5 b=0.25")
    assert list(window.built.scene.parameter_values) == ["m", "g", "l", "b"]
    player = replay(qtbot, window, "\n\n\nset k 2", expect=2)
    assert player.message == f"{SOURCE}:4: unknown parameter 'k' (parameters: m, g, l, b)"
    player = replay(qtbot, window, "set l 0", expect=2)
    assert player.message.startswith(f"{SOURCE}:1: l = 0 refused")
    assert window.compiled.parameters[names.index("l")] == 1.5  # the refusal kept the value


def test_given_by_particles_replayed(qtbot, blank_window):
    """A scene given by particles: switching "Given by" away and back to particles is a
    line the script replays, and the particles typed before are kept."""
    # T is blank then: that build fails, and the script says so
    script = "open bead_on_rotating_hoop\nedit given-by energies\ndid-not-build"
    replay(qtbot, blank_window, script)
    assert blank_window.editor.kind_combo.currentData() == "energies"
    replay(qtbot, blank_window, "edit given-by particles")
    assert blank_window.editor.kind_combo.currentData() == "particles"
    from systems.scene import load_scene

    [bead] = load_scene("bead_on_rotating_hoop").particles
    particles = blank_window.editor.document()["particles"]
    assert particles[bead.name]["position"] == list(bead.position)


def test_effects_replayed(qtbot, blank_window):
    replay(qtbot, blank_window, "open damped_pendulum\neffect dissipation off")
    assert "dissipation" in blank_window.built.scene.disabled
    assert blank_window.built.compiled.mechanics.classification.conservative
    replay(qtbot, blank_window, 'edit dissipation "b*theta_dot**2"\neffect dissipation on')
    assert blank_window.built.scene.dissipation == "b*theta_dot**2"
    assert not blank_window.built.scene.disabled


def test_orbits_launched_deleted_cleared_and_reset(qtbot, window):
    replay(qtbot, window, "launch theta=0.5 p_theta=2\nlaunch theta=-1\nrun-until 0.5")
    store = window.store
    assert [t.key for t in store] == [0, 1, 2]
    assert list(store.trajectories[1].y0) == [0.5, 2.0]
    assert list(store.trajectories[2].y0) == [-1.0, window.phase_view.y0[1]]
    assert store.trajectories[1].last_t > 0
    replay(qtbot, window, "delete 1")
    assert [t.key for t in window.store] == [0, 2]
    player = replay(qtbot, window, "delete 1", expect=2)
    assert "no launched orbit 1 (launched orbits: 2)" in player.message
    old = window.store
    replay(qtbot, window, "reset")
    assert window.store is not old and len(window.store) == 2  # the launch is started again
    replay(qtbot, window, "clear")
    assert [t.key for t in window.store] == [0]
    player = replay(qtbot, window, "launch theta_dot=1 p_theta=1", expect=2)
    assert "give the velocities q_dot or the momenta p_q of a launch, not both" in player.message


def test_section_and_pair_replayed(qtbot, blank_window):
    window = blank_window
    replay(qtbot, window, "open henon_heiles\npair x,p_x")
    assert window.phase_view.index == 0 and window.phase_view.pair_combo.currentIndex() == 0
    replay(qtbot, window, "section on\nlaunch x=0 y=0.1 p_x=0.3 p_y=0.1\nrun-until 20")
    assert window.phase_view.mode == "poincare" and window.settings.section is not None
    assert len(window.store) == 2
    player = replay(qtbot, window, "pair x,p_x", expect=2)
    assert "while the Poincaré section is on" in player.message
    replay(qtbot, window, "section off\npair y,p_y")
    assert window.phase_view.mode == "phase" and window.phase_view.index == 1
    player = replay(qtbot, window, "pair r,p_r", expect=2)
    assert player.message.endswith("(pairs: x,p_x; y,p_y)")
    player = replay(qtbot, window, "open simple_pendulum\nsection on", expect=2)
    assert player.message.startswith(f"{SOURCE}:2: this system has no Poincaré section")


def test_files_and_tabs_replayed(qtbot, blank_window, tmp_path):
    window = blank_window
    script = "open double_pendulum\nrun-until 0.3\ntab equilibria\nexport phase phase.png\n"
    script += "export csv orbits.csv\nsave copy.toml"
    replay(qtbot, window, script, folder=tmp_path)
    tabs = window.textbook.tabs
    assert window.docks["textbook"].isVisible()
    assert tabs.tabText(tabs.currentIndex()).lower() == "equilibria"
    assert (tmp_path / "phase.png").read_bytes().startswith(b"\x89PNG")
    header = (tmp_path / "orbits.csv").read_text().splitlines()[0]
    assert "theta1" in header and "theta2" in header
    from systems.scene import load_scene

    assert load_scene(tmp_path / "copy.toml").coordinates == ("theta1", "theta2")
    replay(qtbot, window, "open simple_pendulum\nopen copy.toml\nrun-until 0.1", folder=tmp_path)
    assert window.built.scene.coordinates == ("theta1", "theta2")
    assert window.scene_path == (tmp_path / "copy.toml").resolve()
    player = replay(qtbot, window, "open missing.toml", folder=tmp_path, expect=2)
    assert player.message.startswith(f"{SOURCE}:1: not opened: ")
    assert "missing.toml" in player.message
    player = replay(qtbot, window, "tab nowhere", expect=2)
    assert "no tab 'nowhere'" in player.message and "equilibria" in player.message
    player = replay(qtbot, window, "export phase no/such/folder/x.png", folder=tmp_path, expect=2)
    assert player.message.startswith(f"{SOURCE}:1: could not export")
    player = replay(qtbot, window, "export sideways x.png", expect=2)
    assert "unknown panel 'sideways'" in player.message


def test_chaos_map_and_orbit_diagram_recorded_and_replayed(qtbot, blank_window, monkeypatch):
    from explorer.panels import chaos_map_layer, orbit_diagram_view
    from explorer.session import Recorder

    monkeypatch.setattr(chaos_map_layer, "GRID", 8)
    monkeypatch.setattr(chaos_map_layer, "T_END", 20.0)
    monkeypatch.setattr(orbit_diagram_view, "TRANSIENT_PERIODS", 5)
    window = blank_window
    recorder = Recorder(window)
    script = "open henon_heiles\nsection on\nchaos-map\n"
    replay(qtbot, window, script, recorder=recorder)
    layer = window.phase_view.map_layer
    assert layer.result is not None and layer.result.megno.shape == (8, 8)  # drawn before the end
    script = "open driven_damped_pendulum\norbit-diagram A 1.0 1.1 5"
    replay(qtbot, window, script, recorder=recorder)
    diagram = window.orbit_diagram_view.diagram
    assert diagram is not None and np.allclose(diagram.values, np.linspace(1.0, 1.1, 5))
    assert diagram.parameter == "A"
    assert "chaos-map" in recorder.lines and "orbit-diagram A 1 1.1 5" in recorder.lines
    player = replay(qtbot, window, "orbit-diagram B 1 2 5", expect=2)
    assert "no parameter 'B' to scan (parameters: " in player.message
    player = replay(qtbot, window, "chaos-map", expect=2)
    assert "turn it on first (`section on`)" in player.message


@pytest.mark.qt_no_exception_capture  # a missing piece fails at once, with its message
def test_new_scene_replayed(qtbot, window):
    before = window.editor.data()
    replay(qtbot, window, "new")
    assert window.editor.data() != before
    assert window.scene_path is None


def test_run_until_says_why_it_could_not_wait(qtbot, window):
    player = replay(qtbot, window, "method euler\ndt 0.1\nrun-until 1000", expect=2)
    assert player.message.startswith(f"{SOURCE}:3: the run stopped at t = ")
    assert "before t = 1000: energy_error" in player.message
    player = replay(qtbot, window, "reset\npause\nrun-until 1000", expect=2)
    assert "the simulation is paused at t = " in player.message
    script = "method auto\ndt auto\nplay\nspeed max\nrun-until 1e12 timeout=0.3"
    player = replay(qtbot, window, script, expect=2)
    assert "after waiting 0.3 s for t = 1e+12" in player.message
    # at a finite speed a time too far away for the time allowed is said at once
    player = replay(qtbot, window, "speed 0.1\nreset\nrun-until 1000 timeout=30", expect=2)
    assert "at speed 0.1, t = 1000 is " in player.message
    assert "beyond the 30 s allowed" in player.message


@pytest.mark.qt_no_exception_capture  # the window's ErrorReporter must see it, as in use
def test_an_exception_in_the_window_ends_the_replay_with_status_1(qtbot, window, monkeypatch):
    from explorer.panels.conserved_view import ConservedView

    def broken(self, store):
        if store.main.last_t > 0.5:
            raise RuntimeError("conserved view broken on purpose")

    monkeypatch.setattr(ConservedView, "refresh", broken)
    player = replay(qtbot, window, "reset\nrun-until 1000", expect=1)
    assert player.message.startswith(f"{SOURCE}:2: the application raised an exception")
    assert "RuntimeError: conserved view broken on purpose" in player.message
    assert "conserved view broken on purpose" in window.error_details
    monkeypatch.undo()


# -- recording ---------------------------------------------------------------------------------


def test_a_recorded_session_replays_to_the_same_script(qtbot, blank_window):
    from PySide6.QtCore import Qt

    from explorer.editor.parameters_table import VALUE
    from explorer.session import Recorder
    from explorer.session.recorder import TIME_MARK_SECONDS

    window = blank_window
    recorder = Recorder(window)
    window.open_scene("simple_pendulum")
    qtbot.waitUntil(lambda: window.compiled is not None, timeout=REPLAY_MS)
    controls, phase, editor = window.controls, window.phase_view, window.editor
    controls.method_combo.setCurrentIndex(controls.method_combo.findData("yoshida4"))
    controls.step_edit.setFocus()
    qtbot.keyClicks(controls.step_edit, "0.02")
    qtbot.keyClick(controls.step_edit, Qt.Key.Key_Return)
    controls.speed_combo.setCurrentIndex(5)
    table = editor.parameter_table
    for text in ("1.1", "1.2", "1.3"):  # a value typed, changed, changed again
        table.item(2, VALUE).setText(text)
    phase.launch_at(0.3, 1.0)
    qtbot.wait(int(1000 * TIME_MARK_SECONDS) + 300)  # the run goes on: a time mark comes
    # ... once the launched orbit has moved on (a busy machine may keep it waiting)
    qtbot.waitUntil(
        lambda: window.store.main is not None and window.store.main.last_t > 0.01,
        timeout=REPLAY_MS,
    )
    qtbot.mouseClick(controls.play_button, Qt.MouseButton.LeftButton)
    qtbot.mouseClick(controls.step_button, Qt.MouseButton.LeftButton)
    qtbot.mouseClick(controls.play_button, Qt.MouseButton.LeftButton)
    editor.initial_table.item(0, 1).setText("0.8")
    qtbot.waitUntil(lambda: window.store.main.y0[0] == 0.8, timeout=REPLAY_MS)
    qtbot.mouseClick(controls.clear_button, Qt.MouseButton.LeftButton)
    qtbot.mouseClick(controls.reset_button, Qt.MouseButton.LeftButton)
    editor.catalogue_selected.emit("henon_heiles")
    qtbot.waitUntil(lambda: window.built.scene.name == "henon_heiles", timeout=REPLAY_MS)
    phase.poincare_box.click()
    phase.launch_at(0.05, 0.1)
    phase.poincare_box.click()
    phase.pair_combo.setCurrentIndex(0)
    recorded = recorder.text()
    # the run went on between the actions: some are preceded by the time it had reached
    marks = [i for i, text in enumerate(recorded.splitlines()[1:]) if text.startswith("run-until")]
    lines = [text for text in recorded.splitlines()[1:] if not text.startswith("run-until")]
    assert lines[:4] == ["open simple_pendulum", "method yoshida4", "dt 0.02", "speed 5"]
    assert lines[4] == "set l 1.3" and lines[5].startswith("launch theta=0.3 p_theta=1")
    assert lines[6:] == [
        "pause",
        "step",
        "play",
        "initial theta=0.8",
        "clear",
        "reset",
        "open henon_heiles",
        "section on",
        lines[14],
        "section off",
        "pair x,p_x",
    ]
    assert lines[14].startswith("launch x=0 y=0.05 p_x=")
    launch = recorded.splitlines()[1:].index(lines[5])
    assert launch + 1 in marks  # the wait after the launch
    parse(recorded)  # it is a script

    second = type(window)()  # a window like the first, replaying instead of a user
    second.show()
    try:
        recorder_again = Recorder(second)
        replay(qtbot, second, recorded, recorder=recorder_again)
        assert recorder_again.text() == recorded
    finally:
        second.close()
        second.deleteLater()
        qtbot.wait(10)


# -- the command line ------------------------------------------------------------------------


def _main_py(tmp_path, script: str, prelude: str = "") -> subprocess.CompletedProcess:
    """``python main.py open --session demo.session --offscreen --exit`` in ``tmp_path``.

    ``prelude``: code run first in the same process (``main.py`` is then run by runpy).
    """
    (tmp_path / "demo.session").write_text(script, encoding="utf-8")
    arguments = ["open", "--session", "demo.session", "--offscreen", "--exit"]
    command = [sys.executable, str(ROOT / "main.py"), *arguments]
    if prelude:
        runner = f"import runpy, sys\nsys.argv = {['main.py', *arguments]!r}\n"
        runner += f"runpy.run_path({str(ROOT / 'main.py')!r}, run_name='__main__')\n"
        command = [sys.executable, "-c", prelude + runner]
    environment = {**os.environ, "PYTHONPATH": str(ROOT)}
    environment.pop("QT_QPA_PLATFORM", None)  # --offscreen sets it
    return subprocess.run(
        command, cwd=tmp_path, env=environment, capture_output=True, text=True, timeout=240
    )


def test_cli_replay_that_runs_through_exits_0(tmp_path):
    done = _main_py(tmp_path, "open simple_pendulum\nset l 1.2\nrun-until 0.3\nexport phase p.png")
    assert done.returncode == 0, done.stderr
    assert (tmp_path / "p.png").exists()


def test_cli_replay_with_an_exception_exits_1_with_the_traceback(tmp_path):
    prelude = (
        "from explorer.panels.conserved_view import ConservedView\n"
        "def refresh(self, store):\n"
        "    if store.main.last_t > 0.5:  # while line 2 runs\n"
        "        raise ZeroDivisionError('injected into the conserved view')\n"
        "ConservedView.refresh = refresh\n"
    )
    done = _main_py(tmp_path, "open simple_pendulum\nrun-until 100", prelude)
    assert done.returncode == 1, done.stderr
    assert "Traceback (most recent call last)" in done.stderr
    assert "ZeroDivisionError: injected into the conserved view" in done.stderr
    assert "demo.session:2: the application raised an exception" in done.stderr


def test_cli_replay_with_a_script_error_exits_2_naming_the_line(tmp_path):
    done = _main_py(tmp_path, "open simple_pendulum\nrun-until 0.1\n# k is no parameter\nset k 2\n")
    assert done.returncode == 2, done.stderr
    assert done.stderr.strip().splitlines()[-1] == (
        "demo.session:4: unknown parameter 'k' (parameters: m, g, l)"
    )


def test_cli_refuses_a_grammar_error_before_any_window(tmp_path, capsys, monkeypatch):
    import explorer.app
    from explorer.cli import main

    def no_window(*_args, **_kwargs):
        raise AssertionError("a window was started for a script that does not parse")

    for name in ("application", "run", "run_session", "create_window"):
        monkeypatch.setattr(explorer.app, name, no_window)
    monkeypatch.chdir(tmp_path)
    Path("demo.session").write_text("open simple_pendulum\nlaunch theta\n", encoding="utf-8")
    assert main(["open", "--session", "demo.session", "--offscreen", "--exit"]) == 2
    assert capsys.readouterr().err.strip() == (
        "demo.session:2: 'theta' is not NAME=VALUE (usage: launch NAME=VALUE ... (q, and "
        "q_dot or p_q))"
    )
    assert main(["open", "--session", "missing.session", "--exit"]) == 2
    assert "missing.session: cannot read the file" in capsys.readouterr().err
    assert main(["open", "--exit"]) == 2
    assert "--session" in capsys.readouterr().err


# -- regression scripts (issue 10) ---------------------------------------------------------------


def _phase_axes_name(window, q: str) -> None:
    from explorer.labels import coordinate_label

    bottom = window.phase_view.plot.getAxis("bottom").labelText
    assert coordinate_label(q) in bottom, bottom
    assert window.phase_view.pair_combo.currentText().startswith(coordinate_label(q))


def _check_section_switches(window) -> None:
    assert window.built.scene.name == "harmonic_oscillator"
    assert window.phase_view.mode == "phase"
    _phase_axes_name(window, window.built.scene.coordinates[0])
    assert len(window.store.main.y0) == 2


def _check_section_then_planetary(window) -> None:
    assert window.built.scene.name == "planetary_motion"
    assert window.phase_view.mode == "phase" and not window.phase_view.poincare_box.isChecked()
    _phase_axes_name(window, "r")
    assert window.settings.section is None


def _check_dt_not_carried(window) -> None:
    assert window.built.scene.name == "double_pendulum"
    assert window.controls.step_edit.text() == "" and window.settings.dt is None


def _check_stop_message_cleared(window) -> None:
    assert not window.statusBar().currentMessage().startswith("stopped")


def _check_planetary_then_pendulum(window) -> None:
    assert window.built.scene.name == "simple_pendulum"
    _phase_axes_name(window, "theta")


def _check_section_continues(window) -> None:
    assert window.phase_view.mode == "poincare"
    assert window.store.main.last_t >= 6000


REGRESSIONS = {
    "section_scene_switches": _check_section_switches,
    "section_then_planetary": _check_section_then_planetary,
    "dt_not_carried": _check_dt_not_carried,
    "stop_message_cleared": _check_stop_message_cleared,
    "planetary_then_one_coordinate": _check_planetary_then_pendulum,
    "section_run_continues": _check_section_continues,
}


def test_every_regression_script_has_its_checks():
    assert sorted(p.stem for p in SESSIONS.glob("*.session")) == sorted(REGRESSIONS)


@pytest.mark.qt_no_exception_capture  # the window's ErrorReporter must see them, as in use
@pytest.mark.parametrize("name", sorted(REGRESSIONS))
def test_regression_session(qtbot, blank_window, name):
    from explorer.session import Player, load

    path = SESSIONS / f"{name}.session"
    player = Player(blank_window, load(path), source=path.name, folder=SESSIONS)
    player.start()
    qtbot.waitUntil(lambda: player.status is not None, timeout=REPLAY_MS)
    assert player.status == 0, f"{player.message}\n{blank_window.error_details}"
    REGRESSIONS[name](blank_window)
    assert np.isfinite(blank_window.store.main.last_t)
