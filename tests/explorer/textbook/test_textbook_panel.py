"""The Textbook dock: installed into the main window, it shows the theorems on any system."""

from __future__ import annotations

import math

import numpy as np
import pytest
from PySide6.QtWidgets import QMainWindow

from explorer.textbook import TextbookPanel, install
from systems import processes


def _wait_result(qtbot, view, attribute: str = "result", timeout: int = 60000) -> None:
    qtbot.waitUntil(lambda: getattr(view, attribute) is not None, timeout=timeout)


def _close(qtbot, window, panel=None) -> None:
    window.close()
    if panel is not None:  # closing the window ended every textbook computation's worker
        assert panel.runner.running == 0
        assert panel.runner.pending == 0
    window.deleteLater()
    qtbot.wait(10)


@pytest.fixture
def textbook(qtbot):
    """A main window on the simple pendulum with the Textbook dock installed, raised."""
    from explorer.app import create_window

    window = create_window("simple_pendulum")
    window.controls.play_button.setChecked(False)  # the worker idles: less load in tests
    window.show()
    panel = install(window)
    panel.dock.raise_()
    qtbot.waitUntil(lambda: window.compiled is not None, timeout=60000)
    yield window, panel
    _close(qtbot, window, panel)


def test_install_adds_a_dock_and_pendulum_equilibria(qtbot, textbook):
    window, panel = textbook
    assert isinstance(panel, TextbookPanel)
    assert window.docks["textbook"].windowTitle() == "Textbook"
    assert window.docks["textbook"] in window.tabifiedDockWidgets(window.docks["conserved"])
    _wait_result(qtbot, panel.equilibria)
    equilibria = panel.equilibria.result.search.equilibria
    assert [e.kind for e in equilibria] == ["minimum", "maximum"]
    bottom, top = equilibria
    g = dict(zip(window.compiled.parameter_names, window.compiled.parameters, strict=True))
    assert bottom.q["theta"] == pytest.approx(0.0, abs=1e-9) and bottom.stable
    assert bottom.frequencies[0] == pytest.approx(math.sqrt(g["g"] / g["l"]), rel=1e-9)
    assert abs(top.q["theta"]) == pytest.approx(math.pi) and not top.stable
    rows = panel.equilibria.row_texts()
    first, second = (" | ".join(row) for row in rows)
    assert rows[0][0] == "0" and "| stable" in first and "ω = 3.13209" in first
    assert rows[1][0] == "π" and "| unstable" in second
    # markers in the phase view: a dot at theta = 0, crosses at ±pi (and the 2pi copies)
    spots = panel.markers.spots()
    assert panel.markers.item in window.phase_view.plot.items
    dots = {round(s["pos"][0], 6) for s in spots if s["symbol"] == "o"}
    crosses = {round(s["pos"][0], 6) for s in spots if s["symbol"] == "x"}
    assert 0.0 in dots and round(math.pi, 6) in crosses and round(-math.pi, 6) in crosses
    assert all(s["pos"][1] == 0.0 for s in spots)
    assert "ω = 3.13209" in next(s["data"] for s in spots if s["pos"][0] == 0.0)
    assert len(panel.markers.item.data) == len(spots)


def test_parameter_change_recomputes_equilibria(qtbot, textbook):
    window, panel = textbook
    _wait_result(qtbot, panel.equilibria)
    window.editor.parameter_table.set_value("g", 4.0)
    qtbot.waitUntil(
        lambda: (
            panel.equilibria.result is not None
            and panel.equilibria.result.search.equilibria[0].frequencies[0]
            == pytest.approx(2.0, rel=1e-9)
        ),
        timeout=60000,
    )


