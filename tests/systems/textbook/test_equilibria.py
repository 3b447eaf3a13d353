import math

import numpy as np
import pytest
import scipy.optimize

from systems.mechanics import derive
from systems.textbook._numeric import run_bounded
from systems.textbook.equilibria import equilibria_json, find_equilibria, search_equilibria
from tests.systems.scenes import DRIVEN_DAMPED, PENDULUM, PLANETARY, VARIABLE_LENGTH, scene
from tests.systems.textbook.scenes import COUPLED, HOOP, TRANSCENDENTAL


def test_pendulum_bottom_stable_at_sqrt_g_over_l_top_unstable():
    mech = derive(scene(PENDULUM))
    g, l = mech.scene.parameter_values["g"], mech.scene.parameter_values["l"]
    result = search_equilibria(mech)
    assert result.periodic == ("theta",)
    assert [e.kind for e in result.equilibria] == ["minimum", "maximum"]
    bottom, top = result.equilibria
    assert bottom.q == {"theta": 0.0} and bottom.stable
    assert bottom.p == {"p_theta": 0.0}
    assert bottom.potential == pytest.approx(-mech.scene.parameter_values["m"] * g * l)
    assert bottom.frequencies == pytest.approx([math.sqrt(g / l)], rel=1e-12)
    assert top.q["theta"] == pytest.approx(math.pi, abs=1e-12) and not top.stable
    assert top.frequencies == []
    assert top.omega_squared[0] == pytest.approx(-g / l, rel=1e-12)  # growth rate^2
    assert top.growth_rates == pytest.approx([math.sqrt(g / l)], rel=1e-12)
    assert equilibria_json(mech) == [
        {
            "q": {"theta": 0.0},
            "stable": True,
            "frequencies": [pytest.approx(math.sqrt(g / l))],
            "kind": "minimum",
            "decided_by": "U has a strict minimum (K positive definite)",
        },
        {
            "q": {"theta": pytest.approx(math.pi)},
            "stable": False,
            "frequencies": [],
            "kind": "maximum",
            "decided_by": "U has a maximum (K has a negative eigenvalue)",
            "growth_rates": [pytest.approx(math.sqrt(g / l))],
        },
    ]


def test_pendulum_numeric_search_agrees_with_symbolic():
    mech = derive(scene(PENDULUM))
    numeric = search_equilibria(mech, symbolic=False)
    assert numeric.method == "numeric"
    symbolic = equilibria_json(mech)
    assert len(numeric.equilibria) == len(symbolic) == 2
    for got, want in zip(numeric.equilibria, symbolic, strict=True):
        got = got.as_json()
        assert got["q"]["theta"] == pytest.approx(want["q"]["theta"], abs=1e-10)
        assert got["stable"] == want["stable"]
        assert got["frequencies"] == pytest.approx(want["frequencies"], rel=1e-10)


def test_three_equal_springs_normal_modes():
    mech = derive(scene(COUPLED))
    m, k = mech.scene.parameter_values["m"], mech.scene.parameter_values["k"]
    (eq,) = find_equilibria(mech)
    assert eq.kind == "minimum"
    assert eq.q == pytest.approx({"x1": 0.0, "x2": 0.0}, abs=1e-12)
    assert eq.frequencies == pytest.approx([math.sqrt(k / m), math.sqrt(3 * k / m)], rel=1e-12)
    slow, fast = eq.modes.T
    assert slow[0] == pytest.approx(slow[1], rel=1e-10)  # in phase
    assert fast[0] == pytest.approx(-fast[1], rel=1e-10)  # opposite
    assert slow @ (m * np.eye(2)) @ slow == pytest.approx(1.0)  # M-normalized


def test_spinning_hoop_uses_the_velocity_free_kinetic_term():
    mech = derive(scene(HOOP))
    v = mech.scene.parameter_values
    c = v["g"] / (v["w"] ** 2 * v["R"])  # cos of the off-axis equilibria
    result = search_equilibria(mech)
    angles = sorted(e.q["theta"] for e in result.equilibria)
    assert angles == pytest.approx([-math.acos(c), 0.0, math.acos(c), math.pi], abs=1e-10)
    by_angle = {round(e.q["theta"], 6): e for e in result.equilibria}
    side = by_angle[round(math.acos(c), 6)]
    assert side.stable and not by_angle[0.0].stable  # spun fast, the bottom is unstable
    assert side.frequencies == pytest.approx([v["w"] * math.sqrt(1 - c**2)], rel=1e-10)
    assert side.exact  # sympy found the closed form acos(g/(R w^2))


