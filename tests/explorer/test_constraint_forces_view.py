"""The constraint-forces panel: offered for scenes with constraints or particles and not
for others, filled from a run in the window with the right numbers in its caption, and
started afresh on reset and on a change of scene."""

from __future__ import annotations

import dataclasses
import math
import re

import numpy as np
import pytest

from explorer.panels.constraint_forces_view import ConstraintForcesView, _number, caption
from systems import constraint_forces as cf
from systems.compiled import compile_system
from systems.mechanics import derive
from systems.scene import load_scene
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
    assert view.force_legend.entries() == ["λ<sub>1</sub> (holonomic)", "|R<sub>bob</sub>|"]
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
    # the rope, then the pulley and the floor for each mass (issue 25)
    stops = ["-y1 ≥ 0", "-y2 ≥ 0", "h + y1 ≥ 0", "h + y2 ≥ 0"]
    assert view.force_legend.entries() == [
        "λ<sub>1</sub> (holonomic)",
        *(f"λ<sub>{k}</sub> ({stop})" for k, stop in enumerate(stops, start=2)),
        "|R<sub>mass1</sub>|",
        "|R<sub>mass2</sub>|",
    ]
    # the rope's tension, 2 m1 m2 g/(m1 + m2), on the rope's curve and each reaction;
    # no stop touches before the landing at t = 3.36
    tension = 2 * 1.2 * 1.0 * 9.81 / 2.2
    for k, series in enumerate(view._force_series):
        _, values = series.columns()
        expected = 0.0 if 1 <= k <= 4 else tension
        np.testing.assert_allclose(values, expected, rtol=1e-10, atol=1e-12)
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
    assert view.force_legend.entries() == ["λ<sub>1</sub> (holonomic)", "|R<sub>bob</sub>|"]
    assert len(view._force_series) == 2
    assert window.error_details == ""


def test_the_caption_says_what_is_not_known():
    analysis = cf.ConstraintForces(applies=True, k=1, rheonomic=True, balance=False)
    text, _ = caption(analysis, 3e-16, 0.5, math.nan, math.nan, gaps=1)
    assert "W = unknown" in text and "3e-16 (zero: D'Alembert)" in text
    text, _ = caption(analysis, 0.2, 0.5, 1.0, math.nan)
    assert "NOT zero" in text


# -- nonholonomic and unilateral constraints: the view alone, on numpy -----------------------------


def _standalone(qtbot, name: str):
    """The view of a catalogue scene compiled without kernels (nothing for numba to
    compile: the forces come from numpy), with its analysis made here so that
    ``set_system`` shows it at once."""
    mechanics = derive(load_scene(name))
    compiled = compile_system(mechanics, ())
    cf.analyse(mechanics)
    view = ConstraintForcesView()
    qtbot.addWidget(view)
    view.set_system(compiled)
    return view, compiled


def test_the_analysis_is_made_in_a_worker_and_kept_for_the_derivation(qtbot):
    """Without an analysis of its derivation, ``set_system`` has one made in a worker
    process: its functions evaluate here, and it is filed under this derivation."""
    mechanics = derive(load_scene("cartesian_pendulum"))
    compiled = compile_system(mechanics, ())
    view = ConstraintForcesView()
    qtbot.addWidget(view)
    view.set_system(compiled)
    assert view.analysis is None and "Working out" in view.message.text()
    qtbot.waitUntil(lambda: view.analysis is not None, timeout=30000)
    assert view.analysis.computes and view.analysis.k == 1
    assert cf.known(mechanics) is view.analysis
    assert view.stack.currentWidget() is view.layout_widget
    t = np.linspace(0.0, 1.0, 11)
    view.update(t, np.tile(compiled.initial_state(), (len(t), 1)))
    assert view._force_series[0].rows.data.shape == (len(t), 2)
    view.set_system(compiled.with_parameters({"g": 1.0}))  # the same derivation: at once
    assert view.analysis is cf.known(mechanics)
    _settled(qtbot, view)


def _settled(qtbot, view) -> None:
    view.shutdown()  # no timer left behind
    qtbot.waitUntil(lambda: not view.layout_widget._later.isActive(), timeout=5000)


def test_the_rolling_disk_s_multipliers_are_drawn_by_kind(qtbot):
    view, compiled = _standalone(qtbot, "rolling_disk")
    assert view.stack.currentWidget() is view.layout_widget  # not "not computed"
    assert view.force_legend.entries() == [
        "λ<sub>1</sub> (nonholonomic)",
        "λ<sub>2</sub> (nonholonomic)",
        "|R<sub>contact</sub>|",
    ]
    # the scene's motion: a circle of radius 2 at speed 1, phi_dot = 0.5, psi_dot = 2
    m, R = compiled.parameters
    t = np.linspace(0.0, 4.0, 81)
    phi = 0.5 * t
    Y = np.stack(
        [
            2 * np.sin(phi),
            -2 * np.cos(phi),
            phi,
            2 * t,
            m * np.cos(phi),
            m * np.sin(phi),
            m * R**2 / 4 * 0.5 + 0 * t,
            m * R**2 / 2 * 2 + 0 * t,
        ],
        axis=1,
    )
    view.update(t, Y)
    # lambda = m R phi_dot psi_dot (sin phi, -cos phi); the ground's sideways force on the
    # contact point is the centripetal m v^2/r = 0.5
    lam = [view._force_series[i].columns()[1] for i in range(2)]
    np.testing.assert_allclose(lam[0], 0.5 * np.sin(phi), rtol=0, atol=1e-14)
    np.testing.assert_allclose(lam[1], -0.5 * np.cos(phi), rtol=0, atol=1e-14)
    np.testing.assert_allclose(view._force_series[2].columns()[1], 0.5, rtol=1e-14)
    assert view._force_curves[0].point_count() > 0 and view.power_curve.point_count() > 0
    text = view.caption.text()
    assert "(zero: D'Alembert)" in text and "power: zero, scleronomic" in text, text
    assert "not computed" not in text and "impacts" not in text
    assert view.largest_virtual_work <= 1e-15 and view.largest_relative_power <= 1e-15
    assert "a·δq = 0" in view.caption.toolTip()
    _settled(qtbot, view)


