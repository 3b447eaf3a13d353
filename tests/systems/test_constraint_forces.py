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
from systems import constraints
from systems.compiled import compile_system
from systems.mechanics import derive
from systems.scene import load_scene, parse_scene
from systems.simulation import required_wants, stream

WANTS = {"rhs", "hamiltonian", "velocities"}


def _compiled(scene, method: str | None = None):
    """The scene on the plain-Python kernels: these runs are short, and numba's
    compilation of a constrained scene's kernels takes 10 to 15 s."""
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
    # the rope, then the pulley and the floor for each mass (unilateral: issue 25)
    assert analysis.k == 5 and analysis.particles == ("mass1", "mass2")
    assert analysis.kinds == ("holonomic",) + ("unilateral",) * 4
    assert not analysis.rheonomic and analysis.impacts
    # the left mass lands at t = 3.36: until then no stop touches and the rope holds alone
    t, y = _run(compiled, 3.0, method="constrained_dop853", tol=1e-12)
    forces = analysis.evaluate(compiled, t, y)
    m1, m2, g = compiled.parameters[:3]
    tension = 2 * m1 * m2 * g / (m1 + m2)
    # Phi = -y1 - y2 - L: the force -Phi_q^T lambda = (lambda, lambda) pulls both masses up
    assert np.max(np.abs(forces.multipliers[:, 0] - tension)) <= 1e-9
    assert not forces.multipliers[:, 1:].any()
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


# -- nonholonomic and unilateral constraints, without numba ----------------------------------------
#
# These scenes' forces are evaluated with numpy only (the lambdified functions and
# ``constraints.Numeric``).


def _numpy_only(scene, **values):
    """A scene compiled without any kernel (nothing for numba to compile): the forces come
    from the lambdified functions and ``constraints.Numeric`` alone."""
    mechanics = derive(parse_scene(scene) if "\n" in scene else load_scene(scene))
    compiled = compile_system(mechanics, ())
    return compiled.with_parameters(values) if values else compiled


def _catalogue_run(name: str, t_end: float):
    """A short ``constrained_dop853`` run of a catalogue scene."""
    mechanics = derive(load_scene(name))
    compiled = compile_system(mechanics, WANTS | required_wants("constrained_dop853"))
    t, y = _run(compiled, t_end, method="constrained_dop853")
    return compiled, t, y


def _disk_states(compiled, count: int = 50, seed: int = 7):
    """Random states of the rolling disk on its constraints: x_dot = R cos(phi) psi_dot,
    y_dot = R sin(phi) psi_dot; returns (Y (N, 8), phi_dot, psi_dot)."""
    m, R = compiled.parameters
    rng = np.random.default_rng(seed)
    x, y, phi, psi = rng.uniform(-3, 3, (4, count))
    phi_dot, psi_dot = rng.uniform(-2, 2, (2, count))
    x_dot, y_dot = R * np.cos(phi) * psi_dot, R * np.sin(phi) * psi_dot
    p = np.stack([m * x_dot, m * y_dot, m * R**2 / 4 * phi_dot, m * R**2 / 2 * psi_dot], axis=1)
    return np.concatenate([np.stack([x, y, phi, psi], axis=1), p], axis=1), phi_dot, psi_dot


