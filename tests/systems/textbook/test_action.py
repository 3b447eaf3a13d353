import math

import numpy as np
import pytest

from systems.mechanics import derive
from systems.textbook.action import (
    action,
    action_curve,
    second_variation,
    shoot_two_point,
    sine_variation,
    solve_two_point,
)
from tests.systems.scenes import HENON_HEILES, OSCILLATOR, PENDULUM, scene

X1, X2 = 0.3, -0.7


@pytest.fixture(scope="module")
def oscillator():
    mech = derive(scene(OSCILLATOR))
    m, k = mech.scene.parameter_values["m"], mech.scene.parameter_values["k"]
    return mech, m, k, math.sqrt(k / m)


def true_path(w, duration, samples=2001):
    """The oscillator's path from X1 at t = 0 to X2 at t = duration."""
    t = np.linspace(0.0, duration, samples)
    a, b = X1, (X2 - X1 * math.cos(w * duration)) / math.sin(w * duration)
    x = a * np.cos(w * t) + b * np.sin(w * t)
    v = w * (-a * np.sin(w * t) + b * np.cos(w * t))
    return t, x[:, None], v[:, None]


@pytest.mark.parametrize("fraction", [0.3, 0.8, 1.4])
def test_oscillator_action_along_the_true_path(oscillator, fraction):
    mech, m, _, w = oscillator
    duration = fraction * math.pi / w  # in units of half a period
    t, q, v = true_path(w, duration)
    exact = (
        m
        * w
        / (2 * math.sin(w * duration))
        * ((X1**2 + X2**2) * math.cos(w * duration) - 2 * X1 * X2)
    )
    assert action(mech, t, q, v) == pytest.approx(exact, rel=1e-11)


def test_action_curve_is_a_parabola_with_zero_slope_on_the_true_path(oscillator):
    mech, m, k, w = oscillator
    duration = 0.7 * math.pi / w
    t, q, v = true_path(w, duration)
    curve = action_curve(mech, t, q, v, np.linspace(-0.4, 0.4, 9), k=1)
    S0 = action(mech, t, q, v)
    assert abs(curve.slope) < 1e-10 * abs(S0)
    # L is quadratic, so S(eps) = S0 + curvature * eps^2 / 2 exactly
    predicted_curvature = (m * (math.pi / duration) ** 2 - k) * duration / 2
    assert curve.curvature == pytest.approx(predicted_curvature, rel=1e-6)
    assert curve.action == pytest.approx(S0 + predicted_curvature * curve.eps**2 / 2, rel=1e-9)
    # the straight line from X1 to X2 is not a solution: it has a first variation
    line = X1 + (X2 - X1) * (t - t[0]) / duration
    speed = np.full_like(t, (X2 - X1) / duration)
    wrong = action_curve(mech, t, line[:, None], speed[:, None], k=1)
    assert abs(wrong.slope) > 1e-3 * abs(S0)


def test_user_given_variation(oscillator):
    mech, _, _, w = oscillator
    t, q, v = true_path(w, 0.5 * math.pi / w)
    s = (t - t[0]) / (t[-1] - t[0])
    bump = (s**2 * (1 - s) ** 2)[:, None], (2 * s * (1 - s) * (1 - 2 * s))[:, None] / t[-1]
    curve = action_curve(mech, t, q, v, variation=bump)
    assert abs(curve.slope) < 1e-10 and curve.curvature > 0


def test_minimum_before_half_a_period_and_saddle_after(oscillator):
    mech, *_, w = oscillator
    natures = {}
    for fraction in (0.5, 0.95, 1.05, 1.6):
        t, q, v = true_path(w, fraction * math.pi / w)
        natures[fraction] = second_variation(mech, t, q, v, modes=4).nature
        curve = action_curve(mech, t, q, v, k=1)
        assert (curve.curvature > 0) == (fraction < 1)
    assert natures == {0.5: "minimum", 0.95: "minimum", 1.05: "saddle", 1.6: "saddle"}


def test_sine_variation_vanishes_at_the_ends():
    t = np.linspace(1.0, 3.0, 11)
    eta, etadot = sine_variation(t, 2, [1.0, -2.0])
    assert eta.shape == etadot.shape == (11, 2)
    assert np.abs(eta[[0, -1]]).max() < 1e-15
    assert etadot[0] == pytest.approx([math.pi, -2 * math.pi])


def test_two_point_problem_agrees_with_shooting_to_second_order():
    mech = derive(scene(PENDULUM))
    shot = shoot_two_point(mech, [0.0], [1.0], 1.0, samples=201)
    assert shot.converged
    assert shot.q[-1, 0] == pytest.approx(1.0, abs=1e-9)
    errors = []
    for nodes in (101, 201):
        path = solve_two_point(mech, [0.0], [1.0], 1.0, nodes=nodes)
        assert path.converged
        reference = np.interp(path.t, shot.t, shot.q[:, 0])
        errors.append(np.max(np.abs(path.q[:, 0] - reference)))
    assert errors[1] < 1e-4
    assert 3.5 < errors[0] / errors[1] < 4.5  # the midpoint rule's second order
    assert path.action == pytest.approx(shot.action, rel=1e-4)


def test_two_point_problem_with_two_coupled_coordinates():
    mech = derive(scene(HENON_HEILES))
    qa, qb = [0.0, 0.1], [0.3, -0.2]
    path = solve_two_point(mech, qa, qb, 2.0, nodes=201)
    shot = shoot_two_point(mech, qa, qb, 2.0, samples=201)
    assert path.converged and shot.converged
    assert np.max(np.abs(path.q - shot.q)) < 1e-4
    fine = solve_two_point(mech, qa, qb, 2.0, nodes=1601)  # 3200 unknowns: banded Newton
    assert fine.converged
    assert np.max(np.abs(fine.q[::8] - shot.q)) < np.max(np.abs(path.q - shot.q)) / 30
    assert path.q[0] == pytest.approx(qa) and path.q[-1] == pytest.approx(qb)
