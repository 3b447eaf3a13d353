"""Fill section… in the main window: Run menu, status bar, Esc, another scene, closing,
exports with the layer, and sessions (``section-fill N``) recorded and replayed, in the
window (``open --session FILE --offscreen --exit`` runs the same ``Player``: a process
of its own costs 13-16 s here, so it was checked by hand)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from PySide6.QtCore import Qt
from PySide6.QtGui import QColor, QImage

from explorer import main_window
from explorer.orbit_colours import orbit_colour
from explorer.panels import section_fill_layer
from explorer.session import Player, ScriptError, parse

SOURCE = "fill.session"


def replay(qtbot, window, text: str, folder=None, recorder=None, expect=0) -> Player:
    player = Player(window, parse(text, SOURCE), source=SOURCE, folder=folder, recorder=recorder)
    player.start()
    qtbot.waitUntil(lambda: player.status is not None, timeout=60000)
    assert player.status == expect, player.message
    return player


def _near(path: Path, colour: str, within: int = 40) -> int:
    """Pixels of the PNG at ``path`` within ``within`` (per channel) of ``colour``."""
    image = QImage(str(path)).convertToFormat(QImage.Format.Format_RGB888)
    width, height = image.width(), image.height()
    row = image.bytesPerLine()
    data = np.frombuffer(image.constBits(), dtype=np.uint8)[: row * height]
    pixels = data.reshape(height, row)[:, : 3 * width].reshape(height, width, 3).astype(int)
    target = QColor(colour)
    want = np.array([target.red(), target.green(), target.blue()])
    return int(np.count_nonzero(np.all(np.abs(pixels - want) <= within, axis=2)))


def test_grammar_of_section_fill():
    assert parse("section-fill 30")[0].value == 30
    for text, reason in (
        ("section-fill", "usage: section-fill ORBITS"),
        ("section-fill 0", "ORBITS is a whole number from 1 to 10000, not '0'"),
        ("section-fill 2.5", "not '2.5'"),
        ("section-fill 10001", "not '10001'"),
    ):
        with pytest.raises(ScriptError, match=reason):
            parse(text)


def test_fill_recorded_replayed_and_exported(qtbot, blank_window, tmp_path, monkeypatch):
    from explorer.session import Recorder

    monkeypatch.setattr(section_fill_layer, "T_END", 100.0)
    window = blank_window
    recorder = Recorder(window)
    replay(qtbot, window, "open henon_heiles\nsection on", tmp_path)
    window.export_panel("phase", tmp_path / "before.png", (600, 400))
    layer = window.phase_view.fill_layer
    run_menu = next(a.menu() for a in window.menuBar().actions() if a.text() == "&Run")
    assert layer.fill_action in run_menu.actions() and layer.stop_action in run_menu.actions()
    assert layer.fill_action.isEnabled()
    replay(qtbot, window, "section-fill 6\nexport phase fill.svg\n", tmp_path, recorder=recorder)
    window.export_panel("phase", tmp_path / "fill.png", (600, 400))
    portrait = layer.portrait  # drawn before the export: the player waited for it
    assert portrait is not None and len(portrait.starts) == 6 and len(layer.kept) == 6
    energy = window.phase_view.section_energy
    H = window.compiled.hamiltonian(0.0, layer.points())
    assert np.max(np.abs(H - energy)) <= 1e-8
    assert "section-fill 6" in recorder.lines
    # said in the header (the status bar's may be the section run's by now)
    assert window.phase_view.hint.text().startswith("6 of 6 orbits filled, ")
    # the exports hold the layer: its colours, which the figure before had not
    colours = [orbit_colour(r, 6) for r in range(6)]
    for colour in colours:
        assert (
            _near(tmp_path / "fill.png", colour) > 20 * _near(tmp_path / "before.png", colour) + 20
        )
    svg = (tmp_path / "fill.svg").read_text(encoding="utf-8").lower()
    assert all(colour in svg for colour in colours)
    # another scene: the layer goes; there a line that cannot fill says why
    player = replay(qtbot, window, "open simple_pendulum\nsection-fill 6", tmp_path, expect=2)
    assert layer.item is None and layer.portrait is None
    assert f"{SOURCE}:2: cannot fill the section: A Poincaré section needs two degrees" in (
        player.message
    )


def test_esc_stops_a_fill_and_the_window_runs_on(qtbot, blank_window, monkeypatch):
    monkeypatch.setattr(section_fill_layer, "T_END", 2e4)
    # "runs on" needs a section run with time left: at t = 5000 it pauses for Play (and
    # says so in the status bar), which a fast run had reached before the fill's Esc
    monkeypatch.setattr(main_window, "POINCARE_T_END", 1e9)
    window = blank_window
    replay(qtbot, window, "open henon_heiles\nsection on")
    layer = window.phase_view.fill_layer
    layer.start(400)
    assert window.statusBar().currentMessage().startswith("filling section: 400 orbits at H = ")
    qtbot.waitUntil(lambda: layer.progress.maximum() > 0, timeout=60000)
    assert window.statusBar().currentMessage().startswith("filling section: ")
    thread = layer._thread
    window.activateWindow()
    qtbot.keyClick(window.phase_view.plot_widget, Qt.Key.Key_Escape)
    assert not layer.running  # Esc: the Run menu's "Stop filling the section"
    qtbot.waitUntil(lambda: not thread.is_alive(), timeout=30000)
    assert not layer.running and layer.item is None
    assert window.statusBar().currentMessage() == "section fill stopped"
    # the window runs on: the section run advances and a new fill draws
    t = window.store.main.last_t
    qtbot.waitUntil(lambda: window.store.main.last_t > t, timeout=30000)
    monkeypatch.setattr(section_fill_layer, "T_END", 50.0)
    layer.start(3)
    qtbot.waitUntil(lambda: layer.portrait is not None, timeout=60000)
    # a fill under way ends with the window
    monkeypatch.setattr(section_fill_layer, "T_END", 2e4)
    layer.start(400)
    qtbot.waitUntil(lambda: layer.progress.maximum() > 0, timeout=60000)
    thread = layer._thread
    window.close()
    qtbot.waitUntil(lambda: not thread.is_alive(), timeout=30000)
