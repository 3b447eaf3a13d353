"""Holonomic constraints with Lagrange multipliers: the scene table, the derivation, the
constrained integrators and what a run reports.

The Cartesian pendulum (``resources/scenes/cartesian_pendulum.toml``) is the bob of a
simple pendulum in x, y with ``Phi = x**2 + y**2 - l**2 = 0``, T = m (x_dot**2 +
y_dot**2)/2 and V = m g y. Its multiplier is the string's tension, up to a factor:

    M qddot + Phi_q^T lambda = F  gives  m (x_ddot, y_ddot) = (0, -m g) - 2 lambda (x, y),

so the constraint force on the bob is -2 lambda (x, y), of size 2 |lambda| l, pointing
to the pivot when lambda > 0. Along the string (unit vector (x, y)/l out of the pivot),
Newton's law with the centripetal acceleration -l theta_dot**2 reads

    m (-l theta_dot**2) = -m g cos(theta) - 2 lambda l,

with theta = atan2(x, -y) measured from the downward vertical (the component of
gravity (0, -m g) along (x, y)/l = (sin(theta), -cos(theta)) is m g cos(theta)).
Hence the tension 2 lambda l = m (g cos(theta) + l theta_dot**2), with
cos(theta) = -y/l and theta_dot = (x y_dot - y x_dot)/l**2.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import sympy
from scipy.integrate import solve_ivp
from scipy.special import ellipk

from systems import constraints
from systems.compiled import compile_system
from systems.integrators import STEPPERS
from systems.mechanics import DerivationError, derive
from systems.report import derivation_json, readable
from systems.scene import SceneError, catalogue, document_toml, load_scene, parse_scene
from systems.simulation import Run, Sampler, required_wants, stream

NAME = "cartesian_pendulum"
THETA0 = 1.2  # the start of both pendulum scenes


def _period(g: float = 9.81, l: float = 1.0, amplitude: float = THETA0) -> float:
    """The pendulum's period at this amplitude: 4 K(sin(amplitude/2)**2) / sqrt(g/l)."""
    return 4.0 * ellipk(math.sin(amplitude / 2) ** 2) / math.sqrt(g / l)


@pytest.fixture(scope="module")
def compiled():
    mechanics = derive(load_scene(NAME))
    return compile_system(mechanics, required_wants("constrained_dop853") | {"hamiltonian"})


def _trajectory(compiled, method="constrained_dop853", **options):
    blocks = list(stream(compiled, method=method, max_points=100_000, **options))
    assert blocks[-1].status == "ok", blocks[-1].message
    t = np.concatenate([b.t for b in blocks])
    y = np.concatenate([b.y for b in blocks])
    return t, y, blocks[-1]


# -- the scene table ---------------------------------------------------------------------------

BASE = """
[system]
coordinates = ["x", "y"]
parameters = {{ m = 1.0, g = 9.81, l = 1.0 }}
kinetic = "m*(x_dot**2 + y_dot**2)/2"
potential = "m*g*y"

[constraints]
{constraints}

[initial]
x = 0.6
y = -0.8
"""


def _scene(constraints_text: str):
    return parse_scene(BASE.format(constraints=constraints_text), source="c.toml")


