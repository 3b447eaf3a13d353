import dataclasses

import pytest

from systems.scene import SceneError, document_toml, parse_scene, read_document, scene_from_dict
from tests.systems.scenes import DRIVEN_DAMPED, OSCILLATOR, PENDULUM, PLANETARY, scene


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


# -- what does not fit the system: left out with drop_unfit, an error otherwise ----------


def _renamed_pendulum() -> str:
    """The pendulum with theta renamed to phi in the system only: drawing and view left."""
    system = PENDULUM.replace('["theta"]', '["phi"]').replace("theta = 1.0", "phi = 1.0")
    system = system.replace("theta_dot", "phi_dot")
    system = system.replace('potential = "-m*g*l*cos(theta)"', 'potential = "-m*g*l*cos(phi)"')
    assert 'points = { bob = ["l*sin(theta)", "-l*cos(theta)"] }' in system
    return system + (
        '\n[view]\nt_end = 12.0\nphase = ["theta", "p_theta"]\n'
        "ranges = { theta = [-3.0, 3.0], x = [-1.0, 1.0] }\n"
        'angles = ["theta"]\n'
    )


def test_unfit_drawing_and_view_are_errors_when_read_strictly():
    with pytest.raises(SceneError) as info:
        parse_scene(_renamed_pendulum(), source="renamed.toml")
    assert str(info.value).startswith("renamed.toml: view.phase: ")


def test_unfit_drawing_and_view_are_left_out_with_warnings():
    s = parse_scene(_renamed_pendulum(), source="<editor>", drop_unfit=True)
    assert s.coordinates == ("phi",)
    assert s.drawing is None
    # the view keeps what fits: t_end and the drawing area's x range
    assert dict(s.view) == {"t_end": 12.0, "ranges": {"x": [-1.0, 1.0]}}
    fields = [w.field for w in s.warnings]
    assert fields == [
        "view.phase",
        "view.ranges.theta",
        "view.angles",
        "drawing.points.bob.x",
        "drawing.points.bob.y",
    ]
    bob_x = s.warnings[3]
    assert bob_x.part == "drawing" and bob_x.position == 7
    assert "unknown name 'theta'" in bob_x.reason
    assert str(bob_x).startswith("<editor>: drawing.points.bob.x: unknown name 'theta'")
    assert str(bob_x).endswith("the drawing left out")
    assert s.warnings[0].part == "view.phase"
    # the scene derives what is left: every expression was parsed
    assert set(s._expressions) == {"system.kinetic", "system.potential"}


def test_drop_unfit_never_changes_the_callers_tables():
    import tomllib

    data = tomllib.loads(_renamed_pendulum())
    before = repr(data)
    scene_from_dict(data, source="<editor>", drop_unfit=True)
    assert repr(data) == before


def test_a_fitting_scene_has_no_warnings_and_equals_the_strict_one():
    strict = parse_scene(PENDULUM, source="p.toml")
    lenient = parse_scene(PENDULUM, source="p.toml", drop_unfit=True)
    assert lenient.warnings == () and lenient == strict
    assert lenient.drawing == strict.drawing


def test_warnings_take_no_part_in_equality():
    s = parse_scene(_renamed_pendulum(), source="<editor>", drop_unfit=True)
    assert s == dataclasses.replace(s, warnings=())


@pytest.mark.parametrize(
    "drawing, field",
    [
        ('points = { a = ["x", "0"] }\nlinks = [["origin", "b"]]', "drawing.links[0]"),
        ('points = { a = ["x"] }', "drawing.points.a"),
        ("points = 5", "drawing.points"),
        ('points = { a = ["x", "0"] }\ntrace = ["b"]', "drawing.trace"),
        ('points = { a = ["x +", "0"] }', "drawing.points.a.x"),
        ('points = { a = ["x_dot", "0"] }', "drawing.points.a.x"),
    ],
)
def test_any_drawing_problem_leaves_the_drawing_out(drawing, field):
    text = OSCILLATOR + "\n[drawing]\n" + drawing + "\n"
    with pytest.raises(SceneError):
        parse_scene(text)
    s = parse_scene(text, drop_unfit=True)
    assert s.drawing is None
    assert [w.field for w in s.warnings] == [field]


def test_every_drawing_problem_is_reported_at_once():
    text = OSCILLATOR + (
        '\n[drawing]\npoints = { a = ["q", "w"], b = ["x", "0"] }\n'
        'links = [["origin", "c"], ["a", "b"], ["b", "d"]]\ntrace = ["e"]\n'
    )
    s = parse_scene(text, drop_unfit=True)
    assert [w.field for w in s.warnings] == [
        "drawing.links[0]",
        "drawing.links[2]",
        "drawing.trace",
        "drawing.points.a.x",
        "drawing.points.a.y",
    ]


