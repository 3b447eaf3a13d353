"""A periodically driven scene's section is stroboscopic: the Poincaré box is offered,
and the points are the states once per period of the drive."""

from __future__ import annotations

import math

import numpy as np

from systems.simulation import Run, Sampler
from tests.explorer.conftest import wait_for_points


def test_the_driven_pendulums_section_is_one_point_per_period(qtbot, window):
    request = window.open_scene("driven_damped_pendulum")
    qtbot.waitUntil(
        lambda: window.built is not None and window.built.request == request, timeout=90000
    )
    phase = window.phase_view
    T = 3 * math.pi  # w = 2/3
    assert phase.poincare_available and phase.section is None
    assert phase.strobe_period == np.float64(T) or abs(phase.strobe_period - T) < 1e-12
    assert "once per period" in phase.poincare_box.toolTip()
    phase.poincare_box.setChecked(True)
    assert phase.mode == "poincare" and window.settings.strobe == phase.strobe_period
    assert window.settings.section is None and window.settings.speed == np.inf
    assert "Stroboscopic" in phase.plot.titleLabel.text
    wait_for_points(qtbot, window, 2)
    qtbot.waitUntil(lambda: len(phase.section_points(0)) >= 5, timeout=60000)
    points = phase.section_points(0)[:5]
    compiled = window.compiled
    run = Run(compiled, method="dop853", tol=1e-12, t_end=6 * T)
    exact = np.array([y for _, y in Sampler(run, T * np.arange(1, 6))][1:])
    assert np.abs(points - exact).max() < 1e-5  # the window's own method and step
    # a click starts an orbit at that (theta, p_theta)
    launched = []
    phase.launch_requested.connect(launched.append)
    phase.launch_at(0.5, -0.25)
    assert np.allclose(launched[0], [0.5, -0.25])
    phase.poincare_box.setChecked(False)
    assert window.settings.strobe is None