def test_the_rolling_disk_s_ground_pushes_it_round_its_circle():
    """The disk turns at a constant phi_dot and rolls at a constant psi_dot (psi'' = 0
    from (I + m R^2) psi'' = 0), so its contact point moves on a circle of radius
    R psi_dot/phi_dot at the speed v = R psi_dot. Newton's law for x and y, m x'' =
    -lambda_1 and m y'' = -lambda_2 with x'' = -R sin(phi) phi_dot psi_dot, gives
    lambda = m R phi_dot psi_dot (sin phi, -cos phi): the ground's sideways force, of
    size m v^2 / radius, towards the circle's centre, and none on phi and psi."""
    compiled = _numpy_only("rolling_disk")
    analysis = cf.analyse(compiled.mechanics)
    assert analysis.computes and analysis.k == 2 and not analysis.note
    assert analysis.kinds == ("nonholonomic", "nonholonomic")
    assert analysis.multiplier_labels == ["lambda_1 (nonholonomic)", "lambda_2 (nonholonomic)"]
    assert not analysis.rheonomic and not analysis.impacts  # no t and b = 0
    assert analysis.balance and analysis.energy_name == "h"
    Y, phi_dot, psi_dot = _disk_states(compiled)
    t = np.linspace(0.0, 3.0, len(Y))
    forces = analysis.evaluate(compiled, t, Y)
    m, R = compiled.parameters
    phi = Y[:, 2]
    size = m * R * phi_dot * psi_dot
    expected = size[:, None] * np.stack([np.sin(phi), -np.cos(phi)], axis=1)
    np.testing.assert_allclose(forces.multipliers, expected, rtol=0, atol=1e-14)
    assert forces.acting.all()
    speed, radius = R * np.abs(psi_dot), R * np.abs(psi_dot / phi_dot)
    np.testing.assert_allclose(
        np.hypot(*forces.generalized[:, :2].T), m * speed**2 / radius, rtol=1e-13
    )
    np.testing.assert_allclose(forces.generalized[:, 2:], 0.0, rtol=0, atol=1e-15)
    # the force points to the centre: perpendicular to the velocity, to its left when
    # the disk turns left (phi_dot > 0)
    heading = np.stack([np.cos(phi), np.sin(phi)], axis=1)
    left = np.stack([-np.sin(phi), np.cos(phi)], axis=1)
    along = np.einsum("nj,nj->n", forces.generalized[:, :2], heading)
    across = np.einsum("nj,nj->n", forces.generalized[:, :2], left)
    np.testing.assert_allclose(along, 0.0, rtol=0, atol=1e-15)
    np.testing.assert_allclose(across, size, rtol=1e-13)


def test_the_rolling_constraint_does_no_virtual_work_and_no_work():
    compiled = _numpy_only("rolling_disk")
    analysis = cf.analyse(compiled.mechanics)
    Y, _, _ = _disk_states(compiled, seed=11)
    forces = analysis.evaluate(compiled, 0.0, Y)
    # D'Alembert for nonholonomic constraints: no work on the displacements the rows
    # allow, a . delta q = 0: rolling (R cos phi, R sin phi, 0, 1) and turning (0, 0, 1, 0)
    assert np.max(forces.virtual_work) <= 1e-15
    m, R = compiled.parameters
    phi = Y[:, 2]
    rolling = np.stack([R * np.cos(phi), R * np.sin(phi), 0 * phi, 1 + 0 * phi], axis=1)
    Q = forces.generalized
    scale = np.linalg.norm(Q, axis=1)
    assert np.max(np.abs(np.einsum("nj,nj->n", Q, rolling)) / scale) <= 1e-15
    assert np.max(np.abs(Q[:, 2]) / scale) <= 1e-15
    # a sideways slip is not allowed, and the ground's force does work on it: the
    # check can tell
    slip = np.stack([-np.sin(phi), np.cos(phi), 0 * phi, 0 * phi], axis=1)
    assert np.min(np.abs(np.einsum("nj,nj->n", Q, slip)) / scale) > 0.99
    # no t and b = 0: no power, Q_c . qdot = lambda^T b = 0 to round-off
    assert np.max(np.abs(forces.power) / forces.power_scale) <= 1e-15


def test_a_run_of_the_rolling_disk_keeps_its_multipliers_and_its_energy():
    compiled, t, y = _catalogue_run("rolling_disk", 2.0)
    analysis = cf.analyse(compiled.mechanics)
    forces = analysis.evaluate(compiled, t, y)
    m, R = compiled.parameters
    phi, phi_dot, psi_dot = y[:, 2], y[:, 6] / (m * R**2 / 4), y[:, 7] / (m * R**2 / 2)
    expected = (m * R * phi_dot * psi_dot)[:, None] * np.stack([np.sin(phi), -np.cos(phi)], 1)
    np.testing.assert_allclose(forces.multipliers, expected, rtol=0, atol=1e-12)
    # the scene's start: |lambda| = m v^2/r with v = 1 on a circle of radius 2
    np.testing.assert_allclose(np.hypot(*forces.multipliers.T), 0.5, rtol=1e-9)
    W = analysis.work(compiled, t, y)
    assert np.max(np.abs(W)) <= 1e-14
    assert np.max(np.abs(forces.energy - forces.energy[0] - W)) <= 1e-12


CONVEYOR = """
title = "A block carried at the belt's speed u and pushed back by a force k"
[system]
coordinates = ["x", "y"]
parameters = { m = 1.5, k = 2.0, u = 0.7 }
kinetic = "m*(x_dot**2 + y_dot**2)/2"
potential = "k*x"
[constraints]
nonholonomic = ["x_dot - u"]
[initial]
x_dot = 0.7
y_dot = 0.3
"""


