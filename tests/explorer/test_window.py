"""The live window: data arrives in every panel, clicks launch orbits, edits take effect."""

from __future__ import annotations

import numpy as np
import pytest
from PySide6.QtCore import QPoint, QPointF, Qt

from tests.explorer.conftest import wait_for_points


def _curve_points(curve) -> int:
    return curve.point_count()


def test_pendulum_window_is_alive(qtbot, window):
    wait_for_points(qtbot, window, 30)
    qtbot.waitUntil(lambda: window.redraws > 3, timeout=10000)
    window._on_redraw_timer_timeout()
    phase = window.phase_view
    # level sets, the separatrix through the saddles at theta = ±pi, and a moving orbit
    assert phase.level_sets_available
    energies = {round(s.energy, 6) for s in phase.saddles}
    m, g, l = (window.compiled.parameters[i] for i in range(3))
    assert energies == {round(m * g * l, 6)}
    assert sorted(round(abs(s.q), 4) for s in phase.saddles) == [round(np.pi, 4)] * 2
    assert _curve_points(phase._curves[0]) >= 30
    # every point is drawn: nothing clipped or downsampled away from a closed orbit
    shown_x, shown_y = phase._curves[0].tail.getData()
    main = window.store.main
    assert len(shown_x) == len(main.t) and np.allclose(shown_y, main.y.data[:, 1])
    # the mechanism: one rod from the pivot to the bob, of length l
    rod_x, rod_y = window.configuration_view._rods.getData()
    assert np.hypot(rod_x[1] - rod_x[0], rod_y[1] - rod_y[0]) == pytest.approx(l)
    # the conserved view shows a small relative energy error
    error_curve = window.conserved_view._energy_curves[0]
    assert _curve_points(error_curve) >= 30
    assert "ΔH" in window.error_label.text()
    assert window.method_label.text().endswith(window.built.method)
    # one signal per frame, not per point: far fewer frames than points
    assert window.worker.frames < len(window.store.main.t)


def test_running_redraws_set_no_axis_label_again(qtbot, window, monkeypatch):
    """Frames move the plots' ranges; no axis sets its label's HTML again for that (with
    pyqtgraph's automatic SI prefix every axis did, hidden ones too: 28 a second)."""
    import pyqtgraph as pg

    set_again = []
    update_label = pg.AxisItem._updateLabel
    monkeypatch.setattr(
        pg.AxisItem, "_updateLabel", lambda axis: (set_again.append(axis), update_label(axis))
    )
    wait_for_points(qtbot, window, 30)
    redraws = window.redraws
    qtbot.waitUntil(lambda: window.redraws > redraws + 10, timeout=20000)
    assert len(window.store.main.t) > 30  # the orbit grew, and the ranges with it
    assert set_again == []


def test_click_in_phase_view_launches_a_trajectory(qtbot, window):
    wait_for_points(qtbot, window, 5)
    phase = window.phase_view
    view = phase.plot.getViewBox()
    scene_point = view.mapViewToScene(QPointF(0.5, 2.0))  # theta = 0.5, p_theta = 2.0
    pixel = phase.plot_widget.mapFromScene(scene_point)
    qtbot.mouseClick(phase.plot_widget.viewport(), Qt.MouseButton.LeftButton, pos=QPoint(pixel))
    qtbot.waitUntil(lambda: len(window.store) == 2, timeout=5000)
    launched = window.store.trajectories[1]
    assert launched.y0 == pytest.approx([0.5, 2.0], abs=0.05)
    wait_for_points(qtbot, window, 10, key=1)
    qtbot.waitUntil(lambda: 1 in phase._curves and phase._curves[1].point_count() >= 10)
    assert launched.colour != window.store.main.colour
    # its level set is drawn in its colour; clearing removes it again
    assert 1 in phase._energy_items
    window.controls.clear_button.click()
    assert len(window.store) == 1
    qtbot.waitUntil(lambda: 1 not in phase._curves, timeout=3000)


