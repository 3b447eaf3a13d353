"""The window's Max accuracy button (issue 28 item 2): one click switches the run to
taylor at a tolerance below machine epsilon (double-double, ``systems.taylor.double``)
where the system allows it, or says why not; choosing a method again undoes it; a
session records it as the method and step lines it amounts to."""

from __future__ import annotations

import numpy as np
from PySide6.QtCore import Qt

from tests.explorer.conftest import wait_for_points

EPS = float(np.finfo(float).eps)


def test_one_click_runs_taylor_in_double_double_and_the_list_undoes_it(qtbot, window):
    from explorer.session import Recorder

    recorder = Recorder(window)
    controls = window.controls
    assert controls.method is None  # automatic
    assert "below machine epsilon" in controls.accuracy_button.toolTip()
    # a tolerance typed for another adaptive method goes
    controls.method_combo.setCurrentIndex(controls.method_combo.findData("dop853"))
    controls.step_edit.setText("1e-9")
    controls.step_edit.editingFinished.emit()
    assert window.worker.settings.tol == 1e-9
    with qtbot.waitSignal(controls.notice_posted) as posted:
        qtbot.mouseClick(controls.accuracy_button, Qt.MouseButton.LeftButton)
    assert controls.method == "taylor" and controls.step_edit.text() == "1e-16"
    assert "Max accuracy: taylor" in posted.args[0] and "dop853" in posted.args[0]
    assert window.statusBar().currentMessage() == posted.args[0]
    settings = window.worker.settings
    assert settings.method == "taylor" and settings.tol == 1e-16 < EPS  # double-double
    wait_for_points(qtbot, window, 5)
    qtbot.waitUntil(lambda: window.store.main.setting_value == 1e-16, timeout=60000)
    # a second click changes nothing and says so
    with qtbot.waitSignal(controls.notice_posted) as posted:
        qtbot.mouseClick(controls.accuracy_button, Qt.MouseButton.LeftButton)
    assert "Already at max accuracy" in posted.args[0] and controls.method == "taylor"
    # undone by choosing a method again: the tolerance goes with it
    controls.method_combo.setCurrentIndex(0)
    assert controls.method is None and window.worker.settings.method != "taylor"
    assert controls.step_edit.text() == "" and window.worker.settings.tol is None
    lines = [text for text in recorder.lines if not text.startswith("run-until")]
    assert lines[-7:] == [
        "method dop853", "dt 1e-09", "dt auto", "method taylor", "dt 1e-16", "dt auto",
        "method auto",
    ]  # fmt: skip


def test_where_taylor_does_not_apply_the_click_says_why_and_changes_nothing(qtbot, window):
    request = window.open_scene("atwood_machine")
    qtbot.waitUntil(
        lambda: window.built is not None and window.built.request == request, timeout=90000
    )
    controls = window.controls
    before = (controls.method, window.worker.settings.method)
    reason = controls.refusal("taylor")
    assert reason and "constraints" in reason
    assert reason in controls.accuracy_button.toolTip()
    with qtbot.waitSignal(controls.notice_posted) as posted:
        qtbot.mouseClick(controls.accuracy_button, Qt.MouseButton.LeftButton)
    assert posted.args[0] == f"Max accuracy is not available here: {reason}"
    assert window.statusBar().currentMessage() == posted.args[0]
    # in full at the button too (the status bar cuts it beside its readouts)
    from PySide6.QtWidgets import QToolTip

    assert QToolTip.isVisible() and QToolTip.text() == posted.args[0]
    assert (controls.method, window.worker.settings.method) == before
