"""Stability where the coordinates fail (issue 26 item 2): a set of equilibria is decided
at a regular point of the chart, and an equilibrium at a chart singularity (the pole of
polar angles, where M is singular) in a regular local chart, its frequencies counted with
multiplicity, or it is reported as a chart singularity with the reason: never a verdict
from the singular chart's Hessian."""

import math
from pathlib import Path

import numpy as np
import pytest

from systems.mechanics import derive
from systems.scene import load_scene, parse_scene
from systems.textbook.equilibria import search_equilibria

USERS = Path(__file__).resolve().parents[2] / "user_systems"

SPHERE = """
title = "Particle on a sphere in a harmonic trough"
[system]
coordinates = ["theta", "phi"]
parameters = { m = 1.5, k = 2.0, R = 0.8 }
potential = "k*(R*sin(theta)*cos(phi))**2/2"
[particles]
bob = { mass = "m", position = ["R*sin(theta)*cos(phi)", "R*sin(theta)*sin(phi)", "R*cos(theta)"] }
"""

SPHERE_TV = """
title = "Particle on a sphere in a harmonic trough, T and V"
[system]
coordinates = ["theta", "phi"]
parameters = { m = 1.5, k = 2.0, R = 0.8 }
kinetic = "m*R**2*(theta_dot**2 + sin(theta)**2*phi_dot**2)/2"
potential = "k*(R*sin(theta)*cos(phi))**2/2"
"""

CONE = """
title = "Particle in a bowl-shaped well on a cone"
[system]
coordinates = ["r", "phi"]
parameters = { m = 1.0, k = 3.0 }
potential = "k*r**2/2"
[particles]
bob = { mass = "m", position = ["r*cos(phi)", "r*sin(phi)", "r"] }
"""


def test_spherical_pendulum_bottom_has_two_equal_frequencies():
    mech = derive(load_scene("spherical_pendulum"))
    g, l = mech.scene.parameter_values["g"], mech.scene.parameter_values["l"]
    bottom, top = search_equilibria(mech).equilibria
    assert bottom.q["theta"] == 0.0 and bottom.stable and bottom.kind == "minimum"
    assert bottom.frequencies == pytest.approx([math.sqrt(g / l)] * 2, rel=1e-8)
    assert bottom.chart.startswith("chart singularity at theta = 0")
    assert bottom.as_json()["chart_singularity"] == bottom.chart
    assert top.q["theta"] == pytest.approx(math.pi) and not top.stable
    assert top.kind == "maximum"
    assert top.growth_rates == pytest.approx([math.sqrt(g / l)] * 2, rel=1e-8)


@pytest.mark.parametrize("text", [SPHERE, SPHERE_TV], ids=["particles", "T and V"])
def test_great_circle_of_minima_is_stable_across_at_sqrt_k_over_m(text):
    mech = derive(parse_scene(text))
    values = mech.scene.parameter_values
    omega = math.sqrt(values["k"] / values["m"])
    search = search_equilibria(mech)
    sets = [e for e in search.equilibria if e.continuum is not None]
    assert sets, "the great circle x = 0 is a set of equilibria"
    for e in sets:
        # decided at a regular point of the chart: off the poles, on the circle x = 0
        assert abs(math.sin(e.q["theta"])) > 0.5
        assert math.cos(e.q["phi"]) == pytest.approx(0.0, abs=1e-9)
        assert e.stable, e.decided_by
        assert e.frequencies == pytest.approx([omega], rel=1e-9)
        assert "neutral along it" in e.decided_by and "unstable" not in e.decided_by
    # the poles lie on the circle: no entry of their own, and never an unstable verdict
    isolated = [e for e in search.equilibria if e.continuum is None]
    assert all(abs(math.sin(e.q["theta"])) == pytest.approx(1.0) for e in isolated)
    for e in isolated:  # x = +-R: maxima of U on the sphere
        assert not e.stable and e.kind == "maximum"
        assert e.growth_rates == pytest.approx([omega, omega], rel=1e-9)


def test_elastic_spherical_pendulum_counts_its_swing_twice():
    mech = derive(load_scene(str(USERS / "elastic_spherical_pendulum.toml")))
    v = mech.scene.parameter_values
    r = v["l0"] + v["m"] * v["g"] / v["k"]
    bottom = search_equilibria(mech).equilibria[0]
    assert bottom.q["theta"] == 0.0 and bottom.stable
    swing, stretch = math.sqrt(v["g"] / r), math.sqrt(v["k"] / v["m"])
    assert bottom.frequencies == pytest.approx([swing, swing, stretch], rel=1e-7)
    assert "limit from the regular points" in bottom.decided_by


def test_heavy_top_hanging_swings_in_two_planes():
    mech = derive(load_scene(str(USERS / "top.toml")))
    v = mech.scene.parameter_values
    omega = math.sqrt(v["M"] * v["g"] * v["l"] / v["I1"])
    search = search_equilibria(mech)
    hanging = next(e for e in search.equilibria if e.q["theta"] == pytest.approx(math.pi))
    upright = next(e for e in search.equilibria if e.q["theta"] == 0.0)
    assert hanging.stable and hanging.frequencies == pytest.approx([omega] * 2, rel=1e-7)
    assert not upright.stable and upright.growth_rates == pytest.approx([omega] * 2, rel=1e-7)


def test_the_tip_of_a_cone_is_a_chart_singularity_not_a_verdict():
    search = search_equilibria(derive(parse_scene(CONE)))
    (tip,) = search.equilibria
    assert tip.q["r"] == 0.0
    assert tip.verdict == "undecided" and not tip.stable and tip.frequencies == []
    assert tip.decided_by.startswith("chart singularity at r = 0: the mass matrix is singular")
    assert "not smooth" in tip.decided_by


def test_a_regular_chart_is_left_as_it_was():
    # a point of the sphere away from the poles: nothing of the chart is said
    search = search_equilibria(derive(parse_scene(SPHERE)))
    assert all(e.chart == "" for e in search.equilibria)
    assert all("chart_singularity" not in e.as_json() for e in search.equilibria)
    assert np.all([e.kind != "degenerate" for e in search.equilibria])