@pytest.mark.parametrize(
    "change, field",
    [
        (('potential = "-m*g*l*cos(theta)"', 'potential = "-m*g*l*cos(phi)"'), "system.potential"),
        (("theta = 1.0", "phi = 1.0"), "initial.phi"),
        (('coordinates = ["theta"]', 'coordinates = ["theta", "m"]'), "system.parameters"),
    ],
)
def test_problems_of_the_system_still_raise_with_drop_unfit(change, field):
    text = PENDULUM.replace(*change)
    with pytest.raises(SceneError) as info:
        parse_scene(text, source="<editor>", drop_unfit=True)
    assert info.value.field == field


def test_a_view_that_is_not_a_table_is_left_out():
    s = scene_from_dict({**_tables(PENDULUM), "view": 5}, drop_unfit=True)
    assert dict(s.view) == {} and [w.field for w in s.warnings] == ["view"]
    assert s.drawing is not None


# -- [view] angles ---------------------------------------------------------------------


def test_view_angles_names_coordinates():
    s = scene(PLANETARY + '\n[view]\nangles = ["theta"]\n')
    assert s.view.get("angles") == ["theta"]
    assert parse_scene(s.to_toml(), source="test.toml") == s


@pytest.mark.parametrize(
    "angles, words",
    [
        ('["phi"]', "'phi' is not a coordinate (coordinates: r, theta)"),
        ('["theta", "theta"]', "listed twice"),
        ('"theta"', "must be a list of coordinate names"),
        ("[1]", "must be a list of coordinate names"),
    ],
)
def test_view_angles_are_checked(angles, words):
    with pytest.raises(SceneError) as info:
        parse_scene(PLANETARY + f"\n[view]\nangles = {angles}\n", source="k.toml")
    assert str(info.value).startswith("k.toml: view.angles: ")
    assert words in str(info.value)


# -- documents: the tables as typed, valid or not ----------------------------------------------


def _tables(text: str) -> dict:
    return read_document(text)


def test_document_toml_reads_back_to_the_same_tables():
    data = {
        "title": 'A "quoted" title\\ with a backslash',
        "system": {
            "coordinates": ["x", "2y"],
            "parameters": {"m": 1.0, "n": 3, "w": "2/3"},
            "kinetic": "m*(x_dot**2 +",
        },
        "initial": {"x": 0.97000436, "x_dot": "sqrt(2)"},
        "drawing": {"points": {"a": ["x", "0"]}, "links": [["origin", "a", "b"]]},
        "view": {"t_end": 5.0, "ranges": {"x": [-1.0, 1.0]}, "flag": True},
    }
    text = document_toml(data)
    assert read_document(text) == data
    # an unfinished document is written all the same; reading it as a scene says why not
    with pytest.raises(SceneError, match="system.coordinates"):
        parse_scene(text)


def test_document_toml_escapes_control_characters():
    data = {"title": "tab\there, bell\x07, line\nbreak", "system": {}}
    assert read_document(document_toml(data)) == data


def test_document_toml_of_a_scene_document_is_the_scene():
    for text in (PENDULUM, PLANETARY, DRIVEN_DAMPED):
        s = scene(text)
        assert parse_scene(document_toml(_tables(text)), source="test.toml") == s


def test_a_document_with_non_ascii_names_is_written_as_toml_that_reads_back():
    """TOML takes only ASCII letters, digits, _ and - bare; θ1 or a¹ must be quoted (they
    were written bare, so a saved scene with a particle named θ1 could not be opened)."""
    import tomllib

    from systems.scene import document_toml

    document = {
        "system": {"coordinates": ["x"], "parameters": {"m": 1.0}},
        "particles": {"θ1": {"mass": "m", "position": ["x", "0"]}, "a¹": {"mass": "m"}},
    }
    assert tomllib.loads(document_toml(document))["particles"] == document["particles"]


@pytest.mark.parametrize(
    ("system", "field", "words"),
    [
        ('coordinates = ["H"]\nkinetic = "H_dot**2/2"', "system.coordinates", "Hamiltonian"),
        (
            'coordinates = ["lambda_1"]\nkinetic = "lambda_1_dot**2/2"',
            "system.coordinates",
            "Lagrange multiplier",
        ),
        (
            'coordinates = ["x"]\nparameters = { x_ddot = 1.0 }\nkinetic = "x_dot**2/2"',
            "system.parameters",
            "acceleration of x",
        ),
    ],
)
def test_names_the_output_uses_are_refused(system, field, words):
    """A coordinate H gave a CSV with two H columns, lambda_1 one with two multiplier
    columns, and a parameter x_ddot printed exactly like x's acceleration."""
    with pytest.raises(SceneError) as info:
        parse_scene(f"[system]\n{system}\n")
    assert info.value.field == field and words in str(info.value)


def test_a_parameter_named_h_is_still_a_height():
    scene = parse_scene(
        '[system]\ncoordinates = ["x"]\nparameters = { H = 2.0 }\nkinetic = "H*x_dot**2"'
    )
    assert dict(scene.parameters)["H"] == 2.0
