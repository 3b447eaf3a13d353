"""Systems users typed: every scene of ``tests/user_systems`` derives, opens, runs, exports
and replays cleanly.

The project's rule is that the scenes in ``../shared/user-systems`` (written the way users
write them, with what the textbook says about each in their README) must all work. That
folder lies outside the repository, so CI (a clean clone) never saw it: the scenes are
vendored byte for byte into ``tests/user_systems`` (``test_classification.py`` checks the
copies against the originals where they are) and checked here on every run.

- ``test_the_readme_lists_every_scene``: the README's table and the vendored files agree.
- ``test_user_scene_derives``: ``load_scene`` and ``derive`` take the file, and
  ``python main.py derive FILE --json`` (through ``explorer.cli.main``) writes JSON whose
  expressions read back and whose classification is the derivation's.
- ``test_user_scene_opens_runs_exports_and_replays``: *File > Open* shows the scene in a
  window, data arrives in every panel, the run goes on with finite states, and so does an
  orbit launched by a click in the phase view; PNG, SVG and CSV come out of the panels
  through the window's export functions, whole (Qt reads the PNG, the SVG parses, the CSV
  has ``csv_header``'s columns and finite rows); the session recorded meanwhile (open,
  launch, exports) replays offscreen in a new window, as ``open --session`` does, runs
  through and records the same script again.

Each scene's system functions are written as LLVM IR and compiled in milliseconds, and
the stepping loops come compiled from the session's cache (``python main.py warm``), so
the file takes seconds per scene. The replay goes to a new window. Windows are closed
whatever their builder is doing: while it lays out the derivation (sympy's printing,
the equilibrium search) was where an asynchronous ``Abandoned`` once landed inside an
import and hung the process (``tests/systems/test_deadline.py``).
"""

from __future__ import annotations

import contextlib
import csv
import io
import json
import math
import re
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest
import sympy
from PySide6.QtGui import QImage

from explorer.cli import main
from explorer.export import csv_header
from systems.mechanics import derive
from systems.scene import load_scene
from tests.explorer.conftest import assert_data_in_every_panel, wait_for_points

VENDORED = Path(__file__).resolve().parents[1] / "user_systems"
SCENES = sorted(VENDORED.glob("*.toml"))
IDS = [path.stem for path in SCENES]
FIGURE_PANELS = ("phase", "configuration", "conserved")
WAIT_MS = 60000
REPLAY_MS = 90000


# -- the README -------------------------------------------------------------------------------


def test_the_readme_lists_every_scene():
    """The README's table names exactly the vendored scenes."""
    readme = (VENDORED / "README.md").read_text(encoding="utf-8")
    listed = set(re.findall(r"^\| *([\w.-]+\.toml) *\|", readme, flags=re.MULTILINE))
    assert len(SCENES) >= 14
    assert listed == {path.name for path in SCENES}


# -- deriving --------------------------------------------------------------------------------


def _derive_json(path: Path) -> dict:
    """``python main.py derive PATH --json``, in this process; its JSON."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        status = main(["derive", str(path), "--json"])
    assert status == 0, err.getvalue()
    assert not err.getvalue(), err.getvalue()
    return json.loads(out.getvalue())


@pytest.mark.parametrize("path", SCENES, ids=IDS)
def test_user_scene_derives(path):
    """``derive`` and ``derive FILE --json`` agree; the JSON's expressions read back."""
    scene = load_scene(path)
    mechanics = derive(scene)
    report = _derive_json(path)
    coordinates = list(scene.coordinates)
    momenta = list(scene.momentum_names)
    assert report["title"] == scene.title
    assert report["coordinates"] == coordinates
    assert report["classification"] == json.loads(json.dumps(mechanics.classification.as_dict()))
    assert set(report["hamilton_equations"]) == {*coordinates, *momenta}
    assert set(report["momenta"]) == set(coordinates)
    assert set(report["conserved"]) == set(mechanics.conserved)
    assert ("H" in report["conserved"]) == mechanics.classification.hamiltonian_conserved
    names = {
        name: sympy.Symbol(name)
        for name in [*coordinates, *scene.velocity_names, *momenta, *scene.parameter_values, "t"]
    }
    expressions = [
        report["hamiltonian"],
        *report["hamilton_equations"].values(),
        *report["momenta"].values(),
        *report["conserved"].values(),
    ]
    for text in expressions:
        expression = sympy.sympify(text, locals=names)
        assert expression.free_symbols <= set(names.values()), text
    for equilibrium in report["equilibria"]:
        assert set(equilibrium["q"]) == set(coordinates)
        assert all(math.isfinite(value) for value in equilibrium["q"].values())


# -- the window --------------------------------------------------------------------------------


class Windows:
    """Main windows opened with no scene yet (as ``open`` starts one), each shut down by
    ``close`` or at the end of the test."""

    def __init__(self, qtbot):
        self.qtbot = qtbot
        self.open: list = []

    def new(self):
        from explorer.app import application
        from explorer.main_window import MainWindow

        application()
        window = MainWindow()
        window.show()
        self.open.append(window)
        return window

    def close(self, window) -> None:
        self.open.remove(window)
        window.close()
        window.deleteLater()
        self.qtbot.wait(10)