def test_bad_expression_shows_inline_error_and_keeps_text(qtbot, window):
    editor = window.editor
    field = editor.fields["potential"]
    field.edit.clear()
    qtbot.keyClicks(field.edit, "-m*g*l*cos(theta")
    qtbot.waitUntil(lambda: field.has_error, timeout=20000)
    assert field.text() == "-m*g*l*cos(theta"
    text = field.error_label.text()
    assert "never closed" in text and "position 11" in text
    # the running system is untouched by a failed edit
    assert window.runner is not None and window.runner.running
    # fixing it clears the error and starts the new system
    qtbot.keyClicks(field.edit, ")")
    qtbot.waitUntil(
        lambda: not field.has_error and editor.state_label.text().startswith("derived"),
        timeout=30000,
    )


def test_undo_restores_an_edit(qtbot, window):
    editor = window.editor
    field = editor.fields["kinetic"]
    original = field.text()
    qtbot.keyClicks(field.edit, "*2")
    qtbot.waitUntil(lambda: editor.undo_button.isEnabled(), timeout=5000)
    editor.undo()
    assert field.text() == original
    assert editor.redo_button.isEnabled()
    editor.redo()
    assert field.text() == original + "*2"


def test_parameter_change_mid_run_restarts_on_new_values(qtbot, window):
    wait_for_points(qtbot, window, 10)
    old_generation = window.worker.generation
    old_saddle = window.phase_view.saddles[0].energy
    window.editor.parameter_table.set_value("g", 4.0)
    qtbot.waitUntil(lambda: window.worker.generation > old_generation, timeout=5000)
    values = dict(zip(window.compiled.parameter_names, window.compiled.parameters, strict=True))
    assert values["g"] == 4.0
    wait_for_points(qtbot, window, 10)
    assert window.phase_view.saddles[0].energy == pytest.approx(old_saddle * 4.0 / 9.81)
    # the old worker's thread ended
    assert window.worker.frames > 0


def test_hidden_panel_gets_no_diagnostics(qtbot, window):
    wait_for_points(qtbot, window, 5)
    assert "H" in window.settings.diagnostics
    window.docks["conserved"].hide()
    qtbot.waitUntil(lambda: "H" not in window.worker.settings.diagnostics, timeout=3000)
    count = len(window.store.main.t)
    wait_for_points(qtbot, window, count + 5)
    assert np.isnan(window.store.main.energy.data[-1])
    window.docks["conserved"].show()
    qtbot.waitUntil(lambda: "H" in window.worker.settings.diagnostics, timeout=3000)


def test_pause_step_and_reset(qtbot, window):
    wait_for_points(qtbot, window, 5)
    window.controls.play_button.setChecked(False)
    worker = window.worker
    # the frame being computed when Pause came may still arrive: wait until the worker
    # has gone round its loop twice since (it now idles) and the GUI took every frame
    turns = worker.iterations
    qtbot.waitUntil(
        lambda: worker.iterations >= turns + 2 and worker._receipt.taken == worker.frames,
        timeout=10000,
    )
    frozen = len(window.store.main.t)
    qtbot.wait(200)
    assert len(window.store.main.t) == frozen
    window.controls.step_button.click()
    qtbot.waitUntil(lambda: len(window.store.main.t) > frozen, timeout=3000)
    window.controls.play_button.setChecked(True)
    window.controls.reset_button.click()
    wait_for_points(qtbot, window, 3)
    assert window.store.main.t.data[0] == 0.0


def test_close_stops_every_thread(qtbot, qt_activity):
    from explorer.app import create_window

    win = create_window("simple_pendulum")
    win.show()
    qtbot.waitUntil(lambda: win.runner is not None, timeout=60000)
    assert qt_activity.dangling()  # the worker, the builder and the redraw timer
    win.close()
    assert qt_activity.dangling() == []