@pytest.mark.parametrize(
    ("text", "field", "words"),
    [
        ('holonomic = ["x**2 + y**2 - l**2", "x + (y"]', "constraints.holonomic[1]", "("),
        ('holonomic = ["x**2 + z**2 - l**2"]', "constraints.holonomic[0]", "unknown name 'z'"),
        ('holonomic = ["x*x_dot + y*y_dot"]', "constraints.holonomic[0]", "nonholonomic"),
        ('holonomic = ["x**2 + y**2 - l**2", true]', "constraints.holonomic[1]", "string"),
        ('holonomic = "x**2 + y**2 - l**2"', "constraints.holonomic", "list"),
        ("holonomic = []", "constraints.holonomic", "list"),
        ('nonholonomic = ["x - y"]', "constraints.nonholonomic[0]", "at least one"),
        ('nonholonomic = ["x_dot**2 - y_dot"]', "constraints.nonholonomic[0]", "linear in x_dot"),
        ('nonholonomic = ["x_dot*y_dot"]', "constraints.nonholonomic[0]", "linear in"),
        ('nonholonomic = ["p_x"]', "constraints.nonholonomic[0]", "only allowed in a hamiltonian"),
        ("nonholonomic = []", "constraints.nonholonomic", "list"),
        ('unilateral = ["x_dot"]', "constraints.unilateral[0]", "not allowed"),
        ('unilateral = ["l"]', "constraints.unilateral[0]", "depend on the coordinates"),
        ('unilateral = "y"', "constraints.unilateral", "list"),
        ('rigid = ["x"]', "constraints.rigid", "unknown key"),
        ('holonomic = ["l - 1"]', "constraints.holonomic[0]", "depend on the coordinates"),
        ('holonomic = ["g*t - l"]', "constraints.holonomic[0]", "depend on the coordinates"),
    ],
)
def test_mistakes_in_the_table_name_the_field(text, field, words):
    with pytest.raises(SceneError) as caught:
        _scene(text)
    assert caught.value.field == field, str(caught.value)
    assert words in str(caught.value)
    assert f"c.toml: {field}: " in str(caught.value)


def test_the_velocity_message_points_to_nonholonomic():
    with pytest.raises(SceneError) as caught:
        _scene('holonomic = ["x**2 + y**2 - l**2 + x_dot"]')
    message = str(caught.value)
    assert "'x_dot'" in message and "'nonholonomic'" in message


@pytest.mark.parametrize(
    ("kind", "text"),
    [("nonholonomic", 'nonholonomic = ["x_dot - y_dot"]'), ("unilateral", 'unilateral = ["y"]')],
)
def test_every_kind_is_read_and_written_back(kind, text):
    scene = _scene(text)
    assert getattr(scene, f"{kind}_constraints") == (text.split('"')[1],)
    assert f"[constraints]\n{text}" in scene.to_toml()
    assert parse_scene(scene.to_toml(), source="c.toml") == scene


@pytest.mark.parametrize(
    ("text", "words"),
    [
        ('holonomic = ["x**2 + y**2 - l**2", "2*(x**2 + y**2 - l**2)"]', "not independent"),
        ('holonomic = ["x - 0.6", "y + 0.8"]', "no degree of freedom"),
    ],
)
def test_dependent_or_too_many_constraints_are_refused(text, words):
    with pytest.raises(DerivationError) as caught:
        derive(_scene(text))
    assert caught.value.field == "constraints.holonomic"
    assert words in str(caught.value)


def test_the_table_is_written_back():
    scene = load_scene(NAME)
    assert scene.holonomic_constraints == ("x**2 + y**2 - l**2",)
    text = scene.to_toml()
    assert '[constraints]\nholonomic = ["x**2 + y**2 - l**2"]' in text
    assert parse_scene(text, source=scene.source, name=scene.name) == scene
    document = document_toml(
        {"system": {"coordinates": ["x"]}, "constraints": {"holonomic": ["x"]}}
    )
    assert document.index("[system]") < document.index("[constraints]")


def test_the_editor_keeps_the_table():
    from explorer.editor.editor_panel import DOCUMENT_KEYS, data_from_scene

    assert "constraints" in DOCUMENT_KEYS
    data = data_from_scene(load_scene(NAME))
    assert data["constraints"] == {"holonomic": ["x**2 + y**2 - l**2"]}


# -- the derivation ----------------------------------------------------------------------------


# the catalogue scenes with [constraints]: (velocity degrees of freedom, configuration
# degrees of freedom, constraints); every other scene has one per coordinate and none
CONSTRAINED = {
    NAME: (1, 1, 1),
    "atwood_rope": (1, 1, 5),  # the rope, and the floor and the pulley for each mass
    "atwood_machine": (1, 1, 4),  # the floor and the pulley for each mass
    "rolling_disk": (2, 4, 2),  # two rolling conditions on x, y, phi, psi: not integrable
    "bouncing_ball": (2, 2, 1),  # a floor y >= 0 restricts where, not how many
    "gas_in_box": (2, 2, 4),
}


