import math

import numpy as np
import pytest
from scipy.special import ellipe, ellipk

from systems.mechanics import derive
from systems.textbook.action_angle import action_angle, action_angle_table
from tests.systems.scenes import OSCILLATOR, PENDULUM, PLANETARY, scene
from tests.systems.textbook.scenes import HOOP


@pytest.fixture(scope="module")
def pendulum():
    mech = derive(scene(PENDULUM))
    v = mech.scene.parameter_values
    return mech, v["m"], v["g"], v["l"]


@pytest.mark.parametrize("amplitude", [0.05, 0.5, 1.5, 2.5, 3.0, 3.1])
def test_pendulum_libration_period_is_the_elliptic_integral(pendulum, amplitude):
    mech, m, g, l = pendulum
    E = -m * g * l * math.cos(amplitude)
    result = action_angle(mech, E)
    k2 = math.sin(amplitude / 2) ** 2
    assert result.motion == "libration" and result.converged
    assert result.turning_points == pytest.approx((-amplitude, amplitude), rel=1e-12)
    assert result.period == pytest.approx(4 * math.sqrt(l / g) * ellipk(k2), rel=1e-8)
    # J = 16 sqrt(m^2 g l^3) (E(k^2) - (1 - k^2) K(k^2)), the closed integral of p dq
    J = 16 * math.sqrt(m**2 * g * l**3) * (ellipe(k2) - (1 - k2) * ellipk(k2))
    assert result.action == pytest.approx(J, rel=1e-8)


@pytest.mark.parametrize("excess", [1.001, 1.5, 10.0])
def test_pendulum_rotation_period_above_the_separatrix(pendulum, excess):
    mech, m, g, l = pendulum
    E = excess * m * g * l
    k2 = 2 * m * g * l / (E + m * g * l)
    for direction in (1, -1):
        result = action_angle(mech, E, direction=direction)
        assert result.motion == "rotation" and result.converged
        period = 2 * math.sqrt(k2) * math.sqrt(l / g) * ellipk(k2)
        assert result.period == pytest.approx(period, rel=1e-8)


def test_period_is_dJ_dE(pendulum):
    mech, m, g, l = pendulum
    for E in (-0.5 * m * g * l, 2.0 * m * g * l):
        h = 1e-4 * m * g * l
        J_plus, J_minus = (action_angle(mech, E + s).action for s in (h, -h))
        assert action_angle(mech, E).period == pytest.approx((J_plus - J_minus) / (2 * h), rel=1e-6)


def test_period_diverges_at_the_separatrix(pendulum):
    mech, m, g, l = pendulum
    separatrix = m * g * l
    energies = separatrix * np.array([-0.9, 0.0, 0.9, 0.999, 1.001, 1.1, 3.0])
    J, T, motion = action_angle_table(mech, energies)
    assert motion == ["libration"] * 4 + ["rotation"] * 3
    assert np.all(np.diff(T[:4]) > 0) and np.all(np.diff(T[4:]) < 0)
    assert T[3] > 3 * 2 * math.pi * math.sqrt(l / g)
    assert np.isnan(action_angle_table(mech, [-2 * separatrix])[1][0])  # below the minimum


def test_harmonic_oscillator_action_is_two_pi_E_over_omega():
    mech = derive(scene(OSCILLATOR))
    w = math.sqrt(mech.scene.parameter_values["k"] / mech.scene.parameter_values["m"])
    result = action_angle(mech, 0.8)
    assert result.action == pytest.approx(2 * math.pi * 0.8 / w, rel=1e-10)
    assert result.period == pytest.approx(2 * math.pi / w, rel=1e-10)


def test_off_centre_well_of_the_spinning_hoop():
    mech = derive(scene(HOOP))
    v = mech.scene.parameter_values
    c = v["g"] / (v["w"] ** 2 * v["R"])
    bottom = math.acos(c)
    small = v["w"] * math.sqrt(1 - c**2)  # small-oscillation frequency of the side well
    U0 = -v["m"] * v["g"] * v["R"] * c - v["m"] * (v["w"] * v["R"]) ** 2 * (1 - c**2) / 2
    result = action_angle(mech, U0 + 1e-6, q0=bottom)
    assert result.frequency == pytest.approx(small, rel=1e-4)
    lo, hi = result.turning_points
    assert lo < bottom < hi and 0 < lo


def test_refusals():
    with pytest.raises(ValueError, match="one-degree"):
        action_angle(derive(scene(PLANETARY)), -0.1)
    with pytest.raises(ValueError, match="unbounded"):
        action_angle(_free_particle(), 1.0)


def _free_particle():
    text = """
title = "Ramp"
[system]
coordinates = ["x"]
kinetic = "x_dot**2/2"
potential = "x"
"""
    return derive(scene(text))