def test_principle_slope_vanishes_and_action_angle_period(qtbot, textbook):
    window, panel = textbook
    principle = panel.principle
    panel.show_tab(principle)
    _wait_result(qtbot, principle)
    result = principle.result
    assert abs(result.slope) < 1e-5 * abs(result.curvature)
    assert result.nature == "minimum"
    assert "minimum" in principle.summary.text()
    # past half a period of the swing there is a conjugate point: only stationary
    principle.duration.setValue(2.5)
    qtbot.waitUntil(
        lambda: principle.result is not None and principle.result.index == 0, timeout=60000
    )
    assert principle.result.run.t[-1] == pytest.approx(2.5)
    assert principle.result.nature == "saddle"
    assert "past a conjugate point" in principle.summary.text()
    assert abs(principle.result.slope) < 1e-5 * abs(principle.result.curvature)
    principle.duration.setValue(1.0)
    _wait_result(qtbot, principle)
    # the two-point problem: both methods reach B and agree
    principle._on_solve_clicked()
    _wait_result(qtbot, principle, "boundary")
    path, shot = principle.boundary.action_path, principle.boundary.shooting_path
    assert path.converged and shot.converged
    assert path.action == pytest.approx(shot.action, rel=1e-3)

    view = panel.action_angle
    panel.show_tab(view)
    _wait_result(qtbot, view)
    r = view.result
    below = (r.energies < r.separatrix) & np.isfinite(r.exact)
    assert below.sum() > 20
    assert np.all(np.isfinite(r.period[below]))
    assert np.allclose(r.period[below], r.exact[below], rtol=1e-8)
    assert r.separatrix == pytest.approx(9.81)
    assert r.small_period == pytest.approx(2 * math.pi / math.sqrt(9.81))
    # T grows towards the separatrix
    assert r.period[below][-1] > 3 * r.small_period


def test_energy_tab_hoop_conserves_h_not_t_plus_v(qtbot, textbook):
    window, panel = textbook
    view = panel.energy
    panel.show_tab(view)
    window.open_scene("bead_on_rotating_hoop")
    qtbot.waitUntil(lambda: window.built.scene.name == "bead_on_rotating_hoop", timeout=60000)
    _wait_result(qtbot, view)
    b = view.result.balance
    assert np.ptp(b.hamiltonian) < 1e-6 * abs(b.hamiltonian[0])
    assert np.ptp(b.energy) > 1.0
    assert "not</b> T + V" in view.summary.text()
    assert np.allclose(b.rate, b.predicted, atol=1e-5)


def test_reduction_planetary_and_none_for_pendulum(qtbot, textbook):
    window, panel = textbook
    view = panel.reduction
    panel.show_tab(view)
    _wait_result(qtbot, view, "setup")
    assert view.setup.reduction is None and "No reduction" in view.summary.text()
    window.open_scene("planetary_motion")
    qtbot.waitUntil(
        lambda: view.setup is not None and view.setup.reduction is not None, timeout=60000
    )
    p_theta = float(view.setup.p_cyclic[0])
    m, k = 1.0, 1.0
    assert view.minimum_position() == pytest.approx(p_theta**2 / (m * k), rel=1e-6)
    assert view.curves.turning == pytest.approx([1.0, 3.0], rel=1e-6)  # perihelion, aphelion
    # another conserved momentum on the slider moves the minimum to p^2/(m k), drawn with
    # the functions the worker made (nothing lambdified here)
    made = set(view.setup.reduction._functions)
    view.set_momenta([1.0])
    assert set(view.setup.reduction._functions) == made
    assert view.curves.p_cyclic[0] == pytest.approx(1.0, abs=2e-3)
    assert view.minimum_position() == pytest.approx(view.curves.p_cyclic[0] ** 2, rel=1e-6)
    # no cyclic coordinate in Cartesian Kepler; action-angle refuses two degrees of freedom
    panel.show_tab(panel.action_angle)
    qtbot.waitUntil(lambda: "Not available" in panel.action_angle.summary.text(), timeout=5000)


def test_bare_window_without_phase_view(qtbot):
    """install() needs only ``system_started``; the panel works on a plain QMainWindow."""
    from PySide6.QtCore import Signal

    from explorer.builder import build
    from systems.scene import load_scene

    class Stub(QMainWindow):
        system_started = Signal(object)

    window = Stub()
    qtbot.addWidget(window)
    window.show()
    panel = install(window)
    assert panel.markers is None
    window.system_started.emit(build(load_scene("harmonic_oscillator")))
    _wait_result(qtbot, panel.equilibria)
    assert panel.equilibria.result.search.equilibria[0].frequencies[0] == pytest.approx(1.0)
    window.close()
    assert panel.runner.running == 0


