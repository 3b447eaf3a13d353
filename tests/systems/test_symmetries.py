"""Noether charges beyond cyclic coordinates (systems.symmetries): which are found, that
they are conserved along runs, and that nothing that is not conserved is claimed."""

from __future__ import annotations

import numpy as np
import pytest
import sympy

from systems.compiled import compile_system
from systems.integrators import choose_method
from systems.mechanics import derive
from systems.report import derivation_json, readable
from systems.scene import SceneError, load_scene, parse_scene
from systems.simulation import Run, required_wants
from systems.symmetries import charge_functions, generators, phase_space_charges

KEPLER_PERIOD = 2 * np.pi * 2**1.5  # semi-major axis 2, k = m = 1


def _scene(system: str, rest: str = "") -> str:
    return f"[system]\n{system}\n{rest}"


def _same(a: sympy.Expr, b: sympy.Expr) -> bool:
    return sympy.simplify(sympy.sympify(a) - sympy.sympify(b)) == 0


def _charges(mechanics) -> set[str]:
    return {name for name in mechanics.conserved if name != "H" and not name.startswith("p_")}


PLANAR = 'coordinates = ["x", "y"]\nparameters = { m = 1.0 }\n'
T_XY = 'kinetic = "m*(x_dot**2 + y_dot**2)/2"\n'
PARTICLE = '[particles]\nbody = { mass = "m", position = ["x", "y"] }\n'


# -- Cartesian Kepler ------------------------------------------------------------------------


def test_cartesian_kepler_gets_the_angular_momentum():
    mechanics = derive(load_scene("kepler_cartesian"))
    assert _charges(mechanics) == {"L_z"}
    s = mechanics.scene.symbols
    m, x, y, xd, yd = (s[k] for k in ("m", "x", "y", "x_dot", "y_dot"))
    assert _same(mechanics.conserved["L_z"], m * (x * yd - y * xd))
    assert _same(phase_space_charges(mechanics)["L_z"], x * s["p_y"] - y * s["p_x"])
    assert set(derivation_json(mechanics)["conserved"]) == {"H", "L_z"}
    text = readable(mechanics, equilibria=False)
    assert "L_z = " in text and "angular momentum about the z axis" in text


def test_angular_momentum_stays_constant_to_round_off_on_cartesian_kepler():
    """300 periods with the default method; a quantity that is not conserved (x p_y +
    y p_x, built the same way) drifts by order one, so the bound tells them apart."""
    mechanics = derive(load_scene("kepler_cartesian"))
    method, _ = choose_method(mechanics)
    compiled = compile_system(mechanics, required_wants(method, ()))
    run = Run(compiled, t_end=300 * KEPLER_PERIOD, max_points=4096, energy_tolerance=None)
    blocks = [run.advance(seconds=60.0)]
    while blocks[-1].status == "running":
        blocks.append(run.advance(seconds=60.0))
    assert blocks[-1].status == "ok", blocks[-1].message
    t = np.concatenate([b.t for b in blocks])
    y = np.concatenate([b.y for b in blocks])
    assert t[-1] == pytest.approx(300 * KEPLER_PERIOD) and len(t) > 1000
    L = charge_functions(mechanics)["L_z"](t, y, compiled.parameters)
    assert L.shape == t.shape and L[0] == pytest.approx(np.sqrt(1.5), rel=1e-12)
    drift = np.abs(L - L[0]).max() / abs(L[0])
    assert drift <= 1e-12, drift  # measured 1.1e-15 with logh_yoshida6
    other = y[:, 0] * y[:, 3] + y[:, 1] * y[:, 2]
    assert np.abs(other - other[0]).max() > 0.1


# -- which generators are symmetries ----------------------------------------------------------


def test_figure_eight_gets_angular_and_linear_momentum():
    mechanics = derive(load_scene("figure_eight"))
    assert _charges(mechanics) == {"L_z", "P_x", "P_y"}
    s = mechanics.scene.symbols
    P_x = s["m"] * (s["x1_dot"] + s["x2_dot"] + s["x3_dot"])
    assert _same(mechanics.conserved["P_x"], P_x)
    L_z = sum(s[f"x{i}"] * s[f"p_y{i}"] - s[f"y{i}"] * s[f"p_x{i}"] for i in (1, 2, 3))
    assert _same(phase_space_charges(mechanics)["L_z"], L_z)


