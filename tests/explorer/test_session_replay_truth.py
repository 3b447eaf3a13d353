"""Sessions record everything and never lie (issue 25, item 4).

- every kind of edit made in the editor (fields, initial state, parameters, given-by,
  particles, gravity, constraints, symmetries, drawing, view) is recorded as a line, and
  the recorded script replayed in another window gives the same document and the same
  built scene; a build that failed while recording is marked ``did-not-build``;
- a table written by a line reads back, and typed into the editor gives back the table
  it was recorded from (property tests);
- a replay whose build fails where the script expects it to build stops there with
  status 1, naming the line, and leaves every file that existed untouched (checksums);
- ``initial`` and ``launch`` take velocities as well as momenta;
- impossible paths are script errors (status 2); ``run-until`` a time the run cannot
  reach says so at once.
"""

from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from explorer.session import ScriptError, parse
from explorer.session.edits import table_line
from systems.scene import SCENES_DIR
from tests.explorer.test_sessions import REPLAY_MS, SOURCE, replay

ROOT = Path(__file__).resolve().parents[2]


# -- tables written as lines (no Qt) ---------------------------------------------------------

NAMES = st.from_regex(r"[A-Za-z_][A-Za-z0-9_]{0,6}", fullmatch=True)
KEYS = st.one_of(NAMES, st.text(max_size=6))
SCALARS = st.one_of(
    st.text(max_size=12),
    st.floats(allow_nan=False),
    st.integers(min_value=-(2**63), max_value=2**63 - 1),
    st.booleans(),
)
VALUES = st.recursive(
    SCALARS,
    lambda inner: st.one_of(st.lists(inner, max_size=3), st.dictionaries(KEYS, inner, max_size=3)),
    max_leaves=10,
)


@settings(max_examples=300, deadline=None)
@given(
    st.sampled_from(["particles", "constraints", "symmetries", "drawing", "view"]),
    st.one_of(st.none(), st.dictionaries(KEYS, VALUES, max_size=4)),
)
def test_a_table_line_reads_back_as_the_table(field, table):
    text = table_line(field, table)
    assert "\n" not in text
    (command,) = parse(text)
    assert command.verb == "edit"
    assert command.value == (field, table)


@pytest.mark.parametrize(
    ("text", "words"),
    [
        ("edit particles 3", "takes one TOML inline table"),
        ("edit drawing '{ points = '", "takes a TOML inline table"),
        ("open 'scene\0.toml'", "holds a NUL byte"),
        ("export phase 'a\0.png'", "holds a NUL byte"),
        ("save '\0'", "holds a NUL byte"),
        ("run-until 2\ndid-not-build", "did-not-build follows the line whose build failed"),
        ("did-not-build", "did-not-build follows the line whose build failed"),
        ("initial =1", "is not NAME=VALUE"),
    ],
)
def test_malformed_new_lines_are_script_errors(text, words):
    with pytest.raises(ScriptError) as caught:
        parse(text, SOURCE)
    assert words in caught.value.reason


# -- the editor takes back what it recorded --------------------------------------------------

EXPRESSIONS = st.sampled_from(["m", "2*m", "l*sin(q)", "-l*cos(q)", "x + y", "0", "k*x**2/2"])
PARTICLES = st.dictionaries(
    NAMES,
    st.fixed_dictionaries(
        {"mass": EXPRESSIONS, "position": st.lists(EXPRESSIONS, min_size=2, max_size=3)}
    ),
    max_size=3,
)
CONSTRAINTS = st.dictionaries(
    st.sampled_from(["holonomic", "nonholonomic", "unilateral"]),
    st.lists(EXPRESSIONS, min_size=1, max_size=2),
    max_size=3,
)
SYMMETRIES = st.dictionaries(NAMES, st.dictionaries(st.sampled_from(["x", "y"]), EXPRESSIONS))
DRAWINGS = st.one_of(
    st.none(),
    st.fixed_dictionaries(
        {
            "points": st.dictionaries(
                NAMES, st.lists(EXPRESSIONS, min_size=2, max_size=2), min_size=1
            )
        },
        optional={
            "links": st.lists(st.lists(NAMES, min_size=2, max_size=2), min_size=1, max_size=3),
            "trace": st.lists(NAMES, min_size=1, max_size=2),
        },
    ),
)
VIEWS = st.dictionaries(
    st.sampled_from(["t_end", "phase", "ranges"]),
    st.one_of(st.floats(1, 100), st.lists(NAMES, min_size=2, max_size=2)),
)
TABLES = st.one_of(
    st.tuples(st.just("particles"), PARTICLES),
    st.tuples(st.just("constraints"), CONSTRAINTS),
    st.tuples(st.just("symmetries"), SYMMETRIES),
    st.tuples(st.just("drawing"), DRAWINGS),
    st.tuples(st.just("view"), VIEWS),
    st.tuples(st.just("gravity"), st.sampled_from(["", "g", "[0, -g]", "[0, 0, -g]", "[g]"])),
)


