"""Steppers on hand-written systems with exact solutions: orders, symplecticity, registry."""

import numpy as np
import pytest

from systems.integrators import STEPPERS, gauss_tableau, get_stepper
from systems.integrators.codes import Status
from tests.systems.integrators.handwritten import (
    KEPLER_CARTESIAN,
    KEPLER_POLAR,
    OSCILLATOR,
    PENDULUM,
    module,
    run_to,
)


def run_fixed(mod, name, P, y0, dt, nsteps, kahan=True):
    """Final state after ``nsteps`` fixed steps of the named fixed-step method."""
    y, steps, code, t = run_to(mod, name, P, y0, dt * nsteps, dt, kahan)
    assert code == Status.END and steps == nsteps
    return y


def run_dop853(mod, P, y0, t_end, rtol):
    y, steps, code, t = run_to(mod, "dop853", P, y0, t_end, rtol)
    assert code == Status.END and t == t_end
    return y, steps


@pytest.fixture(scope="module")
def oscillator():
    return module(OSCILLATOR)


@pytest.fixture(scope="module")
def pendulum():
    return module(PENDULUM)


def fitted_order(errors, steps):
    return np.polyfit(np.log(steps), np.log(errors), 1)[0]


# Step sizes where each method is in its asymptotic regime and far above round-off.
# yoshida8 is fitted on the pendulum below: on the linear oscillator its leading error
# coefficient nearly cancels and no step range is cleanly asymptotic above round-off.
ORDER_CASES = {
    "leapfrog": (0.2, 0.1, 0.05),
    "yoshida4": (0.2, 0.1, 0.05),
    "yoshida6": (0.4, 0.2, 0.1),
    "implicit_midpoint": (0.2, 0.1, 0.05),
    "gauss_legendre4": (0.4, 0.2, 0.1),
    "gauss_legendre6": (0.8, 0.4, 0.2),
}


@pytest.mark.parametrize("name", sorted(ORDER_CASES))
def test_fixed_step_convergence_order_matches_declared(oscillator, name):
    # exact solution of m q'' = -k q, m = 2, k = 3, over t = 12
    P = np.array([2.0, 3.0])
    w = np.sqrt(3.0 / 2.0)
    T = 12.0
    exact = np.array([np.cos(w * T), -2.0 * w * np.sin(w * T)])
    errors = []
    steps = ORDER_CASES[name]
    for dt in steps:
        n = int(round(T / dt))
        y = run_fixed(oscillator, name, P, [1.0, 0.0], T / n, n)
        errors.append(np.abs(y - exact).max())
    order = fitted_order(errors, steps)
    assert order == pytest.approx(STEPPERS[name].order, abs=0.3)


@pytest.mark.parametrize("name", ["yoshida8", "gauss_legendre6"])
def test_high_orders_on_a_nonlinear_system(pendulum, name):
    # the harmonic oscillator is linear; the pendulum checks the order conditions that
    # only nonlinear problems see. Reference: the same method at a much smaller step.
    P = np.array([1.0, 1.0, 1.0])
    y0 = [2.0, 0.0]
    T = 12.0
    ref = run_fixed(pendulum, name, P, y0, T / 2400, 2400)
    steps = (0.4, 0.2, 0.1)
    errors = [np.abs(run_fixed(pendulum, name, P, y0, dt, int(round(T / dt))) - ref).max()
              for dt in steps]  # fmt: skip
    assert fitted_order(errors, steps) == pytest.approx(STEPPERS[name].order, abs=0.4)


def test_dop853_error_follows_the_tolerance(oscillator):
    P = np.array([2.0, 3.0])
    w = np.sqrt(1.5)
    exact = np.array([np.cos(w * 20.0), -2.0 * w * np.sin(w * 20.0)])
    errors, steps = [], []
    for rtol in (1e-6, 1e-8, 1e-10):
        y, count = run_dop853(oscillator, P, [1.0, 0.0], 20.0, rtol)
        errors.append(np.abs(y - exact).max())
        steps.append(count)
    assert errors[0] > errors[1] > errors[2]
    assert errors[2] < 1e-8
    # an 8th-order method: 100x the accuracy costs about 100**(1/8) = 1.8x the steps
    assert 1.3 < steps[2] / steps[1] < 2.6