@pytest.mark.parametrize("particles", [False, True], ids=["coordinates", "particles"])
def test_a_potential_that_breaks_rotation_gets_no_angular_momentum(particles):
    body = PARTICLE if particles else ""
    kinetic = "" if particles else T_XY
    broken = derive(parse_scene(_scene(PLANAR + kinetic + 'potential = "x**2 + 2*y**2"', body)))
    assert _charges(broken) == set()
    round_ = derive(
        parse_scene(_scene(PLANAR + kinetic + 'potential = "exp(-(x**2 + y**2))"', body))
    )
    assert _charges(round_) == {"L_z"}


def test_magnetic_field_in_symmetric_gauge_conserves_the_canonical_angular_momentum():
    text = _scene(
        'coordinates = ["x", "y"]\nparameters = { m = 1.0, e = 1.0, B = 2.0 }\n'
        'lagrangian = "m*(x_dot**2 + y_dot**2)/2 + e*B*(x*y_dot - y*x_dot)/2"'
    )
    mechanics = derive(parse_scene(text))
    # translations change L by a total derivative only: p_x itself is not conserved
    assert _charges(mechanics) == {"L_z"}
    s = mechanics.scene.symbols
    x, y = s["x"], s["y"]
    assert _same(phase_space_charges(mechanics)["L_z"], x * s["p_y"] - y * s["p_x"])
    kinetic = s["m"] * (x * s["y_dot"] - y * s["x_dot"])
    assert _same(mechanics.conserved["L_z"], kinetic + s["e"] * s["B"] * (x**2 + y**2) / 2)


def test_damping_removes_the_charges_and_switching_it_off_brings_them_back():
    text = _scene(
        'coordinates = ["x1", "y1", "x2", "y2"]\nparameters = { m = 1.0, k = 1.0, b = 0.2 }\n'
        'kinetic = "m*(x1_dot**2 + y1_dot**2 + x2_dot**2 + y2_dot**2)/2"\n'
        'potential = "k*((x1 - x2)**2 + (y1 - y2)**2)/2"',
        '[effects]\ndissipation = "b*(x1_dot**2 + y1_dot**2 + x2_dot**2 + y2_dot**2)/2"\n',
    )
    scene = parse_scene(text)
    assert _charges(derive(scene)) == set()
    assert _charges(derive(scene.with_effects([]))) == {"L_z", "P_x", "P_y"}
    # friction on the relative motion only does no work along rotations or translations
    relative = text.replace(
        "b*(x1_dot**2 + y1_dot**2 + x2_dot**2 + y2_dot**2)/2",
        "b*((x1_dot - x2_dot)**2 + (y1_dot - y2_dot)**2)/2",
    )
    assert _charges(derive(parse_scene(relative))) == {"P_x", "P_y"}


def test_a_driving_force_removes_only_what_it_works_against():
    text = _scene(
        'coordinates = ["x1", "y1", "x2", "y2"]\nparameters = { m = 1.0, k = 1.0 }\n'
        'kinetic = "m*(x1_dot**2 + y1_dot**2 + x2_dot**2 + y2_dot**2)/2"\n'
        'potential = "k*((x1 - x2)**2 + (y1 - y2)**2)/2"',
        '[effects]\nforces = { y1 = "cos(t)" }\n',
    )
    assert _charges(derive(parse_scene(text))) == {"P_x"}


def test_a_cyclic_momentum_is_not_listed_twice():
    """In polar coordinates the rotation is theta -> theta + eps: L_z is p_theta, kept
    under that name; the spherical pendulum's rotation about the vertical is -p_phi."""
    planetary = derive(load_scene("planetary_motion"))
    assert "L_z" in {g.name for g in generators(planetary.scene)}
    assert set(planetary.conserved) == {"H", "p_theta"}
    spherical = derive(load_scene("spherical_pendulum"))
    assert set(spherical.conserved) == {"H", "p_phi"}


