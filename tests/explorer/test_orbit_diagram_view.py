"""View > Orbit diagram: offered for a periodically driven scene only; Draw plots the
state once per period over the parameter, with progress and Cancel."""

from __future__ import annotations

import numpy as np

from explorer.panels import orbit_diagram_view


def _open(qtbot, window, name):
    request = window.open_scene(name)
    qtbot.waitUntil(
        lambda: window.built is not None and window.built.request == request, timeout=90000
    )
    return window.orbit_diagram_view


def test_the_driven_pendulums_period_doubling(qtbot, window, monkeypatch):
    monkeypatch.setattr(orbit_diagram_view, "TRANSIENT_PERIODS", 100)
    view = _open(qtbot, window, "driven_damped_pendulum")
    action = window.docks["orbit_diagram"].toggleViewAction()
    assert view.reason is None and action.isEnabled()
    assert view.parameter_combo.currentText() == "A"
    assert (view.low.value(), view.high.value()) == (1.0, 1.5)  # two thirds of A to A
    view.count.setValue(12)
    view.draw_button.click()
    assert not view.draw_button.isEnabled()
    qtbot.waitUntil(lambda: view.diagram is not None, timeout=120000)
    diagram = view.diagram
    assert diagram.parameter == "A" and diagram.samples.shape == (12, 32, 2)
    assert np.allclose(diagram.values, np.linspace(1.0, 1.5, 12))
    x, y = view.scatter.getData()
    assert len(x) == 12 * 32 and np.isfinite(y).all()
    assert "once per period" in view.info.text() and view.draw_button.isEnabled()
    assert diagram.method == "taylor" and "taylor" in view.info.text()
    # shown (View > Orbit diagram) while the pendulum runs: the window's redraw passes it
    # by (it draws its own results, not the store's: refresh raised AttributeError)
    action.trigger()
    assert not window.docks["orbit_diagram"].isHidden()
    window.store.mark_dirty()
    window._on_redraw_timer_timeout()


def test_cancel_and_an_autonomous_scene(qtbot, window, monkeypatch):
    monkeypatch.setattr(orbit_diagram_view, "TRANSIENT_PERIODS", 2000)
    monkeypatch.setattr(orbit_diagram_view, "CHUNK", 1)  # a cancel waits for one chunk
    view = _open(qtbot, window, "driven_damped_pendulum")
    view.count.setValue(400)
    view.start()
    thread = view._thread
    view.cancel_button.click()
    assert not thread.is_alive() and view.diagram is None and view.draw_button.isEnabled()
    view = _open(qtbot, window, "henon_heiles")
    assert "not a periodic drive" in view.reason or "no parameters" in view.reason
    assert not window.docks["orbit_diagram"].toggleViewAction().isEnabled()
    assert not view.draw_button.isEnabled()
