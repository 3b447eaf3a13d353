"""The chapter's classification (``systems.classification``) against its definitions.

Three tables: every catalogue scene, the cases of the issue that found the old answers
wrong, and the users' scenes (``tests/user_systems``, copies of ``../shared/user-systems``,
whose README says what the textbook says about each). Every row carries the reason for its answers.

The columns, in the chapter's order: rheonomic, holonomic, bilateral, conservative, simple
(scleronomic, holonomic and conservative), then time_dependent (t explicit in the
equations of motion), hamiltonian_conserved, hamiltonian_is_energy (None: no energy can
be named), natural, separable.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import sympy

from systems.classification import Classification, Constraints, classify
from systems.mechanics import derive
from systems.scene import catalogue, load_scene, parse_scene

KEYS = (
    "rheonomic",
    "holonomic",
    "bilateral",
    "conservative",
    "simple",
    "time_dependent",
    "hamiltonian_conserved",
    "hamiltonian_is_energy",
    "natural",
    "separable",
)
T, F, N = True, False, None

# fmt: off
# name: (rheonomic, holonomic, bilateral, conservative, simple,
#        time_dependent, H conserved, H = T + V, natural, separable), reason
CATALOGUE = {
    "atwood_machine":           ((F, T, F, F, F, F, F, T, T, T), "fixed pulley, gravity only, H = T + V between impacts; the masses stop at the floor and the pulley (issue 25: they ran through it), unilateral constraints with restitution e = 0: not bilateral, the landing takes the energy, so not conservative and H not conserved"),  # noqa: E501
    "atwood_rope":              ((F, T, F, F, F, F, F, T, T, T), "y1, y2 tied by the fixed rope -y1 - y2 - L = 0: scleronomic, holonomic; the floor and the pulley stop the masses (issue 25), unilateral with restitution e = 0: not bilateral, not conservative, H not conserved (H = T + V between impacts), M = diag(m1, m2)"),  # noqa: E501
    "bead_on_rotating_hoop":    ((T, T, T, T, F, F, T, F, F, T), "hoop turned at omega: T0 = m a^2 omega^2 sin^2/2 shows r(q, t); L has no t, so H = T2 - T0 + V is conserved but is not T + V; the t in the drawing changes nothing"),  # noqa: E501
    "cartesian_pendulum":       ((F, T, T, T, T, F, T, T, T, T), "x, y tied by the fixed equation x^2 + y^2 - l^2 = 0: scleronomic, holonomic, bilateral; gravity only: simple; H = T + V, M = m I"),  # noqa: E501
    "bouncing_ball":            ((F, T, F, F, F, F, F, T, T, T), "the floor y >= 0 is unilateral; its impacts keep a fraction e (the restitution slider) of the normal speed and so may take energy away: not conservative, H not conserved (or watched), though between impacts H = T + V"),  # noqa: E501
    "coupled_oscillators":      ((F, T, T, T, T, F, T, T, T, T), "springs, no constraint in motion: simple"),  # noqa: E501
    "damped_pendulum":          ((F, T, T, F, F, F, F, T, T, T), "Rayleigh dissipation acts: not conservative, H not conserved; the equations have no t"),  # noqa: E501
    "double_pendulum":          ((F, T, T, T, T, F, T, T, T, F), "fixed pivot: simple; M(q) couples the angles, so H is not separable"),  # noqa: E501
    "driven_damped_pendulum":   ((F, T, T, F, F, T, F, T, T, T), "the force A cos(w t) puts t in the equations: time dependent, not conservative; T and V have no t: scleronomic"),  # noqa: E501
    "figure_eight":             ((F, T, T, T, T, F, T, T, T, T), "three free bodies, Newtonian gravity: simple"),  # noqa: E501
    "fpu_chain":                ((F, T, T, T, T, F, T, T, T, T), "a lattice of springs: simple, separable"),  # noqa: E501
    "gas_in_box":               ((F, T, F, T, T, F, T, T, T, T), "four walls, unilateral and fixed; elastic impacts (no restitution parameter: e = 1) do no work: conservative and simple, H = T conserved"),  # noqa: E501
    "harmonic_oscillator":      ((F, T, T, T, T, F, T, T, T, T), "the textbook's simple system"),  # noqa: E501
    "henon_heiles":             ((F, T, T, T, T, F, T, T, T, T), "given by a t-free H with a positive kinetic form: H is the energy"),  # noqa: E501
    "kapitza_pendulum":         ((T, T, T, F, F, T, F, F, F, F), "the pivot is shaken, a cos(w t) in the bob's position with T1 != 0: rheonomic; the shaking does work: neither conservative nor H conserved, and H is not T + V"),  # noqa: E501
    "kepler_cartesian":         ((F, T, T, T, T, F, T, T, T, T), "free particle in a central potential: simple"),  # noqa: E501
    "mathieu_oscillator":       ((F, T, T, F, F, T, F, T, T, T), "the stiffness delta + eps cos t puts t in V only: scleronomic but time dependent, so not conservative and H (= T + V) not conserved"),  # noqa: E501
    "pendulum_chain":           ((F, T, T, T, T, F, T, T, T, F), "fixed pivot, rigid links (matrix form): simple; M(q) couples"),  # noqa: E501
    "pendulum_ring":            ((F, T, T, T, T, F, T, T, T, T), "pendulums and torsion springs: simple"),  # noqa: E501
    "planetary_motion":         ((F, T, T, T, T, F, T, T, T, F), "central force in polar coordinates: simple; M(r) so not separable"),  # noqa: E501
    "rolling_disk":             ((F, F, T, T, F, F, T, T, T, T), "rolling without slipping: two velocity constraints a(q) . qdot = 0 that do not integrate: nonholonomic, so not simple; no t and no velocity-free part: scleronomic, the rolling does no work and H = T is conserved"),  # noqa: E501
    "simple_pendulum":          ((F, T, T, T, T, F, T, T, T, T), "fixed pivot, gravity: simple"),  # noqa: E501
    "spherical_pendulum":       ((F, T, T, T, T, F, T, T, T, F), "fixed pivot: simple; M(theta)"),  # noqa: E501
    "stiff_spring_pendulum":    ((F, T, T, T, T, F, T, T, T, F), "spring and gravity, fixed pivot: simple"),  # noqa: E501
    "variable_length_pendulum": ((T, T, T, F, F, T, F, F, F, F), "the string is pulled: l(t) in T, T0 != 0; the string's agent does work, so not conservative and H = T2 - T0 + V is not T + V"),  # noqa: E501
}
# fmt: on


def _expected(flags: tuple) -> dict:
    return dict(zip(KEYS, flags, strict=True))


def _actual(classification: Classification) -> dict:
    return {key: classification.as_dict()[key] for key in KEYS}


@pytest.fixture(scope="module")
def derived():
    cache = {}

    def get(name_or_path: str):
        if name_or_path not in cache:
            cache[name_or_path] = derive(load_scene(name_or_path))
        return cache[name_or_path]

    return get


def test_the_table_has_a_row_for_every_catalogue_scene():
    names = {entry.name for entry in catalogue()}
    assert names == set(CATALOGUE), "every catalogue scene needs a row (and only those)"


@pytest.mark.parametrize("name", sorted(CATALOGUE))
def test_catalogue_scene_classification(name, derived):
    flags, reason = CATALOGUE[name]
    assert _actual(derived(name).classification) == _expected(flags), reason


def test_simple_means_scleronomic_holonomic_and_conservative(derived):
    for name in CATALOGUE:
        c = derived(name).classification
        assert c.simple == (not c.rheonomic and c.holonomic and c.conservative), name


def test_derive_json_has_the_new_keys_and_null(derived):
    from systems.report import derivation_json

    data = derivation_json(derive(_scene(TIME_DEPENDENT_L)))["classification"]
    assert set(data) == {*KEYS, "dissipative", "gauge_time"}
    assert data["dissipative"] is False and data["gauge_time"] is False
    assert '"hamiltonian_is_energy": null' in json.dumps(data)
    hoop = derived("bead_on_rotating_hoop").classification.as_dict()
    assert hoop["rheonomic"] is True and hoop["simple"] is False and hoop["holonomic"] is True


# -- the cases -----------------------------------------------------------------------


def _scene(text: str):
    return parse_scene(text, source="test.toml")


def classified(text: str) -> Classification:
    return derive(_scene(text)).classification


DRIVEN_BY_FORCE = """
title = "Driven oscillator (force)"
[system]
coordinates = ["x"]
parameters = { m = 1.0, k = 1.0, F = 0.5, w = 1.3 }
kinetic = "m*x_dot**2/2"
potential = "k*x**2/2"
[effects]
forces = { x = "F*cos(w*t)" }
"""

DRIVEN_BY_POTENTIAL = """
title = "Driven oscillator (potential)"
[system]
coordinates = ["x"]
parameters = { m = 1.0, k = 1.0, F = 0.5, w = 1.3 }
kinetic = "m*x_dot**2/2"
potential = "k*x**2/2 - F*x*cos(w*t)"
"""

SHAKEN_IN_T = """
title = "Pendulum on a shaken support (T)"
[system]
coordinates = ["theta"]
parameters = { m = 1.0, g = 9.81, l = 1.0, A = 0.1, w = 5.0 }
kinetic = "m*((-A*w*sin(w*t) + l*cos(theta)*theta_dot)**2 + (l*sin(theta)*theta_dot)**2)/2"
potential = "-m*g*l*cos(theta)"
"""

# the same equation of motion: the support's acceleration as an inertial force in V
SHAKEN_IN_V = """
title = "Pendulum on a shaken support (V)"
[system]
coordinates = ["theta"]
parameters = { m = 1.0, g = 9.81, l = 1.0, A = 0.1, w = 5.0 }
kinetic = "m*l**2*theta_dot**2/2"
potential = "-m*g*l*cos(theta) - m*A*w**2*l*cos(w*t)*sin(theta)"
"""

MAGNETIC = """
title = "Charged particle in a magnetic field"
[system]
coordinates = ["x", "y"]
parameters = { m = 1.0, q = 1.0, B = 2.0 }
lagrangian = "m*(x_dot**2 + y_dot**2)/2 + q*B*(x*y_dot - y*x_dot)/2"
"""

RELATIVISTIC = """
title = "Relativistic oscillator"
[system]
coordinates = ["x"]
parameters = { m = 1.0, c = 2.0, k = 1.0 }
lagrangian = "-m*c**2*sqrt(1 - x_dot**2/c**2) - k*x**2/2"
"""

TIME_DEPENDENT_L = """
title = "A driven oscillator given by its Lagrangian"
[system]
coordinates = ["x"]
parameters = { m = 1.0, k = 1.0, F = 0.5, w = 1.3 }
lagrangian = "m*x_dot**2/2 - k*x**2/2 + F*x*cos(w*t)"
"""

HOOP_WITHOUT_DRAWING = """
title = "Bead on a rotating hoop, no drawing"
[system]
coordinates = ["theta"]
parameters = { m = 1.0, g = 9.81, a = 1.0, omega = 5.0 }
kinetic = "m*a**2*(theta_dot**2 + omega**2*sin(theta)**2)/2"
potential = "-m*g*a*cos(theta)"
"""

PENDULUM_WITH_A_TURNING_DRAWING = """
title = "Pendulum drawn with a turning marker"
[system]
coordinates = ["theta"]
parameters = { m = 1.0, g = 9.81, l = 1.0 }
kinetic = "m*l**2*theta_dot**2/2"
potential = "-m*g*l*cos(theta)"
[drawing]
points = { bob = ["l*sin(theta)", "-l*cos(theta)"], marker = ["0.2*cos(t)", "0.2*sin(t)"] }
links = [["origin", "bob"]]
"""


def test_a_driving_force_makes_the_equations_time_dependent():
    mech = derive(_scene(DRIVEN_BY_FORCE))
    c = mech.classification
    assert mech.hamilton_equations[1].has(mech.t)  # cos(w t) in dp_x/dt
    assert c.time_dependent and not c.conservative and not c.hamiltonian_conserved
    assert not c.rheonomic and not c.simple  # no constraint moves: T and V have no t
    assert c.hamiltonian_is_energy is True  # H = T + V at every instant
    assert "time dependent" in " ".join(c.describe())
    assert "scleronomic" in " ".join(c.describe())


def test_driving_by_force_and_by_potential_agree():
    by_force, by_potential = classified(DRIVEN_BY_FORCE), classified(DRIVEN_BY_POTENTIAL)
    assert _actual(by_force) == _actual(by_potential)


def _accelerations_at(mech, values: dict) -> float:
    (a,) = mech.accelerations()
    names = {s.name: s for s in a.free_symbols}
    return float(a.xreplace({names[k]: v for k, v in values.items() if k in names}))


def test_shaken_support_in_T_or_in_V_is_not_conservative_either_way():
    in_T, in_V = derive(_scene(SHAKEN_IN_T)), derive(_scene(SHAKEN_IN_V))
    state = {"theta": 0.4, "theta_dot": -0.3, "t": 0.7, "m": 1.0, "g": 9.81, "l": 1.0}
    state |= {"A": 0.1, "w": 5.0}
    # the same dynamics ...
    assert _accelerations_at(in_T, state) == pytest.approx(_accelerations_at(in_V, state))
    # ... the same answers
    for c in (in_T.classification, in_V.classification):
        assert not c.conservative and c.time_dependent and not c.hamiltonian_conserved
        assert not c.simple
    # the support's motion shows in T only: written through V it reads as a driving field
    assert in_T.classification.rheonomic and not in_V.classification.rheonomic


def test_magnetic_particle_H_is_its_kinetic_energy():
    mech = derive(_scene(MAGNETIC))
    c = mech.classification
    assert c.hamiltonian_is_energy is True
    assert c.conservative and c.hamiltonian_conserved and not c.time_dependent
    assert not c.rheonomic and c.simple  # the velocity-linear term is a potential, not a frame
    m = mech.params["m"]
    kinetic = m * sum(v**2 for v in mech.qdot) / 2
    energy = mech.energy_function()
    assert sympy.simplify(energy - kinetic) == 0


def test_relativistic_particle_H_is_gamma_m_c2_plus_V():
    mech = derive(_scene(RELATIVISTIC))
    c = mech.classification
    assert c.hamiltonian_is_energy is True and c.conservative and not c.natural
    m, cc, k = (mech.params[n] for n in ("m", "c", "k"))
    (x,), (v,) = mech.q, mech.qdot
    energy = m * cc**2 / sympy.sqrt(1 - v**2 / cc**2) + k * x**2 / 2
    point = {x: 0.3, v: 0.9, m: 1.0, cc: 2.0, k: 1.0}
    assert float(mech.energy_function().xreplace(point)) == pytest.approx(
        float(energy.xreplace(point)), rel=1e-12
    )


def test_a_lagrangian_with_explicit_t_and_no_T_V_names_no_energy():
    c = classified(TIME_DEPENDENT_L)
    assert c.hamiltonian_is_energy is None
    assert c.as_dict()["hamiltonian_is_energy"] is None
    assert c.time_dependent and not c.conservative
    assert not c.rheonomic  # the t is in L0 only: a driving field
    assert "no energy can be named" in " ".join(c.describe())


def test_a_lagrangian_without_a_positive_kinetic_energy_names_no_energy():
    text = """