@pytest.mark.parametrize("entry", catalogue(), ids=lambda entry: entry.name)
def test_degrees_of_freedom_of_every_catalogue_scene(entry):
    mechanics = derive(load_scene(entry.name))
    n = mechanics.n
    velocity, configuration, k = CONSTRAINED.get(entry.name, (n, n, 0))
    assert constraints.degrees_of_freedom(mechanics) == velocity
    assert constraints.configuration_degrees_of_freedom(mechanics) == configuration
    assert constraints.count(mechanics.scene) == k


def test_derivation_shows_the_constraints_and_the_degrees_of_freedom():
    mechanics = derive(load_scene(NAME))
    data = derivation_json(mechanics)
    assert data["degrees_of_freedom"] == 1
    assert data["constraints"]["holonomic"] == ["-l**2 + x**2 + y**2"]
    assert data["constraints"]["jacobian"] == [["2*x", "2*y"]]
    # L has no x, but the string pulls along x: x is not cyclic and p_x is not conserved
    assert data["cyclic"] == [] and "p_x" not in data["conserved"] and "H" in data["conserved"]
    text = readable(mechanics, equilibria=False)
    assert "degrees of freedom: 1 = 2 coordinates − 1 independent constraint" in text
    assert "Φ₁" in text and "Hamilton's equations (free, without −Φ_qᵀ λ)" in text
    plain = derivation_json(derive(load_scene("simple_pendulum")))
    assert plain["degrees_of_freedom"] == 1 and plain["constraints"] is None


def test_gamma_is_minus_the_second_derivative_without_qddot():
    """For a moving constraint x - a sin(w t) = 0 (a bead driven along x):
    Phi_q qddot = x_ddot and d2Phi/dt2 = x_ddot + a w**2 sin(w t), so gamma = -a w**2 sin(w t)."""
    text = """
[system]
coordinates = ["x", "y"]
parameters = { m = 1.0, a = 0.5, w = 2.0 }
kinetic = "m*(x_dot**2 + y_dot**2)/2"
[constraints]
holonomic = ["x - a*sin(w*t)"]
"""
    mechanics = derive(parse_scene(text))
    pieces = constraints.holonomic(mechanics)
    a, w, t = mechanics.params["a"], mechanics.params["w"], mechanics.t
    assert sympy.simplify(pieces.gamma[0] + a * w**2 * sympy.sin(w * t)) == 0
    c = mechanics.classification
    # the moving constraint makes the system rheonomic and its H is not conserved
    assert c.rheonomic and c.time_dependent and not c.hamiltonian_conserved
    assert "H" not in mechanics.conserved


# -- the methods -------------------------------------------------------------------------------


def test_only_the_constrained_methods_apply_and_the_others_say_why():
    mechanics = derive(load_scene(NAME))
    for name, stepper in STEPPERS.items():
        reason = stepper.applies_to(mechanics)
        if stepper.family.constrained:
            assert reason is None, name
            continue
        assert reason is not None and name in reason and "[constraints]" in reason, name
        if stepper.symplectic:
            assert "symplectic" in reason and "RATTLE" in reason
    from systems.integrators import choose_method

    assert choose_method(mechanics)[0] == "constrained_dop853"
    free = derive(load_scene("simple_pendulum"))
    for name in ("constrained_dop853", "constrained_rk4"):
        assert "has none" in STEPPERS[name].applies_to(free)


# -- the dynamics ------------------------------------------------------------------------------


