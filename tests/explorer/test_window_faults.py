"""The window never hides an error or hangs (issue 11, deliverable 7).

- a bad file opened from the catalogue or File > Open is reported in the window (status
  bar and editor), the running scene goes on untouched, and nothing reaches stderr;
- a parameter value that is not finite, or that makes the equations singular (l = 0), is
  refused in the editor with the reason, and the previous value stays in force;
- closing returns within a second in every state (a derivation, numba compiling in a
  child process, running at full speed) and leaves no thread or child process behind;
- an unexpected exception in a slot or a thread is shown in the status bar, with its
  traceback behind "Details…", and the system keeps running.
"""

from __future__ import annotations

import os
import threading
import time
from pathlib import Path

import pytest

from systems.scene import SCENES_DIR
from tests.explorer.conftest import wait_for_points

# -- helpers -----------------------------------------------------------------------------------


def _scene_text(name: str) -> str:
    return (SCENES_DIR / f"{name}.toml").read_text(encoding="utf-8")


def _children(grace: float = 5.0) -> list[tuple[int, str, str]]:
    """(pid, state, command line) of every descendant process of this one but the fork
    server of ``systems.processes`` and multiprocessing's resource tracker (started
    once, kept), from /proc; ended workers may
    take a moment to be reaped, so this waits up to ``grace`` seconds for none."""
    proc = Path("/proc")
    if not (proc / "self" / "stat").exists():
        pytest.skip("needs /proc to list child processes")
    end = time.monotonic() + grace
    while True:
        found = _descendants(proc)
        if not found or time.monotonic() > end:
            return found
        time.sleep(0.05)


def _descendants(proc: Path) -> list[tuple[int, str, str]]:
    parents: dict[int, tuple[int, str, str]] = {}
    for stat in proc.glob("[0-9]*/stat"):
        try:
            text = stat.read_text()
            fields = text.rsplit(")", 1)[1].split()
            cmdline = (stat.parent / "cmdline").read_bytes().replace(b"\0", b" ").decode()
        except (OSError, ValueError, IndexError):
            continue  # it ended while being read
        parents[int(stat.parent.name)] = (int(fields[1]), fields[0], cmdline.strip())
    mine = {os.getpid()}
    found = []
    grew = True
    while grew:
        grew = False
        for pid, (parent, state, cmdline) in parents.items():
            if parent in mine and pid not in mine:
                mine.add(pid)
                grew = True
                kept = "multiprocessing.forkserver" in cmdline or "resource_tracker" in cmdline
                if not kept and state != "Z":
                    found.append((pid, state, cmdline))
    return found


def _threads_left(before: set[int], grace: float = 0.5) -> list[str]:
    """Python threads started since ``before`` (idents) that are still alive."""
    deadline = time.monotonic() + grace  # a daemon timer may need a moment to see its stop
    while True:
        left = [t for t in threading.enumerate() if t.ident not in before and t.is_alive()]
        if not left or time.monotonic() > deadline:
            return [t.name for t in left]
        time.sleep(0.02)


def _numba_warm(qtbot) -> None:
    """Let numba's once-per-process warm-up (started at the first frame) end: closing
    waits for it within its second but never interrupts it (numba cut short in an import
    is broken for the rest of the process), and on a loaded machine it can take longer."""
    from systems.integrators.warmup import numba_is_warm

    qtbot.waitUntil(numba_is_warm, timeout=30000)


def _timed_close(win) -> float:
    """Close ``win``; the time is printed (``-s``), never asserted: a shared machine's
    wall clock decides nothing here. The tests assert instead that everything the window
    started has ended when ``close`` returns: its threads and its processes."""
    start = time.perf_counter()
    win.close()
    seconds = time.perf_counter() - start
    print(f"closing took {seconds:.3f} s")  # shown with -s, for the record
    return seconds


