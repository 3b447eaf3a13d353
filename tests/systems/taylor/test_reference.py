"""The reference Taylor integrator (plain numpy): Jorba and Zou's order and step."""

import math

import numpy as np
import pytest

from systems.mechanics import derive
from systems.scene import load_scene
from systems.taylor.coefficients import jorba_zou
from systems.taylor.decompose import decompose_mechanics
from systems.taylor.reference import EPSILON, integrate, taylor_step


def _system(name):
    mechanics = derive(load_scene(name))
    P = np.array([v for _, v in mechanics.scene.parameters])
    y0 = np.array([v for _, v in mechanics.scene.initial], dtype=float)
    return decompose_mechanics(mechanics), P, y0


def test_the_order_is_jorba_and_zous():
    assert jorba_zou(EPSILON) == 20
    assert jorba_zou(1e-10) == 13
    assert jorba_zou(1e-6) == 8


def test_the_oscillator_after_ten_periods_to_round_off():
    d, P, _ = _system("harmonic_oscillator")  # m = k = 1: period 2 pi
    times, states = integrate(d, 0.0, np.array([1.0, 0.0]), P, 20 * math.pi)
    assert times[-1] == 20 * math.pi
    assert np.abs(states[-1] - [1.0, 0.0]).max() < 1e-13
    assert 20 <= len(times) - 1 <= 200  # a few steps per radian: h ~ rho / e^2


def test_kepler_after_one_period_returns_to_its_start():
    d, P, _ = _system("kepler_cartesian")  # k = m = 1
    y0 = np.array([0.5, 0.0, 0.0, math.sqrt(3.0)])  # perihelion of e = 0.5, a = 1
    energy = y0[3] ** 2 / 2 - 1 / 0.5
    a = -1 / (2 * energy)
    period = 2 * math.pi * a**1.5
    times, states = integrate(d, 0.0, y0, P, period)
    assert np.abs(states[-1] - y0).max() < 1e-12
    steps = len(times) - 1
    coarse = len(integrate(d, 0.0, y0, P, period, tolerance=1e-8)[0]) - 1
    # Jorba and Zou: the tolerance sets the order (20 and 11 here), the step stays about
    # rho / e^2 whatever the tolerance (38 steps at both when written)
    assert steps <= 60
    assert abs(coarse - steps) <= steps // 4


@pytest.mark.parametrize("tolerance", [1e-6, 1e-10, EPSILON])
def test_the_step_keeps_the_truncation_error_near_the_tolerance(tolerance):
    d, P, y0 = _system("planetary_motion")
    step = taylor_step(d, 0.0, y0, P, tolerance)
    finer = taylor_step(d, 0.0, y0, P, tolerance / 1e6)  # more orders, same h below
    from systems.taylor.coefficients import horner

    exact = horner(finer.coefficients, step.h)
    error = np.abs(step.y - exact).max() / max(1.0, np.abs(y0).max())
    assert error < 10 * tolerance