def test_gauss_legendre_is_symplectic_on_a_nonseparable_system():
    # theta is cyclic, so (r, p_r) at fixed p_theta is a one-degree-of-freedom Hamiltonian
    # system of its own: its flow map, and a symplectic method's, has Jacobian
    # determinant 1 in (r, p_r). An adaptive Runge-Kutta run does not.
    mod = module(KEPLER_POLAR)
    P = np.array([1.0, 1.0])
    base = np.array([1.2, 0.0, 0.1, 0.9])
    eps = 1e-5

    def determinant(step):
        J = np.empty((2, 2))
        for col, index in enumerate((0, 2)):
            up, down = base.copy(), base.copy()
            up[index] += eps
            down[index] -= eps
            J[:, col] = (step(up) - step(down))[[0, 2]] / (2 * eps)
        return np.linalg.det(J)

    for name in ("implicit_midpoint", "gauss_legendre4", "gauss_legendre6"):
        det = determinant(lambda y, name=name: run_fixed(mod, name, P, y, 0.1, 100))
        assert abs(det - 1) < 1e-8, name
    det = determinant(lambda y: run_dop853(mod, P, y, 10.0, 1e-5)[0])
    assert abs(det - 1) > 1e-6


def test_logh_leapfrog_keeps_a_very_eccentric_kepler_orbit():
    mod = module(KEPLER_CARTESIAN)
    P = np.array([1.0, 1.0])
    e = 0.999
    y0 = np.array([1 + e, 0.0, 0.0, np.sqrt((1 - e) / (1 + e))])
    H0 = mod.hamiltonian(0.0, y0, P)
    t_end = 2 * np.pi * 20
    y, steps, code, t = run_to(mod, "logh_yoshida4", P, y0, t_end, 0.05)
    assert code == Status.END and t == t_end  # landed on t_end exactly
    assert abs(mod.hamiltonian(0.0, y, P) / H0 - 1) < 1e-12
    # 20 whole periods: back where it started
    assert np.abs(y - y0).max() < 1e-4


def test_gauss_tableaux_satisfy_the_order_conditions():
    for s in (1, 2, 3):
        A, b, c, E = gauss_tableau(s)
        for k in range(1, 2 * s + 1):
            assert b @ c ** (k - 1) == pytest.approx(1 / k, abs=1e-14)
        for k in range(1, s + 1):
            np.testing.assert_allclose(A @ c ** (k - 1), c**k / k, atol=1e-14)
        # the extrapolation is exact for increments of a polynomial of degree <= s
        u = np.polynomial.Polynomial(np.arange(1.0, s + 2))
        Z = (u(c) - u(0.0))[:, None]
        np.testing.assert_allclose(E @ Z, (u(1 + c) - u(1.0))[:, None], rtol=1e-12)


def test_composition_weights_sum_to_one_and_are_symmetric():
    for stepper in STEPPERS.values():
        if stepper.family.name in ("composition", "logh"):
            w = np.array(stepper.weights)
            assert w.sum() == pytest.approx(1.0, abs=1e-14)
            np.testing.assert_array_equal(w, w[::-1])
            kick, drift = stepper.kick_drift()
            assert kick.sum() == pytest.approx(1.0, abs=1e-14)


def test_registry_declares_structure():
    assert STEPPERS["leapfrog"].needs_separable and STEPPERS["leapfrog"].symplectic
    assert not STEPPERS["gauss_legendre4"].needs_separable
    assert STEPPERS["gauss_legendre6"].order == 6
    assert STEPPERS["dop853"].adaptive and not STEPPERS["dop853"].symplectic
    assert STEPPERS["logh_yoshida4"].time_transformed
    assert STEPPERS["radau"].stiff
    with pytest.raises(KeyError, match="choose from"):
        get_stepper("euler_maruyama")