@pytest.fixture
def open_window(qtbot):
    """``open_window()`` -> a new window on the pendulum, shown; closed after the test."""
    from explorer.app import create_window

    windows = []

    def make():
        win = create_window("simple_pendulum")
        win.show()
        windows.append(win)
        return win

    yield make
    for win in windows:
        win.close()  # a no-op for a window the test closed
        win.deleteLater()
    qtbot.wait(10)


def _still_running(qtbot, win) -> None:
    """The window's system is still being integrated: its time moves on."""
    assert win.runner is not None and win.runner.running
    t = win.store.main.last_t
    qtbot.waitUntil(lambda: win.store.main.last_t > t, timeout=5000)


@pytest.fixture
def bad_files(tmp_path) -> dict[str, Path]:
    kepler = _scene_text("planetary_motion")
    pendulum = _scene_text("simple_pendulum")
    files = {
        "binary": bytes(range(256)) * 4,
        "kepler_r0": kepler.replace("\nr = 1.0\n", "\nr = 0.0\n"),
        "kepler_m0": kepler.replace("m = 1.0, k = 1.0", "m = 0.0, k = 1.0"),
        "view_t_end": pendulum.replace("t_end = 20.0", 't_end = "abc"'),
    }
    paths = {}
    for name, content in files.items():
        path = tmp_path / f"{name}.toml"
        if isinstance(content, bytes):
            path.write_bytes(content)
        else:
            assert content != (kepler if name.startswith("kepler") else pendulum)
            path.write_text(content, encoding="utf-8")
        paths[name] = path
    return paths


# -- 1. bad files ---------------------------------------------------------------------------------

EXPECTED = {
    "binary": "not a text file",
    "kepler_r0": "singular",
    "kepler_m0": "zero parameters: m",
    "view_t_end": "view.t_end",
}


@pytest.mark.parametrize("kind", sorted(EXPECTED))
def test_bad_file_from_the_catalogue_is_reported_and_the_scene_kept(
    qtbot, window, bad_files, capfd, kind
):
    wait_for_points(qtbot, window, 5)
    runner, compiled, built = window.runner, window.compiled, window.built
    path = bad_files[kind]
    capfd.readouterr()
    window.editor.catalogue_selected.emit(str(path))  # what a catalogue click sends
    status = window.statusBar()
    qtbot.waitUntil(lambda: status.currentMessage().startswith("not opened"), timeout=30000)
    message = status.currentMessage()
    assert str(path) in message and EXPECTED[kind] in message
    general = window.editor.general_error
    assert general.isVisible() and EXPECTED[kind] in general.text()
    # the pendulum is still what runs, and what the editor shows
    assert window.runner is runner and window.compiled is compiled and window.built is built
    _still_running(qtbot, window)
    assert window.editor.coordinates.text() == "theta"
    assert window.windowTitle().endswith("Simple pendulum")
    assert "Traceback" not in capfd.readouterr().err


def test_bad_file_from_file_open_is_shown_to_be_fixed_and_the_scene_kept(
    qtbot, window, bad_files, monkeypatch
):
    """File > Open shows a user's file in the editor even when it does not build (it may
    have been saved unfinished), with the reason; the running system keeps running."""
    from PySide6.QtWidgets import QFileDialog

    wait_for_points(qtbot, window, 5)
    runner, built = window.runner, window.built
    path = bad_files["kepler_r0"]
    monkeypatch.setattr(QFileDialog, "getOpenFileName", lambda *a, **k: (str(path), ""))
    window._on_open_triggered()
    status = window.statusBar()
    qtbot.waitUntil(lambda: window.editor.build_status == "failed", timeout=30000)
    assert "initial" in status.currentMessage() and "r = 0" in status.currentMessage()
    assert window.runner is runner and window.built is built
    _still_running(qtbot, window)
    # the editor holds the file as written, to be fixed there
    assert window.editor.coordinates.text() == "r, theta"
    assert window.editor.document_text() == path.read_text(encoding="utf-8") or (
        "r = 0.0" in window.editor.document_text()
    )
    # a binary file is refused and the editor keeps what it had
    request = window.open_file(bad_files["binary"])
    assert request == 0 and "not a text file" in status.currentMessage()
    assert window.editor.coordinates.text() == "r, theta"
    # a good file afterwards opens as usual
    good = path.with_name("kepler_good.toml")
    good.write_text(_scene_text("planetary_motion"), encoding="utf-8")
    request = window.open_file(good)
    qtbot.waitUntil(lambda: window.built.request == request, timeout=60000)
    assert window.compiled.mechanics.scene.coordinates == ("r", "theta")
    assert window.scene_path == good.resolve()


