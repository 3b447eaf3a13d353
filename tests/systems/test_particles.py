"""Scenes that describe their bodies: ``[particles]`` and ``system.gravity``.

T = sum m |dr/dt|**2/2 split as T2 + T1 + T0 and V = -sum m g.r come from the positions
r_i(q, t) (``systems.particles``); errors name the field; the catalogue scenes written
with particles have the same T and V, and so the same dynamics, as they had written by
hand (``hand_written_energies.toml``).
"""

from __future__ import annotations

import copy
import dataclasses
import random
import time
import tomllib
from pathlib import Path

import numpy as np
import pytest
import sympy
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from systems.compiled import compile_system
from systems.mechanics import DerivationError, derive
from systems.report import derivation_json, readable
from systems.scene import SceneError, catalogue, load_scene, parse_scene, scene_from_dict
from systems.simulation import stream

HAND_WRITTEN = tomllib.loads(
    (Path(__file__).parent / "hand_written_energies.toml").read_text(encoding="utf-8")
)

PENDULUM = """
title = "Pendulum from its bob"
[system]
coordinates = ["theta"]
parameters = { m = 1.5, g = 9.81, l = 0.7 }
gravity = "g"
[particles]
bob = { mass = "m", position = ["l*sin(theta)", "-l*cos(theta)"] }
[initial]
theta = 1.0
"""

# the support moves horizontally, x = A cos(w t): a rheonomic transformation
SHAKEN = """
title = "Pendulum on a shaken support"
[system]
coordinates = ["theta"]
parameters = { m = 1.0, g = 9.81, l = 1.0, A = 0.1, w = 3.0 }
gravity = "g"
[particles]
bob = { mass = "m", position = ["A*cos(w*t) + l*sin(theta)", "-l*cos(theta)"] }
[initial]
theta = 0.5
"""

SPHERICAL = """
title = "Spherical pendulum, z up"
[system]
coordinates = ["theta", "phi"]
parameters = {{ m = 1.2, g = 9.81, l = 0.8 }}
gravity = {gravity}
[particles]
bob = {{ mass = "m", position = {position} }}
[drawing]
links = [["origin", "bob"]]
[initial]
theta = 1.0
phi_dot = 2.0
"""
Z_UP = '["l*sin(theta)*cos(phi)", "l*sin(theta)*sin(phi)", "-l*cos(theta)"]'
Y_UP = '["l*sin(theta)*cos(phi)", "-l*cos(theta)", "l*sin(theta)*sin(phi)"]'


def scene(text: str):
    return parse_scene(text, source="test.toml")


def _random_values(scene, rng, parameters=True) -> dict:
    """Every symbol of ``scene`` at a random value in [0.3, 1.7] (velocities of either
    sign); the scene's own parameter values unless ``parameters`` is False."""
    values = {s: rng.uniform(0.3, 1.7) for s in scene.symbols.values()}
    for name in scene.velocity_names:
        values[scene.symbols[name]] *= rng.choice((-1, 1))
    if parameters:
        values.update({scene.symbols[k]: v for k, v in scene.parameters})
    return values


def _value(expr, values) -> float:
    return float(sympy.sympify(expr).xreplace(values).evalf(30))


def assert_same_function(a, b, scene, *, states=8, relative=1e-12):
    """``a`` and ``b`` agree at random states, with the scene's and with random parameters."""
    rng = random.Random(f"{scene.name}:{a}")
    for i in range(states):
        values = _random_values(scene, rng, parameters=i % 2 == 0)
        x, y = _value(a, values), _value(b, values)
        assert abs(x - y) <= relative * max(1.0, abs(x)), (scene.name, a, b, values)


# -- T, V and the transformation --------------------------------------------------------------


def test_a_plane_pendulum_gets_the_textbook_t_and_v():
    s = scene(PENDULUM)
    m, g, l, theta, theta_dot = (s.symbols[n] for n in ("m", "g", "l", "theta", "theta_dot"))
    T, V = s.energies()
    assert sympy.simplify(T - m * l**2 * theta_dot**2 / 2) == 0
    assert sympy.simplify(V + m * g * l * sympy.cos(theta)) == 0
    T2, T1, T0 = s.transformation.kinetic_parts
    assert T1 == 0 and T0 == 0 and sympy.simplify(T2 - T) == 0
    assert s.transformation_depends_on_time is False
    assert s.kind == "energies"


