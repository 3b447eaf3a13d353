"""The work-precision panel sweeps in the background, draws one curve per method, cancels."""

from __future__ import annotations

from PySide6.QtGui import QImage

from explorer.builder import build
from explorer.cli import main
from explorer.panels.workprecision_view import WorkPrecisionView
from systems.scene import load_scene


def test_sweep_runs_in_background_and_draws_each_method(qtbot):
    view = WorkPrecisionView()
    qtbot.addWidget(view)
    view.set_system(build(load_scene("harmonic_oscillator")).compiled)
    view.t_end_box.setValue(2.0)
    with qtbot.waitSignal(view.result_ready, timeout=120000) as blocker:
        view.run_button.click()
        assert view.running and not view.run_button.isEnabled()
    result = blocker.args[0]
    assert not view.running
    assert result.reference.startswith("exact")
    drawn = [item.name() for item in view.error_plot.listDataItems()]
    finished = [m for m in result.methods if result.curve(m)]
    assert sorted(drawn) == sorted(finished) and len(finished) >= 3
    assert view.progress.value() == view.progress.maximum()


def test_cancel_stops_the_sweep(qtbot):
    view = WorkPrecisionView()
    qtbot.addWidget(view)
    view.set_system(build(load_scene("double_pendulum")).compiled)
    view.t_end_box.setValue(50.0)
    view.start()
    qtbot.waitUntil(lambda: view.progress.value() >= 1, timeout=120000)
    view.cancel()
    assert not view.running and view.run_button.isEnabled()


def test_export_command_draws_the_workprecision_panel(tmp_path):
    out = tmp_path / "wp.png"
    assert (
        main(
            [
                "export",
                "harmonic_oscillator",
                "--panel",
                "workprecision",
                "--t-end",
                "2",
                "--out",
                str(out),
            ]
        )
        == 0
    )
    assert QImage(str(out)).width() > 500