def test_three_dimensional_particle_in_uniform_gravity():
    """Gravity along -y leaves the rotation about y and the translations along x and z."""
    text = _scene(
        'coordinates = ["x", "y", "z"]\nparameters = { m = 1.0, g = 9.81 }\ngravity = "g"',
        '[particles]\nball = { mass = "m", position = ["x", "y", "z"] }\n',
    )
    mechanics = derive(parse_scene(text))
    # x and z are cyclic: P_x and P_z are p_x and p_z, listed under those names
    assert set(mechanics.conserved) == {"H", "p_x", "p_z", "L_y"}
    s = mechanics.scene.symbols
    assert _same(phase_space_charges(mechanics)["L_y"], s["z"] * s["p_x"] - s["x"] * s["p_z"])


def test_particles_in_polar_coordinates_about_a_fixed_centre():
    """Two particles in polar coordinates (r1, a1, r2, a2) with a central pair potential:
    the rotation is a1, a2 -> a1 + eps, a2 + eps (found numerically, M diagonal); no
    coordinate is cyclic, so L_z is new."""
    text = _scene(
        'coordinates = ["r1", "a1", "r2", "a2"]\nparameters = { m = 1.0, k = 1.0 }\n'
        'potential = "k*(r1**2 + r2**2 - 2*r1*r2*cos(a1 - a2))/2 + k*(r1 - 1)**2"',
        '[particles]\none = { mass = "m", position = ["r1*cos(a1)", "r1*sin(a1)"] }\n'
        'two = { mass = "m", position = ["r2*cos(a2)", "r2*sin(a2)"] }\n',
    )
    mechanics = derive(parse_scene(text))
    assert _charges(mechanics) == {"L_z"}
    s = mechanics.scene.symbols
    assert _same(phase_space_charges(mechanics)["L_z"], s["p_a1"] + s["p_a2"])


@pytest.mark.parametrize(
    ("potential", "expected"),
    [("", {"L_z", "P_x", "P_y"}), ("k*(x**2 + y**2)", {"L_z"}), ("k*x**2", set())],
)
def test_particle_seen_from_a_rotating_frame(potential, expected):
    """r = R(w t) (x, y): a rheonomic transformation. The rotation is x, y -> -y, x as in
    an inertial frame; a translation is a generator that turns with time, (cos w t,
    -sin w t), whose dxi/dt enters dQ/dt."""
    text = _scene(
        'coordinates = ["x", "y"]\nparameters = { m = 1.0, w = 0.7, k = 1.0 }\n'
        + (f'potential = "{potential}"' if potential else ""),
        '[particles]\nb = { mass = "m", position = '
        '["x*cos(w*t) - y*sin(w*t)", "x*sin(w*t) + y*cos(w*t)"] }\n',
    )
    mechanics = derive(parse_scene(text))
    assert _charges(mechanics) == expected
    s = mechanics.scene.symbols
    x, y, w, t = s["x"], s["y"], s["w"], s["t"]
    by_name = {g.name: g.xi for g in generators(mechanics.scene)}
    assert by_name["L_z"] == (-y, x)
    assert _same(by_name["P_x"][0], sympy.cos(w * t)) and _same(
        by_name["P_x"][1], -sympy.sin(w * t)
    )


def test_a_hamiltonian_without_lagrangian_is_tested_by_poisson_brackets():
    text = _scene(
        'coordinates = ["x", "y"]\nparameters = { k = 1.0 }\n'
        'hamiltonian = "sqrt(1 + p_x**2 + p_y**2) - k/sqrt(x**2 + y**2)"'
    )
    mechanics = derive(parse_scene(text))
    assert mechanics.lagrangian is None
    assert _charges(mechanics) == {"L_z"}
    s = mechanics.scene.symbols
    assert _same(mechanics.conserved["L_z"], s["x"] * s["p_y"] - s["y"] * s["p_x"])
    anisotropic = text.replace("x**2 + y**2", "x**2 + 3*y**2")
    assert _charges(derive(parse_scene(anisotropic))) == set()