@pytest.mark.parametrize(
    ("gravity", "position"),
    [('"g"', Y_UP), ('["0", "-g", "0"]', Y_UP), ('["0", "0", "-g"]', Z_UP)],
    ids=["scalar, y up", "vector, y up", "vector, z up"],
)
def test_three_components_and_gravity_as_a_scalar_or_a_vector(gravity, position):
    s = scene(SPHERICAL.format(gravity=gravity, position=position))
    m, g, l = (s.symbols[n] for n in ("m", "g", "l"))
    theta, phi_dot, theta_dot = (s.symbols[n] for n in ("theta", "phi_dot", "theta_dot"))
    T, V = s.energies()
    expected = m * l**2 * (theta_dot**2 + sympy.sin(theta) ** 2 * phi_dot**2) / 2
    assert sympy.simplify(T - expected) == 0
    assert sympy.simplify(V + m * g * l * sympy.cos(theta)) == 0
    assert len(s.transformation.positions[0]) == 3
    mechanics = derive(s)
    assert "phi" in mechanics.cyclic


def test_gravity_in_the_plane_as_a_vector():
    sideways = PENDULUM.replace('gravity = "g"', 'gravity = ["g", "0"]')
    s = scene(sideways)
    m, g, l, theta = (s.symbols[n] for n in ("m", "g", "l", "theta"))
    assert sympy.simplify(s.energies()[1] + m * g * l * sympy.sin(theta)) == 0
    down = scene(PENDULUM.replace('gravity = "g"', 'gravity = ["0", "-g"]'))
    assert sympy.simplify(down.energies()[1] - scene(PENDULUM).energies()[1]) == 0


def test_no_gravity_and_a_potential_of_its_own():
    s = scene(PENDULUM.replace('gravity = "g"', 'potential = "m*theta**2"'))
    m, theta = s.symbols["m"], s.symbols["theta"]
    assert s.energies()[1] == m * theta**2
    both = scene(PENDULUM.replace('gravity = "g"', 'gravity = "g"\npotential = "m*theta**2"'))
    g, l = both.symbols["g"], both.symbols["l"]
    assert sympy.simplify(both.energies()[1] - (m * theta**2 - m * g * l * sympy.cos(theta))) == 0


def test_a_moving_support_is_rheonomic_with_t1_and_t0():
    s = scene(SHAKEN)
    m, l, A, w, t = (s.symbols[n] for n in ("m", "l", "A", "w", "t"))
    theta, theta_dot = s.symbols["theta"], s.symbols["theta_dot"]
    T2, T1, T0 = s.transformation.kinetic_parts
    assert sympy.simplify(T2 - m * l**2 * theta_dot**2 / 2) == 0
    expected_T1 = -m * A * w * l * sympy.sin(w * t) * sympy.cos(theta) * theta_dot
    assert sympy.simplify(T1 - expected_T1) == 0
    assert sympy.simplify(T0 - m * A**2 * w**2 * sympy.sin(w * t) ** 2 / 2) == 0
    # the parts are what their names say
    assert not T0.has(theta_dot)
    assert sympy.simplify(T1.diff(theta_dot, 2)) == 0 and T1.diff(theta_dot) != 0
    assert s.transformation_depends_on_time is True
    # T itself is m |v|^2 / 2 with v the total time derivative of r(theta(t), t)
    vx, vy = s.transformation.velocities[0]
    assert sympy.simplify(vx - (-A * w * sympy.sin(w * t) + l * sympy.cos(theta) * theta_dot)) == 0
    assert sympy.simplify(s.energies()[0] - m * (vx**2 + vy**2) / 2) == 0


def test_a_t_that_cancels_is_not_rheonomic():
    s = scene(PENDULUM.replace('"-l*cos(theta)"', '"-l*cos(theta)*(sin(t)**2 + cos(t)**2)"'))
    assert s.transformation_depends_on_time is False
    T2, T1, T0 = s.transformation.kinetic_parts
    assert_same_function(T1, 0, s)
    assert_same_function(T0, 0, s)


