"""The constraint-forces panel: offered for scenes with constraints or particles and not
for others, filled from a run in the window with the right numbers in its caption, and
started afresh on reset and on a change of scene."""

from __future__ import annotations

import math
import re

import numpy as np
import pytest

from explorer.panels.constraint_forces_view import _number
from systems import constraint_forces as cf
from tests.explorer.conftest import wait_for_points


def _opened(qtbot, window, name: str) -> None:
    request = window.open_scene(name)
    qtbot.waitUntil(
        lambda: window.built is not None and window.built.request == request, timeout=120000
    )
    qtbot.waitUntil(lambda: window.constraint_view.analysis is not None, timeout=30000)


def _shown(qtbot, window, rows: int = 40) -> None:
    """Bring the panel forward and wait until it has drawn ``rows`` rows."""
    window.show_tab("constraints")
    view = window.constraint_view
    wait_for_points(qtbot, window, rows)
    qtbot.waitUntil(lambda: view.power_curve.point_count() >= rows, timeout=30000)


def _main_rows(window):
    main = window.store.main
    t, y = main.t.data.copy(), main.y.data.copy()
    keep = np.all(np.isfinite(y), axis=1)
    return t[keep], y[keep]


def test_offered_for_constraints_and_particles_only(qtbot, window):
    dock, view = window.docks["constraints"], window.constraint_view
    action = dock.toggleViewAction()
    # the simple pendulum is written with T and V: no constraint anywhere
    assert dock.isHidden() and not action.isEnabled()
    assert view.analysis is not None and not view.analysis.applies
    for name, offered in [
        ("cartesian_pendulum", True),
        ("planetary_motion", False),  # a particle in polar coordinates: none eliminated
        ("double_pendulum", True),
        ("kepler_cartesian", False),
    ]:
        _opened(qtbot, window, name)
        assert dock.isHidden() is not offered, name
        assert action.isEnabled() is offered, name
        assert view.analysis.applies is offered, name
    # a scene with forces on its coordinates only: a reason instead of numbers
    _opened(qtbot, window, "damped_pendulum")
    assert not dock.isHidden()
    window.show_tab("constraints")
    assert view.stack.currentWidget() is view.message
    assert "not computed" in view.message.text() and "dissipation" in view.message.text()
    assert view._force_curves == [] or view.power_curve.point_count() == 0
    assert window.error_details == ""


def test_the_cartesian_pendulum_fills_the_panel_with_the_tension(qtbot, window):
    view = window.constraint_view
    _opened(qtbot, window, "cartesian_pendulum")
    assert view.analysis.k == 1 and view.stack.currentWidget() is view.layout_widget
    _shown(qtbot, window)
    # lambda, and the force on the bob, whose x and y are the coordinates
    assert view.force_legend.entries() == ["λ<sub>1</sub>", "|R<sub>bob</sub>|"]
    text = view.caption.text()
    assert "(zero: D'Alembert)" in text and "power: zero, scleronomic" in text, text
    assert view.largest_virtual_work <= 1e-15
    assert view.largest_relative_power <= 1e-14
    # the curve holds the multipliers of the run's rows: the string's tension 2 lambda l
    t, y = _main_rows(window)
    drawn_t, drawn = view._force_series[0].columns()
    n = min(len(drawn_t), len(t))
    np.testing.assert_array_equal(drawn_t[:n], t[:n])
    lam = window.compiled.constraints().multipliers(t[:n], y[:n])[:, 0]
    np.testing.assert_allclose(drawn[:n], lam, rtol=1e-13, atol=1e-13)
    x, yy, vx, vy = y[:n].T
    tension = 9.81 * (-yy) + (x * vy - yy * vx) ** 2  # m = l = 1
    np.testing.assert_allclose(2 * drawn[:n], tension, rtol=0, atol=1e-9)
    _, bob = view._force_series[1].columns()
    np.testing.assert_allclose(bob[:n], tension, rtol=0, atol=1e-9)
    # the reported virtual work is the largest of the rows drawn
    shown = float(re.search(r"constraint forces: ([0-9.e+-]+) ", text).group(1))
    assert shown == float(f"{view.largest_virtual_work:.1g}")
    assert window.error_details == ""


