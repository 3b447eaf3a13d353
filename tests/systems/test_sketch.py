"""The drawing of a scene given by particles without links of its own (issue 25 item 6):
bodies, rods to the supports and between particles that the transformation or a
holonomic constraint ties (``systems.sketch``)."""

from __future__ import annotations

import pytest

from systems.scene import catalogue, load_scene, parse_scene
from systems.sketch import sketch

HOOKED_DOUBLE_PENDULUM = """
title = "Double pendulum hung from a hook at (0.5, 1)"
[system]
coordinates = ["theta1", "theta2"]
parameters = { m1 = 2.0, m2 = 0.5, l1 = 1.0, l2 = 0.8, g = 9.81 }
gravity = "g"
[particles]
bob1 = { mass = "m1", position = ["0.5 + l1*sin(theta1)", "1 - l1*cos(theta1)"] }
[particles.bob2]
mass = "m2"
position = ["0.5 + l1*sin(theta1) + l2*sin(theta2)", "1 - l1*cos(theta1) - l2*cos(theta2)"]
[initial]
theta1 = 1.0
"""

DUMBBELL = """
title = "Dumbbell on a string, both tied by constraints"
[system]
coordinates = ["x1", "y1", "x2", "y2"]
parameters = { m1 = 1.0, m2 = 3.0, l = 1.0, d = 0.6, g = 9.81 }
gravity = "g"
[particles]
a = { mass = "m1", position = ["x1", "y1"] }
b = { mass = "m2", position = ["x2", "y2"] }
[constraints]
holonomic = ["sqrt(x1**2 + y1**2) - l", "(x1 - x2)**2 + (y1 - y2)**2 - d**2"]
[initial]
x1 = 0.6
y1 = -0.8
x2 = 1.2
y2 = -0.8
"""

SHAKEN = """
title = "Pendulum whose support is shaken sideways, in 3D"
[system]
coordinates = ["theta", "phi"]
parameters = { m = 1.0, a = 0.2, w = 3.0, l = 1.0, g = 9.81 }
gravity = "g"
[particles]
fixed = { mass = "m", position = ["2", "0", "0"] }
spring = { mass = "m", position = ["2 + theta", "-1", "0"] }
[particles.bob]
mass = "m"
position = ["a*cos(w*t) + l*sin(theta)*cos(phi)", "-l*cos(theta)", "l*sin(theta)*sin(phi)"]
[initial]
theta = 0.5
"""


def test_a_hooked_double_pendulum_has_a_support_and_two_rods():
    drawn = sketch(parse_scene(HOOKED_DOUBLE_PENDULUM))
    assert drawn.bodies == ("bob1", "bob2")
    assert [str(m) for m in drawn.masses] == ["m1", "m2"]
    (support,) = drawn.supports
    assert support[0] == "support" and (float(support[1]), float(support[2])) == (0.5, 1.0)
    # bob2 is not at a constant distance from the hook, but from bob1
    assert drawn.links == (("support", "bob1"), ("bob1", "bob2"))


def test_constraints_that_fix_a_distance_are_rods():
    drawn = sketch(parse_scene(DUMBBELL))
    assert drawn.bodies == ("a", "b") and drawn.supports == ()
    # |r_a - r_b| = d fixed by the second constraint, |r_a| = l by the first (a function
    # of x1**2 + y1**2, not the square itself)
    assert set(drawn.links) == {("a", "b"), ("origin", "a")}


def test_a_moving_support_fixed_points_and_a_spring_are_told_apart():
    drawn = sketch(parse_scene(SHAKEN))
    # the fixed particle is no body: nothing moves it; nor is a support's distance kept
    # to a particle a coordinate stretches
    assert drawn.bodies == ("spring", "bob")
    (support,) = drawn.supports
    x, y = support[1], support[2]
    assert str(x) == "a*cos(t*w)" and y == 0
    assert drawn.links == (("support", "bob"),)


@pytest.mark.parametrize(
    "name, links",
    [
        ("double_pendulum", {("origin", "bob1"), ("bob1", "bob2")}),
        ("spherical_pendulum", {("origin", "bob")}),
        ("kapitza_pendulum", {("pivot", "bob")}),  # the massless pivot, which t moves
        ("figure_eight", set()),  # free bodies: nothing ties them
        ("stiff_spring_pendulum", set()),  # a spring, not a rod
        ("atwood_machine", set()),  # a rope over a pulley is no distance
    ],
)
def test_catalogue_scenes_sketched(name, links):
    scene = load_scene(name)
    drawn = sketch(scene)
    assert set(drawn.links) == links
    assert "pivot" not in drawn.bodies  # mass 0


def test_every_catalogue_scene_with_particles_names_known_points():
    for entry in catalogue():
        scene = load_scene(entry.name)
        drawn = sketch(scene)
        known = {p.name for p in scene.particles} | {"origin"} | {s[0] for s in drawn.supports}
        assert all(a in known and b in known for a, b in drawn.links), entry.name
