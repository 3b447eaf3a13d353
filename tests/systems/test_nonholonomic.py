"""Nonholonomic constraints a(q, t) . qdot + b(q, t) = 0 with Lagrange multipliers.

The catalogue's rolling disk (``resources/scenes/rolling_disk.toml``): a vertical disk of
radius R rolls without slipping on a plane; x, y is its point of contact, phi its heading,
psi its rolling angle, T = m (x_dot**2 + y_dot**2)/2 + I psi_dot**2/2 + J phi_dot**2/2 with
I = m R**2/2 and J = m R**2/4, and the contact point does not slip:

    x_dot - R cos(phi) psi_dot = 0,   y_dot - R sin(phi) psi_dot = 0.

With M qddot + A^T lambda = 0 (no applied force) the equations are

    m x_ddot = -lambda_1,  m y_ddot = -lambda_2,  J phi_ddot = 0,
    I psi_ddot = R (cos(phi) lambda_1 + sin(phi) lambda_2),

and differentiating the constraints gives x_ddot = R (cos(phi) psi_ddot - sin(phi)
phi_dot psi_dot), y_ddot = R (sin(phi) psi_ddot + cos(phi) phi_dot psi_dot). Putting these
into the psi equation: (I + m R**2) psi_ddot = 0. So phi_dot = w and psi_dot = s are
constant and the contact point runs round a circle of radius rho = R s / w:
x = x_c + rho sin(phi), y = y_c - rho cos(phi), with x_ddot = -rho w**2 sin(phi), hence
lambda_1 = m rho w**2 sin(phi) and lambda_2 = -m rho w**2 cos(phi) (the centripetal force
of the ground on the disk is -A^T lambda). The scene starts at (0, -2) heading along x,
with w = 0.5 and s = 2 and R = 0.5: rho = 2, a circle about the origin.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
import sympy

from systems import constraints
from systems.compiled import compile_system
from systems.mechanics import DerivationError, derive
from systems.report import derivation_json, readable
from systems.scene import load_scene, parse_scene
from systems.simulation import Run, Sampler, required_wants, stream

NAME = "rolling_disk"
R, W, S, M = 0.5, 0.5, 2.0, 1.0  # radius, phi_dot, psi_dot, mass of the scene
RHO = R * S / W


@pytest.fixture(scope="module")
def compiled():
    mechanics = derive(load_scene(NAME))
    return compile_system(mechanics, required_wants("constrained_dop853") | {"hamiltonian"})


def _plain_python(mechanics):
    """A scene with what a constrained_dop853 run and its energy need."""
    wants = required_wants("constrained_dop853") | {"hamiltonian"}
    return compile_system(mechanics, wants)


def _trajectory(compiled, method="constrained_dop853", **options):
    blocks = list(stream(compiled, method=method, max_points=100_000, **options))
    assert blocks[-1].status == "ok", blocks[-1].message
    t = np.concatenate([b.t for b in blocks])
    y = np.concatenate([b.y for b in blocks])
    return t, y


def _slip(y: np.ndarray) -> np.ndarray:
    """The contact point's velocity (x_dot - R cos(phi) psi_dot, y_dot - R sin(phi)
    psi_dot), from the momenta p = (m x_dot, m y_dot, J phi_dot, I psi_dot); (N, 2)."""
    x_dot, y_dot = y[:, 4] / M, y[:, 5] / M
    psi_dot = y[:, 7] / (M * R**2 / 2)
    phi = y[:, 2]
    return np.stack([x_dot - R * np.cos(phi) * psi_dot, y_dot - R * np.sin(phi) * psi_dot], 1)


# -- the derivation ----------------------------------------------------------------------------


def test_derivation_counts_both_degrees_of_freedom_and_shows_the_constraints():
    mechanics = derive(load_scene(NAME))
    data = derivation_json(mechanics)
    assert data["degrees_of_freedom"] == 2 and isinstance(data["degrees_of_freedom"], int)
    given = data["constraints"]
    assert given["holonomic"] == [] and given["unilateral"] == []
    assert given["nonholonomic"] == ["-R*psi_dot*cos(phi) + x_dot", "-R*psi_dot*sin(phi) + y_dot"]
    assert given["coefficients"] == [["1", "0", "0", "-R*cos(phi)"], ["0", "1", "0", "-R*sin(phi)"]]
    assert given["free_terms"] == ["0", "0"]
    assert given["nonholonomic_gamma"] == [
        "-R*phi_dot*psi_dot*sin(phi)",
        "R*phi_dot*psi_dot*cos(phi)",
    ]
    assert given["configuration_degrees_of_freedom"] == 4
    assert given["velocity_degrees_of_freedom"] == 2
    assert given["multipliers"] == ["lambda_1", "lambda_2"] and given["restitution"] is None
    json.dumps(data)
    text = readable(mechanics, equilibria=False)
    assert (
        "degrees of freedom: 2 for the velocities = 4 coordinates − 2 nonholonomic "
        "constraints; the configuration needs 4 coordinates" in text
    )
    assert "Nonholonomic constraints a(q, t)·q̇ + b(q, t) = 0" in text and "Ψ₂" in text
    assert "Hamilton's equations (free, without the constraint force −Aᵀ λ)" in text
    c = mechanics.classification
    assert not c.holonomic and c.bilateral and not c.rheonomic and not c.simple
    assert c.hamiltonian_conserved and "H" in mechanics.conserved
    # the ground pushes along x and y (and rolls psi): neither their momenta nor Noether's
    # translations are conserved; the heading phi appears in the rows only through
    # cos(phi) and sin(phi), its column is zero, so p_phi is conserved
    assert mechanics.cyclic == ("phi",)
    assert set(mechanics.conserved) == {"H", "p_phi"}
    assert constraints.multiplier_names(mechanics.scene) == ["lambda_1", "lambda_2"]


def test_gamma_is_minus_the_derivative_without_qddot():
    mechanics = derive(load_scene(NAME))
    pieces = constraints.rows(mechanics)
    assert pieces.kinds == ("nonholonomic", "nonholonomic")
    # d/dt (x_dot - R cos(phi) psi_dot) = x_ddot - R cos(phi) psi_ddot + R sin(phi) phi_dot psi_dot
    x, y, phi, psi = mechanics.q
    _, _, phi_dot, psi_dot = mechanics.qdot
    Rs = mechanics.params["R"]
    assert (pieces.gamma[0] + Rs * sympy.sin(phi) * phi_dot * psi_dot).equals(0)
    assert constraints.holonomic(mechanics) is None


# -- the motion --------------------------------------------------------------------------------


def test_the_disk_rolls_round_its_circle_without_slipping(compiled):
    """Measured: over 40 turns (about 500 time units) the slip stays at 2e-16, phi_dot
    exact and psi_dot constant to 8e-13, the energy to 7e-13 (relative) and the contact
    point within 1e-12 of the exact circle."""
    t_end = 40 * 2 * math.pi / W
    t, y = _trajectory(compiled, t_end=t_end)
    assert t[-1] == pytest.approx(t_end)
    assert np.max(np.abs(_slip(y))) <= 1e-10
    qdot = compiled.constraints().qdot(t, y)
    assert np.max(np.abs(qdot[:, 2] - W)) <= 1e-10
    assert np.max(np.abs(qdot[:, 3] - S)) <= 1e-10
    # the exact solution: phi = w t, psi = s t, and the contact point on the circle
    assert np.max(np.abs(y[:, 2] - W * t)) <= 1e-8
    assert np.max(np.abs(y[:, 3] - S * t)) <= 1e-8
    assert np.max(np.abs(y[:, 0] - RHO * np.sin(W * t))) <= 1e-8
    assert np.max(np.abs(y[:, 1] + RHO * np.cos(W * t))) <= 1e-8
    assert np.max(np.abs(np.hypot(y[:, 0], y[:, 1]) - RHO)) <= 1e-10
    H = compiled.hamiltonian(t, y)
    assert np.max(np.abs(H - H[0])) / H[0] <= 1e-10
    assert H[0] == pytest.approx(M * (R * S) ** 2 / 2 + M * R**2 / 4 * S**2 + M * R**2 / 8 * W**2)


def test_the_multipliers_are_the_grounds_centripetal_force(compiled):
    t, y = _trajectory(compiled, t_end=30.0)
    lam = compiled.constraints().multipliers(t, y)
    phi = y[:, 2]
    assert np.max(np.abs(lam[:, 0] - M * RHO * W**2 * np.sin(phi))) <= 1e-9
    assert np.max(np.abs(lam[:, 1] + M * RHO * W**2 * np.cos(phi))) <= 1e-9
    kernel = np.empty(2)
    for row in range(0, len(t), max(1, len(t) // 40)):
        compiled.constrained("c_multipliers", float(t[row]), y[row], compiled.parameters, kernel)
        assert np.max(np.abs(kernel - lam[row])) <= 1e-12


def test_the_run_reports_the_violation_of_the_velocity_constraints(compiled):
    run = Run(compiled, method="constrained_dop853", t_end=200.0, diagnostics=("H",))
    sampler = Sampler(run, np.linspace(0.0, 200.0, 401))
    rows = list(sampler)
    assert sampler.last.status == "ok", sampler.last.message
    assert 0.0 <= sampler.violation <= 1e-10
    y = np.array([r[1] for r in rows])
    values = compiled.constraints().values(np.array([r[0] for r in rows]), y)
    assert values.shape == (len(rows), 2) and len(rows) > 300
    assert np.allclose(values, _slip(y), atol=1e-15)
    # a state that slips: the violation is |a . qdot + b|
    slipping = y[:1].copy()
    slipping[0, 4] += 0.25 * M  # x_dot 0.25 more than rolling allows
    assert compiled.constraints().violation(0.0, slipping) == pytest.approx(0.25)


def test_the_fixed_step_method_keeps_the_constraints_too(compiled):
    t, y = _trajectory(compiled, method="constrained_rk4", t_end=20.0, dt=0.01)
    assert np.max(np.abs(_slip(y))) <= 1e-10
    assert np.max(np.abs(np.hypot(y[:, 0], y[:, 1]) - RHO)) <= 1e-7  # RK4's own error


def test_a_slipping_start_is_moved_onto_the_constraints(compiled):
    """x_dot = 0 with psi_dot = 2 slips; the start is moved to the nearest rolling state
    in the kinetic metric: minimising m dx**2/2 + I dpsi**2/2 with
    (x_dot + dx) - R (psi_dot + dpsi) = 0 gives m dx = mu, I dpsi = -R mu, hence
    psi_dot' = (I psi_dot + m R x_dot)/(I + m R**2) and x_dot' = R psi_dot'."""
    y0 = compiled.initial_state()
    y0[4] = 0.0  # p_x = m x_dot = 0
    run = Run(compiled, method="constrained_dop853", y0=y0, t_end=1.0)
    I = M * R**2 / 2
    psi_dot = I * S / (I + M * R**2)
    assert run.y0[7] / I == pytest.approx(psi_dot, rel=1e-14)
    assert run.y0[4] / M == pytest.approx(R * psi_dot, rel=1e-14)
    assert np.max(np.abs(_slip(run.y0[None]))) <= 1e-15