def test_the_pulled_string_s_work_is_the_change_of_energy(qtbot, window):
    view = window.constraint_view
    _opened(qtbot, window, "variable_length_pendulum")
    _shown(qtbot, window, 120)
    text = view.caption.text()
    assert "power ≠ 0: the constraint moves (rheonomic)" in text, text
    found = re.search(r"W = ([-0-9.e+]+), E − E₀ = ([-0-9.e+]+)", text)
    assert found, text
    assert found.group(1) == _number(view.work) and found.group(2) == _number(view.energy_change)
    # the panel's W is the work along the rows it was given: E - E0 at the last row
    analysis, compiled = view.analysis, window.compiled
    t, y = _main_rows(window)
    seen = t <= view._seen_t
    t, y = t[seen], y[seen]
    energy = analysis.evaluate(compiled, t, y).energy
    assert view.energy_change == pytest.approx(energy[-1] - energy[0], abs=1e-12)
    assert abs(view.work - view.energy_change) <= 1e-7 * max(1.0, abs(view.energy_change))
    drawn_t, drawn_w = view._work_series.columns()
    assert np.max(np.abs(drawn_w)) > 0.1  # the string did work
    assert drawn_t[-1] == t[-1] and drawn_w[-1] == view.work
    assert window.error_details == ""


def test_reset_and_another_scene_start_the_panel_afresh(qtbot, window):
    view = window.constraint_view
    _opened(qtbot, window, "atwood_rope")
    _shown(qtbot, window, 4)  # a uniform acceleration: DOP853 takes few, long steps
    assert view.force_legend.entries() == [
        "λ<sub>1</sub>",
        "|R<sub>mass1</sub>|",
        "|R<sub>mass2</sub>|",
    ]
    # the rope's tension, 2 m1 m2 g/(m1 + m2), on each curve
    tension = 2 * 1.2 * 1.0 * 9.81 / 2.2
    for series in view._force_series:
        _, values = series.columns()
        np.testing.assert_allclose(values, tension, rtol=1e-10)
    before = view._power.rows.data.shape[0]
    store = window.store
    window.controls.reset_requested.emit()
    assert window.store is not store
    assert view._power.rows.data.shape[0] == 0 and math.isinf(view._seen_t)
    assert view.caption.text().startswith("Waiting") or view.caption.text() == ""
    wait_for_points(qtbot, window, 3)
    qtbot.waitUntil(lambda: view._power.rows.data.shape[0] >= 3, timeout=30000)
    t, _ = _main_rows(window)
    drawn_t, _ = view._power.columns()
    assert drawn_t[0] == t[0] == 0.0  # from the new start, nothing of the last run
    assert before >= 4
    # another scene: nothing of the last one stays
    _opened(qtbot, window, "simple_pendulum")
    assert window.docks["constraints"].isHidden()
    assert view._force_curves == [] and view._power.rows.data.shape[0] == 0
    _opened(qtbot, window, "cartesian_pendulum")
    _shown(qtbot, window, 10)
    assert view.force_legend.entries() == ["λ<sub>1</sub>", "|R<sub>bob</sub>|"]
    assert len(view._force_series) == 2
    assert window.error_details == ""


def test_the_caption_says_what_is_not_known():
    analysis = cf.ConstraintForces(applies=True, k=1, rheonomic=True, balance=False)
    from explorer.panels.constraint_forces_view import caption

    text, _ = caption(analysis, 3e-16, 0.5, math.nan, math.nan, gaps=1)
    assert "W = unknown" in text and "3e-16 (zero: D'Alembert)" in text
    text, _ = caption(analysis, 0.2, 0.5, 1.0, math.nan)
    assert "NOT zero" in text
