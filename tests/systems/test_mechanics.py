import pytest
import sympy

from systems.mechanics import DerivationError, derive
from tests.systems.scenes import (
    DRIVEN_DAMPED,
    HENON_HEILES,
    OSCILLATOR,
    PENDULUM,
    PLANETARY,
    VARIABLE_LENGTH,
    scene,
)


def symbols_of(mech):
    return {s.name: s for s in mech.scene.symbols.values()}


def test_harmonic_oscillator_equation():
    mech = derive(scene(OSCILLATOR))
    s = symbols_of(mech)
    (xddot,) = mech.accelerations()
    assert sympy.simplify(xddot + s["k"] / s["m"] * s["x"]) == 0
    assert (
        sympy.simplify(mech.hamiltonian - (s["p_x"] ** 2 / (2 * s["m"]) + s["k"] * s["x"] ** 2 / 2))
        == 0
    )


def test_pendulum_equation():
    mech = derive(scene(PENDULUM))
    s = symbols_of(mech)
    (thetaddot,) = mech.accelerations()
    assert sympy.simplify(thetaddot + s["g"] / s["l"] * sympy.sin(s["theta"])) == 0


def test_planetary_motion_equations_cyclic_and_conserved():
    mech = derive(scene(PLANETARY))
    s = symbols_of(mech)
    m, k, r, theta_dot = s["m"], s["k"], s["r"], s["theta_dot"]
    rddot, _ = mech.accelerations()
    assert sympy.simplify(m * rddot - m * r * theta_dot**2 + k / r**2) == 0
    assert mech.cyclic == ("theta",)
    assert sympy.simplify(mech.conserved["p_theta"] - m * r**2 * theta_dot) == 0
    assert "H" in mech.conserved
    # Hamilton's equations: dp_theta/dt = 0, dr/dt = p_r/m
    assert mech.hamilton_equations[3] == 0
    assert sympy.simplify(mech.hamilton_equations[0] - s["p_r"] / m) == 0


@pytest.mark.parametrize("text", [OSCILLATOR, PENDULUM, PLANETARY])
def test_scleronomic_conservative_scenes_have_H_equal_T_plus_V(text):
    mech = derive(scene(text))
    c = mech.classification
    assert not c.time_dependent and c.conservative and c.hamiltonian_conserved
    assert c.hamiltonian_is_energy is True and c.natural
    assert not c.rheonomic and c.holonomic and c.bilateral and c.simple
    energy = mech.energy_function()
    assert sympy.simplify(energy - (mech.kinetic + mech.potential)) == 0


def test_rheonomic_scene_has_H_not_T_plus_V_and_not_conserved():
    mech = derive(scene(VARIABLE_LENGTH))
    c = mech.classification
    assert c.time_dependent and c.rheonomic and not c.conservative and not c.simple
    assert c.hamiltonian_is_energy is False
    assert not c.hamiltonian_conserved
    assert not c.natural  # T has a velocity-free term m (a w cos wt)^2 / 2
    assert sympy.simplify(mech.energy_function() - (mech.kinetic + mech.potential)) != 0


def test_separability():
    assert derive(scene(PENDULUM)).classification.separable
    assert not derive(scene(PLANETARY)).classification.separable


def test_effects_enter_only_when_enabled():
    full = derive(scene(DRIVEN_DAMPED))
    s = symbols_of(full)
    Q = full.generalized_forces[0]
    assert sympy.simplify(Q - (-s["b"] * s["theta_dot"] + s["A"] * sympy.cos(s["w"] * s["t"]))) == 0
    assert not full.classification.conservative
    assert not full.classification.hamiltonian_conserved
    assert full.classification.time_dependent  # the driving force A cos(w t)
    assert not full.classification.rheonomic  # ... moves no constraint
    off = derive(scene(DRIVEN_DAMPED).with_effects([]))
    assert off.generalized_forces == (0,)
    assert not any(e.has(s["A"]) or e.has(s["b"]) for e in off.hamilton_equations)
    assert off.classification.conservative and not off.classification.time_dependent


def test_hamiltonian_scene_gets_equations_and_lagrangian():
    mech = derive(scene(HENON_HEILES))
    s = symbols_of(mech)
    x, y, xd, yd = s["x"], s["y"], s["x_dot"], s["y_dot"]
    assert mech.hamilton_equations[0] == s["p_x"]
    assert sympy.simplify(mech.hamilton_equations[2] - (-x - 2 * x * y)) == 0
    expected_L = (xd**2 + yd**2) / 2 - ((x**2 + y**2) / 2 + x**2 * y - y**3 / 3)
    assert sympy.simplify(mech.lagrangian - expected_L) == 0
    assert mech.classification.separable


def test_singular_legendre_transform_is_refused():
    text = OSCILLATOR.replace('kinetic = "m*x_dot**2/2"', 'kinetic = "m*x*x_dot"')
    with pytest.raises(DerivationError, match="Legendre transform is singular"):
        derive(scene(text))


def test_lagrangian_not_quadratic_in_velocities():
    text = """
title = "Relativistic oscillator"
[system]
coordinates = ["x"]
parameters = { m = 1.0, c = 2.0, k = 1.0 }
lagrangian = "-m*c**2*sqrt(1 - x_dot**2/c**2) - k*x**2/2"
"""
    mech = derive(scene(text))
    s = symbols_of(mech)
    # dx/dt = c p / sqrt(p^2 + m^2 c^2)
    value = {s["p_x"]: 0.7, s["m"]: 1.0, s["c"]: 2.0, s["x"]: 0.1}
    expected = 2.0 * 0.7 / (0.7**2 + 4.0) ** 0.5
    assert float(mech.velocities[0].xreplace(value)) == pytest.approx(expected, rel=1e-12)
    assert not mech.classification.natural
    assert mech.classification.hamiltonian_is_energy is True  # H = gamma m c^2 + V