def test_the_multiplier_is_the_string_tension(compiled):
    T = _period()
    t, y, _ = _trajectory(compiled, t_end=10 * T)
    numeric = compiled.constraints()
    lam = numeric.multipliers(t, y)[:, 0]
    m, g, l = 1.0, 9.81, 1.0
    x, yy, vx, vy = y.T  # p = m qdot with m = 1
    theta_dot = (x * vy - yy * vx) / l**2
    tension = m * (g * (-yy / l) + l * theta_dot**2)
    assert np.max(np.abs(2 * lam * l - tension)) <= 1e-9
    assert tension.min() > 0  # a string that stays taut: lambda > 0 all along
    # the kernels' multipliers (numba, the run's own) agree with numpy's
    kernel = np.empty(1)
    for row in range(0, len(t), max(1, len(t) // 50)):
        compiled.constrained("c_multipliers", float(t[row]), y[row], compiled.parameters, kernel)
        assert abs(kernel[0] - lam[row]) <= 1e-12 * max(1.0, abs(lam[row]))


def test_theta_agrees_with_the_polar_pendulum(compiled):
    """theta(t) = atan2(x, -y) of the constrained run against the catalogue's polar
    simple pendulum (same m, g, l and start), integrated by scipy to 1e-13."""
    T = _period()
    t, y, _ = _trajectory(compiled, t_end=10 * T)
    polar = compile_system(derive(load_scene("simple_pendulum")), ("rhs",))
    assert tuple(polar.initial_state()) == (THETA0, 0.0)
    reference = solve_ivp(
        polar.rhs, (0.0, t[-1]), polar.initial_state(), method="DOP853", rtol=1e-13,
        atol=1e-14, dense_output=True,
    )  # fmt: skip
    theta = np.arctan2(y[:, 0], -y[:, 1])
    error = np.max(np.abs(theta - reference.sol(t)[0]))
    assert error <= 1e-8, error
    assert t[-1] == pytest.approx(10 * T)


def test_constraint_holds_over_ten_thousand_periods(compiled):
    """Measured: 1e4 periods (about 22 000 time units, ~7e5 steps) take about 2 s after
    compiling; the largest |Phi| over every kept state is about 2e-16, and the relative
    energy error grows to about 5e-9 (DOP853 at its default tolerance 1e-12 is not
    symplectic: the error drifts, slowly)."""
    T = _period()
    run = Run(compiled, method="constrained_dop853", t_end=1e4 * T, diagnostics=("H",))
    sampler = Sampler(run, np.linspace(0.0, 1e4 * T, 2001))
    rows = list(sampler)
    assert sampler.last.status == "ok", sampler.last.message
    assert rows[-1][0] == pytest.approx(1e4 * T)
    assert sampler.violation <= 1e-10
    t = np.array([r[0] for r in rows])
    y = np.array([r[1] for r in rows])
    assert compiled.constraints().violation(t, y) <= 1e-10
    # the velocities stay tangent: d/dt Phi = 2 (x x_dot + y y_dot) = 0
    assert np.max(np.abs(2 * (y[:, 0] * y[:, 2] + y[:, 1] * y[:, 3]))) <= 1e-10
    H0 = compiled.hamiltonian(0.0, y[:1])[0]
    assert sampler.worst / abs(H0) <= 1e-8


def test_fixed_step_projection_keeps_the_constraint(compiled):
    T = _period()
    t, y, last = _trajectory(compiled, method="constrained_rk4", t_end=20 * T, dt=0.01)
    assert compiled.constraints().violation(t, y) <= 1e-10
    assert last.steps == pytest.approx(20 * T / 0.01, abs=2)


def test_a_start_off_the_constraint_is_moved_onto_it(compiled):
    y0 = np.array([0.7, -0.8, 0.5, 0.5])  # |r| != l and a radial velocity
    run = Run(compiled, method="constrained_dop853", y0=y0, t_end=1.0)
    x, yy, vx, vy = run.y0
    assert abs(x * x + yy * yy - 1.0) <= 1e-15
    assert abs(x * vx + yy * vy) <= 1e-15
    block = run.advance()
    while not block.finished:
        block = run.advance()
    assert block.status == "ok", block.message
    assert compiled.constraints().violation(block.t, block.y) <= 1e-10


def test_a_moving_constraint_is_followed_and_not_energy_checked():
    """A bead on a rod that turns at a constant rate w (x sin(w t) - y cos(w t) = 0), free
    of gravity: its distance from the axis grows as r0 cosh(w t) when it starts at rest
    on the rod."""
    text = """
[system]
coordinates = ["x", "y"]
parameters = { m = 1.0, w = 1.5 }
kinetic = "m*(x_dot**2 + y_dot**2)/2"
[constraints]
holonomic = ["x*sin(w*t) - y*cos(w*t)"]
[initial]
x = 0.5
"""
    mechanics = derive(parse_scene(text))
    assert not mechanics.classification.hamiltonian_conserved
    wants = required_wants("constrained_dop853") | {"hamiltonian"}
    compiled = compile_system(mechanics, wants)  # a short run
    y0 = compiled.initial_state()
    # the start is moved onto the moving constraint: the bead turns with the rod
    assert y0[3] == pytest.approx(0.5 * 1.5)
    t, y, _ = _trajectory(compiled, t_end=2.0)
    r = np.hypot(y[:, 0], y[:, 1])
    assert np.max(np.abs(r - 0.5 * np.cosh(1.5 * t))) <= 1e-8
    numeric = compiled.constraints()
    assert numeric.violation(t, y) <= 1e-10
    # the rod does work on the bead: the energy tab says it cannot balance it yet
    from systems.textbook import jobs

    with pytest.raises(ValueError, match="constraint moves"):
        jobs.energy(compile_system(mechanics, ("rhs", "hamiltonian", "velocities")), 1.0)


def test_the_numpy_constraints_are_lambdified_as_they_are_needed(compiled):
    """Opening a constrained scene again checks its start and its runs' violation: the
    positions' function alone of the seven (2-3 ms each), made once for the system and
    every copy with other parameter values."""
    numeric = constraints.Numeric(compiled)
    assert numeric._made == {}
    y0 = compiled.initial_state()
    assert numeric.violation(0.0, y0[None]) <= 1e-12
    assert set(numeric._made) == {"positions"}
    other = numeric.bound_to(compiled.with_parameters({"l": 2.0}))
    other.multipliers(0.0, y0[None])
    assert set(numeric._made) == set(other._made) >= {"positions", "mass", "forcing", "gamma"}


def test_a_scene_opened_again_takes_its_numpy_constraints_from_the_disk(compiled, monkeypatch):
    """sympy prints each function once per scene (1-3 ms apiece, on the way to a reopened
    scene's first block): a new process, here a new ``Numeric``, compiles the source text
    remembered with the derivation, and projects to the same bits."""
    off = compiled.initial_state() + np.array([0.01, -0.02, 0.03, 0.01])
    projected = constraints.Numeric(compiled).project(0.0, off)

    def refused(*args, **kwargs):
        raise AssertionError("lambdified again")

    monkeypatch.setattr(sympy, "lambdify", refused)
    monkeypatch.setattr(constraints, "rows", refused)  # nor the rows' derivatives (3 ms)
    again = constraints.Numeric(compiled)
    assert np.array_equal(again.project(0.0, off), projected)
    assert {"positions", "jacobian", "mass", "momenta"} <= set(again._made)
    assert "pieces" not in vars(again) and "_sources" not in vars(again)


@pytest.mark.parametrize("name", ["cartesian_pendulum", "rolling_disk", "bouncing_ball"])
def test_the_drivers_sizes_are_counted_from_the_scene(name):
    mechanics = derive(load_scene(name))
    kinds = constraints.rows(mechanics).kinds
    holonomic = kinds.count("holonomic")
    bilateral = holonomic + kinds.count("nonholonomic")
    index = constraints.restitution_index(mechanics.scene)
    expected = [len(kinds), holonomic, bilateral, -1 if index is None else index]
    assert constraints.sizes(mechanics).tolist() == expected


def test_other_parameter_values_are_used_without_lambdifying_again(compiled):
    longer = compiled.with_parameters({"l": 2.0})
    assert longer.constraints()._positions is compiled.constraints()._positions
    y0 = longer.initial_state()  # the scene's start, moved onto the circle of radius 2
    assert math.hypot(y0[0], y0[1]) == pytest.approx(2.0, abs=1e-15)
    assert math.atan2(y0[0], -y0[1]) == pytest.approx(THETA0, abs=1e-15)
    # at rest the tension is m g cos(theta): 2 lambda l = g cos(theta) with l = 2
    lam = longer.constraints().multipliers(0.0, y0[None])[0, 0]
    assert 2 * lam * 2.0 == pytest.approx(9.81 * math.cos(THETA0), rel=1e-12)
    assert compiled.constraints().violation(0.0, compiled.initial_state()[None]) <= 1e-15


def test_a_start_where_the_constraints_are_singular_is_refused():
    """At x = y = 0 the circle's gradient vanishes: no nearest point, a clear error."""
    mechanics = derive(_scene('holonomic = ["x**2 + y**2 - l**2"]').with_initial(x=0.0, y=0.0))
    compiled = compile_system(mechanics, ("rhs", "hamiltonian"))
    with pytest.raises(DerivationError) as caught:
        compiled.initial_state()
    assert caught.value.field == "initial" and "cannot be moved onto the constraints" in str(
        caught.value
    )
    assert np.isnan(compiled.constraints().multipliers(0.0, np.zeros((1, 4)))).all()


def test_equilibria_and_cyclic_coordinates_are_not_those_of_the_free_coordinates():
    """The free coordinates' answers would be wrong: dV/dq = (0, m g) vanishes nowhere
    (no equilibria, where the pendulum hangs at rest at the bottom), and L has no x
    (cyclic, where the string pulls along x). The equilibria are those on the circle,
    with the string's force, and no coordinate is called cyclic."""
    from systems.report import derivation_json, readable

    mechanics = derive(load_scene("cartesian_pendulum"))
    assert mechanics.cyclic == () and "p_x" not in mechanics.conserved
    data = derivation_json(mechanics)
    assert data["cyclic"] == []
    found = sorted(data["equilibria"], key=lambda e: float(e["q"]["y"]))
    assert len(found) == 2
    bottom, top = found
    assert float(bottom["q"]["y"]) == pytest.approx(-1.0) and bottom["stable"] is True
    assert float(top["q"]["y"]) == pytest.approx(1.0) and top["stable"] is False
    text = readable(mechanics)
    assert "not computed yet" not in text and "cyclic coordinates: none" in text


def test_the_action_tab_refuses_a_constrained_scene_instead_of_a_failing_principle():
    """Free variations of the Cartesian pendulum's path leave the circle: S(eps) then has a
    slope (-7.5 for k = 2), which would read as Hamilton's principle failing."""
    from systems.textbook import jobs

    compiled = compile_system(
        derive(load_scene("cartesian_pendulum")), ("rhs", "hamiltonian", "velocities")
    )
    with pytest.raises(ValueError, match="constraints"):
        jobs.principle(compiled, 3.0, 2, 0, 0.01)
    with pytest.raises(ValueError, match="constraints"):
        jobs.two_point(compiled, [0.0, -1.0], [0.5, -0.866], 1.0)


def test_normal_modes_of_a_constrained_scene_keep_to_the_constraint():
    """The free coordinates' analysis would say x "moves freely" (V = m g y has no x);
    on the circle there is one mode, the pendulum's sqrt(g/l), along x at the bottom."""
    from systems.normal_modes import analyse

    analysis = analyse(derive(load_scene("cartesian_pendulum")))
    assert analysis.applies, analysis.reason
    modes = analysis.modes
    assert modes.n == 1 and modes.omega[0] == pytest.approx(math.sqrt(9.81 / 1.0), rel=1e-9)
    assert modes.q0 == pytest.approx([0.0, -1.0], abs=1e-12)
    assert abs(modes.shapes[0, 0]) > 0 and modes.shapes[1, 0] == pytest.approx(0.0, abs=1e-12)