def test_save_scene_writes_the_edited_system(qtbot, window, tmp_path):
    from systems.scene import load_scene

    wait_for_points(qtbot, window, 3)
    window.editor.parameter_table.set_value("l", 1.5)
    qtbot.waitUntil(lambda: window.compiled.parameters[2] == 1.5, timeout=5000)
    path = tmp_path / "long_pendulum.toml"
    window.save_scene(path)
    saved = load_scene(path)
    assert saved.parameter_values["l"] == 1.5
    assert saved.coordinates == ("theta",) and saved.potential == "-m*g*l*cos(theta)"


def test_switching_an_effect_off_rebuilds_a_conservative_system(qtbot, window):
    request = window.open_scene("damped_pendulum")
    qtbot.waitUntil(
        lambda: window.built is not None and window.built.request == request, timeout=90000
    )
    assert not window.compiled.mechanics.classification.conservative
    assert "not conserved" in window.conserved_view.energy_plot.titleLabel.text
    window.editor.dissipation_switch.setChecked(False)
    qtbot.waitUntil(
        lambda: (
            window.built.request > request and window.compiled.mechanics.classification.conservative
        ),
        timeout=90000,
    )
    assert window.compiled.mechanics.scene.enabled_effects() == []
    assert "energy error" in window.conserved_view.energy_plot.titleLabel.text
    wait_for_points(qtbot, window, 5)


def test_dragging_a_slider_restarts_once_it_rests(qtbot, window):
    wait_for_points(qtbot, window, 3)
    start = window.worker.generation
    slider = window.editor.parameter_table.slider("g")
    for position in range(400, 700, 10):  # thirty values in quick succession
        slider.setValue(position)
    qtbot.waitUntil(lambda: window.worker.generation > start, timeout=5000)
    qtbot.wait(300)
    assert window.worker.generation == start + 1
    g = dict(zip(window.compiled.parameter_names, window.compiled.parameters, strict=True))["g"]
    assert g == pytest.approx(19.62 * 690 / 1000, rel=1e-3)


def test_classification_card_lists_the_equilibria(qtbot, window):
    window.open_scene("simple_pendulum")
    qtbot.waitUntil(lambda: "Equilibria" in window.editor.classification_card.text(), timeout=60000)
    text = window.editor.classification_card.text()
    assert "θ = 0: stable, ω = 3.132" in text
    assert "θ = 3.142: unstable" in text


def test_methods_that_would_drop_an_effect_are_disabled_with_the_reason(qtbot, window):
    request = window.open_scene("damped_pendulum")
    qtbot.waitUntil(
        lambda: window.built is not None and window.built.request == request, timeout=90000
    )
    combo = window.controls.method_combo
    names = [combo.itemData(i) for i in range(combo.count())]
    from systems.integrators import STEPPERS

    assert names[1:] == list(STEPPERS)  # every method is listed
    for name in ("leapfrog", "yoshida8", "logh_yoshida6"):
        index = names.index(name)
        assert not combo.model().item(index).isEnabled()
        assert "dissipation" in window.controls.refusal(name)
    for name in ("gauss_legendre6", "dop853", "rk4"):
        assert combo.model().item(names.index(name)).isEnabled()
        assert window.controls.refusal(name) is None
    # the adaptive automatic choice takes a tolerance, and shows the one in use
    assert window.controls.step_label.text() == "tol:"
    wait_for_points(qtbot, window, 5)
    window._update_status()
    assert window.controls.step_edit.placeholderText() == "auto: 1e-12"


def test_automatic_step_is_shown_and_the_energy_guard_is_a_setting(qtbot, window):
    wait_for_points(qtbot, window, 5)
    window._update_status()
    main = window.store.main
    assert main.setting == "dt" and main.setting_value > 0
    assert window.controls.step_edit.placeholderText() == f"auto: {main.setting_value:.3g}"
    window.set_energy_tolerance(None)
    assert window.worker.settings.energy_tolerance is None
    window.set_energy_tolerance(1e-3)
    assert window.worker.settings.energy_tolerance == 1e-3