title = "Indefinite kinetic term"
[system]
coordinates = ["x", "y"]
lagrangian = "x_dot**2/2 - y_dot**2/2 - x**2/2 - y**2/2"
"""
    c = classified(text)
    assert c.hamiltonian_is_energy is None and c.conservative and not c.time_dependent
    flipped = classified(text.replace("- y_dot**2/2", "+ y_dot**2/2"))
    assert flipped.hamiltonian_is_energy is True


def test_a_t_in_the_drawing_alone_changes_nothing(derived):
    hoop = derived("bead_on_rotating_hoop")
    assert any(
        hoop.scene.expression(f"drawing.points.{name}.x").has(hoop.t)
        for name, _, _ in hoop.scene.drawing.points
    )
    c = hoop.classification
    assert not c.time_dependent and c.hamiltonian_conserved and "H" in hoop.conserved
    assert _actual(c) == _actual(classified(HOOP_WITHOUT_DRAWING))
    pendulum = classified(PENDULUM_WITH_A_TURNING_DRAWING)
    assert not pendulum.rheonomic and not pendulum.time_dependent and pendulum.simple


# -- the equations decide, not the way they are written -----------------------------------


def _lagrangian(L: str) -> str:
    return f"""
title = "An oscillator given by its Lagrangian"
[system]
coordinates = ["x"]
parameters = {{ m = 1.0, k = 1.0, F = 0.5, w = 1.3 }}
lagrangian = "{L}"
"""


def test_a_total_time_derivative_in_L_leaves_the_system_conservative():
    """L + d/dt (x sin(w t)): the same oscillator. Hamilton's equations carry t (p is not
    m x_dot), Lagrange's do not: scleronomic and simple like the oscillator; H (of these
    momenta) is not conserved and is not the energy, E is."""
    mech = derive(_scene(_lagrangian("m*x_dot**2/2 - k*x**2/2 + x_dot*sin(w*t) + x*w*cos(w*t)")))
    c = mech.classification
    assert c.conservative and c.time_dependent and not c.hamiltonian_conserved
    assert c.gauge_time and not c.rheonomic and c.simple
    assert c.hamiltonian_is_energy is False
    assert set(mech.conserved) == {"E"}
    m, k = mech.params["m"], mech.params["k"]
    (x,), (v,) = mech.q, mech.qdot
    assert sympy.simplify(mech.conserved["E"] - (m * v**2 / 2 + k * x**2 / 2)) == 0


def test_a_lagrangian_scaled_by_exp_gamma_t_is_not_conservative():
    """Caldirola-Kanai: e^{gamma t} (m x_dot^2/2 - k x^2/2) is the damped oscillator,
    whose accelerations have no t; its Lagrange equations M qddot = F do."""
    c = classified(_lagrangian("exp(F*t)*(m*x_dot**2/2 - k*x**2/2)"))
    assert not c.conservative and c.time_dependent and c.rheonomic
    assert c.hamiltonian_is_energy is None


def _with_forces(forces: str) -> str:
    return f"""