def test_the_energy_tab_balances_a_rolling_disk(compiled):
    from systems.textbook import jobs

    result = jobs.energy(
        compile_system(compiled.mechanics, ("rhs", "hamiltonian", "velocities")), 5.0
    )
    balance = result.balance
    # the rolling does no work: dH/dt = 0 = the prediction (no t, no effects)
    assert np.max(np.abs(balance.rate)) <= 1e-6 * balance.hamiltonian[0]
    assert np.max(np.abs(balance.partial)) == 0.0 and np.max(np.abs(balance.power)) == 0.0
    assert np.ptp(balance.hamiltonian) <= 1e-8 * balance.hamiltonian[0]
    assert not result.rheonomic


# -- other scenes: a moving constraint, mistakes -----------------------------------------------

SKATE = """
[system]
coordinates = ["x", "y"]
parameters = {{ m = 1.0, w = 1.5 }}
kinetic = "m*(x_dot**2 + y_dot**2)/2"

[constraints]
nonholonomic = [{constraint}]

[initial]
x_dot = 1.0
"""


def _skate(constraint: str):
    return parse_scene(SKATE.format(constraint=constraint), source="skate.toml")


def test_a_turning_knife_edge_is_rheonomic_and_followed():
    """A knife edge whose direction turns at a constant rate w: the velocity may only be
    along (cos(w t), sin(w t)): -sin(w t) x_dot + cos(w t) y_dot = 0. The speed along the
    blade is conserved (the constraint force is normal to it), so the point runs round a
    circle of radius v/w: x = sin(w t) v/w, y = (1 - cos(w t)) v/w from rest at the origin
    with speed v along x. The constraint has t: rheonomic, time dependent, and the blade's
    force does no work here, but H is not reported conserved (a moving constraint may
    work)."""
    mechanics = derive(_skate('"-sin(w*t)*x_dot + cos(w*t)*y_dot"'))
    c = mechanics.classification
    assert c.rheonomic and not c.holonomic and c.time_dependent
    assert not c.hamiltonian_conserved and "H" not in mechanics.conserved
    compiled = _plain_python(mechanics)
    t, y = _trajectory(compiled, t_end=10.0)
    v, w = 1.0, 1.5
    assert np.max(np.abs(y[:, 0] - v / w * np.sin(w * t))) <= 1e-8
    assert np.max(np.abs(y[:, 1] - v / w * (1 - np.cos(w * t)))) <= 1e-8
    assert compiled.constraints().violation(t, y) <= 1e-10
    from systems.textbook import jobs

    with pytest.raises(ValueError, match="constraint moves"):
        jobs.energy(compile_system(mechanics, ("rhs", "hamiltonian", "velocities")), 1.0)


