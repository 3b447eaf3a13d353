"""Linear normal modes and the energy in each (``systems.normal_modes``): a harmonic chain's
textbook frequencies and constant mode energies that sum to H; an FPU-alpha chain's energy
flowing out of mode 1; and a reason, never numbers, where modes do not apply."""

from __future__ import annotations

import math

import numpy as np
import pytest

from systems.compiled import compile_system
from systems.families import fpu_chain
from systems.mechanics import derive
from systems.normal_modes import analyse, analyse_compiled
from systems.scene import load_scene, parse_scene
from systems.simulation import Run, Sampler

CHAIN = """
title = "Three coupled oscillators, ends fixed"
[system]
coordinates = ["x1", "x2", "x3"]
parameters = { m = 1.0, k = 1.0 }
kinetic = "m*(x1_dot**2 + x2_dot**2 + x3_dot**2)/2"
potential = "k*(x1**2 + (x2 - x1)**2 + (x3 - x2)**2 + x3**2)/2"
[initial]
x1 = 0.3
x2 = -0.1
x3 = 0.2
x2_dot = 0.15
"""


def states(compiled, t_end: float, samples: int, **settings) -> tuple[np.ndarray, np.ndarray]:
    run = Run(compiled, t_end=t_end, **settings)
    rows = list(Sampler(run, np.linspace(0.0, t_end, samples + 1)))
    assert run.finished and run.t == pytest.approx(t_end)
    return np.array([t for t, _ in rows]), np.array([y for _, y in rows])


def test_a_chain_of_three_oscillators_has_the_textbook_modes():
    mechanics = derive(parse_scene(CHAIN))
    modes = analyse(mechanics).modes
    n = 3
    k = np.arange(1, n + 1)
    np.testing.assert_allclose(modes.omega, 2 * np.sin(k * np.pi / (2 * (n + 1))), rtol=1e-12)
    np.testing.assert_allclose(modes.q0, 0.0, atol=1e-14)
    np.testing.assert_allclose(modes.shapes.T @ modes.mass @ modes.shapes, np.eye(n), atol=1e-12)
    # mode k is sin(i k pi / (n + 1)) along the chain
    for column, kk in zip(modes.shapes.T, k, strict=True):
        shape = np.sin(np.arange(1, n + 1) * kk * np.pi / (n + 1))
        assert abs(column @ shape) / (np.linalg.norm(column) * np.linalg.norm(shape)) == (
            pytest.approx(1.0, abs=1e-12)
        )
    # parameters are numbers at analysis time: stiffer springs, faster modes
    stiffer = analyse(mechanics, {"k": 4.0}).modes
    np.testing.assert_allclose(stiffer.omega, 2 * modes.omega, rtol=1e-12)


def test_a_harmonic_chain_keeps_each_mode_energy_and_they_sum_to_h():
    mechanics = derive(parse_scene(CHAIN))
    compiled = compile_system(mechanics, ["rhs", "hamiltonian", "separable"])
    modes = analyse_compiled(compiled).modes
    t, Y = states(compiled, 60.0, 120, method="yoshida8")
    E = modes.energies(Y)
    H = compiled.hamiltonian(t, Y)
    assert np.all(E[0] > 1e-3 * H[0])  # every mode is excited
    np.testing.assert_allclose(E.sum(axis=1), H, rtol=1e-12)
    assert np.max(np.abs(E - E[0])) < 1e-9 * H[0]
    assert modes.energies(Y, modes=2).shape == (len(Y), 2)


def test_an_fpu_chain_moves_energy_out_of_mode_one_into_higher_modes():
    mechanics = derive(parse_scene(fpu_chain(32)))
    compiled = compile_system(mechanics, ["rhs", "hamiltonian", "separable"])
    analysis = analyse_compiled(compiled)
    assert analysis.applies, analysis.reason
    modes = analysis.modes
    k = np.arange(1, 33)
    np.testing.assert_allclose(modes.omega, 2 * np.sin(k * np.pi / 66), rtol=1e-10)
    t, Y = states(compiled, 2000.0, 40, method="yoshida8", dt=0.25)
    E = modes.energies(Y)
    H0 = float(compiled.hamiltonian(0.0, Y[:1])[0])
    assert E[0, 0] == pytest.approx(H0, rel=1e-4)  # all of it starts in mode 1
    assert np.all(E[0, 1:] < 1e-20 * H0)
    # modes 2, 3 and 4 each take a good share, and mode 1 gives it
    assert np.all(E[:, 1:4].max(axis=0) > 0.05 * H0), E[:, 1:4].max(axis=0) / H0
    assert E[:, 0].min() < 0.5 * H0
    # the anharmonic part of the energy stays small: the mode energies nearly add up to H
    np.testing.assert_allclose(E.sum(axis=1), H0, rtol=0.05)


@pytest.mark.parametrize(
    ("name", "words"),
    [
        ("planetary_motion", "does not depend on theta"),
        ("variable_length_pendulum", "rheonomic"),
        ("kepler_cartesian", "no stable equilibrium"),
    ],
)
def test_where_modes_do_not_apply_there_is_a_reason(name, words):
    analysis = analyse(derive(load_scene(name)))
    assert not analysis.applies and analysis.modes is None
    assert words in analysis.reason


def test_gyroscopic_terms_and_free_translations_are_refused():
    magnetic = """
title = "Charge in a magnetic field and a harmonic trap"
[system]
coordinates = ["x", "y"]
parameters = { B = 1.0 }
lagrangian = "(x_dot**2 + y_dot**2)/2 + B*(x*y_dot - y*x_dot)/2 - (x**2 + y**2)/2"
[initial]
x = 0.5
"""
    assert "linear in the velocities" in analyse(derive(parse_scene(magnetic))).reason
    ring = """
title = "Three particles on a ring of springs"
[system]
coordinates = ["a", "b", "c"]
kinetic = "(a_dot**2 + b_dot**2 + c_dot**2)/2"
potential = "(b - a)**2/2 + (c - b)**2/2 + (a - c)**2/2"
[initial]
a = 0.5
"""
    assert "zero frequency" in analyse(derive(parse_scene(ring))).reason


def test_the_nearest_minimum_of_a_double_well_from_its_top():
    double_well = """
title = "Double well"
[system]
coordinates = ["x"]
kinetic = "x_dot**2/2"
potential = "-x**2/2 + x**4/4"
[initial]
x = -0.2
"""
    mechanics = derive(parse_scene(double_well))
    assert analyse(mechanics).modes.q0 == pytest.approx([-1.0])
    assert analyse(mechanics, start=[0.7]).modes.q0 == pytest.approx([1.0])
    top = analyse(mechanics, start=[0.0]).modes  # on the maximum: off it, then down
    assert abs(top.q0[0]) == pytest.approx(1.0)
    assert top.omega == pytest.approx([math.sqrt(2.0)])
