"""Equilibria and normal modes with [constraints]: virtual work with the constraint forces
(dU/dq + A^T lambda = 0 on the constraints), stability on their tangent space, contacts
that must push, and refusals where the answer would be wrong. Symbolic and numpy only:
nothing here compiles a constrained scene's kernels."""

import math

import numpy as np
import pytest

from systems.mechanics import derive
from systems.normal_modes import analyse
from systems.scene import load_scene, parse_scene
from systems.textbook.equilibria import equilibria_json, search_equilibria
from tests.systems.textbook.scenes import (
    CARTESIAN_HOOP,
    HOOP,
    MOVING_RING,
    RING_QUARTIC,
    RING_WELL,
    SKATE_ON_SLOPE,
    SPRING_OVER_FLOOR,
)


@pytest.fixture(scope="module")
def pendulum():
    return derive(load_scene("cartesian_pendulum"))


def test_cartesian_pendulum_hangs_with_the_tension_m_g_and_stands_unstable_on_top(pendulum):
    v = pendulum.scene.parameter_values
    m, g, l = v["m"], v["g"], v["l"]
    search = search_equilibria(pendulum)
    assert search.method == "symbolic" and search.multipliers == ("lambda_1",)
    bottom, top = search.equilibria
    assert bottom.q == pytest.approx({"x": 0.0, "y": -l}, abs=1e-12)
    assert bottom.stable and bottom.kind == "minimum"
    assert bottom.frequencies == pytest.approx([math.sqrt(g / l)], rel=1e-12)
    # the force on the bob is -Phi_q^T lambda = -2 lambda (x, y): a tension 2 lambda l
    assert 2 * bottom.multipliers["lambda_1"] * l == pytest.approx(m * g, rel=1e-12)
    assert bottom.modes.shape == (2, 1) and abs(bottom.modes[1, 0]) < 1e-12  # along x
    assert top.q == pytest.approx({"x": 0.0, "y": l}, abs=1e-12) and not top.stable
    assert top.growth_rates == pytest.approx([math.sqrt(g / l)], rel=1e-12)
    assert 2 * top.multipliers["lambda_1"] * l == pytest.approx(-m * g, rel=1e-12)  # a strut
    data = equilibria_json(pendulum)
    assert data[0]["multipliers"] == {"lambda_1": pytest.approx(m * g / (2 * l))}
    assert data[0]["contacts"] == []


def test_a_bead_on_a_hoop_has_the_same_frequencies_in_x_y_as_in_its_angle():
    for w in (6.0,):  # spinning: off-axis minima (at rest: see the normal modes below)
        angle = search_equilibria(derive(parse_scene(HOOP)), parameters={"w": w}, symbolic=False)
        cartesian = search_equilibria(
            derive(parse_scene(CARTESIAN_HOOP)), parameters={"w": w}, symbolic=False
        )
        R = 0.8
        want = sorted(
            (round(R * math.sin(e.q["theta"]), 9), round(-R * math.cos(e.q["theta"]), 9))
            for e in angle.equilibria
        )
        got = sorted((round(e.q["x"], 9), round(e.q["y"], 9)) for e in cartesian.equilibria)
        np.testing.assert_allclose(got, want, atol=1e-8)
        by_place = {(round(e.q["x"], 6), round(e.q["y"], 6)): e for e in cartesian.equilibria}
        for e in angle.equilibria:
            twin = by_place[
                (round(R * math.sin(e.q["theta"]), 6), round(-R * math.cos(e.q["theta"]), 6))
            ]
            assert twin.stable == e.stable
            assert twin.frequencies == pytest.approx(e.frequencies, rel=1e-10)
            assert twin.growth_rates == pytest.approx(e.growth_rates, rel=1e-8)
    assert any(e.stable for e in cartesian.equilibria)


def test_atwood_rope_unbalanced_rests_on_the_floor_and_balanced_is_neutral_along_the_rope():
    mechanics = derive(load_scene("atwood_rope"))
    # the heavier left mass rests on the floor (h = 2.5 below the pulley), which pushes
    # it up with (m1 - m2) g; nowhere else is it at rest (issue 25: it ran through)
    (floor,) = search_equilibria(mechanics, symbolic=False).equilibria
    assert floor.contacts == ("lambda_4",) and floor.stable
    assert floor.q["y1"] == pytest.approx(-2.5, abs=1e-12)
    assert floor.q["y2"] == pytest.approx(-0.5, abs=1e-12)
    assert floor.multipliers["lambda_4"] == pytest.approx(-0.2 * 9.81, rel=1e-10)
    balanced = search_equilibria(mechanics, parameters={"m1": 1.0}, symbolic=False).equilibria
    # the line of rest, and its ends, where a mass touches the floor without a push
    (line,) = [e for e in balanced if e.kind == "continuum"]
    ends = sorted(e.contacts for e in balanced if e.kind != "continuum")
    assert ends == [("lambda_4",), ("lambda_5",)]
    assert line.kind == "continuum" and line.stable and line.continuum.dimension == 1
    assert "straight line" in line.continuum.description
    assert line.q["y1"] + line.q["y2"] == pytest.approx(-3.0, abs=1e-9)
    assert line.multipliers["lambda_1"] == pytest.approx(9.81, rel=1e-10)  # the tension m g


def test_a_ring_in_a_centred_well_is_a_circle_of_equilibria():
    (circle,) = search_equilibria(derive(parse_scene(RING_WELL)), symbolic=False).equilibria
    assert circle.continuum.description == "the circle x² + y² = 1"
    assert circle.continuum.closed and circle.stable
    assert circle.multipliers["lambda_1"] == pytest.approx(-1.0, rel=1e-10)  # -k/2


