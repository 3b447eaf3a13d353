import numpy as np
import pytest
import sympy

from systems.mechanics import derive
from systems.textbook.conservation import energy_balance
from systems.textbook.routhian import integrate_reduced, motion_interval, reduce, turning_points
from tests.systems.scenes import DRIVEN_DAMPED, PENDULUM, PLANETARY, VARIABLE_LENGTH, scene
from tests.systems.textbook.runs import full_run
from tests.systems.textbook.scenes import HOOP


@pytest.fixture(scope="module")
def planetary():
    mech = derive(scene(PLANETARY))
    return mech, reduce(mech)


def test_planetary_effective_potential_and_routhian(planetary):
    mech, reduction = planetary
    s = {sym.name: sym for sym in mech.scene.symbols.values()}
    m, k, r, p = s["m"], s["k"], s["r"], s["p_theta"]
    assert reduction.cyclic == ("theta",) and reduction.rest == ("r",)
    expected = p**2 / (2 * m * r**2) - k / r
    assert sympy.simplify(reduction.effective_potential - expected) == 0
    R = reduction.routhian
    assert sympy.simplify(R - (m * s["r_dot"] ** 2 / 2 - expected)) == 0
    V = reduction.effective_potential_function()
    values = mech.scene.parameter_values
    assert V([2.0], [0.7])[0] == pytest.approx(
        0.7**2 / (2 * values["m"] * 4.0) - values["k"] / 2.0, rel=1e-14
    )


def test_planetary_turning_points(planetary):
    mech, reduction = planetary
    m, k = mech.scene.parameter_values["m"], mech.scene.parameter_values["k"]
    p_theta, r0, pr0 = 1.04, 1.0, 0.2
    E = pr0**2 / (2 * m) + p_theta**2 / (2 * m * r0**2) - k / r0
    # E r^2 + k r - p^2/(2m) = 0
    exact = sorted(np.roots([E, k, -(p_theta**2) / (2 * m)]).real)
    assert turning_points(reduction, E, [p_theta], 1e-3, 100.0) == pytest.approx(exact, rel=1e-12)
    assert motion_interval(reduction, E, [p_theta], r0) == pytest.approx(exact, rel=1e-12)
    # an unbound orbit has one turning point and an open side
    low, high = motion_interval(reduction, 0.1, [p_theta], r0)
    assert high is None and low == pytest.approx(
        max(np.roots([0.1, k, -(p_theta**2) / (2 * m)]).real), rel=1e-12
    )


def test_reduced_dynamics_matches_the_full_run(planetary):
    mech, reduction = planetary
    r0, pr0, p_theta = 1.0, 0.2, 1.04
    t = np.linspace(0.0, 12.0, 241)
    full = full_run(mech, [r0, 0.3, pr0, p_theta], t)  # y = (r, theta, p_r, p_theta)
    reduced = integrate_reduced(reduction, [r0], [pr0], [p_theta], t, q_cyclic0=[0.3])
    assert np.max(np.abs(reduced.q_rest[:, 0] - full[:, 0])) < 1e-8
    assert np.max(np.abs(reduced.p_rest[:, 0] - full[:, 2])) < 1e-8
    assert np.max(np.abs(reduced.q_cyclic[:, 0] - full[:, 1])) < 1e-8
    assert np.ptp(full[:, 0]) > 0.2  # r really moves: the comparison means something


def test_reduce_refuses_a_system_without_cyclic_coordinates():
    with pytest.raises(ValueError, match="no cyclic coordinate"):
        reduce(derive(scene(PENDULUM)))


@pytest.mark.parametrize("name", ["bouncing_ball", "cartesian_pendulum"])
def test_reduce_refuses_a_constrained_scene(name):
    """The ball's x is cyclic, but its reduced portrait in y would leave out the floor."""
    from systems.scene import load_scene

    with pytest.raises(ValueError, match="constraints"):
        reduce(derive(load_scene(name)))


def test_spinning_hoop_conserves_H_but_not_T_plus_V():
    mech = derive(scene(HOOP))
    t = np.linspace(0.0, 3.0, 601)
    y = full_run(mech, [0.4, 0.0], t)
    balance = energy_balance(mech, t, y)
    assert np.ptp(balance.hamiltonian) < 1e-9
    assert np.max(np.abs(balance.rate)) < 1e-7
    assert np.max(np.abs(balance.predicted)) == 0.0
    assert np.ptp(balance.energy) > 0.1  # T + V is not conserved


def test_rheonomic_dH_dt_equals_minus_partial_L_partial_t():
    mech = derive(scene(VARIABLE_LENGTH))
    y0 = [1.0, 0.0]
    errors = []
    for samples in (501, 1001):
        t = np.linspace(0.0, 4.0, samples)
        balance = energy_balance(mech, t, full_run(mech, y0, t))
        scale = np.max(np.abs(balance.partial))
        assert scale > 1.0  # H really changes
        inner = slice(5, -5)
        errors.append(np.max(np.abs(balance.rate - balance.predicted)[inner]) / scale)
    assert errors[1] < 1e-6
    assert errors[1] < errors[0] / 4  # the left side converges to the right side


def test_damped_driven_power_enters_the_balance():
    mech = derive(scene(DRIVEN_DAMPED))
    t = np.linspace(0.0, 10.0, 2001)
    balance = energy_balance(mech, t, full_run(mech, [1.0, 0.0], t))
    assert np.max(np.abs(balance.partial)) == 0.0
    assert np.max(np.abs(balance.power)) > 0.1
    inner = slice(5, -5)
    assert np.max(np.abs(balance.rate - balance.predicted)[inner]) < 1e-6
