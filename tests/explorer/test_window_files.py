"""The window's files, menus and clean starts (issue 10, items 1, 2, 5 and 8).

A new scene starts clean (method, step, section and messages of the last one do not
carry over); Save writes exactly what the editor holds, buildable or not; typed work that
is replaced unsaved is kept; the window fits a 1366 x 768 screen; every control has a
tooltip; Help shows the scene format.
"""

from __future__ import annotations

import math
import stat

import pytest
from PySide6.QtWidgets import QAbstractButton, QComboBox, QLineEdit, QTextBrowser

from tests.explorer.conftest import wait_for_points


def _open(qtbot, window, name: str) -> None:
    request = window.open_scene(name)
    assert request
    qtbot.waitUntil(
        lambda: window.built is not None and window.built.request == request, timeout=60000
    )


def _type(window, key: str, text: str) -> None:
    """Type ``text`` into the editor's field ``key`` and let the debounce go at once."""
    field = window.editor.fields[key]
    field.set_text(text)
    field.edited.emit()
    window.editor.flush()


def test_a_step_typed_for_one_scene_does_not_carry_over(qtbot, window):
    wait_for_points(qtbot, window, 3)
    controls = window.controls
    controls.step_edit.setText("0.3")
    controls.step_edit.editingFinished.emit()
    assert window.settings.dt == 0.3 or window.settings.tol == 0.3
    index = next(
        i
        for i in range(1, controls.method_combo.count())
        if controls.method_combo.model().item(i).isEnabled()
    )
    controls.method_combo.setCurrentIndex(index)
    chosen = controls.method_combo.itemData(index)
    assert isinstance(chosen, str)
    # the chosen method runs before the switch: a worker still in numba's first compile
    # of it is waited for, not cut short, and would outlive the test (a slow CI machine)
    qtbot.waitUntil(lambda: window.store.main.method == chosen, timeout=120000)
    window.statusBar().showMessage("stopped: energy_error: from the last scene")
    _open(qtbot, window, "double_pendulum")
    assert controls.step_edit.text() == ""
    assert controls.method is None  # automatic again
    assert window.settings.dt is None and window.settings.tol is None
    assert "last scene" not in window.statusBar().currentMessage()


def test_an_edit_of_the_same_system_keeps_the_chosen_method_and_step(qtbot, window):
    wait_for_points(qtbot, window, 3)
    controls = window.controls
    index = controls.method_combo.findData("leapfrog")
    assert index > 0
    controls.method_combo.setCurrentIndex(index)
    controls.step_edit.setText("0.01")
    controls.step_edit.editingFinished.emit()
    before = window.built
    _type(window, "potential", "-m*g*l*cos(theta) + 0*theta")
    qtbot.waitUntil(lambda: window.built is not before, timeout=60000)
    assert controls.method == "leapfrog" and controls.step_edit.text() == "0.01"
    assert window.settings.dt == 0.01


def test_section_on_then_other_scenes_shows_no_error(qtbot, window):
    _open(qtbot, window, "henon_heiles")
    window.phase_view.set_mode("poincare")
    wait_for_points(qtbot, window, 3)
    _open(qtbot, window, "planetary_motion")
    assert window.phase_view.mode == "phase"
    wait_for_points(qtbot, window, 3)
    _open(qtbot, window, "simple_pendulum")
    wait_for_points(qtbot, window, 10)
    qtbot.wait(300)  # several redraws of every panel
    assert window.error_details == ""
    assert "theta" in window.phase_view.pair_combo.currentText()


def test_a_section_run_that_reached_its_end_goes_on_when_play_is_pressed(
    qtbot, window, monkeypatch
):
    _open(qtbot, window, "henon_heiles")
    # a short section run: 50 time units, as much again each time Play continues it
    monkeypatch.setattr(
        window, "_section_t_end", lambda _scene_t_end: 50.0 * (1 + window._section_continued)
    )
    window.phase_view.set_mode("poincare")
    qtbot.waitUntil(lambda: window.store.main.last_t >= 50.0, timeout=60000)
    qtbot.waitUntil(lambda: not window.controls.playing, timeout=10000)
    assert "press Play" in window.statusBar().currentMessage()
    window.controls.play_button.setChecked(True)
    qtbot.waitUntil(lambda: window.store.main.last_t >= 100.0, timeout=60000)
    qtbot.waitUntil(lambda: not window.controls.playing, timeout=10000)


def test_save_writes_what_the_editor_holds_even_when_it_does_not_build(qtbot, window, tmp_path):
    wait_for_points(qtbot, window, 3)
    _type(window, "potential", "-m*g*l*cos(theta) + (")
    qtbot.waitUntil(lambda: window.editor.build_status == "failed", timeout=30000)
    path = tmp_path / "unfinished.toml"
    assert window.save_scene(path)
    text = path.read_text(encoding="utf-8")
    assert text == window.editor.document_text()
    assert "cos(theta) + (" in text
    assert "does not build yet" in window.statusBar().currentMessage()
    assert not list(tmp_path.glob(".*part*"))  # written atomically: no temporary left
    assert window.scene_path == path.resolve()
    assert str(path.resolve()) in window.preferences.recent
    # reopened, it shows the same text, unfinished as it is
    _type(window, "potential", "-m*g*l*cos(theta)")
    assert window.open_file(path)
    assert window.editor.document_text() == text