def test_the_derivation_shows_the_transformation_and_says_rheonomic():
    mechanics = derive(scene(SHAKEN))
    text = readable(mechanics, equilibria=False)
    assert "transformation equations r = r(q, t)" in text
    assert "r_bob = (A·cos(t·w) + l·sin(θ), −l·cos(θ))" in text
    assert "v_bob = " in text and "T₁ (linear in q̇)" in text and "T₀ (free of q̇)" in text
    assert "The transformation is rheonomic" in text
    data = derivation_json(mechanics)["particles"]
    assert data["transformation_depends_on_time"] is True
    assert data["positions"] == {"bob": ["A*cos(t*w) + l*sin(theta)", "-l*cos(theta)"]}
    s = mechanics.scene
    for key, part in zip(("T2", "T1", "T0"), s.transformation.kinetic_parts, strict=True):
        assert sympy.simplify(sympy.sympify(data["kinetic"][key], locals=s.symbols) - part) == 0
    assert set(data) == {
        "positions",
        "velocities",
        "masses",
        "kinetic",
        "gravity_potential",
        "transformation_depends_on_time",
    }
    still = derive(scene(PENDULUM))
    assert "The transformation is scleronomic" in readable(still, equilibria=False)
    assert derivation_json(still)["particles"]["transformation_depends_on_time"] is False
    assert derivation_json(derive(load_scene("henon_heiles")))["particles"] is None


# -- the drawing --------------------------------------------------------------------------------


def test_the_drawing_comes_from_the_particles_without_links():
    s = scene(PENDULUM)
    assert s.drawing.points == (("bob", "l*sin(theta)", "-l*cos(theta)"),)
    assert s.drawing.links == () and s.drawing.trace == ()


def test_a_drawing_may_link_the_particles_add_points_and_replace_a_particle_point():
    text = (
        PENDULUM
        + """
[drawing]
points = { pivot = ["0", "0.2"], bob = ["l*sin(theta)", "-l*cos(theta) - 0.1"] }
links = [["pivot", "bob"]]
trace = ["bob"]
"""
    )
    s = scene(text)
    assert s.drawing.points == (
        ("bob", "l*sin(theta)", "-l*cos(theta) - 0.1"),
        ("pivot", "0", "0.2"),
    )
    assert s.drawing.links == (("pivot", "bob"),) and s.drawing.trace == ("bob",)
    again = parse_scene(s.to_toml(), source="test.toml")
    assert again == s
    with pytest.raises(SceneError, match="unknown point 'bobb'") as info:
        scene(PENDULUM + '[drawing]\nlinks = [["origin", "bobb"]]\n')
    assert info.value.field == "drawing.links[0]"


def test_the_editor_reading_keeps_the_particle_points_when_the_drawing_is_left_out():
    text = PENDULUM + '[drawing]\npoints = { tip = ["phi", "0"] }\nlinks = [["origin", "bob"]]\n'
    s = parse_scene(text, source="<editor>", drop_unfit=True)
    assert s.drawing.points == (("bob", "l*sin(theta)", "-l*cos(theta)"),)
    assert [w.field for w in s.warnings] == ["drawing.points.tip.x"]


# -- writing and reading back ---------------------------------------------------------------------


@pytest.mark.parametrize(
    "text",
    [
        PENDULUM,
        SHAKEN,
        SPHERICAL.format(gravity='["0", "0", "-g"]', position=Z_UP),
        PENDULUM.replace('gravity = "g"', 'gravity = "g"\npotential = "m*theta**2"'),
    ],
)
def test_a_particle_scene_round_trips_through_toml(text):
    s = scene(text)
    again = parse_scene(s.to_toml(), source="test.toml")
    assert again == s
    assert "[particles]" in s.to_toml() and "points" not in s.to_toml()


# -- errors name the field ---------------------------------------------------------------------


