"""Constraint forces (``systems.constraint_forces``): multipliers, reaction forces, their
virtual work (D'Alembert), their power, and the energy balance the work closes.

The reference values are Newton's law along and across the string. For a bob on a
string of length l(t) from a fixed pivot at angle theta from the downward vertical, with
e_r = (sin theta, -cos theta) pointing from the pivot to the bob, the string pulls with
the tension T along -e_r, and

    radial:      m (l'' - l theta'^2) = m g cos(theta) - T,
    transverse:  m (l theta'' + 2 l' theta') = -m g sin(theta),

so the reaction on the bob is R = -T e_r with T = m (g cos(theta) + l theta'^2 - l''),
nothing across the string, and its power is R . v = -T l' (v . e_r = l'). With a
constant l the power vanishes. The Atwood machine's rope pulls each mass up with
2 m1 m2 g/(m1 + m2).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from systems import constraint_forces as cf
from systems.compiled import compile_system
from systems.mechanics import derive
from systems.scene import load_scene, parse_scene
from systems.simulation import required_wants, stream

WANTS = {"rhs", "hamiltonian", "velocities"}


def _compiled(scene, method: str | None = None):
    mechanics = derive(parse_scene(scene) if "\n" in scene else load_scene(scene))
    wants = WANTS | (required_wants(method) if method else set())
    return compile_system(mechanics, wants)


def _run(compiled, t_end: float, **options):
    blocks = list(stream(compiled, t_end=t_end, max_points=200_000, **options))
    assert blocks[-1].status == "ok", blocks[-1].message
    t = np.concatenate([b.t for b in blocks])
    y = np.concatenate([b.y for b in blocks])
    return t, y


# -- explicit constraints: the Cartesian pendulum ------------------------------------------------


@pytest.fixture(scope="module")
def cartesian():
    compiled = _compiled("cartesian_pendulum", "constrained_dop853")
    t, y = _run(compiled, 10.0, method="constrained_dop853", tol=1e-12)
    analysis = cf.analyse(compiled.mechanics)
    return compiled, analysis, t, y, analysis.evaluate(compiled, t, y)


def test_the_cartesian_pendulum_string_does_no_virtual_work_and_no_work(cartesian):
    compiled, analysis, t, y, forces = cartesian
    assert analysis.applies and analysis.computes and analysis.k == 1
    assert analysis.particles == () and not analysis.rheonomic
    assert analysis.points == (("bob", 0, 1),)  # x, y are the bob's Cartesian coordinates
    assert len(t) > 200
    # Q_c = -Phi_q^T lambda is normal to the circle: round-off on its tangent
    assert np.max(forces.virtual_work) <= 2e-15
    # the string is fixed (scleronomic): no power beyond round-off, however large it is
    assert np.max(np.abs(forces.power) / forces.power_scale) <= 1e-14
    assert np.max(np.abs(forces.power)) <= 1e-12
    # the work closes the balance of h = T + V (the integrator's own error, 1e-12)
    W = analysis.work(compiled, t, y)
    assert analysis.balance and analysis.energy_name == "h"
    assert np.max(np.abs(forces.energy - forces.energy[0] - W)) <= 1e-10


def test_the_cartesian_reaction_is_the_tension_along_the_string(cartesian):
    _, _, t, y, forces = cartesian
    m, g, l = 1.0, 9.81, 1.0
    x, yy, vx, vy = y.T  # p = m qdot, m = 1
    theta_dot = (x * vy - yy * vx) / l**2
    tension = m * (g * (-yy / l) + l * theta_dot**2)
    expected = -tension[:, None] * np.stack([x, yy], axis=1) / l  # towards the pivot
    assert np.max(np.abs(forces.generalized - expected)) <= 1e-12
    assert np.max(np.abs(2 * forces.multipliers[:, 0] * l - tension)) <= 1e-12


# -- particles: the variable-length pendulum ------------------------------------------------------


@pytest.fixture(scope="module")
def pumped():
    compiled = _compiled("variable_length_pendulum")
    t, y = _run(compiled, 6.0, method="rk4", dt=1e-3)
    analysis = cf.analyse(compiled.mechanics)
    return compiled, analysis, t, y, analysis.evaluate(compiled, t, y)


def test_the_pumped_string_does_no_virtual_work_but_does_work(pumped):
    compiled, analysis, t, y, forces = pumped
    assert analysis.particles == ("bob",) and analysis.k == 0 and forces.multipliers is None
    assert analysis.rheonomic and analysis.balance and analysis.energy_name == "T + V"
    assert np.max(forces.virtual_work) <= 1e-14
    # the power is of the size of the forces' power, and takes both signs: the string is
    # pulled in and let out
    ratio = forces.power / forces.power_scale
    assert ratio.max() > 0.3 and ratio.min() < -0.3


def test_the_pumped_string_pulls_along_itself_with_the_tension(pumped):
    compiled, _, t, y, forces = pumped
    m, g, l0, a, w = compiled.parameters
    theta = y[:, 0]
    theta_dot = compiled.velocities(t, y)[:, 0]
    l = l0 + a * np.sin(w * t)
    l_dot = a * w * np.cos(w * t)
    l_ddot = -a * w**2 * np.sin(w * t)
    tension = m * (g * np.cos(theta) + l * theta_dot**2 - l_ddot)
    e_r = np.stack([np.sin(theta), -np.cos(theta)], axis=1)
    R = forces.reactions[:, 0, :]
    np.testing.assert_allclose(R, -tension[:, None] * e_r, rtol=0, atol=1e-11)
    np.testing.assert_allclose(forces.power, -tension * l_dot, rtol=0, atol=1e-11)


def test_the_string_s_work_is_the_change_of_the_energy(pumped):
    compiled, analysis, t, y, forces = pumped
    W = analysis.work(compiled, t, y)
    balance = forces.energy - forces.energy[0] - W
    assert np.ptp(W) > 1.0  # the string's work is not small
    assert np.max(np.abs(balance)) <= 1e-10, np.max(np.abs(balance))
    # from one row in 40 (a window keeps few rows where the orbit moves slowly) the
    # quintic between rows still gives W to 1e-8 of its size
    sparse = np.r_[0 : len(t) : 40]
    coarse = analysis.work(compiled, t[sparse], y[sparse])
    assert np.max(np.abs(coarse - W[sparse])) <= 1e-8 * np.ptp(W)
    # the trapezoid rule on those rows would be far off: the test can tell
    trapezoid = np.concatenate(
        [
            [0.0],
            np.cumsum(
                np.diff(t[sparse]) * (forces.power[sparse][1:] + forces.power[sparse][:-1]) / 2
            ),
        ]
    )
    assert np.max(np.abs(trapezoid - W[sparse])) > 1e-4 * np.ptp(W)


def test_the_work_goes_on_over_pieces_and_gaps_only_where_the_balance_holds(pumped):
    compiled, analysis, t, y, forces = pumped
    W = analysis.work(compiled, t, y)
    gapped = y.copy()
    gapped[1000:1200] = np.nan  # rows left out
    energy = np.where(np.isnan(gapped[:, 0]), np.nan, forces.energy)
    integral = cf.WorkIntegral(analysis, compiled)
    pieced = np.concatenate(
        [integral.add(t[a:b], gapped[a:b], energy[a:b]) for a, b in _cuts(len(t))]
    )
    assert integral.gaps == 1 and np.all(np.isnan(pieced[1000:1200]))
    np.testing.assert_allclose(pieced[:1000], W[:1000], rtol=0, atol=1e-12)
    # over the gap the balance carries it: after it W is E - E0 again
    after = pieced[1200:] - (forces.energy[1200:] - forces.energy[0])
    assert np.max(np.abs(after)) <= 1e-10
    # without the balance, the work after a gap is unknown, never a wrong number
    blind = cf.WorkIntegral(dataclasses.replace(analysis, balance=False), compiled)
    unknown = np.concatenate([blind.add(t[a:b], gapped[a:b]) for a, b in _cuts(len(t))])
    assert np.all(np.isnan(unknown[1000:])) and np.all(np.isfinite(unknown[:1000]))


def _cuts(size: int, step: int = 377) -> list[tuple[int, int]]:
    edges = [*range(0, size, step), size]
    return list(zip(edges[:-1], edges[1:], strict=True))


# -- particles with a fixed string -----------------------------------------------------------------

PENDULUM = """
title = "Pendulum from a particle"
[system]
coordinates = ["theta"]
parameters = {{ m = 1.3, g = 9.81, l = 0.7 }}
gravity = "g"
{extra}
[particles]
bob = {{ mass = "m", position = ["l*sin(theta)", "-l*cos(theta)"] }}
[initial]
theta = 1.0
"""


def test_a_pendulum_from_a_particle_feels_the_tension_and_no_power():
    compiled = _compiled(PENDULUM.format(extra=""))
    analysis = cf.analyse(compiled.mechanics)
    assert analysis.particles == ("bob",) and not analysis.rheonomic
    t, y = _run(compiled, 5.0, method="rk4", dt=1e-3)
    forces = analysis.evaluate(compiled, t, y)
    m, g, l = compiled.parameters
    theta = y[:, 0]
    theta_dot = y[:, 1] / (m * l**2)
    tension = m * (g * np.cos(theta) + l * theta_dot**2)
    e_r = np.stack([np.sin(theta), -np.cos(theta)], axis=1)
    np.testing.assert_allclose(forces.reactions[:, 0], -tension[:, None] * e_r, rtol=0, atol=1e-12)
    assert np.max(forces.virtual_work) <= 1e-14
    assert np.max(np.abs(forces.power) / forces.power_scale) <= 1e-14


def test_forces_that_are_not_cartesian_on_the_particles_are_not_computed():
    spring = derive(
        parse_scene(
            PENDULUM.format(extra='potential = "k*theta**2/2"').replace(
                "l = 0.7 }", "l = 0.7, k = 2.0 }"
            )
        )
    )
    analysis = cf.analyse(spring)
    assert analysis.applies and not analysis.computes and analysis.particles == ()
    assert "not computed" in analysis.note and "potential" in analysis.note
    compiled = compile_system(spring, WANTS)
    with pytest.raises(ValueError, match="not computed"):
        analysis.evaluate(compiled, 0.0, compiled.initial_state())
    damped = cf.analyse(derive(load_scene("damped_pendulum")))
    assert not damped.computes and "dissipation" in damped.note


def test_scenes_without_constraint_forces_say_so():
    plain = cf.analyse(derive(load_scene("simple_pendulum")))
    assert not plain.applies and "no constraints" in plain.reason
    free = cf.analyse(derive(load_scene("kepler_cartesian")))
    assert not free.applies and "one to one" in free.reason


# -- the Atwood machine with its rope --------------------------------------------------------------


def test_the_atwood_rope_s_multiplier_is_its_tension():
    compiled = _compiled("atwood_rope", "constrained_dop853")
    analysis = cf.analyse(compiled.mechanics)
    assert analysis.k == 1 and analysis.particles == ("mass1", "mass2")
    assert not analysis.rheonomic and analysis.balance
    t, y = _run(compiled, 3.0, method="constrained_rk4", dt=0.01)
    forces = analysis.evaluate(compiled, t, y)
    m1, m2, g = compiled.parameters[:3]
    tension = 2 * m1 * m2 * g / (m1 + m2)
    # Phi = -y1 - y2 - L: the force -Phi_q^T lambda = (lambda, lambda) pulls both masses up
    assert np.max(np.abs(forces.multipliers[:, 0] - tension)) <= 1e-9
    assert np.max(np.abs(forces.generalized - tension)) <= 1e-9
    np.testing.assert_allclose(forces.reactions[:, :, 1], tension, rtol=0, atol=1e-9)
    np.testing.assert_allclose(forces.reactions[:, :, 0], 0.0, rtol=0, atol=1e-9)
    assert np.max(forces.virtual_work) <= 1e-15
    assert np.max(np.abs(forces.power)) <= 1e-12
    assert math.isclose(tension, 10.701818181818181, rel_tol=1e-12)


# -- an explicit constraint that moves -------------------------------------------------------------

DRIVEN = """
title = "Pendulum whose pivot is moved up and down"
[system]
coordinates = ["x", "y"]
parameters = { m = 1.0, g = 9.81, l = 1.0, a = 0.1, w = 5.0 }
kinetic = "m*(x_dot**2 + y_dot**2)/2"
potential = "m*g*y"
[constraints]
holonomic = ["x**2 + (y - a*sin(w*t))**2 - l**2"]
[initial]
x = 0.5
y = -0.8
"""


def test_a_moving_explicit_constraint_works_and_the_balance_closes():
    compiled = _compiled(DRIVEN, "constrained_dop853")
    analysis = cf.analyse(compiled.mechanics)
    assert analysis.rheonomic and analysis.balance and analysis.energy_name == "h"
    t, y = _run(compiled, 4.0, method="constrained_rk4", dt=1e-3)
    forces = analysis.evaluate(compiled, t, y)
    assert np.max(forces.virtual_work) <= 2e-15
    # lambda^T Phi_t with Phi_t = -2 (y - a sin(w t)) a w cos(w t)
    m, g, l, a, w = compiled.parameters
    phi_t = -2 * (y[:, 1] - a * np.sin(w * t)) * a * w * np.cos(w * t)
    np.testing.assert_allclose(forces.power, forces.multipliers[:, 0] * phi_t, rtol=0, atol=1e-11)
    assert np.max(np.abs(forces.power)) > 1.0
    W = analysis.work(compiled, t, y)
    assert np.max(np.abs(forces.energy - forces.energy[0] - W)) <= 1e-10