def test_the_bouncing_ball_s_floor_pushes_only_in_contact_and_impacts_are_not_forces(qtbot):
    view, compiled = _standalone(qtbot, "bouncing_ball")
    assert view.stack.currentWidget() is view.layout_widget
    assert view.force_legend.entries() == ["λ<sub>1</sub> (y ≥ 0)", "|R<sub>ball</sub>|"]
    m, g, e = compiled.parameters
    # falling from y = 1, moving along x at 0.8 ...
    t = np.linspace(0.0, 0.4, 9)
    falling = np.stack([0.8 * t - 2, 1 - g * t**2 / 2, 0.8 * m + 0 * t, -m * g * t], axis=1)
    view.update(t, falling)
    assert "no contact (free)" in view.caption.text(), view.caption.text()
    # ... then sliding on the floor (a rebound too slow to leave: all the normal motion
    # gone at the impact, none of it by a force lambda)
    later = np.linspace(0.5, 1.0, 6)
    resting = np.stack([0.8 * later - 2, 0 * later, 0.8 * m + 0 * later, 0 * later], axis=1)
    view.update(later, resting)
    drawn_t, lam = view._force_series[0].columns()
    np.testing.assert_array_equal(drawn_t, np.concatenate([t, later]))
    assert np.all(lam[: len(t)] == 0.0)  # free flight
    np.testing.assert_allclose(lam[len(t) :], -m * g, rtol=1e-15)  # the floor's -m g
    np.testing.assert_allclose(view._force_series[1].columns()[1][len(t) :], m * g, rtol=1e-15)
    assert view.contacts == [(0, pytest.approx(-m * g, rel=1e-15))]
    text, tip = view.caption.text(), view.caption.toolTip()
    assert "in contact: y ≥ 0 (λ₁ = -9.81)" in text, text
    assert "impacts: velocity jumps, not forces λ" in text
    # the floor did no work; the energy lost, m g y0 = 9.81, is the impact's, said as such
    assert view.work == 0.0
    assert view.energy_change == pytest.approx(-m * g * 1.0, rel=1e-13)
    assert "h − h₀ − W = -9.81" in text, text
    assert "h − h₀ = W does not hold across impacts" in tip and "1 − e²" in tip, tip
    assert "e = 0.8" in tip
    assert "(rheonomic)" not in text and "E − E₀ =" not in text  # no balance shown as held
    _settled(qtbot, view)


def test_the_caption_of_elastic_walls_says_the_impacts_keep_the_energy():
    analysis = cf.ConstraintForces(
        applies=True, k=1, kinds=("unilateral",), descriptions=("x ≥ 0",), impacts=True,
        energy_name="h",
    )  # fmt: skip
    text, tip = caption(analysis, 0.0, 0.0, 0.0, 2e-15, contacts=[], restitution=1.0)
    assert "no contact (free)" in text and "h − h₀ − W = 2e-15" in text, text
    assert "With e = 1 and walls fixed in time they keep the energy" in tip
    text, tip = caption(analysis, 0.0, 0.0, math.nan, -1.0, contacts=None, restitution=0.5)
    assert "contact" not in text and "h − h₀ − W" not in text  # W unknown: no number
    assert "keep the energy" not in tip
    moving = dataclasses.replace(analysis, rheonomic=True)
    text, tip = caption(moving, 0.0, 0.3, math.nan, -1.0, contacts=[(0, -2.0)], restitution=1.0)
    assert "W = unknown (from an impact on" in text and "x ≥ 0 (λ₁ = -2)" in text, text
    assert "keep the energy" not in tip  # a moving wall changes it at impacts


def test_the_window_draws_every_bounce_of_the_ball(qtbot, window):
    """The trajectory the window stores (and draws in the path, the phase plane and the
    animation) rises to each flight's apex: DOP853 would otherwise cross every flight
    after the second in one exact step, and the stored states would be the impacts only,
    the ball lying on the floor from t = 1.2 s while it bounces until 4.06 s."""
    from explorer.controls import SPEEDS

    _opened(qtbot, window, "bouncing_ball")
    window.controls.speed_combo.setCurrentIndex([s for _, s in SPEEDS].index(20.0))
    qtbot.waitUntil(lambda: window.store.main.last_t >= 3.5, timeout=60000)
    t, y = _main_rows(window)
    g, e = 9.81, 0.8
    t1, v0 = math.sqrt(2 / g), math.sqrt(2 * g)  # dropped from 1 m
    start = t1
    for k in range(1, 8):  # the flights after the k-th impact
        flight = 2 * e**k * v0 / g
        inside = (t > start) & (t < start + flight)
        assert inside.any(), k
        apex = (e**k * v0) ** 2 / (2 * g)
        assert y[inside, 1].max() == pytest.approx(apex, abs=0.01), k
        start += flight
    # every impact stored as the ball arriving and leaving, at one time: the phase plane
    # draws the jump at the floor, never a chord from a state before it
    leaving = np.flatnonzero((np.abs(y[:, 1]) <= 1e-12) & (y[:, 3] > 0))
    assert len(leaving) >= 7
    assert np.all(t[leaving - 1] == t[leaving]) and np.all(y[leaving - 1, 3] < 0)
