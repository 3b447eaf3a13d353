"""The window's Max accuracy button (issue 28 item 2): one click switches the run to
taylor at machine epsilon where the system allows it, or says why not; choosing a method
again undoes it; a session records it as the method lines it amounts to."""

from __future__ import annotations

import numpy as np
from PySide6.QtCore import Qt

from tests.explorer.conftest import wait_for_points

EPS = float(np.finfo(float).eps)


def test_one_click_runs_taylor_at_machine_epsilon_and_the_list_undoes_it(qtbot, window):
    from explorer.session import Recorder

    recorder = Recorder(window)
    controls = window.controls
    assert controls.method is None  # automatic
    assert "machine-epsilon" in controls.accuracy_button.toolTip()
    # a tolerance typed for another adaptive method is not machine epsilon: it goes
    controls.method_combo.setCurrentIndex(controls.method_combo.findData("dop853"))
    controls.step_edit.setText("1e-9")
    controls.step_edit.editingFinished.emit()
    assert window.worker.settings.tol == 1e-9
    with qtbot.waitSignal(controls.notice_posted) as posted:
        qtbot.mouseClick(controls.accuracy_button, Qt.MouseButton.LeftButton)
    assert controls.method == "taylor" and controls.step_edit.text() == ""
    assert "Max accuracy: taylor" in posted.args[0] and "dop853" in posted.args[0]
    assert window.statusBar().currentMessage() == posted.args[0]
    settings = window.worker.settings
    assert settings.method == "taylor" and settings.tol is None  # the default: eps
    wait_for_points(qtbot, window, 5)
    qtbot.waitUntil(lambda: window.store.main.setting_value == EPS, timeout=60000)
    window._update_status()
    assert controls.step_edit.placeholderText() == f"auto: {EPS:.3g}"
    # a second click changes nothing and says so
    with qtbot.waitSignal(controls.notice_posted) as posted:
        qtbot.mouseClick(controls.accuracy_button, Qt.MouseButton.LeftButton)
    assert "Already at max accuracy" in posted.args[0] and controls.method == "taylor"
    # undone by choosing a method again
    controls.method_combo.setCurrentIndex(0)
    assert controls.method is None and window.worker.settings.method != "taylor"
    lines = [text for text in recorder.lines if not text.startswith("run-until")]
    assert lines[-5:] == ["method dop853", "dt 1e-09", "dt auto", "method taylor", "method auto"]


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