def test_a_nonholonomic_constraint_with_b_works_lambda_b():
    """x_dot = u holds the block against k: m x'' = -k - lambda with x'' = 0, lambda = -k,
    and the power is Q_c . qdot = k u = lambda^T b (b = -u), all of it the change of h."""
    compiled = _numpy_only(CONVEYOR)
    analysis = cf.analyse(compiled.mechanics)
    assert analysis.rheonomic and analysis.balance and analysis.energy_name == "h"
    m, k, u = compiled.parameters
    t = np.linspace(0.0, 2.0, 41)
    Y = np.stack([u * t, 0.3 * t, m * u + 0 * t, m * 0.3 + 0 * t], axis=1)
    forces = analysis.evaluate(compiled, t, Y)
    np.testing.assert_allclose(forces.multipliers[:, 0], -k, rtol=1e-14)
    np.testing.assert_allclose(forces.power, forces.multipliers[:, 0] * -u, rtol=1e-14)
    np.testing.assert_allclose(forces.power, k * u, rtol=1e-14)
    assert np.max(forces.virtual_work) <= 1e-15
    W = analysis.work(compiled, t, Y)
    np.testing.assert_allclose(W, k * u * t, rtol=0, atol=1e-13)
    np.testing.assert_allclose(forces.energy - forces.energy[0], W, rtol=0, atol=1e-13)


# -- unilateral: the bouncing ball -----------------------------------------------------------------


def test_the_floor_pushes_a_resting_ball_with_its_weight_and_a_flying_one_not_at_all():
    compiled = _numpy_only("bouncing_ball", m=2.5, g=3.7)
    scene = compiled.mechanics.scene
    analysis = cf.analyse(compiled.mechanics)
    assert analysis.computes and analysis.kinds == ("unilateral",)
    assert analysis.multiplier_labels == ["lambda_1 (y ≥ 0)"]
    # the same columns as the CSV export's
    assert analysis.multiplier_names == constraints.multiplier_names(scene)
    # the impacts change the energy too: no balance, but the energy is formed
    assert analysis.impacts and not analysis.balance and analysis.energy_name == "h"
    assert not analysis.rheonomic and cf.restitution(compiled) == 0.8
    m, g = 2.5, 3.7
    Y = np.array(
        [
            [-1.0, 0.0, 0.8 * m, 0.0],  # resting (sliding) on the floor
            [0.4, 0.0, 0.0, 0.0],  # resting
            [0.2, 0.7, 0.8 * m, -1.0 * m],  # in flight
            [0.2, 0.0, 0.8 * m, 2.0 * m],  # just bounced: at the floor, leaving it
            [0.2, 1e-3, 0.0, 0.0],  # at the top of a tiny hop
        ]
    )
    forces = analysis.evaluate(compiled, 0.0, Y)
    lam = forces.multipliers[:, 0]
    # -G^T lambda with G = (0, 1): the floor pushes up with m g where lambda = -m g
    np.testing.assert_allclose(lam[:2], -m * g, rtol=1e-15)
    np.testing.assert_allclose(forces.generalized[:2], [[0.0, m * g]] * 2, rtol=1e-15, atol=0)
    assert np.all(lam[2:] == 0.0) and np.all(forces.generalized[2:] == 0.0)
    assert forces.acting[:, 0].tolist() == [True, True, False, False, False]
    # resting: m y'' = -m g - lambda = 0; flying: y'' = -g
    np.testing.assert_allclose(forces.accelerations[:, 1], [0, 0, -g, -g, -g], atol=1e-15)
    assert np.all(forces.virtual_work == 0.0)  # along the floor, and nothing to do in flight
    assert np.all(forces.power == 0.0)


def test_the_floor_s_work_is_zero_and_the_impacts_take_one_minus_e_squared():
    """Dropped from y0 = 1 at rest, the ball reaches the floor with v1 = sqrt(2 g y0) and
    leaves it with e v1: each impact keeps e^2 of the energy above the floor, so after
    j impacts E - E0 = -(1 - e^(2j)) m g y0, and none of it is the floor's work W."""
    compiled, t, y = _catalogue_run("bouncing_ball", 2.0)  # impacts at 0.45, 1.17, 1.75
    analysis = cf.analyse(compiled.mechanics)
    forces = analysis.evaluate(compiled, t, y)
    m, g, e = compiled.parameters
    W = analysis.work(compiled, t, y)
    assert np.all(np.abs(W) <= 1e-15)
    v1 = math.sqrt(2 * g * 1.0)
    impacts = v1 / g + np.cumsum([0.0, *(2 * e**j * v1 / g for j in (1, 2))])
    # the impacts at or before each row (a step ends at the impact, a few units of
    # round-off short of it, with the state arriving; the next row, at the same time,
    # is the state after it)
    done = np.searchsorted(impacts - 1e-9, t, side="right")
    arriving = np.flatnonzero(t[1:] == t[:-1])
    assert len(arriving) == 3
    done[arriving] -= 1
    assert set(done) == {0, 1, 2, 3}
    jump = forces.energy - forces.energy[0] - W
    np.testing.assert_allclose(jump, -(1 - e ** (2 * done)) * m * g * 1.0, rtol=0, atol=1e-9)
    # rows left out: W is carried across as zero (no power anywhere), never unknown
    gapped = y.copy()
    gapped[3:5] = np.nan
    integral = cf.WorkIntegral(analysis, compiled)
    pieced = integral.add(t, gapped)
    assert integral.gaps == 1 and np.all(pieced[5:] == pieced[2]) and abs(pieced[2]) <= 1e-15