def test_open_scene_never_raises_for_a_missing_file(qtbot, window, tmp_path):
    assert window.open_scene(tmp_path / "nowhere.toml") == 0
    assert "cannot read the file" in window.statusBar().currentMessage()
    assert window.runner is not None and window.runner.running


# -- 2. parameters that make the system singular ------------------------------------------------


def _value_cell(table, name: str):
    from explorer.editor.parameters_table import VALUE

    row = [table.item(r, 0).text() for r in range(table.rowCount())].index(name)
    return table.item(row, VALUE)


def test_zero_length_is_refused_with_the_reason(qtbot, window):
    wait_for_points(qtbot, window, 5)
    editor, table = window.editor, window.editor.parameter_table
    generation, compiled = window.worker.generation, window.compiled
    table.set_value("l", 0.0)  # as if typed
    assert editor.parameter_error.isVisible()
    reason = editor.parameter_error.text()
    assert "l = 0 refused" in reason and "singular" in reason and "zero parameters: l" in reason
    assert _value_cell(table, "l").text() == "1"  # the previous value is back
    assert "l = 0 refused" in window.statusBar().currentMessage()
    qtbot.wait(300)  # longer than the parameter debounce: nothing restarts
    assert window.worker.generation == generation and window.compiled is compiled
    _still_running(qtbot, window)
    # a good value is taken, and clears the refusal
    table.set_value("l", 1.5)
    assert not editor.parameter_error.isVisible()
    qtbot.waitUntil(lambda: window.compiled.parameters[2] == 1.5, timeout=5000)


@pytest.mark.parametrize("text", ["nan", "inf", "-inf", "abc"])
def test_values_that_are_not_finite_numbers_are_refused(qtbot, window, text):
    wait_for_points(qtbot, window, 5)
    editor, table = window.editor, window.editor.parameter_table
    generation = window.worker.generation
    _value_cell(table, "l").setText(text)  # typed into the cell
    assert editor.parameter_error.isVisible()
    assert "refused" in editor.parameter_error.text()
    assert "finite" in editor.parameter_error.text() or "number" in editor.parameter_error.text()
    assert _value_cell(table, "l").text() == "1"
    assert table.slider("l").value() == 500  # l = 1 in [0, 2]
    qtbot.wait(300)
    assert window.worker.generation == generation
    assert list(window.compiled.parameters) == [1.0, 9.81, 1.0]
    _still_running(qtbot, window)


def test_slider_dragged_to_zero_is_refused_and_goes_back(qtbot, window):
    wait_for_points(qtbot, window, 5)
    table = window.editor.parameter_table
    slider = table.slider("l")
    slider.setValue(250)  # l = 0.5: fine
    qtbot.waitUntil(lambda: window.compiled.parameters[2] == 0.5, timeout=5000)
    slider.setValue(0)  # l = 0: singular
    assert _value_cell(table, "l").text() == "0.5" and slider.value() == 250
    assert "l = 0 refused (kept l = 0.5)" in window.editor.parameter_error.text()
    qtbot.wait(300)
    assert window.compiled.parameters[2] == 0.5


def test_range_typed_as_nan_does_not_break_the_slider(qtbot, window):
    from explorer.editor.parameters_table import HIGH

    table = window.editor.parameter_table
    row = [table.item(r, 0).text() for r in range(table.rowCount())].index("l")
    table.item(row, HIGH).setText("nan")  # no exception from placing the slider
    assert "l" not in table.ranges()