def test_transcendental_well_falls_back_to_numeric_roots():
    mech = derive(scene(TRANSCENDENTAL))
    a = mech.scene.parameter_values["a"]
    result = search_equilibria(mech, box={"x": (-6.0, 6.0)}, timeout=0.5)
    assert result.method in ("numeric", "symbolic+numeric")

    def grad(x):
        return -math.sin(x) + 2 * a * x

    expected = [0.0]
    for lo, hi in [(1.0, 3.0), (-3.0, -1.0)]:
        expected.append(scipy.optimize.brentq(grad, lo, hi, xtol=1e-14))
    found = sorted(e.q["x"] for e in result.equilibria)
    assert found == pytest.approx(sorted(expected), abs=1e-9)
    kinds = {round(e.q["x"], 6): e.kind for e in result.equilibria}
    assert kinds[0.0] == "maximum"  # U'' = -1 + 2a < 0


def test_planetary_motion_has_no_equilibrium_and_theta_is_free():
    result = search_equilibria(derive(scene(PLANETARY)))
    assert result.equilibria == []
    assert result.free == ("theta",) and result.searched == ("r",)
    assert "nowhere" in result.reason


def test_a_scene_with_t_in_its_equations_has_none_with_a_reason():
    """No constant solution of V alone: t is in the equations, periodically, so the
    reason points to Floquet theory (issue 26 item 8: explicit t, not "rheonomic")."""
    result = search_equilibria(derive(scene(VARIABLE_LENGTH)))
    assert result.equilibria == [] and result.method == "none"
    assert "explicitly on t" in result.reason and "Floquet" in result.reason


def test_driven_damped_scene_gives_the_conservative_part():
    result = search_equilibria(derive(scene(DRIVEN_DAMPED)))
    assert [e.kind for e in result.equilibria] == ["minimum", "maximum"]
    assert "conservative part" in result.reason


def test_box_limits_the_search():
    mech = derive(scene(PENDULUM))
    result = search_equilibria(mech, box={"theta": (-1.0, 1.0)})
    assert [e.q["theta"] for e in result.equilibria] == [0.0]


def _slow():
    x = 0
    while True:  # CPU time, which the bound counts
        x += 1


def test_bounded_run_gives_up_past_its_cpu_time():
    assert run_bounded(_slow, (), 0.3) is None
    assert run_bounded(math.hypot, (3.0, 4.0), 5.0) == 5.0


def test_a_constraint_whose_gradient_is_0_over_0_somewhere_does_not_stop_the_search():
    """sqrt(X**2 + Z**2) - l has no gradient at the origin, where the scan's grid starts:
    those starts are dropped (the search ended in 'SVD did not converge')."""
    from systems.scene import parse_scene

    text = """
title = "pendulum in its own Cartesian coordinates"
[system]
coordinates = ["X", "Z"]
parameters = { m = 1.0, g = 9.81, l = 1.0 }
kinetic = "m*(X_dot**2 + Z_dot**2)/2"
potential = "m*g*Z"
[constraints]
holonomic = ["sqrt(X**2 + Z**2) - l"]
[initial]
X = 0.5
"""
    found = search_equilibria(derive(parse_scene(text, source="xz.toml")))
    points = sorted((round(e.q["X"], 9) + 0.0, round(e.q["Z"], 9)) for e in found.equilibria)
    assert points == [(0.0, -1.0), (0.0, 1.0)]
    (stable,) = [e for e in found.equilibria if e.stable]
    assert stable.q["Z"] == pytest.approx(-1.0)
    assert stable.frequencies[0] == pytest.approx(math.sqrt(9.81), rel=1e-9)


def test_a_constant_potential_in_one_coordinate_is_not_a_curve_with_an_across():
    """Atwood's machine with equal masses: every x is an equilibrium (the derive command
    once ended in an IndexError here, the window in 'equilibria not found')."""
    from systems.report import equilibria_sentences
    from systems.scene import parse_scene

    text = """
title = "Atwood machine, equal masses"
[system]
coordinates = ["x"]
parameters = { m1 = 1.0, m2 = 1.0, I = 0.1, R = 0.2, g = 9.81 }
kinetic = "(m1 + m2)/2*x_dot**2 + I/2*(x_dot/R)**2"
potential = "(m2 - m1)*g*x"
[initial]
x_dot = 0.1
"""
    lines, _ = equilibria_sentences(derive(parse_scene(text, source="atwood.toml")))
    assert len(lines) == 1 and lines[0].startswith("U is constant around x = ")
    assert lines[0].endswith(
        "every configuration there is an equilibrium, neutral (a body at rest stays at rest)"
    )


def test_coordinates_zero_to_round_off_are_reported_as_zero():
    # a six-mass FPU chain's 23 equilibria: Newton ended five of their coordinates a few
    # ulps from 0 (printed as q = -1.7e-15); each is 0 or far from it
    from systems.families import fpu_chain
    from systems.scene import parse_scene

    result = search_equilibria(derive(parse_scene(fpu_chain(6))))
    assert len(result.equilibria) == 23
    values = np.array([v for e in result.equilibria for v in e.q.values()])
    assert np.any(values == 0.0)
    assert not np.any((values != 0.0) & (np.abs(values) < 1e-9))