@pytest.mark.parametrize(
    ("change", "field", "words"),
    [
        (('"-l*cos(theta)"', '"-l*cos(theta"'), "particles.bob.position[1]", "never closed"),
        (('"l*sin(theta)"', '"L*sin(theta)"'), "particles.bob.position[0]", "unknown name 'L'"),
        (('"-l*cos(theta)"', '"-l*theta_dot"'), "particles.bob.position[1]", "a velocity"),
        (('mass = "m"', 'mass = "m*theta"'), "particles.bob.mass", "a mass is a constant"),
        (('mass = "m"', 'mass = "m*t"'), "particles.bob.mass", "a mass is a constant"),
        (('mass = "m", ', ""), "particles.bob.mass", "missing"),
        (('mass = "m"', "mass = true"), "particles.bob.mass", "must be a string"),
        (
            (', position = ["l*sin(theta)", "-l*cos(theta)"]', ""),
            "particles.bob.position",
            "missing",
        ),
        (('"-l*cos(theta)"]', '"-l*cos(theta)", "0", "1"]'), "particles.bob.position", "2 or 3"),
        (('["l*sin(theta)", "-l*cos(theta)"]', '"l*sin(theta)"'), "particles.bob.position", "list"),
        (('"-l*cos(theta)"', "[1]"), "particles.bob.position[1]", "must be a string"),
        (("mass = ", "colour = 3, mass = "), "particles.bob.colour", "unknown key"),
        (("bob = {", "origin = {"), "particles.origin", "'origin'"),
        (("bob = {", "2b = {"), "particles.2b", ""),
        (('gravity = "g"', 'gravity = "g*theta"'), "system.gravity", "field of gravity"),
        (('gravity = "g"', 'gravity = ["0", "-g", "0"]'), "system.gravity", "3 components"),
        (('gravity = "g"', 'gravity = ["0", "-g +"]'), "system.gravity[1]", ""),
        (('gravity = "g"', 'gravity = ["g"]'), "system.gravity", "2 or 3"),
        (
            ('gravity = "g"', 'gravity = "g"\nkinetic = "m*theta_dot**2"'),
            "system.kinetic",
            "not both",
        ),
        (
            ('gravity = "g"', 'gravity = "g"\nlagrangian = "theta_dot**2"'),
            "system.lagrangian",
            "cannot also give",
        ),
        (
            ("[initial]", 'tip = { mass = "m", position = ["0", "0", "theta"] }\n[initial]'),
            "particles.tip.position",
            "all particles move in the same plane",
        ),
    ],
)  # fmt: skip
def test_mistakes_are_errors_naming_the_field(change, field, words):
    text = PENDULUM.replace(*change)
    assert text != PENDULUM
    with pytest.raises(SceneError) as info:
        scene(text)
    assert info.value.field == field, str(info.value)
    assert str(info.value).startswith(f"test.toml: {field}: ")
    assert words in info.value.reason


def test_a_syntax_error_in_a_position_has_its_column():
    with pytest.raises(SceneError) as info:
        scene(PENDULUM.replace('"-l*cos(theta)"', '"-l*cos(theta))"'))
    assert info.value.field == "particles.bob.position[1]"
    assert info.value.position == 14


def test_structural_mistakes_of_the_table():
    with pytest.raises(SceneError, match="give at least one particle") as info:
        scene(PENDULUM.split("[particles]")[0] + "[particles]\n")
    assert info.value.field == "particles"
    with pytest.raises(SceneError) as info:
        scene(PENDULUM.replace("bob = {", 'bob = "m"\nnot_bob = {'))
    assert info.value.field == "particles.bob" and "must be a table" in info.value.reason
    without = PENDULUM.split("[particles]")[0] + 'kinetic = "m*theta_dot**2/2"\n'
    with pytest.raises(SceneError, match="gravity acts on particles") as info:
        scene(without)
    assert info.value.field == "system.gravity"


# -- hostile input ------------------------------------------------------------------------------

BASE = tomllib.loads(
    PENDULUM.replace("[initial]", 'tip = { mass = "m", position = ["l", "0"] }\n[initial]')
)
HOSTILE = st.recursive(
    st.booleans()
    | st.integers(-(10**20), 10**20)
    | st.floats(allow_nan=True, allow_infinity=True)
    | st.sampled_from(
        ["m", "g", "0", "", "theta", "theta_dot", "t", "l*sin(theta)", "sin(", "1/0",
         "x**x**x", "(theta+1)**100", "p_theta", "__import__('os')", "origin", "-l*cos(t)"]
    )
    | st.text(max_size=6),
    lambda inner: st.lists(inner, max_size=4)
    | st.dictionaries(
        st.sampled_from(["mass", "position", "bob", "origin", "x"]), inner, max_size=3
    ),
    max_leaves=8,
)  # fmt: skip
PLACES = st.sampled_from(
    [("particles", "bob"), ("particles", "tip"), ("particles", "new"), ("system", "gravity"),
     ("particles", None), ("bob", "mass"), ("bob", "position"), ("tip", "position")]
)  # fmt: skip