# -- 3. closing --------------------------------------------------------------------------------


TRIPLE_KINETIC = (
    "m*l**2*(3*a_dot**2 + 2*b_dot**2 + c_dot**2 + 4*a_dot*b_dot*cos(a - b)"
    " + 2*a_dot*c_dot*cos(a - c) + 2*b_dot*c_dot*cos(b - c))/2"
)
TRIPLE_PENDULUM = f"""
title = "Triple pendulum"
[system]
coordinates = ["a", "b", "c"]
parameters = {{ m = 1.0, l = 1.0, g = 9.81 }}
kinetic = "{TRIPLE_KINETIC}"
potential = "-m*g*l*(3*cos(a) + 2*cos(b) + cos(c))"
[initial]
a = 1.0
b = 0.5
c = 0.2
"""


def test_close_during_a_derivation_ends_its_process(qtbot, monkeypatch, tmp_path, open_window):
    import explorer.builder
    from tests.slow_work import crawl_if_three_coordinates

    # sympy derives a triple pendulum in well under a second once warm: a stand-in
    # crawls first (pure Python, as sympy is) so that closing surely meets it running
    monkeypatch.setattr(explorer.builder, "build_code", crawl_if_three_coordinates)
    before = {t.ident for t in threading.enumerate()}
    win = open_window()
    # the builder is done with the pendulum (its equilibria, the last thing it sends)
    card = win.editor.classification_card
    qtbot.waitUntil(lambda: "Equilibria" in card.text(), timeout=60000)
    _numba_warm(qtbot)
    path = tmp_path / "triple.toml"
    path.write_text(TRIPLE_PENDULUM, encoding="utf-8")
    request = win.open_scene(path)
    assert request
    # the derivation starts (a loaded machine may take a moment to schedule the builder)
    qtbot.waitUntil(lambda: win.builder.deriving, timeout=30000)
    qtbot.wait(300)
    assert win.builder.deriving, "the derivation should still be running"
    _timed_close(win)
    assert not win.builder._thread.isRunning() and win.runner is None
    assert _threads_left(before) == []
    assert _children() == []
    assert win.built.request != request  # the ended build never arrives


def test_close_during_the_first_build_ends_it(qtbot, monkeypatch, open_window):
    """A slow derivation (stand-in) of the very first scene: nothing runs yet."""
    import explorer.builder
    from tests.slow_work import crawl_then_derive

    monkeypatch.setattr(explorer.builder, "build_code", crawl_then_derive)
    before = {t.ident for t in threading.enumerate()}
    win = open_window()
    qtbot.waitUntil(lambda: win.builder.deriving, timeout=30000)
    _timed_close(win)
    assert win.compiled is None and not win.builder._thread.isRunning()
    assert _threads_left(before) == []
    assert _children() == []


def test_close_while_a_scene_builds(qtbot, open_window):
    """A constrained scene no test built before: a worker derives it, the builder
    compiles its functions, and the window closes meanwhile, within the bound; the
    worker is ended and the builder thread ends."""
    from systems.scene import parse_scene

    win = open_window()
    wait_for_points(qtbot, win, 5)
    _numba_warm(qtbot)
    unique = f"{time.time_ns() % 10**9}e-15"
    text = _scene_text("bouncing_ball").replace(
        'potential = "', f'potential = "{unique}*x**4 + ', 1
    )
    win.open_scene(parse_scene(text))
    qtbot.wait(50)
    _timed_close(win)
    qtbot.waitUntil(lambda: not win.builder._thread.isRunning(), timeout=60000)
    assert _children() == []


def test_close_just_after_opening(qtbot, open_window):
    """The busiest moment: workers lay out the derivation and search equilibria, the
    Textbook's do too, numba warms up."""
    before = {t.ident for t in threading.enumerate()}
    win = open_window()
    qtbot.waitUntil(lambda: win.runner is not None, timeout=60000)
    _timed_close(win)
    assert _children() == []  # no worker process left
    # numba's warm-up is never interrupted (see _numba_warm); it ends on its own
    assert set(_threads_left(before)) <= {"numba-warm-up"}