def test_save_writes_through_a_link_and_keeps_the_files_mode(qtbot, window, tmp_path):
    wait_for_points(qtbot, window, 3)
    for name, save in (("scene.toml", window.save_scene), ("work.session", window.save_session)):
        target = tmp_path / f"kept-{name}"
        target.write_text("old")
        target.chmod(0o640)
        link = tmp_path / name
        link.symlink_to(target.name)
        assert save(link)
        assert link.is_symlink() and target.read_text() != "old"
        assert stat.S_IMODE(target.stat().st_mode) == 0o640
    assert not list(tmp_path.glob(".*part*"))


def test_replacing_typed_work_unsaved_keeps_it_in_a_file(qtbot, window):
    wait_for_points(qtbot, window, 3)
    _type(window, "potential", "-m*g*l*cos(theta) + theta**4/100")
    typed = window.editor.document_text()
    _open(qtbot, window, "harmonic_oscillator")
    kept = [p for p in window.preferences.recent if "unsaved" in p]
    assert kept, window.preferences.recent
    with open(kept[0], encoding="utf-8") as handle:
        assert handle.read() == typed
    assert "unsaved edits are kept" in window.statusBar().currentMessage()


def test_slider_changes_alone_are_not_put_aside(qtbot, window):
    wait_for_points(qtbot, window, 3)
    window.editor.parameter_table.set_value("l", 1.5)
    qtbot.wait(200)
    _open(qtbot, window, "harmonic_oscillator")
    assert not [p for p in window.preferences.recent if "unsaved" in p]


def test_new_scene_builds_the_template(qtbot, window):
    wait_for_points(qtbot, window, 3)
    before = window.built
    window.new_scene()
    qtbot.waitUntil(lambda: window.built is not before, timeout=60000)
    assert window.scene_path is None
    assert window.compiled.mechanics.scene.coordinates == tuple(
        c.strip() for c in window.editor.coordinates.text().split(",")
    )


def test_the_window_fits_small_laptop_screens(qtbot, window):
    hint = window.minimumSizeHint()
    for width, height in ((1366, 768), (1280, 800)):
        # a title bar and a task bar take about 70 px of the screen's height
        assert hint.width() <= width and hint.height() <= height - 70, hint


def test_reset_layout_brings_every_dock_that_applies_back(qtbot, window):
    for dock in window.docks.values():
        dock.hide()
    window.docks["configuration"].setFloating(True)
    window.reset_layout()
    for key, dock in window.docks.items():
        # the pendulum has no normal modes to show (one coordinate) nor constraint forces;
        # the chaos estimates come only when asked for (View > Chaos), and the orbit
        # diagram is for driven scenes
        hidden = ("modes", "constraints", "chaos", "orbit_diagram")
        assert dock.isHidden() == (key in hidden), key
        assert not dock.isFloating(), key


def test_every_control_says_what_it_does(qtbot, window):
    bare = []
    for root in (window.controls, window.phase_view):
        widgets = [
            w for kind in (QAbstractButton, QComboBox, QLineEdit) for w in root.findChildren(kind)
        ]
        for widget in widgets:
            if widget.isVisibleTo(root) and not widget.toolTip():
                label = widget.text() if hasattr(widget, "text") else ""
                bare.append(f"{type(widget).__name__} {label!r}")
    assert not bare, bare
    assert "Automatic choice" in window.controls.method_combo.toolTip()


@pytest.mark.parametrize("show", ["show_quick_tour", "show_scene_format", "show_session_format"])
def test_help_shows_the_documents(qtbot, window, show):
    dialog = getattr(window, show)()
    text = dialog.findChild(QTextBrowser).toPlainText()
    assert len(text) > 500 and "not part of this installation" not in text
    dialog.close()


def test_tabs_are_named_as_session_scripts_name_them(qtbot, window):
    names = window.tab_names()
    for name in ("editor", "configuration", "conserved", "textbook", "equilibria", "derivation"):
        assert name in names
    window.show_tab("equilibria")
    assert window.textbook.tabs.currentIndex() == 0
    window.show_tab("Hamilton's principle")
    assert (
        window.textbook.tabs.tabText(window.textbook.tabs.currentIndex()) == "Hamilton's principle"
    )
    with pytest.raises(KeyError, match="tabs:"):
        window.show_tab("nowhere")


def test_wheel_over_an_unfocused_speed_box_changes_nothing(qtbot, window):
    from PySide6.QtCore import QPoint, QPointF, Qt
    from PySide6.QtGui import QWheelEvent
    from PySide6.QtWidgets import QApplication

    combo = window.controls.speed_combo
    combo.clearFocus()
    before = combo.currentIndex()
    event = QWheelEvent(
        QPointF(5, 5),
        QPointF(combo.mapToGlobal(QPoint(5, 5))),
        QPoint(0, 0),
        QPoint(0, -120),
        Qt.MouseButton.NoButton,
        Qt.KeyboardModifier.NoModifier,
        Qt.ScrollPhase.NoScrollPhase,
        False,
    )
    QApplication.sendEvent(combo, event)
    assert combo.currentIndex() == before
    assert math.isfinite(window.controls.speed) or before == combo.count() - 1