title = "A particle in the plane with forces"
[system]
coordinates = ["x", "y"]
parameters = {{ m = 1.0, k = 1.0, B = 2.0, b = 0.3 }}
kinetic = "m*(x_dot**2 + y_dot**2)/2"
potential = "k*(x**2 + y**2)/2"
[effects]
forces = {{ {forces} }}
"""


@pytest.mark.parametrize(
    ("forces", "conservative", "reason"),
    [
        ('x = "-k*x**3", y = "-k*y"', True, "the gradient of a t-free potential"),
        ('x = "B*y_dot", y = "-B*x_dot"', True, "magnetic: G antisymmetric and constant"),
        ('x = "-b*x_dot", y = "-b*y_dot"', False, "friction"),
        ('x = "k*y", y = "-k*x"', False, "a curl: no potential"),
        ('x = "k*x*cos(B*t)"', False, "a t-dependent force"),
        ('x = "b*x_dot**2"', False, "not affine in the velocities"),
    ],
)
def test_forces_are_conservative_when_they_come_from_a_potential(forces, conservative, reason):
    c = classified(_with_forces(forces))
    assert c.conservative is conservative, reason
    # H does not hold the forces' potential; a magnetic force does no work
    assert c.hamiltonian_conserved is ("B*y_dot" in forces), reason


def test_magnetic_force_as_an_effect_agrees_with_the_magnetic_lagrangian():
    as_force = derive(_scene(_with_forces('x = "B*y_dot", y = "-B*x_dot"')))
    as_potential = derive(
        _scene(
            """
