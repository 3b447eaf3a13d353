import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import sympy

from systems.compiled import compile_system
from systems.mechanics import derive
from tests.systems.scenes import DRIVEN_DAMPED, HENON_HEILES, PENDULUM, PLANETARY, scene

ROOT = Path(__file__).resolve().parents[2]


def numeric(mech, exprs, t, y, params):
    values = {mech.t: t}
    values |= dict(zip(mech.q + mech.p, y, strict=True))
    values |= {mech.params[k]: v for k, v in params.items()}
    return np.array([float(sympy.sympify(e).xreplace(values)) for e in exprs])


@pytest.mark.parametrize("text", [PLANETARY, DRIVEN_DAMPED, HENON_HEILES])
def test_rhs_and_hamiltonian_match_the_symbolic_expressions(text):
    s = scene(text)
    mech = derive(s)
    compiled = compile_system(mech, ("rhs", "hamiltonian"))
    rng = np.random.default_rng(1)
    for _ in range(5):
        y = rng.uniform(0.3, 1.5, 2 * mech.n)
        t = float(rng.uniform(0, 3))
        expected = numeric(mech, mech.hamilton_equations, t, y, s.parameter_values)
        np.testing.assert_allclose(compiled.rhs(t, y), expected, rtol=1e-12, atol=1e-12)
        H = numeric(mech, [mech.hamiltonian], t, y, s.parameter_values)[0]
        assert compiled.hamiltonian(t, y[None, :])[0] == pytest.approx(H, rel=1e-12)


def test_only_what_is_wanted_is_compiled():
    compiled = compile_system(derive(scene(PENDULUM)), ("rhs",))
    assert hasattr(compiled.kernels, "rhs")
    assert not hasattr(compiled.kernels, "hamiltonian")
    with pytest.raises(ValueError, match="was not compiled"):
        compiled.hamiltonian(0.0, np.zeros((1, 2)))


def test_switched_off_effects_leave_no_term_in_the_kernel():
    s = scene(DRIVEN_DAMPED)
    on = compile_system(derive(s), ("rhs",), backend="numba")  # printed as Python source
    off = compile_system(derive(s.with_effects([])), ("rhs",), backend="numba")
    on_source = open(on.kernels.__file__).read().split("def rhs")[1].split("\ndef ")[0]
    off_source = open(off.kernels.__file__).read().split("def rhs")[1].split("\ndef ")[0]
    assert "v_A" in on_source and "v_b" in on_source
    assert "math.cos(v_t" not in off_source
    assert "*v_b" not in off_source and "v_A*" not in off_source


def test_initial_state_turns_velocities_into_momenta():
    s = scene(PLANETARY)
    compiled = compile_system(derive(s), ("rhs", "momenta"))
    y0 = compiled.initial_state()
    m = s.parameter_values["m"]
    np.testing.assert_allclose(y0, [1.0, 0.0, 0.0, m * 1.0**2 * 1.1])


def test_velocities_and_momenta_are_inverse():
    compiled = compile_system(derive(scene(PLANETARY)), ("velocities", "momenta"))
    Y = np.random.default_rng(2).uniform(0.5, 2.0, (50, 4))
    qdot = compiled.velocities(0.0, Y)
    np.testing.assert_allclose(compiled.momenta(0.0, Y[:, :2], qdot), Y[:, 2:], rtol=1e-13)


def test_drawing_points_and_parameters_without_recompiling():
    compiled = compile_system(derive(scene(PENDULUM)), ("drawing",))
    Y = np.array([[0.0, 0.0], [np.pi / 2, 0.0]])
    points = compiled.drawing(0.0, Y)
    assert points.shape == (2, 1, 2)
    np.testing.assert_allclose(points[:, 0, :], [[0.0, -0.7], [0.7, 0.0]], atol=1e-15)
    longer = compiled.with_parameters({"l": 2.0})
    assert longer.kernels is compiled.kernels
    np.testing.assert_allclose(longer.drawing(0.0, Y)[1, 0], [2.0, 0.0], atol=1e-15)


def test_separable_parts_compile_and_match():
    compiled = compile_system(derive(scene(PENDULUM)), ("separable",))
    k = compiled.kernels
    P = compiled.parameters
    m, g, l = P
    out = np.empty(1)
    y = np.array([0.4, 0.3])  # the whole state (theta, p_theta)
    k.grad_kinetic(y, P, out)
    assert out[0] == pytest.approx(0.3 / (m * l**2), rel=1e-14)
    k.grad_potential(0.0, y, P, out)
    assert out[0] == pytest.approx(m * g * l * np.sin(0.4), rel=1e-14)
    assert k.kinetic(y, P) == pytest.approx(0.09 / (2 * m * l**2), rel=1e-14)
    assert k.potential(0.0, y, P) == pytest.approx(-m * g * l * np.cos(0.4))


def test_initial_state_mixing_momenta_and_velocities_in_a_coupled_system():
    text = """
title = "Coupled"
[system]
coordinates = ["a", "b"]
parameters = { m = 1.0 }
kinetic = "m*(a_dot**2 + a_dot*b_dot + b_dot**2)"
potential = "a**2 + b**2"
[initial]
a_dot = 0.5
p_b = 2.0
"""
    compiled = compile_system(derive(scene(text)), ("momenta",))
    y0 = compiled.initial_state()
    # p_a = 2 a_dot + b_dot, p_b = a_dot + 2 b_dot = 2  ->  b_dot = 0.75, p_a = 1.75
    np.testing.assert_allclose(y0, [0.0, 0.0, 1.75, 2.0], rtol=1e-10)


def test_a_run_of_another_family_leaves_the_taylor_module_unimported():
    """A scene's functions for a method other than taylor come from its kernels alone:
    importing ``systems.taylor.compiled`` cost 25 ms of reopening a scene."""
    script = (
        "import sys\n"
        "from systems.compiled import compile_system\n"
        "from systems.mechanics import derive\n"
        "from systems.scene import load_scene\n"
        "from systems.simulation import precompile\n"
        "compiled = compile_system(derive(load_scene('double_pendulum')),"
        " ('rhs', 'hamiltonian', 'velocities'))\n"
        "precompile(compiled, 'gauss_legendre6')\n"
        "print(sorted(name for name in sys.modules if name.startswith('systems.taylor')))\n"
    )
    process = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, cwd=ROOT, timeout=300
    )
    assert process.returncode == 0, process.stderr
    assert process.stdout.strip() == "[]"