def test_a_velocity_free_part_is_rheonomic_too():
    """x_dot - 1 = 0 (a belt) is x = t + x0: rheonomic, and the belt does work."""
    mechanics = derive(_skate('"x_dot - 1"'))
    c = mechanics.classification
    assert c.rheonomic and not c.hamiltonian_conserved and not c.time_dependent


@pytest.mark.parametrize(
    ("text", "field", "words"),
    [
        ('"x_dot - y_dot", "2*x_dot - 2*y_dot"', "constraints.nonholonomic", "not independent"),
        ('"x_dot", "y_dot"', "constraints.nonholonomic", "no degree of freedom"),
    ],
)
def test_dependent_or_too_many_velocity_constraints_are_refused(text, field, words):
    with pytest.raises(DerivationError) as caught:
        derive(_skate(text))
    assert caught.value.field == field and words in str(caught.value)


def test_a_velocity_constraint_that_repeats_a_holonomic_one_is_refused():
    text = SKATE.format(constraint='"x_dot - y_dot"').replace(
        "nonholonomic =", 'holonomic = ["x - y"]\nnonholonomic ='
    )
    with pytest.raises(DerivationError) as caught:
        derive(parse_scene(text, source="skate.toml"))
    assert caught.value.field == "constraints.nonholonomic"
    assert "not independent" in str(caught.value) and "dPhi/dq and a" in str(caught.value)


