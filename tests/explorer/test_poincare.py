"""The Poincaré section of Hénon–Heiles fills with points; clicks start orbits at H = E."""

from __future__ import annotations

import numpy as np
import pytest

from explorer import main_window
from tests.explorer.conftest import wait_for_points


def test_section_fills_and_click_starts_orbit_at_the_energy(qtbot, window, monkeypatch):
    # the section run must still be running when the click comes: at t = 5000 it pauses
    # for Play (a launched orbit then waits), and a fast run had got there first
    monkeypatch.setattr(main_window, "POINCARE_T_END", 1e9)
    request = window.open_scene("henon_heiles")
    qtbot.waitUntil(
        lambda: window.built is not None and window.built.request == request, timeout=90000
    )
    phase = window.phase_view
    assert phase.poincare_available
    phase.poincare_box.setChecked(True)
    assert phase.mode == "poincare"
    assert window.settings.speed == np.inf and window.settings.section is not None
    wait_for_points(qtbot, window, 2)
    qtbot.waitUntil(lambda: len(phase.section_points(0)) >= 30, timeout=60000)
    compiled = window.compiled
    points = phase.section_points(0)
    section = phase.section
    # on the section, moving upward, at the scene's energy
    assert np.allclose(points[:, section.coordinate], section.value, atol=1e-9)
    assert (points[:, compiled.n + section.coordinate] > 0).all()
    energy = compiled.hamiltonian(0.0, points)
    assert energy == pytest.approx(phase.section_energy, rel=1e-4)  # the default step
    # a click in the allowed region starts an orbit at the same energy
    launched = []
    phase.launch_requested.connect(launched.append)
    phase.launch_at(0.1, 0.1)
    assert len(launched) == 1
    assert compiled.hamiltonian(0.0, launched[0][None])[0] == pytest.approx(
        phase.section_energy, rel=1e-10
    )
    qtbot.waitUntil(lambda: len(phase.section_points(1)) >= 5, timeout=60000)
    # a click in the forbidden region is refused with a message
    refused = []
    phase.launch_refused.connect(refused.append)
    phase.launch_at(0.0, 0.59)
    assert refused and "forbidden" in refused[0]
    # leaving section mode returns to paced phase-plane trajectories
    phase.poincare_box.setChecked(False)
    assert np.isfinite(window.settings.speed)
