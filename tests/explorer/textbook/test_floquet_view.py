"""The Floquet tab (``explorer.textbook.floquet_view``): constant solutions of a driven
system, a stability chart computed in blocks with progress, periodic orbits."""

from __future__ import annotations

import numpy as np
import pytest

from explorer.textbook import floquet_view
from explorer.textbook.floquet_view import FloquetView
from explorer.textbook.tasks import TaskRunner
from systems.compiled import compile_system
from systems.mechanics import derive
from systems.scene import load_scene
from systems.textbook.floquet import STABLE, UNKNOWN, UNSTABLE


@pytest.fixture
def view(qtbot):
    runner = TaskRunner()
    widget = FloquetView(runner)
    qtbot.addWidget(widget)
    widget.resize(1100, 500)
    widget.show()
    yield widget
    runner.shutdown()


def _show(qtbot, widget, name: str):
    widget.set_system(compile_system(derive(load_scene(name))))
    qtbot.waitUntil(lambda: widget.result is not None, timeout=60000)


def test_mathieu_chart_in_blocks(qtbot, view, monkeypatch):
    monkeypatch.setattr(floquet_view, "CHART_SIZE", (9, 5))
    monkeypatch.setattr(floquet_view, "BLOCK_POINTS", 18)  # two rows per job: three jobs
    _show(qtbot, view, "mathieu_oscillator")
    assert "period T = 6.28319" in view.summary.text()
    assert "x = 0: unstable" in view.summary.text()  # delta = epsilon = 1: in a tongue
    assert view.chart_controls.isVisibleTo(view) and not view.orbit_controls.isVisibleTo(view)
    assert (view.x_name.currentText(), view.y_name.currentText()) == ("delta", "epsilon")
    view.x_low.setValue(-0.2)
    view.x_high.setValue(1.4)
    view.y_low.setValue(0.0)
    view.y_high.setValue(0.4)
    view.start_chart()
    assert view.stop_button.isEnabled()
    qtbot.waitUntil(lambda: view.progress.value() == 100, timeout=120000)
    assert not view.stop_button.isEnabled()
    codes = view.codes
    assert not np.any(codes == UNKNOWN)
    deltas = np.linspace(-0.2, 1.4, 9)
    # epsilon = 0.4: delta = 0.2 in the first tongue (0.0385..0.4361), 0.6 outside
    assert codes[-1, np.argmin(abs(deltas - 0.2))] == UNSTABLE
    assert codes[-1, np.argmin(abs(deltas - 0.6))] == STABLE
    image = view.image.image
    assert image.shape == (9, 5, 3)


def test_kapitza_lists_both_positions_and_stops_a_chart(qtbot, view):
    _show(qtbot, view, "kapitza_pendulum")
    text = view.summary.text()
    assert "θ = 0: stable" in text and "θ = 3.1416: stable" in text
    assert view.solution.count() == 2 and "3.142" in view.solution.currentText()
    view.start_chart()
    view.stop_chart()
    assert view.chart_button.isEnabled() and not view.stop_button.isEnabled()
    qtbot.waitUntil(lambda: view.runner.running == 0, timeout=30000)


def test_autonomous_system_finds_a_periodic_orbit(qtbot, view):
    _show(qtbot, view, "figure_eight")
    assert "Autonomous system" in view.summary.text()
    assert view.orbit_controls.isVisibleTo(view) and not view.chart_controls.isVisibleTo(view)
    view.start_orbit()
    qtbot.waitUntil(lambda: view.orbit is not None, timeout=120000)
    assert view.orbit.converged and "8 at 1" in view.orbit_note.text()