def test_elastic_walls_keep_the_gas_molecule_s_energy():
    compiled, t, y = _catalogue_run("gas_in_box", 4.0)
    analysis = cf.analyse(compiled.mechanics)
    assert analysis.multiplier_labels == [
        "lambda_1 (x ≥ 0)",
        "lambda_2 (a - x ≥ 0)",
        "lambda_3 (y ≥ 0)",
        "lambda_4 (b - y ≥ 0)",
    ]
    assert analysis.impacts and cf.restitution(compiled) == 1.0
    forces = analysis.evaluate(compiled, t, y)
    assert np.all(forces.multipliers == 0.0)  # nothing pushes without a force to resist
    vx, vy = forces.velocities.T
    assert np.any(np.diff(np.sign(vx)) != 0) and np.any(np.diff(np.sign(vy)) != 0)  # impacts
    W = analysis.work(compiled, t, y)
    assert np.max(np.abs(forces.energy - forces.energy[0] - W)) <= 1e-12


SHAKEN = """
title = "A ball on a plate shaken up and down"
[system]
coordinates = ["x", "y"]
parameters = { m = 1.3, g = 9.81, a = 0.05, w = 3.0, restitution = 0.5 }
kinetic = "m*(x_dot**2 + y_dot**2)/2"
potential = "m*g*y"
[constraints]
unilateral = ["y - a*sin(w*t)"]
[initial]
y = 0.3
"""


def test_a_moving_floor_works_on_a_resting_ball_and_its_impacts_leave_w_unknown():
    """Resting on the plate, y = a sin(w t): the plate pushes with -lambda = m (g + y''),
    its power is -lambda y', and its work is the change of h = T + V, m g dy + m d(y'^2)/2
    (a moving constraint: no balance to lean on, W is integrated). A state leaving the
    plate faster than it moves has just bounced: the velocity jumped, and W across that
    interval is unknown, not a number the quintic would make up."""
    compiled = _numpy_only(SHAKEN)
    analysis = cf.analyse(compiled.mechanics)
    assert analysis.rheonomic and analysis.impacts and not analysis.balance
    m, g, a, w, _ = compiled.parameters
    # rows 0.1 apart: the states between them are off the plate by more than a contact's
    # tolerance, and still in contact (the contacts both rows act on)
    t = np.linspace(0.0, 3.0, 31)
    y, vy = a * np.sin(w * t), a * w * np.cos(w * t)
    Y = np.stack([0 * t, y, 0 * t, m * vy], axis=1)
    forces = analysis.evaluate(compiled, t, Y)
    assert forces.acting.all()
    np.testing.assert_allclose(forces.multipliers[:, 0], -m * (g - a * w**2 * np.sin(w * t)))
    W = analysis.work(compiled, t, Y)
    exact = m * g * (y - y[0]) + m * (vy**2 - vy[0] ** 2) / 2
    assert np.ptp(W) > 0.5
    np.testing.assert_allclose(W, exact, rtol=0, atol=1e-9)
    np.testing.assert_allclose(forces.energy - forces.energy[0], W, rtol=0, atol=1e-9)
    # the same rows with a bounce at row 15: there the ball leaves the plate at 1 m/s
    bounced = Y.copy()
    bounced[15, 3] = m * 1.0
    steps = analysis.interval_work(compiled, t, bounced)
    assert np.isnan(steps[14]) and np.all(np.isfinite(steps[:14]))
    integral = cf.WorkIntegral(analysis, compiled)
    carried = integral.add(t, bounced)
    np.testing.assert_allclose(carried[:15], W[:15], rtol=0, atol=1e-12)
    assert np.all(np.isnan(carried[15:]))