@pytest.fixture
def windows(qtbot):
    """The test's ``Windows``; those still open are closed after it."""
    opened = Windows(qtbot)
    yield opened
    for window in list(opened.open):
        opened.close(window)


def _check_running(window) -> None:
    """The main orbit runs (or ended well) with finite states, and every panel has data."""
    assert_data_in_every_panel(window)


def _launch_near_the_start(window) -> None:
    """A click in the phase view a little away from the initial state: a second orbit."""
    phase = window.phase_view
    x, y = phase.y0[phase.index], phase.y0[window.compiled.n + phase.index]
    phase.launch_at(x + 0.05 * max(1.0, abs(x)), y + 0.05 * max(1.0, abs(y)))
    assert [t.key for t in window.store] == [0, 1], window.statusBar().currentMessage()


def _check_figure(path: Path) -> None:
    """A whole PNG (Qt reads it, not blank) or SVG (parses as XML, has paths)."""
    assert path.is_file() and path.stat().st_size > 0
    if path.suffix == ".png":
        image = QImage(str(path))
        assert not image.isNull() and image.width() > 100 and image.height() > 100
        colours = {
            image.pixelColor(x, y).rgb()
            for x in range(0, image.width(), 7)
            for y in range(0, image.height(), 7)
        }
        assert len(colours) > 2, f"{path.name} is blank"
    else:
        root = ET.parse(path).getroot()
        assert root.tag == "{http://www.w3.org/2000/svg}svg"
        assert any(True for _ in root.iter("{http://www.w3.org/2000/svg}path"))


def _check_csv(path: Path, window) -> None:
    """The header of ``csv_header`` (with ``orbit`` first for several orbits), finite rows."""
    with path.open(newline="", encoding="utf-8") as handle:
        rows = list(csv.reader(handle))
    header = csv_header(window.compiled.mechanics.scene)
    orbits = len(list(window.store))
    assert rows[0] == (["orbit"] if orbits > 1 else []) + header
    table = np.array(rows[1:], dtype=float)
    assert table.shape[0] >= 8 and table.shape[1] == len(rows[0])
    assert np.isfinite(table).all()
    if orbits > 1:
        assert set(table[:, 0]) == set(range(1, orbits + 1))


@pytest.mark.qt_no_exception_capture  # the window's ErrorReporter must see them, as in use
@pytest.mark.parametrize("path", SCENES, ids=IDS)
def test_user_scene_opens_runs_exports_and_replays(qtbot, windows, tmp_path, path):
    """File > Open, run, launch, export PNG/SVG/CSV, then replay the recorded session."""
    from explorer.session import Player, Recorder, parse

    window = windows.new()
    recorder = Recorder(window)
    request = window.open_file(path)  # File > Open
    assert request, window.statusBar().currentMessage()
    qtbot.waitUntil(
        lambda: window.built is not None and window.built.request == request, timeout=WAIT_MS
    )
    assert window.built.scene.title == load_scene(path).title
    assert window.scene_path == path.resolve()
    wait_for_points(qtbot, window, 8, timeout=WAIT_MS)
    qtbot.waitUntil(lambda: window.redraws > 2, timeout=5000)
    _check_running(window)
    _launch_near_the_start(window)
    wait_for_points(qtbot, window, 8, timeout=WAIT_MS, key=1)
    _check_running(window)
    assert np.isfinite(window.store.trajectories[1].y.data).all()
    # File > Export: every panel as PNG and SVG, and the orbits as CSV
    for key in FIGURE_PANELS:
        for suffix in (".png", ".svg"):
            _check_figure(window.export_panel(key, tmp_path / f"{key}{suffix}"))
    _check_csv(window.export_csv(tmp_path / "orbits.csv"), window)
    assert window.error_details == ""
    recorded = recorder.text()
    lines = [text for text in recorded.splitlines()[1:] if not text.startswith("run-until")]
    assert lines[0] == f"open {path}", recorded
    assert lines[1].startswith("launch "), recorded
    assert lines[2:] == [
        f"export {key} {tmp_path / (key + suffix)}"
        for key in FIGURE_PANELS
        for suffix in (".png", ".svg")
    ] + [f"export csv {tmp_path / 'orbits.csv'}"]
    windows.close(window)
    # the session, replayed offscreen in a new window as ``open --session`` does, runs
    # through and records the same script again
    replayed = windows.new()
    again = Recorder(replayed)
    player = Player(
        replayed, parse(recorded, "recorded.session"), source="recorded.session", recorder=again
    )
    player.start()
    qtbot.waitUntil(lambda: player.status is not None, timeout=REPLAY_MS)
    assert player.status == 0, f"{player.message}\n{replayed.error_details}"
    assert again.text() == recorded
    assert [t.key for t in replayed.store] == [0, 1]
    wait_for_points(qtbot, replayed, 8, timeout=WAIT_MS)
    _check_running(replayed)
    for key in FIGURE_PANELS:  # written again by the replay's export lines
        for suffix in (".png", ".svg"):
            _check_figure(tmp_path / f"{key}{suffix}")
    _check_csv(tmp_path / "orbits.csv", replayed)
    assert replayed.error_details == ""