@settings(
    deadline=None,
    derandomize=True,
    max_examples=40,
    database=None,
    suppress_health_check=[HealthCheck.too_slow],
)
@given(changes=st.lists(st.tuples(PLACES, HOSTILE), min_size=1, max_size=3))
def test_hostile_particle_tables_derive_or_are_refused_with_a_field(changes):
    document = copy.deepcopy(BASE)
    for (table, key), value in changes:
        if table in ("bob", "tip"):
            particles = document.get("particles")
            entry = particles.get(table) if isinstance(particles, dict) else None
            if isinstance(entry, dict):
                entry[key] = value
        elif key is None:
            document[table] = value
        elif isinstance(document.get(table), dict):  # an earlier change may have replaced it
            document[table][key] = value
    start = time.process_time()
    try:
        s = scene_from_dict(document, source="fuzz.toml")
        derive(s)
    except SceneError as exc:
        assert exc.field, str(exc)
    except DerivationError:
        pass
    assert time.process_time() - start < 20.0


# -- the catalogue: the same T and V as written by hand ------------------------------------------

PARTICLE_SCENES = sorted(
    entry.name for entry in catalogue() if "[particles]" in entry.path.read_text(encoding="utf-8")
)


def _hand_written(name: str):
    """The catalogue scene ``name`` as it was written by hand: its T and V from
    ``hand_written_energies.toml``, its particles' points in ``[drawing]``."""
    scene = load_scene(name)
    document = tomllib.loads(scene.to_toml())
    del document["particles"]
    document["system"].pop("gravity", None)
    document["system"].update(HAND_WRITTEN[name])
    document["drawing"] = {
        "points": {n: [x, y] for n, x, y in scene.drawing.points},
        "links": [list(link) for link in scene.drawing.links],
        "trace": list(scene.drawing.trace),
    }
    return scene, scene_from_dict(document, source=scene.source, name=name)


def test_every_catalogue_scene_with_particles_has_its_hand_written_t_and_v():
    assert len(PARTICLE_SCENES) >= 10
    assert set(PARTICLE_SCENES) == set(HAND_WRITTEN)


@pytest.mark.parametrize("name", PARTICLE_SCENES)
def test_particles_give_the_hand_written_t_and_v(name):
    scene, hand = _hand_written(name)
    T, V = scene.energies()
    T_hand, V_hand = hand.energies()
    assert_same_function(T, T_hand, scene)
    assert_same_function(V, V_hand, scene)
    assert set(scene.drawing.points) == set(hand.drawing.points)


@pytest.mark.parametrize("name", PARTICLE_SCENES)
def test_particles_give_the_hand_written_equations_of_motion(name):
    scene, hand = _hand_written(name)
    ours, theirs = derive(scene), derive(hand)
    assert ours.classification == theirs.classification
    assert ours.cyclic == theirs.cyclic and set(ours.conserved) == set(theirs.conserved)
    canonical = ours.hamilton_equations + (ours.hamiltonian,)
    reference = theirs.hamilton_equations + (theirs.hamiltonian,)
    for a, b in zip(canonical, reference, strict=True):
        assert_same_function(a, b, scene, states=4, relative=1e-10)


def test_the_rheonomic_catalogue_scenes_are_those_with_t_in_a_position():
    rheonomic = {
        name for name in PARTICLE_SCENES if load_scene(name).transformation_depends_on_time
    }
    assert rheonomic == {"bead_on_rotating_hoop", "kapitza_pendulum", "variable_length_pendulum"}
    hoop = load_scene("bead_on_rotating_hoop").transformation
    T2, T1, T0 = hoop.kinetic_parts
    assert T1 == 0 and T0 != 0  # the hoop turns, but across the bead's path


# -- a particle scene runs ---------------------------------------------------------------------


def test_a_particle_scene_derives_and_runs_with_its_energy_conserved():
    s = scene(SPHERICAL.format(gravity='["0", "0", "-g"]', position=Z_UP))
    compiled = compile_system(derive(s), ("rhs", "hamiltonian", "drawing"))
    blocks = list(stream(compiled, t_end=5.0, diagnostics=("H", "points")))
    last = blocks[-1]
    assert last.status == "ok" and last.t[-1] == 5.0
    H = np.concatenate([b.diagnostics["H"] for b in blocks])
    assert np.ptp(H) / abs(H[0]) < 1e-9
    points = np.concatenate([b.diagnostics["points"] for b in blocks])
    # the bob's drawn (x, y) is its projection, at distance <= l from the pivot
    assert np.all(np.hypot(points[:, 0, 0], points[:, 0, 1]) <= 0.8 + 1e-9)


def test_dataclass_replace_keeps_particles_valid():
    s = scene(PENDULUM)
    with pytest.raises(SceneError, match="not both"):
        dataclasses.replace(s, kinetic="m*theta_dot**2")
