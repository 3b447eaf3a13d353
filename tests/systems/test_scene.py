import pytest

from systems.scene import SceneError, parse_scene
from tests.systems.scenes import DRIVEN_DAMPED, PENDULUM, PLANETARY, scene


def test_reads_fields():
    s = scene(PLANETARY)
    assert s.coordinates == ("r", "theta")
    assert s.parameter_values == {"m": 1.3, "k": 0.8}
    assert s.kind == "energies"
    assert s.initial_values == {"r": 1.0, "theta_dot": 1.1}


def test_round_trip_through_toml():
    for text in (PENDULUM, PLANETARY, DRIVEN_DAMPED):
        s = scene(text)
        assert parse_scene(s.to_toml(), source="test.toml") == s


def test_effects_switch():
    s = scene(DRIVEN_DAMPED)
    assert s.effect_keys() == ["dissipation", "forces.theta"]
    off = s.with_effects(["forces.theta"])
    assert off.enabled_effects() == ["forces.theta"]
    assert parse_scene(off.to_toml(), source="test.toml").disabled == {"dissipation"}


@pytest.mark.parametrize(
    "change, field, words",
    [
        (
            ('potential = "-m*g*l*cos(theta)"', 'potential = "-m*g*l*cos(theta"'),
            "system.potential",
            "never closed",
        ),
        (
            ('potential = "-m*g*l*cos(theta)"', 'potential = "-m*g*L*cos(theta)"'),
            "system.potential",
            "unknown name 'L'",
        ),
        (
            ('potential = "-m*g*l*cos(theta)"', 'potential = "theta_dot"'),
            "system.potential",
            "may not depend on the velocity",
        ),
        (
            ('coordinates = ["theta"]', 'coordinates = ["theta", "theta"]'),
            "system.coordinates",
            "used twice",
        ),
        (("theta = 1.0", "phi = 1.0"), "initial.phi", "not a coordinate"),
        (("[system]", "[system]\nhamiltonian = 'p_theta**2'"), "system", "exactly one"),
        (
            ('links = [["origin", "bob"]]', 'links = [["origin", "bib"]]'),
            "drawing.links[0]",
            "unknown point",
        ),
    ],
)
def test_errors_name_file_field_and_reason(change, field, words):
    text = PENDULUM.replace(*change)
    assert text != PENDULUM
    with pytest.raises(SceneError) as info:
        parse_scene(text, source="pendulum.toml")
    message = str(info.value)
    assert message.startswith(f"pendulum.toml: {field}: ")
    assert words in message


def test_expression_error_has_position():
    with pytest.raises(SceneError) as info:
        parse_scene(PENDULUM.replace("cos(theta)", "cos(theta) + q"), source="p.toml")
    assert info.value.position == 21


def test_bad_toml():
    with pytest.raises(SceneError, match="not valid TOML"):
        parse_scene("title = ", source="x.toml")


@pytest.mark.parametrize(
    "view, field, words",
    [
        ('t_end = "abc"', "view.t_end", "positive finite time"),
        ("t_end = -1.0", "view.t_end", "positive finite time"),
        ("t_end = inf", "view.t_end", "positive finite time"),
        ('phase = ["zz", 5]', "view.phase", "two names"),
        ("ranges = { theta = [1.0, -1.0] }", "view.ranges.theta", "low < high"),
        ("ranges = { zeta = [0.0, 1.0] }", "view.ranges.zeta", "not a coordinate"),
        ("ranges = 3", "view.ranges", "must be a table"),
        ('section = { coordinate = "q" }', "view.section.coordinate", "not a coordinate"),
        ("colour = 1", "view.colour", "unknown key"),
    ],
)
def test_view_is_checked_when_the_scene_loads(view, field, words):
    with pytest.raises(SceneError) as info:
        parse_scene(PENDULUM + f"\n[view]\n{view}\n", source="pendulum.toml")
    message = str(info.value)
    assert message.startswith(f"pendulum.toml: {field}: ")
    assert words in message