def test_close_while_running_at_full_speed(qtbot, open_window):
    before = {t.ident for t in threading.enumerate()}
    win = open_window()
    qtbot.waitUntil(lambda: win.compiled is not None, timeout=60000)
    win.controls.speed_combo.setCurrentIndex(win.controls.speed_combo.count() - 1)
    assert win.controls.speed == float("inf")
    qtbot.waitUntil(lambda: win.worker.settings.speed == float("inf"), timeout=5000)
    wait_for_points(qtbot, win, 2000)
    _numba_warm(qtbot)
    runner = win.runner
    _timed_close(win)
    assert not runner.running and win.runner is None
    assert _threads_left(before) == []
    assert _children() == []


def test_worker_stuck_in_a_long_step_is_let_go(qtbot):
    """A block that does not return (a step of a huge system) cannot hold up ``stop``:
    nothing is raised into the thread; it is kept referenced until it ends by itself,
    and its frames, of an old generation, are ignored."""
    import numpy as np

    from explorer.worker import RunSettings, SimulationWorker, WorkerThread, _orphans

    release = threading.Event()
    entered = threading.Event()

    class Stuck:
        finished = False

        def __init__(self, *args, **kwargs):
            pass

        def advance(self, seconds, until):
            entered.set()
            while not release.is_set():  # pure Python that does not end by itself
                sum(range(1000))

    worker = SimulationWorker(object(), RunSettings(speed=float("inf")), runs=Stuck)
    worker.add_trajectory(0, np.zeros(2))
    runner = WorkerThread(worker)
    runner.start()
    assert entered.wait(30)
    try:
        assert not runner.stop(timeout=0.2)
        assert runner.thread in _orphans
    finally:
        release.set()
    qtbot.waitUntil(lambda: not runner.running, timeout=30000)


# -- 4. unexpected errors ------------------------------------------------------------------------


@pytest.mark.qt_no_exception_capture
def test_an_exception_in_a_slot_is_shown_and_the_run_goes_on(qtbot, window, monkeypatch):
    wait_for_points(qtbot, window, 5)
    calls = []

    def broken(store):
        calls.append(1)
        raise ZeroDivisionError("float division by zero")

    monkeypatch.setattr(window.conserved_view, "refresh", broken)
    status = window.statusBar()
    qtbot.waitUntil(lambda: "unexpected error" in status.currentMessage(), timeout=5000)
    assert "ZeroDivisionError: float division by zero" in status.currentMessage()
    assert window.details_button.isVisible()
    assert "Traceback" in window.error_details and "broken" in window.error_details
    box = window.show_error_details()
    assert box.detailedText() == window.error_details
    box.close()
    _still_running(qtbot, window)
    monkeypatch.undo()


@pytest.mark.filterwarnings("ignore::pytest.PytestUnhandledThreadExceptionWarning")
def test_an_exception_in_a_thread_is_shown(qtbot, window):
    def fail():
        raise RuntimeError("lost in a thread")

    assert not window.details_button.isVisible()
    thread = threading.Thread(target=fail, name="helper")
    thread.start()
    thread.join()
    status = window.statusBar()
    qtbot.waitUntil(lambda: "lost in a thread" in status.currentMessage(), timeout=5000)
    assert "(in helper)" in status.currentMessage()
    assert window.details_button.isVisible()


def test_closing_gives_the_hooks_back(qtbot, open_window):
    import sys

    hook, thread_hook = sys.excepthook, threading.excepthook
    win = open_window()
    assert sys.excepthook != hook and threading.excepthook != thread_hook
    qtbot.waitUntil(lambda: win.compiled is not None, timeout=60000)
    win.close()
    assert sys.excepthook == hook and threading.excepthook == thread_hook