def test_a_constraint_that_works_along_a_rotation_removes_its_charge():
    circle = _scene(
        PLANAR.replace("m = 1.0", "m = 1.0, l = 1.0") + T_XY,
        '[constraints]\nholonomic = ["x**2 + y**2 - l**2"]\n[initial]\nx = 1.0\ny_dot = 1.0\n',
    )
    assert _charges(derive(parse_scene(circle))) == {"L_z"}
    line = circle.replace("x**2 + y**2 - l**2", "x - l")
    assert _charges(derive(parse_scene(line))) == set()


# -- [symmetries] ------------------------------------------------------------------------------

SCREW = _scene(
    'coordinates = ["r", "phi", "z"]\nparameters = { m = 1.0, k = 1.0, e = 0.5, c = 0.3 }\n'
    'kinetic = "m*(r_dot**2 + r**2*phi_dot**2 + z_dot**2)/2"\n'
    'potential = "k*(r - 1)**2 + e*cos(phi - c*z)"',
    '[symmetries]\nscrew = { z = "1", phi = "c" }\ntwist = { phi = "1" }\n',
)


def test_a_given_generator_that_is_a_symmetry_is_reported_and_one_that_is_not_is_left_out():
    scene = parse_scene(SCREW)
    assert scene.symmetries == (("screw", (("z", "1"), ("phi", "c"))), ("twist", (("phi", "1"),)))
    mechanics = derive(scene)
    assert _charges(mechanics) == {"screw"}
    s = scene.symbols
    assert _same(phase_space_charges(mechanics)["screw"], s["p_z"] + s["c"] * s["p_phi"])
    assert set(derivation_json(mechanics)["conserved"]) == {"H", "screw"}
    text = readable(mechanics, equilibria=False)
    assert "screw = " in text
    assert "not conserved, or the same as a quantity above: twist" in text
    assert parse_scene(scene.to_toml()) == scene


def test_a_given_generator_loses_its_charge_to_an_effect_that_works_along_it():
    damped = SCREW + '[effects]\nforces = { z = "-0.1*z_dot" }\n'
    assert _charges(derive(parse_scene(damped))) == set()


@pytest.mark.parametrize(
    ("entry", "field", "words"),
    [
        ("screw = { z = \"__import__('os').system('true')\" }", "symmetries.screw.z", ""),
        ('screw = { z = "x.real" }', "symmetries.screw.z", ""),
        ('screw = { z = "t" }', "symmetries.screw.z", "coordinates, numbers and parameters"),
        ('screw = { z = "z_dot" }', "symmetries.screw.z", "coordinates, numbers and parameters"),
        ('screw = { w = "1" }', "symmetries.screw.w", "not a coordinate"),
        ('screw = "1"', "symmetries.screw", "must be a table"),
        ("screw = {}", "symmetries.screw", "must be a table"),
        ('screw = { z = ["1"] }', "symmetries.screw.z", "must be a string"),
        ('L_z = { phi = "1" }', "symmetries.L_z", "choose another name"),
        ('p_phi = { phi = "1" }', "symmetries.p_phi", "choose another name"),
        ('"not a name" = { phi = "1" }', "symmetries.not a name", "not a valid name"),
    ],
)
def test_hostile_or_wrong_symmetries_are_refused_naming_the_field(entry, field, words):
    text = SCREW.split("[symmetries]")[0] + f"[symmetries]\n{entry}\n"
    with pytest.raises(SceneError) as caught:
        parse_scene(text, source="s.toml")
    assert caught.value.field == field
    assert str(caught.value).startswith(f"s.toml: {field}: ")
    assert words in caught.value.reason


def test_the_derivation_cache_tells_scenes_apart_by_their_symmetries():
    only_twist = SCREW.replace('screw = { z = "1", phi = "c" }\n', "")
    assert _charges(derive(parse_scene(only_twist))) == set()
    assert _charges(derive(parse_scene(SCREW))) == {"screw"}
    assert _charges(derive(parse_scene(only_twist))) == set()