@pytest.fixture
def editor(qtbot):
    """A system editor on a scene of two coordinates, given by particles, alone."""
    from explorer.editor.editor_panel import SystemEditorPanel

    panel = SystemEditorPanel()
    qtbot.addWidget(panel)
    panel.show_document(
        'title = "two"\n[system]\ncoordinates = ["x", "y"]\nparameters = { m = 1.0 }\n'
        'potential = "0"\n[particles]\nbob = { mass = "m", position = ["x", "y"] }\n'
    )
    yield panel
    panel.shutdown()


def _document_part(panel, key):
    document = panel.document()
    if key == "gravity":
        from explorer.session.edits import gravity_text

        return gravity_text(document["system"].get("gravity"))
    return document.get(key) or None


@settings(
    max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(TABLES)
def test_a_recorded_table_typed_into_the_editor_gives_itself_back(editor, key_table):
    """What the editor holds after a table is typed in, written as a line and typed in
    again, is the same: a recorded line reproduces the document it was recorded from."""
    key, table = key_table
    editor.replace_table(key, table)
    shown = _document_part(editor, key)
    if key != "gravity":
        assert shown == (table or None)  # these tables are as the editor writes them
    else:
        assert shown == table
    (command,) = parse(table_line(key, shown) if key != "gravity" else f"edit gravity '{shown}'")
    editor.replace_table(key, command.value[1])
    assert _document_part(editor, key) == shown
    assert editor.debounce.isActive()  # one edit, to be built
    editor.debounce.stop()


# -- the round trip: a user's edits recorded, then replayed ------------------------------------


def _settle(qtbot, window) -> str:
    """Take the edit now and wait for its build; "built" or "failed"."""
    editor = window.editor
    editor.flush()
    qtbot.waitUntil(
        lambda: not window._opening and editor.build_status != "pending", timeout=REPLAY_MS
    )
    return editor.build_status


def _type(field, text: str) -> None:
    """Type ``text`` over an expression field, as the user does (the field says edited)."""
    field.set_text(text)
    field.edited.emit()


@pytest.mark.qt_no_exception_capture  # the window's ErrorReporter must see them, as in use
def test_every_kind_of_edit_is_recorded_and_replays_to_the_same_scene(
    qtbot, blank_window, tmp_path
):
    from explorer.editor.parameters_table import VALUE
    from explorer.session import Recorder

    window = blank_window
    recorder = Recorder(window)
    # a scene file of the user's with a view setting that does not fit its system
    text = (SCENES_DIR / "cartesian_pendulum.toml").read_text(encoding="utf-8")
    path = tmp_path / "pendulum.toml"
    path.write_text(text.replace('phase = ["x", "p_x"]', 'phase = ["w", "p_w"]'), "utf-8")
    window.open_file(path)
    assert _settle(qtbot, window) == "built"
    editor = window.editor
    outcomes = []
    editor.remove_unfit_view()  # the warning's link: [view] loses `phase`
    outcomes.append(_settle(qtbot, window))
    editor.title_edit.setText("A bowl")
    editor.title_edit.textEdited.emit("A bowl")
    outcomes.append(_settle(qtbot, window))
    rows = {editor.initial_table.item(r, 0).text(): r for r in range(4)}
    editor.initial_table.item(rows["x_dot"], 1).setText("0.5")
    outcomes.append(_settle(qtbot, window))
    editor.initial_table.item(rows["y_dot"], 0).setText("p_y")  # a velocity made a momentum
    editor.initial_table.item(rows["y_dot"], 1).setText("0.25")
    outcomes.append(_settle(qtbot, window))
    editor.parameter_table.add_parameter("k", 2.0)
    outcomes.append(_settle(qtbot, window))
    editor.parameter_table.item(3, VALUE).setText("3")  # a value: `set`, no rebuild
    _type(editor.constraints.lists["holonomic"].fields[0], "x**2 + y**2 - l**2*k/k")
    outcomes.append(_settle(qtbot, window))
    editor.symmetries.add_symmetry("turn", x="-y", y="x")
    outcomes.append(_settle(qtbot, window))
    editor.drawing.add_point("pin", "0", "0.5")
    outcomes.append(_settle(qtbot, window))
    editor.kind_combo.setCurrentIndex(editor.kind_combo.findData("particles"))
    outcomes.append(_settle(qtbot, window))  # no particles yet: T is missing
    editor.particles.add_particle("bob", "m", ("x", "y"))
    outcomes.append(_settle(qtbot, window))
    _type(editor.particles.gravity, "[0, -gee]")  # gee is no parameter (yet)
    outcomes.append(_settle(qtbot, window))
    editor.parameter_table.add_parameter("gee", 9.81)
    outcomes.append(_settle(qtbot, window))
    _type(editor.fields["potential"], "k*(x**2 + y**2)/20")
    outcomes.append(_settle(qtbot, window))
    _type(editor.dissipation, "m*(x_dot**2 + y_dot**2)/100")
    outcomes.append(_settle(qtbot, window))
    editor.dissipation_switch.setChecked(False)
    outcomes.append(_settle(qtbot, window))
    assert outcomes.count("failed") >= 2 and outcomes[-1] == "built", outcomes
    recorded = recorder.text()
    lines = recorded.splitlines()[1:]
    for start in (
        f"open {path}",
        "edit view '{",
        "edit title",
        "initial x_dot=0.5",
        "initial p_y=0.25",
        "parameters ",
        "set k 3",
        "edit constraints '{ holonomic = [\"x**2 + y**2 - l**2*k/k\"] }'",
        'edit symmetries \'{ turn = { x = "-y", y = "x" } }\'',
        "edit drawing '{",
        "edit given-by particles",
        'edit particles \'{ bob = { mass = "m", position = ["x", "y"] } }\'',
        'edit gravity "[0, -gee]"',
        "edit potential",
        "edit dissipation",
        "effect dissipation off",
    ):
        assert any(text.startswith(start) for text in lines), (start, recorded)
    assert not any(text.startswith("# not recorded") for text in lines), recorded
    # each build that failed is marked right after the line that asked for it
    marks = [i for i, text in enumerate(lines) if text.startswith("did-not-build")]
    assert len(marks) == outcomes.count("failed"), recorded
    assert lines[marks[0] - 2 : marks[0]] == ["edit given-by particles", "edit particles '{}'"]
    assert lines[marks[1] - 1] == 'edit gravity "[0, -gee]"'

    second = type(window)()
    second.show()
    try:
        recorder_again = Recorder(second)
        replay(qtbot, second, recorded, folder=tmp_path, recorder=recorder_again)
        assert second.editor.document() == editor.document()
        assert second.built.scene.to_toml() == window.built.scene.to_toml()
        parameters = dict(
            zip(second.compiled.parameter_names, second.compiled.parameters, strict=True)
        )
        assert parameters["k"] == 3.0
        assert recorder_again.text().count("did-not-build") == len(marks)
    finally:
        second.close()
        second.deleteLater()
        qtbot.wait(10)


def test_a_velocity_where_the_table_has_a_momentum_and_back(qtbot, window):
    """``initial`` takes q_dot or p_q whichever the table lists (the issue: a session with a
    typed coordinate replayed ``initial u=... u_dot=...`` as an error)."""
    replay(qtbot, window, "initial theta=0.5 p_theta=0.2")
    assert dict(window.built.scene.initial) == {"theta": 0.5, "p_theta": 0.2}
    assert list(window.store.main.y0) == [0.5, 0.2]
    replay(qtbot, window, "initial theta_dot=2")
    assert dict(window.built.scene.initial) == {"theta": 0.5, "theta_dot": 2.0}
    assert window.store.main.y0[1] == pytest.approx(2.0)  # m l^2 theta_dot, m = l = 1
    replay(
        qtbot,
        window,
        "edit coordinates u\nedit kinetic m*l**2*u_dot**2/2\n"
        "edit potential -m*g*l*cos(u)\ninitial u=1 u_dot=0.5",
    )
    assert dict(window.built.scene.initial) == {"u": 1.0, "u_dot": 0.5}
    player = replay(qtbot, window, "initial w_dot=1", expect=2)
    assert "unknown initial value 'w_dot'" in player.message


@settings(
    max_examples=15, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(st.floats(-3, 3), st.floats(-10, 10))
def test_launch_takes_velocities(qtbot, window, theta, theta_dot):
    """A launch from q and q_dot starts at p = dL/dq_dot: m l^2 q_dot for the pendulum."""
    before = len(window.store)
    replay(qtbot, window, f"launch theta={theta!r} theta_dot={theta_dot!r}")
    trajectory = window.store.trajectories[max(t.key for t in window.store)]
    assert len(window.store) == before + 1
    assert trajectory.y0[0] == theta
    assert trajectory.y0[1] == pytest.approx(theta_dot, abs=1e-12)


def test_a_launch_from_a_velocity_keeps_the_other_velocities(qtbot, blank_window):
    window = blank_window
    replay(qtbot, window, "open double_pendulum")
    compiled = window.compiled
    y0 = window.phase_view.y0.copy()
    qdot = compiled.velocities(0.0, y0[None, :])[0]
    replay(qtbot, window, "launch theta1=0.1 theta1_dot=0.7")
    state = window.store.trajectories[max(t.key for t in window.store)].y0
    again = compiled.velocities(0.0, state[None, :])[0]
    assert state[0] == 0.1 and state[1] == y0[1]
    assert again[0] == pytest.approx(0.7) and again[1] == pytest.approx(qdot[1])


# -- a replay that cannot do what the script says: status 1, nothing written ---------------------


def _main_py(folder: Path, script: str) -> subprocess.CompletedProcess:
    """``python main.py open --session demo.session --offscreen --exit`` in ``folder``."""
    (folder / "demo.session").write_text(script, encoding="utf-8")
    command = [
        sys.executable,
        str(ROOT / "main.py"),
        *["open", "--session", "demo.session", "--offscreen", "--exit"],
    ]
    environment = {**os.environ, "PYTHONPATH": str(ROOT)}
    environment.pop("QT_QPA_PLATFORM", None)  # --offscreen sets it
    return subprocess.run(
        command, cwd=folder, env=environment, capture_output=True, text=True, timeout=600
    )


def _checksums(folder: Path) -> dict[str, str]:
    return {
        p.name: hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(folder.iterdir())
        if p.is_file() and p.name != "demo.session"
    }


@pytest.mark.parametrize(
    ("script", "line"),
    [
        # an edit that does not build, unmarked, then the user's files written over
        (
            'open scene.toml\nrun-until 0.2\nedit kinetic "m*x_dot**2/"\n'
            "save scene.toml\nexport phase phase.png\nexport csv orbits.csv\n",
            3,
        ),
        # the session: particles were "not recorded", the rest ran on the template
        (
            "new\nedit title Bead\nedit given-by particles\n"
            "# not recorded: particles edited in the editor (do it again after this line)\n"
            "save scene.toml\nexport phase phase.png\nexport csv orbits.csv\n",
            3,
        ),
    ],
)
def test_a_replay_whose_build_fails_exits_1_and_writes_nothing(tmp_path, script, line):
    shutil.copy(SCENES_DIR / "harmonic_oscillator.toml", tmp_path / "scene.toml")
    (tmp_path / "phase.png").write_bytes(b"\x89PNG the user's own figure")
    (tmp_path / "orbits.csv").write_text("t,x\n0,1\n", encoding="utf-8")
    before = _checksums(tmp_path)
    done = _main_py(tmp_path, script)
    assert done.returncode == 1, done.stderr
    last = done.stderr.strip().splitlines()[-1]
    assert last.startswith(f"demo.session:{line}: did not build: "), done.stderr
    assert "the replay stops here" in last
    assert _checksums(tmp_path) == before


def test_a_failure_marked_did_not_build_is_replayed_through(qtbot, blank_window, tmp_path):
    script = (
        "open harmonic_oscillator\n"
        'edit kinetic "m*x_dot**2/"\n'
        'did-not-build "system.kinetic: invalid syntax"\n'
        'edit kinetic "m*x_dot**2/2"\n'
        "save fixed.toml\n"
    )
    player = replay(qtbot, blank_window, script, folder=tmp_path)
    assert player.status == 0
    from systems.scene import load_scene

    assert load_scene(tmp_path / "fixed.toml").kinetic == "m*x_dot**2/2"
    # a line marked as failing that builds now is said, and the replay goes on
    notes = []
    from explorer.session import Player

    player = Player(blank_window, parse("edit title T\ndid-not-build", SOURCE), source=SOURCE)
    player.noted.connect(notes.append)
    player.start()
    qtbot.waitUntil(lambda: player.status is not None, timeout=REPLAY_MS)
    assert player.status == 0
    assert any("line 1 built in this replay, though the build failed" in n for n in notes)


# -- impossible paths and times ------------------------------------------------------------------


def test_a_path_with_a_nul_byte_is_a_script_error_before_any_window(tmp_path):
    done = _main_py(tmp_path, "open simple_pendulum\nsave 'scene\0.toml'\n")
    assert done.returncode == 2, done.stderr
    assert "demo.session:2: " in done.stderr and "NUL byte" in done.stderr


def test_a_home_folder_of_no_user_is_a_script_error(qtbot, window, tmp_path):
    player = replay(qtbot, window, "export phase ~no_such_user_here/x.png", expect=2)
    assert player.message.startswith(f"{SOURCE}:1: ")
    assert "cannot be a path" in player.message


def test_run_until_past_the_end_of_a_section_run_says_so_at_once(qtbot, blank_window):
    script = "open henon_heiles\nsection on\nrun-until 1e9"
    player = replay(qtbot, blank_window, script, expect=2)
    assert player.message.startswith(f"{SOURCE}:3: the run ends at t = ")
    assert blank_window.store.main.last_t < 1e9


@pytest.mark.qt_no_exception_capture  # the window's ErrorReporter must see them, as in use
def test_the_mark_follows_the_line_that_asked_for_the_build(qtbot, blank_window):
    """A line recorded while a build is derived (the speed changed meanwhile) does not
    take the ``did-not-build`` of the edit before it; the script replays through."""
    from explorer.session import Recorder

    window = blank_window
    recorder = Recorder(window)
    window.open_scene("simple_pendulum")
    qtbot.waitUntil(lambda: window.compiled is not None, timeout=REPLAY_MS)
    editor = window.editor
    _type(editor.fields["kinetic"], "m*l**2*theta_dot**2/")
    editor.flush()  # the build is asked for now; it fails later
    window.controls.speed_combo.setCurrentIndex(window.controls.speed_combo.count() - 1)
    qtbot.waitUntil(lambda: editor.build_status == "failed", timeout=REPLAY_MS)
    lines = [text for text in recorder.lines if not text.startswith("run-until")]
    assert lines[0] == "open simple_pendulum"
    assert lines[1] == "edit kinetic m*l**2*theta_dot**2/"
    assert lines[2].startswith('did-not-build "<editor>: system.kinetic: ')
    assert lines[3:] == ["speed max"]
    second = type(window)()
    second.show()
    try:
        replay(qtbot, second, recorder.text())
        assert second.editor.build_status == "failed"
        assert second.built.scene.kinetic == "m*l**2*theta_dot**2/2"  # the last that built
    finally:
        second.close()
        second.deleteLater()
        qtbot.wait(10)