def test_markers_follow_the_phase_pair(qtbot):
    """Markers sit at (q_i, 0) of the pair shown; none in the Poincaré mode."""
    import pyqtgraph as pg

    from explorer.builder import build
    from explorer.textbook.equilibria_view import EquilibriumMarkers
    from systems.scene import load_scene
    from systems.textbook import jobs

    widget = pg.PlotWidget()
    qtbot.addWidget(widget)
    markers = EquilibriumMarkers(widget.getPlotItem())
    result = jobs.equilibria(build(load_scene("double_pendulum")).compiled)
    markers.show_result(result)
    stable = [s["pos"] for s in markers.spots() if s["symbol"] == "o"]
    assert (0.0, 0.0) in stable and len(markers.spots()) == 4 * 3  # with the ±2π copies
    markers.set_pair(1, True)
    crosses = {round(s["pos"][0], 6) for s in markers.spots() if s["symbol"] == "x"}
    assert round(math.pi, 6) in crosses and 0.0 in crosses  # (θ₁, θ₂) = (π, 0) is a saddle
    assert "normal" not in markers.spots()[0]["data"] and "ω₁" in markers.spots()[0]["data"]
    markers.set_pair(1, False)
    assert markers.spots() == [] and len(markers.item.data) == 0


def test_closing_mid_computation_cancels_and_waits(qtbot):
    """A computation in flight is cancelled at close; no thread or timer is left behind."""

    from explorer.app import create_window

    window = create_window("simple_pendulum")
    window.controls.play_button.setChecked(False)
    window.show()
    panel = install(window)
    panel.dock.raise_()
    qtbot.waitUntil(lambda: window.compiled is not None, timeout=60000)
    panel.show_tab(panel.energy)
    panel.energy.duration.setValue(5000.0)  # a long run: still going when the window closes
    qtbot.waitUntil(lambda: panel.runner.running > 0, timeout=30000)
    pids = panel.runner.pids()
    # closing ends the run's worker (nothing pending); how long it takes is a
    # benchmark's business, not a test's (a busy machine)
    _close(qtbot, window, panel)
    assert not {job.pid for job in processes.running()} & set(pids)


def test_closed_forms_are_read_back_through_the_whitelist_parser(qtbot, textbook):
    window, panel = textbook
    window.open_scene("bead_on_rotating_hoop")
    qtbot.waitUntil(
        lambda: (
            window.compiled is not None
            and window.compiled.mechanics.scene.name == "bead_on_rotating_hoop"
        ),
        timeout=60000,
    )
    qtbot.waitUntil(
        lambda: any("acos" in cell for row in panel.equilibria.row_texts() for cell in row),
        timeout=60000,
    )
    cells = [cell for row in panel.equilibria.row_texts() for cell in row if "acos" in cell]
    assert any("ω" in cell and "g" in cell for cell in cells), cells


def test_a_tab_is_made_when_first_shown_and_computes_for_the_system_shown(qtbot, textbook):
    from explorer.textbook.action_angle_view import ActionAngleView
    from explorer.textbook.equilibria_view import EquilibriaView

    window, panel = textbook
    assert [type(view) for view in panel.made_views] == [EquilibriaView]
    index = next(i for i in range(panel.tabs.count()) if panel.tabs.tabText(i) == "Action–angle")
    assert panel.tabs.widget(index).widget() is None  # an empty page until then
    window.show_tab("action-angle")  # as a click on its tab
    view = panel.tabs.widget(index).widget()
    assert isinstance(view, ActionAngleView) and view is panel.action_angle
    assert [type(view) for view in panel.made_views] == [EquilibriaView, ActionAngleView]
    assert view.compiled is panel.compiled is not None  # the system the panel shows
    _wait_result(qtbot, view)  # and it computes, being in front
    assert view.result.separatrix == pytest.approx(9.81)


def test_a_tab_made_while_presenting_is_drawn_large_at_once(qtbot, textbook):
    from explorer.panels.presentation import LABEL_POINTS

    window, panel = textbook
    window.presentation.set_active(True)
    try:
        view = panel.reduction  # made now, the restyling timer not yet due
        axis = view.potential_plot.getPlotItem().getAxis("bottom")
        assert axis.labelStyle.get("font-size") == f"{LABEL_POINTS}pt"
    finally:
        window.presentation.set_active(False)
    assert axis.labelStyle.get("font-size") != f"{LABEL_POINTS}pt"
