"""Floquet theory for driven systems (``systems.textbook.floquet``, issue 26 items 4, 8).

References: the Kapitza pendulum's inverted position is stable when a²w² > 2gl (Kapitza
1951; Landau & Lifshitz, Mechanics, §30), for a small amplitude a << l. The Mathieu
equation x'' + (delta + epsilon cos t) x = 0 has its transition curves at the
characteristic values of Mathieu functions: with scipy's y'' + (a - 2q cos 2z) y = 0,
t = 2z gives delta = a_m(2 epsilon)/4 and b_m(2 epsilon)/4 (scipy.special.mathieu_a,
mathieu_b: Zhang & Jin, Computation of Special Functions). For small epsilon, Kovacic,
Rand & Sah, "Mathieu's equation and its generalizations", Appl. Mech. Rev. 70 (2018)
020802, eqs. for x'' + (delta + epsilon cos t) x = 0:
delta = -epsilon²/2 + 7 epsilon⁴/32, delta = 1/4 ± epsilon/2 - epsilon²/8 ∓ epsilon³/32,
delta = 1 - epsilon²/12, delta = 1 + 5 epsilon²/12 (up to the next order).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.optimize
import scipy.special
import sympy

from systems.mechanics import derive
from systems.report import derivation_json, readable
from systems.scene import load_scene, parse_scene
from systems.textbook import floquet
from systems.textbook.equilibria import search_equilibria

G, L, A = 9.81, 1.0, 0.1

MATHIEU_L = """
title = "Mathieu (L)"
[system]
coordinates = ["x"]
parameters = { delta = 0.5, epsilon = 0.2 }
lagrangian = "x_dot**2/2 - (delta + epsilon*cos(t))*x**2/2"
"""

DAMPED_MATHIEU = """
title = "Damped Mathieu"
[system]
coordinates = ["x"]
parameters = { delta = 0.5, epsilon = 0.2, b = 0.1 }
kinetic = "x_dot**2/2"
potential = "(delta + epsilon*cos(t))*x**2/2"
[effects]
dissipation = "b*x_dot**2/2"
"""


@pytest.fixture(scope="module")
def kapitza():
    return derive(load_scene("kapitza_pendulum"))


@pytest.fixture(scope="module")
def mathieu():
    mechanics = derive(load_scene("mathieu_oscillator"))
    return floquet.VariationalSystem.build(mechanics)


def _trace(system, delta, epsilon):
    P = system.parameter_vector({"delta": delta, "epsilon": epsilon})
    result = floquet.monodromy(system, system.state_at_rest(np.zeros(1), P), 2 * math.pi, P)
    return float(np.trace(result.matrix))


@pytest.mark.parametrize(("factor", "inverted"), [(1.5, "stable"), (0.5, "unstable")])
def test_kapitza_inverted_position_against_the_threshold(kapitza, factor, inverted):
    w = math.sqrt(factor * 2 * G * L) / A  # a²w² = factor × 2gl
    analysis = floquet.analyse(kapitza, {"w": w, "a": A, "g": G, "l": L})
    assert analysis.periodicity.period == pytest.approx(2 * math.pi / w)
    positions = {round(abs(s.q["theta"]), 9): s for s in analysis.solutions}
    assert set(positions) == {0.0, round(math.pi, 9)}
    assert positions[0.0].verdict.word == "stable"
    assert positions[round(math.pi, 9)].verdict.word == inverted
    for s in analysis.solutions:  # Liouville: a Hamiltonian flow keeps volume
        assert s.determinant == pytest.approx(1.0, abs=1e-9)
        assert s.closure < 1e-9


def test_mathieu_transition_curves_are_scipys_characteristic_values(mathieu):
    for epsilon in (0.1, 0.5, 1.0):
        q = 2 * epsilon
        curves = [
            (scipy.special.mathieu_a(0, q) / 4, 2.0),
            (scipy.special.mathieu_b(1, q) / 4, -2.0),
            (scipy.special.mathieu_a(1, q) / 4, -2.0),
            (scipy.special.mathieu_b(2, q) / 4, 2.0),
            (scipy.special.mathieu_a(2, q) / 4, 2.0),
        ]
        for delta, trace in curves:
            assert _trace(mathieu, delta, epsilon) == pytest.approx(trace, abs=1e-7)


def _boundary(system, epsilon, guess, sign, width=0.05):
    def f(delta):
        return _trace(system, delta, epsilon) - 2 * sign

    return scipy.optimize.brentq(f, guess - width, guess + width, xtol=1e-12)


def test_mathieu_tongues_at_small_epsilon_follow_the_expansions(mathieu):
    e = 0.05
    expected = {  # Kovacic, Rand & Sah (2018), x'' + (delta + eps cos t) x = 0
        "-eps²/2": (-(e**2) / 2 + 7 * e**4 / 32, 1, 0.0),
        "1/4 - eps/2": (0.25 - e / 2 - e**2 / 8 + e**3 / 32, -1, 0.225),
        "1/4 + eps/2": (0.25 + e / 2 - e**2 / 8 - e**3 / 32, -1, 0.275),
        "1 - eps²/12": (1 - e**2 / 12, 1, 0.9995),
        "1 + 5eps²/12": (1 + 5 * e**2 / 12, 1, 1.0015),
    }
    for name, (delta, sign, guess) in expected.items():
        width = 0.0009 if abs(guess - 1) < 0.01 else 0.02
        found = _boundary(mathieu, e, guess, sign, width)
        assert found == pytest.approx(delta, abs=2e-5), name  # the next order: eps⁴ ≈ 6e-6


def test_mathieu_chart_inside_and_outside_the_first_tongue(mathieu):
    epsilon = np.array([0.4])
    deltas = np.linspace(-0.3, 1.3, 33)
    codes, growth = floquet.chart_rows(
        mathieu, np.zeros(1), {}, "delta", deltas, "epsilon", epsilon
    )
    q = 2 * epsilon[0]
    tongues = [
        (scipy.special.mathieu_b(1, q) / 4, scipy.special.mathieu_a(1, q) / 4),
        (scipy.special.mathieu_b(2, q) / 4, scipy.special.mathieu_a(2, q) / 4),
        (-np.inf, scipy.special.mathieu_a(0, q) / 4),
    ]
    for delta, code in zip(deltas, codes[0], strict=True):
        near = min(min(abs(delta - lo), abs(delta - hi)) for lo, hi in tongues)
        if near < 1e-3:
            continue
        inside = any(lo < delta < hi for lo, hi in tongues)
        assert code == (floquet.UNSTABLE if inside else floquet.STABLE), delta
    assert np.all(growth[codes == floquet.STABLE] <= 1 + 1e-6)


def test_periodicity_detection():
    t, w, x = sympy.symbols("t w x")
    found = floquet.time_harmonics([x * sympy.cos(w * t) + sympy.sin(1 - 2 * w * t)], t)
    assert set(found) == {w, 2 * w}
    with pytest.raises(floquet.NotPeriodic):
        floquet.time_harmonics([x * sympy.exp(-t)], t)
    with pytest.raises(floquet.NotPeriodic):
        floquet.time_harmonics([t * x], t)
    with pytest.raises(floquet.NotPeriodic):
        floquet.time_harmonics([sympy.cos(x * t)], t, [w])
    assert floquet.common_period([2.0, 3.0]) == pytest.approx(2 * math.pi)
    assert floquet.common_period([1.0, 0.5]) == pytest.approx(4 * math.pi)
    assert floquet.common_period([1.0, math.sqrt(2)]) is None
    assert floquet.common_period([0.0]) is None


def test_quasi_periodic_drive_is_not_analysed():
    scene = parse_scene(MATHIEU_L.replace("cos(t)", "(cos(t) + cos(sqrt(2)*t))"), "<quasi>")
    mechanics = derive(scene)
    analysis = floquet.analyse(mechanics)
    assert not analysis.periodicity.periodic and not analysis.solutions
    assert "incommensurate" in analysis.note and "no Floquet analysis" in analysis.note


def test_damped_driven_system_checks_liouville():
    mechanics = derive(parse_scene(DAMPED_MATHIEU, "<damped>"))
    analysis = floquet.analyse(mechanics)
    (solution,) = analysis.solutions
    assert not analysis.symplectic
    assert solution.determinant == pytest.approx(math.exp(-0.1 * 2 * math.pi), rel=1e-8)
    assert solution.determinant == pytest.approx(solution.liouville, rel=1e-8)
    assert solution.verdict.word == "asymptotically stable"


def test_text_never_contradicts_itself_for_a_time_dependent_potential():
    for mechanics in (derive(load_scene("mathieu_oscillator")), derive(parse_scene(MATHIEU_L))):
        text = readable(mechanics)
        assert "scleronomic" in text and "rheonomic" not in text
        assert floquet.HEADING in text
        assert "- x = 0: " in text and "multipliers" in text
        note = search_equilibria(mechanics).reason
        assert "rheonomic" not in note and "Floquet" in note


def test_kapitza_derivation_lists_both_constant_solutions(kapitza):
    text = readable(kapitza)
    assert "rheonomic" in text  # the pivot moves: the transformation depends on t
    section = text.split(floquet.HEADING)[1]
    assert "θ = 0: stable" in section and "θ = 3.14159: stable" in section
    data = derivation_json(kapitza)["floquet"]
    assert data["periodic"] and data["period"] == pytest.approx(2 * math.pi / 60.0)
    verdicts = {round(abs(s["q"]["theta"]), 6): s["stability"] for s in data["constant_solutions"]}
    assert verdicts == {0.0: "stable", round(math.pi, 6): "stable"}
    assert derivation_json(derive(load_scene("henon_heiles")))["floquet"] is None