def test_u_is_followed_along_the_constraint_where_its_curvature_vanishes():
    search = search_equilibria(derive(parse_scene(RING_QUARTIC)), symbolic=False)

    def at(x, y):
        return min(search.equilibria, key=lambda e: math.hypot(e.q["x"] - x, e.q["y"] - y))

    assert len(search.equilibria) == 4
    bottom, side = at(0.0, -1.0), at(1.0, 0.0)
    assert bottom.q["x"] == pytest.approx(0.0, abs=1e-6)
    assert bottom.kind == "degenerate" and bottom.stable and bottom.order == 4
    assert side.kind == "maximum" and not side.stable


def test_the_bouncing_ball_rests_on_the_floor_pushed_up_by_m_g():
    mechanics = derive(load_scene("bouncing_ball"))
    search = search_equilibria(mechanics)
    assert search.free == ("x",)  # any x: V has no x
    (rest,) = search.equilibria
    assert rest.q == {"x": 0.0, "y": 0.0} and rest.stable
    assert rest.contacts == ("lambda_1",)
    assert rest.multipliers["lambda_1"] == pytest.approx(-9.81, rel=1e-12)  # pushes
    assert "pushing" in rest.decided_by


@pytest.mark.parametrize(
    ("h", "y", "force", "stable", "frequencies"),
    [
        (1.0, 1.0, 0.0, True, [2.0**0.5]),  # free, above the floor
        (-1.0, 0.0, -2.0, True, []),  # pressed on the floor by the spring
        (0.0, 0.0, 0.0, True, []),  # grazing: a minimum without the floor too
    ],
)
def test_a_spring_over_a_floor_rests_free_or_in_contact(h, y, force, stable, frequencies):
    search = search_equilibria(
        derive(parse_scene(SPRING_OVER_FLOOR)), parameters={"h": h}, symbolic=False
    )
    (e,) = search.equilibria
    assert e.q["y"] == pytest.approx(y, abs=1e-9)
    assert e.multipliers["lambda_1"] == pytest.approx(force, abs=1e-9)
    assert e.stable is stable and e.frequencies == pytest.approx(frequencies)
    assert e.contacts == (() if y > 0 else ("lambda_1",))


def test_a_contact_that_would_pull_is_no_equilibrium_and_grazing_on_a_hill_is_undecided():
    lifted = SPRING_OVER_FLOOR.replace("k*(y - h)**2/2", "-k*y")  # pushed up, off the floor
    assert search_equilibria(derive(parse_scene(lifted)), symbolic=False).equilibria == []
    hill = SPRING_OVER_FLOOR.replace("k*(y - h)**2/2", "-k*y**2/2")
    (top,) = search_equilibria(derive(parse_scene(hill)), symbolic=False).equilibria
    assert top.verdict == "undecided" and not top.stable and "grazing" in top.decided_by


def test_moving_and_nonholonomic_constraints_are_refused_with_their_reason():
    moving = search_equilibria(derive(parse_scene(MOVING_RING)))
    assert moving.method == "none" and moving.equilibria == []
    assert "moves (it depends explicitly on t)" in moving.reason
    skate = derive(parse_scene(SKATE_ON_SLOPE))
    refused = search_equilibria(skate)
    assert refused.method == "not computed" and "not symmetric" in refused.reason
    assert equilibria_json(skate) is None
    disk = search_equilibria(derive(load_scene("rolling_disk")))
    assert disk.method == "none" and "U is constant" in disk.reason


def test_normal_modes_keep_to_the_constraint(pendulum):
    v = pendulum.scene.parameter_values
    analysis = analyse(pendulum)
    assert analysis.applies
    modes = analysis.modes
    assert modes.n == 1 and modes.shapes.shape == (2, 1)
    assert modes.omega == pytest.approx([math.sqrt(v["g"] / v["l"])], rel=1e-12)
    assert modes.shapes.T @ modes.mass @ modes.shapes == pytest.approx(np.eye(1))
    np.testing.assert_allclose(
        modes.stiffness @ modes.shapes, modes.mass @ modes.shapes * modes.omega**2, atol=1e-12
    )
    # a small swing: the mode's energy is the pendulum's energy above the bottom
    theta, rate = 1e-3, 2e-3
    x, y = v["l"] * math.sin(theta), -v["l"] * math.cos(theta)
    px, py = v["m"] * v["l"] * rate * math.cos(theta), v["m"] * v["l"] * rate * math.sin(theta)
    energy = v["m"] * (v["l"] * rate) ** 2 / 2 + v["m"] * v["g"] * (y + v["l"])
    assert modes.energies(np.array([x, y, px, py]))[0, 0] == pytest.approx(energy, rel=1e-5)
    hoop = analyse(derive(parse_scene(CARTESIAN_HOOP)), {"w": 0.0})
    assert hoop.modes.omega == pytest.approx([math.sqrt(9.81 / 0.8)], rel=1e-12)


def test_normal_modes_say_why_not_for_a_free_coordinate_and_nonholonomic_constraints():
    ball = analyse(derive(load_scene("bouncing_ball")))
    assert not ball.applies and "x" in ball.reason and "freely" in ball.reason
    skate = analyse(derive(parse_scene(SKATE_ON_SLOPE)))
    assert not skate.applies and "nonholonomic" in skate.reason