@pytest.mark.parametrize(
    ("constraint", "field", "words"),
    [
        ('"x_dot**2 - y_dot"', "constraints.nonholonomic[0]", "linear in"),
        ('"x - y"', "constraints.nonholonomic[0]", "at least one"),
        ('"x_dot - z"', "constraints.nonholonomic[0]", "unknown name 'z'"),
    ],
)
def test_mistakes_name_the_field(constraint, field, words):
    from systems.scene import SceneError

    with pytest.raises(SceneError) as caught:
        _skate(constraint)
    assert caught.value.field == field and words in str(caught.value)


def test_a_mixed_scene_numbers_the_multipliers_holonomic_first():
    """A particle on the unit sphere (holonomic) kept at its height by z_dot = 0 (a
    velocity constraint, integrable but given as such): two rows, holonomic first; the
    velocities are restricted by both, the configuration by the sphere only."""
    text = """
[system]
coordinates = ["x", "y", "z"]
parameters = { m = 1.0 }
kinetic = "m*(x_dot**2 + y_dot**2 + z_dot**2)/2"
[constraints]
holonomic = ["x**2 + y**2 + z**2 - 1"]
nonholonomic = ["z_dot"]
[initial]
x = 0.8
z = 0.6
y_dot = 1.0
"""
    mechanics = derive(parse_scene(text))
    assert constraints.degrees_of_freedom(mechanics) == 1
    assert constraints.configuration_degrees_of_freedom(mechanics) == 2
    assert constraints.rows(mechanics).kinds == ("holonomic", "nonholonomic")
    compiled = _plain_python(mechanics)
    t, y = _trajectory(compiled, t_end=10.0)
    # z stays 0.6: a horizontal circle of radius 0.8 at speed 1
    assert np.max(np.abs(y[:, 2] - 0.6)) <= 1e-12
    assert compiled.constraints().violation(t, y) <= 1e-12
    lam = compiled.constraints().multipliers(t, y)
    # the circle's centripetal force m v**2/0.8 comes from both: -2 lambda_1 (x, y) in the
    # plane, and along z, -2 lambda_1 z - lambda_2 = 0
    assert np.allclose(2 * lam[:, 0] * 0.8, 1.0 / 0.8, rtol=1e-9)
    assert np.allclose(lam[:, 1], -2 * lam[:, 0] * 0.6, rtol=1e-9)
