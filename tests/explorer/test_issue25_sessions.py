"""Regression scripts for issue 25's teaching moments, replayed offscreen.

Each script in ``sessions/issue25`` reproduces a problem a teacher met preparing a
lecture; it is replayed in a window (as ``python main.py open --session FILE
--offscreen --exit`` does) and the window is checked after its last line:

- "Add g as a parameter" then typing 9.81: the slider's range takes the value (it was
  pinned at the end of 0 to 2);
- ``k/2 (x**2)``: the field says "missing * between 2 and (", not "invalid syntax";
- the catalogue's Atwood machine stops at the floor (it ran through the pulley);
- a scene given by particles is drawn with rods to its support, small grey fixed points;
- a separatrix a round-off below H = 0 is labelled "H = 0" (it said "H = -0");
- Single step at "max" advances one frame of 1x (it jumped by 3, then 27 time units);
- the energy error's log-axis labels never overlap.

The bead on a rotating wire (stopped as unbounded, naming r) has its replayed window test
in ``test_stop_banner.py``. Every script here also replays through the command line
with exit status 0 (``test_every_issue25_script_replays_from_the_command_line``).
"""

from __future__ import annotations

import html
import math
import os
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

SESSIONS = Path(__file__).resolve().parent / "sessions" / "issue25"
REPLAY_MS = 90000
ROOT = Path(__file__).resolve().parents[2]


def replay(qtbot, window, name: str):
    from explorer.session import Player, load

    path = SESSIONS / f"{name}.session"
    player = Player(window, load(path), source=path.name, folder=SESSIONS)
    player.start()
    qtbot.waitUntil(lambda: player.status is not None, timeout=REPLAY_MS)
    assert player.status == 0, f"{player.message}\n{window.error_details}"
    return player


def _plain(text: str) -> str:
    return html.unescape(re.sub(r"<[^>]+>", "", text))


def check_add_g_slider(qtbot, window) -> None:
    from explorer.editor.parameters_table import HIGH, LOW, NAME, SLIDER_STEPS, VALUE

    table = window.editor.parameter_table
    rows = {table.item(r, NAME).text(): r for r in range(table.rowCount())}
    row = rows["g"]
    value, low, high = (float(table.item(row, c).text()) for c in (VALUE, LOW, HIGH))
    assert value == 9.81 and low <= value <= high, (low, value, high)
    assert 0 < table.slider("g").value() < SLIDER_STEPS  # not pinned at an end
    assert window.compiled.parameters[-1] == pytest.approx(9.81)


def check_missing_star(qtbot, window) -> None:
    message = _plain(window.editor.fields["potential"].error_label.text())
    assert "missing * between 2 and (" in message, message
    assert "comma" not in message


def check_atwood_stops(qtbot, window) -> None:
    main = window.store.main
    x = main.y.data[:, 0]
    x = x[np.isfinite(x)]
    # 0 <= x <= h below the pulley, L - h <= x <= L for the other mass: [0.5, 2.5]
    assert x.min() >= 0.5 - 1e-9 and x.max() <= 2.5 + 1e-9, (x.min(), x.max())
    assert x[-1] == pytest.approx(2.5, abs=1e-9)  # landed on the floor, resting there
    assert main.last_t >= 8


def check_particles_rods(qtbot, window) -> None:
    from explorer.panels.configuration_view import FIXED_BRUSH

    view = window.configuration_view
    joined = {name for link in view.links for name in link}
    assert {"bob1", "bob2"} <= joined and len(view.links) >= 2, view.links
    x, _ = view._rods.getData()
    assert x is not None and np.isfinite(x).sum() >= 4  # two rods drawn
    fixed = [view._fixed, view._pivot]
    assert any(len(item.points()) for item in fixed)
    for item in fixed:
        for point in item.points():
            assert point.size() < view._bobs.points()[0].size()
    assert view._fixed.opts["brush"].color() == FIXED_BRUSH.color()


def check_separatrix_zero(qtbot, window) -> None:
    texts = [text for _, text in window.phase_view._legend_static]
    assert "separatrix (H = 0)" in texts, texts
    assert not any("-0" in text or "−0" in text for text in texts)


def check_log_ticks(qtbot, window) -> None:
    from tests.explorer.test_log_axis import drawn_labels

    window.store.mark_dirty()
    window._on_redraw_timer_timeout()
    qtbot.wait(50)
    texts = drawn_labels(window.conserved_view.energy_plot.getAxis("left"))
    labels = [rect for rect, _ in texts]
    assert len(labels) >= 2
    assert not any(a.intersects(b) for i, a in enumerate(labels) for b in labels[i + 1 :])


CHECKS = {
    "add_g_slider": check_add_g_slider,
    "missing_star": check_missing_star,
    "atwood_stops": check_atwood_stops,
    "particles_rods": check_particles_rods,
    "separatrix_zero": check_separatrix_zero,
    "log_ticks": check_log_ticks,
}
PARTS = {"single_step_at_max", "single_step_steps"}  # replayed in turn by their test


def test_every_script_has_its_check():
    assert sorted(p.stem for p in SESSIONS.glob("*.session")) == sorted([*CHECKS, *PARTS])


@pytest.mark.qt_no_exception_capture  # the window's ErrorReporter must see them, as in use
@pytest.mark.parametrize("name", sorted(CHECKS))
def test_issue25_session(qtbot, blank_window, name):
    replay(qtbot, blank_window, name)
    CHECKS[name](qtbot, blank_window)


@pytest.mark.qt_no_exception_capture
def test_single_step_at_max_advances_one_frame_of_1x_each(qtbot, blank_window):
    window = blank_window
    replay(qtbot, window, "single_step_at_max")
    qtbot.waitUntil(lambda: not window.controls.playing, timeout=5000)
    # the pause hands over the states that waited for the row budget: wait for them
    before = math.nan
    for _ in range(80):
        if window.store.main.last_t == before:
            break
        before = window.store.main.last_t
        qtbot.wait(250)
    paused = window.store.main.last_t
    assert paused >= 60
    replay(qtbot, window, "single_step_steps")
    qtbot.waitUntil(lambda: window.store.main.last_t > paused + 0.08, timeout=20000)
    qtbot.wait(200)
    advanced = window.store.main.last_t - paused
    # three frames of 1x, 0.03 time units each (a step ends at or past it)
    assert 0.09 <= advanced < 0.2, advanced
    assert not window.controls.playing


@pytest.fixture(scope="module")
def command_line_replays():
    """Every script replayed by ``main.py open --session FILE --offscreen --exit``, a few
    processes at a time (each mostly waits: for its run to reach a time, for a frame):
    by name, a future of the finished process."""
    from concurrent.futures import ThreadPoolExecutor

    env = {**os.environ, "QT_QPA_PLATFORM": "offscreen"}

    def replay_in_a_process(name: str) -> subprocess.CompletedProcess:
        return subprocess.run(
            [sys.executable, "main.py", "open", "--session", str(SESSIONS / f"{name}.session")]
            + ["--offscreen", "--exit"],
            cwd=ROOT,
            env=env,
            capture_output=True,
            text=True,
            timeout=600,
        )

    with ThreadPoolExecutor(max_workers=3) as pool:
        yield {name: pool.submit(replay_in_a_process, name) for name in sorted([*CHECKS, *PARTS])}


@pytest.mark.soak  # a process per script (about a minute in all)
@pytest.mark.parametrize("name", sorted([*CHECKS, *PARTS]))
def test_every_issue25_script_replays_from_the_command_line(name, command_line_replays):
    done = command_line_replays[name].result()
    assert done.returncode == 0, done.stderr[-3000:]