title = "The same particle, the field in L"
[system]
coordinates = ["x", "y"]
parameters = { m = 1.0, k = 1.0, B = 2.0, b = 0.3 }
lagrangian = "m*(x_dot**2 + y_dot**2)/2 + B*(x*y_dot - y*x_dot)/2 - k*(x**2 + y**2)/2"
"""
        )
    )
    for one, other in zip(as_force.accelerations(), as_potential.accelerations(), strict=True):
        assert sympy.simplify(one - other) == 0  # the same dynamics
    for c in (as_force.classification, as_potential.classification):
        assert c.conservative and not c.time_dependent and not c.rheonomic and c.simple


@pytest.mark.parametrize(
    ("links", "expected"),
    [
        ("shaken", dict(rheonomic=T, conservative=F, time_dependent=T, hamiltonian_is_energy=F)),
        ("turntable", dict(rheonomic=T, conservative=T, time_dependent=F, hamiltonian_is_energy=F)),
        ("breathing", dict(rheonomic=T, conservative=F, time_dependent=T, hamiltonian_is_energy=F)),
    ],
)
def test_matrix_form_classifies_as_the_closed_form(links, expected, monkeypatch):
    """Three-link chains derived in closed form and forced into matrix form (where qdot in
    Hamilton's equations stands for M^-1 (p - a)): a shaken pivot (a(q, t)), a turntable
    (gyroscopic a(q), H conserved), rods of length l(t) (M(q, t))."""
    from tests.systems import test_matrix_form as chains

    text = {
        "shaken": chains.shaken_chain,
        "turntable": chains.turntable_chain,
        "breathing": chains.breathing_chain,
    }[links](3)
    closed, forced = chains._both(text, monkeypatch)
    assert _actual(forced.classification) == _actual(closed.classification)
    for key, value in expected.items():
        assert getattr(closed.classification, key) is value, key


# -- declared constraints (for the coming [constraints] table) -------------------------------


def _reclassified(mech, constraints: Constraints) -> Classification:
    return classify(
        mech.scene,
        t=mech.t,
        q=mech.q,
        qdot=mech.qdot,
        p=mech.p,
        lagrangian=mech.lagrangian,
        kinetic=mech.kinetic,
        potential=mech.potential,
        hamiltonian=mech.hamiltonian,
        mass_matrix=mech.mass_matrix,
        forcing=mech.forcing,
        momenta=mech.momenta,
        hamilton_equations=mech.hamilton_equations,
        forces=mech.generalized_forces,
        natural=mech.classification.natural,
        separable=mech.classification.separable,
        matrix_form=mech.matrix_form,
        constraints=constraints,
    )


def test_declared_constraints_change_the_constraint_classes(derived):
    mech = derived("kepler_cartesian")
    x, y = mech.q
    x_dot, y_dot = mech.qdot
    t = mech.t
    assert _actual(_reclassified(mech, Constraints())) == _actual(mech.classification)
    rolling = _reclassified(mech, Constraints(nonholonomic=(x_dot - y * y_dot,)))
    assert not rolling.holonomic and rolling.bilateral and not rolling.simple
    assert not rolling.rheonomic
    wall = _reclassified(mech, Constraints(unilateral=(y,)))
    assert not wall.bilateral and wall.holonomic and wall.simple
    pulled = _reclassified(mech, Constraints(holonomic=(x**2 + y**2 - (1 + t) ** 2,)))
    assert pulled.rheonomic and not pulled.simple
    belt = _reclassified(mech, Constraints(nonholonomic=(x_dot - 1,)))  # x = t + x0
    assert belt.rheonomic and not belt.holonomic


# -- the energy theorem's words -----------------------------------------------------------


def _energy_words(mech, *, explicit_time: bool = False, effects: bool = False) -> str:
    pytest.importorskip("PySide6")
    from explorer.textbook.energy_view import explanation
    from systems.textbook import jobs
    from systems.textbook.conservation import EnergyBalance

    t = np.linspace(0.0, 1.0, 11)
    balance = EnergyBalance(t, np.ones_like(t), 0 * t, 0 * t, 0 * t, np.sin(t))
    run = jobs.Run(t, np.zeros((len(t), 2)), np.zeros((len(t), 1)), True, "")
    c = mech.classification
    return explanation(
        jobs.EnergyResult(
            balance, run, c.rheonomic, explicit_time, effects, c.hamiltonian_is_energy
        )
    )


def test_the_energy_tab_blames_a_constraint_only_where_one_moves(derived):
    hoop = _energy_words(derived("bead_on_rotating_hoop"))
    assert "not</b> T + V" in hoop and "drives the constraint" in hoop
    for text in (MAGNETIC, RELATIVISTIC):
        words = _energy_words(derive(_scene(text)))
        assert "constraint" not in words and "not</b> T + V" not in words
    driven = _energy_words(derive(_scene(TIME_DEPENDENT_L)), explicit_time=True)
    assert "constraint" not in driven and "No energy T + V can be named" in driven
    assert "time-dependent potential" in driven


# -- the users' scenes ---------------------------------------------------------------------

# the copies of ../shared/user-systems kept with the tests, so that CI checks them too
USERS = Path(__file__).resolve().parents[1] / "user_systems"

# fmt: off
# file: (rheonomic, holonomic, bilateral, conservative, simple,
#        time_dependent, H conserved, H = T + V, natural, separable), what the README says
USER_SCENES = {
    "chain5":                     ((F, T, T, T, T, F, T, T, T, F), "H = T + V; 5 normal modes about the hanging state"),  # noqa: E501
    "charged_particle_trap":      ((F, T, T, T, T, F, T, T, F, F), "H = T + V_trap is the energy"),  # noqa: E501
    "cone":                       ((F, T, T, T, T, F, T, T, T, F), "scleronomic, conservative, H = T + V, p_phi conserved"),  # noqa: E501
    "elastic_spherical_pendulum": ((F, T, T, T, T, F, T, T, T, F), "p_phi conserved (a natural, scleronomic system)"),  # noqa: E501
    "magnetic_3d":                ((F, T, T, T, T, F, T, T, F, F), "H equals the kinetic energy, which is the energy; z cyclic"),  # noqa: E501
    "mexican_hat":                ((F, T, T, T, T, F, T, T, T, T), "a circle of equilibria of a simple system"),  # noqa: E501
    "nonnatural_hamiltonian":     ((F, T, T, T, T, F, T, T, F, F), "not natural; a t-free H with a positive kinetic form is the energy"),  # noqa: E501
    "pendulum_ring":              ((F, T, T, T, T, F, T, T, T, T), "normal modes of the ring; H = T + V"),  # noqa: E501
    "relativistic":               ((F, T, T, T, T, F, T, T, F, T), "H = gamma m c^2 + V is the energy"),  # noqa: E501
    "rotating_helix":             ((T, T, T, T, F, F, T, F, F, T), "H conserved, H != T + V (the helix turns: T1, T0 != 0)"),  # noqa: E501
    "rotating_parabola":          ((T, T, T, T, F, F, T, F, F, F), "written in the rotating frame: H conserved, level sets apply (no t in the equations)"),  # noqa: E501
    "shaken_pendulum":            ((T, T, T, F, F, T, F, F, F, F), "rheonomic, time-dependent, not conservative, H not conserved"),  # noqa: E501
    "spring_pendulum":            ((F, T, T, T, T, F, T, T, T, F), "two coupled modes of a simple system"),  # noqa: E501
    "top":                        ((F, T, T, T, T, F, T, T, T, F), "phi and psi cyclic; H = T + V"),  # noqa: E501
}
# fmt: on
CONSERVED = {
    "cone": {"H", "p_phi"},
    "elastic_spherical_pendulum": {"H", "p_phi"},
    # symmetric gauge: L is invariant under rotations about z, so the canonical
    # L_z = x p_y - y p_x is conserved (Noether, systems.symmetries)
    "magnetic_3d": {"H", "p_z", "L_z"},
    "top": {"H", "p_phi", "p_psi"},
}


def _user_files() -> list[Path]:
    if not USERS.is_dir():
        pytest.skip(f"no users' scenes at {USERS}")
    return sorted(USERS.glob("*.toml"))


def test_the_copies_match_the_users_scenes():
    """tests/user_systems is a byte-for-byte copy of ../shared/user-systems, where that is."""
    originals = Path(__file__).resolve().parents[3] / "shared" / "user-systems"
    if not originals.is_dir():
        pytest.skip(f"no users' scenes at {originals} to compare with")
    ours = {p.name: p.read_bytes() for p in USERS.iterdir() if p.is_file()}
    theirs = {p.name: p.read_bytes() for p in originals.iterdir() if p.is_file()}
    assert ours == theirs


def test_the_users_table_covers_every_users_scene():
    assert {path.stem for path in _user_files()} == set(USER_SCENES)


@pytest.mark.parametrize("name", sorted(USER_SCENES))
def test_users_scene_classifies_as_its_readme_says(name, derived):
    path = next((p for p in _user_files() if p.stem == name), None)
    assert path is not None, f"{name}.toml is missing from {USERS}"
    flags, reason = USER_SCENES[name]
    mech = derived(str(path))
    assert _actual(mech.classification) == _expected(flags), reason
    if name in CONSERVED:
        assert set(mech.conserved) == CONSERVED[name], reason


def test_a_change_to_the_classification_misses_the_derivation_cache(tmp_path, monkeypatch):
    import systems.classification
    from systems import derivation_cache

    derivation_cache._code_version.cache_clear()
    before = derivation_cache._code_version()
    edited = tmp_path / "classification.py"
    edited.write_bytes(Path(systems.classification.__file__).read_bytes() + b"\n# edited\n")
    monkeypatch.setattr(systems.classification, "__file__", str(edited))
    derivation_cache._code_version.cache_clear()
    try:
        assert derivation_cache._code_version() != before
    finally:
        monkeypatch.undo()
        derivation_cache._code_version.cache_clear()
