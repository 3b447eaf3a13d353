"""Derivations and equilibria as text (``systems.report``), as the window shows them.

The ``derive`` command's output (all of ``readable``, ``derivation_json``) is checked
through the CLI in ``tests/explorer/test_cli.py``.
"""

from __future__ import annotations

import sympy

from systems.mechanics import derive
from systems.report import equilibria_sentences, one_line, readable
from systems.scene import parse_scene
from tests.systems.scenes import PENDULUM, PLANETARY


def test_readable_without_equilibria_is_the_window_text():
    mechanics = derive(parse_scene(PLANETARY))
    text = readable(mechanics, equilibria=False)
    assert text.startswith("Planetary motion\n================")
    assert "coordinates: r, θ; parameters: m = 1.3, k = 0.8" in text
    assert "- cyclic coordinates: θ" in text and "p_θ" in text
    assert "Equilibria" not in text


def test_equilibria_sentences_of_the_pendulum():
    lines, note = equilibria_sentences(derive(parse_scene(PENDULUM)), digits=4)
    assert lines == ["θ = 0: stable, ω = 3.744", "θ = 3.142: unstable (maximum)"]
    assert note == ""


def test_one_line_for_people():
    m, r, k, p = sympy.symbols("m r k p_θ", positive=True)
    assert one_line(p**2 / (2 * m * r**2) - k / r) == "−k/r + p_θ²/(2·m·r²)"
    assert one_line(sympy.pi * r**5) == "π·r^5"


def test_combine_trig_joins_sums_of_products_of_sines_and_cosines():
    from systems.display import combine_trig

    a, b, c, m = sympy.symbols("a b c m", real=True)
    sin, cos = sympy.sin, sympy.cos
    chain = m * (38 * sin(a) * sin(b) + 38 * cos(a) * cos(b)) / 2
    assert combine_trig(chain) == 19 * m * cos(a - b)
    assert combine_trig(c * cos(a) * cos(b) - c * sin(a) * sin(b)) == c * cos(a + b)
    assert combine_trig(sin(a) * cos(b) - cos(a) * sin(b)) == sin(a - b)
    assert combine_trig(2 * sin(a) ** 2 + 2 * cos(a) ** 2 + c) == c + 2
    unmatched = sin(a) * sin(b) + 2 * cos(a) * cos(b)  # coefficients differ: left alone
    assert combine_trig(unmatched) == unmatched


def test_a_large_expression_is_shown_on_one_line():
    from systems import report

    mechanics = derive(parse_scene(PENDULUM))
    x = sympy.Symbol("theta", real=True)
    large = sum(sympy.cos(k * x) / k for k in range(1, 200))
    small = sympy.cos(x) ** 2 / 3
    (line,) = report._rows([("S", large)], mechanics.scene)
    assert line.startswith("S = ") and "cos(199·θ)/199" in line
    art = report._rows([("s", small)], mechanics.scene)
    assert len(art) > 1 and any(row.startswith("s = ───") for row in art)  # two-dimensional


def test_equilibria_sentences_on_constraints_give_the_constraint_force():
    """The Cartesian pendulum hangs on its string (lambda = m g / (2 l), the tension
    2 lambda l = m g) and balances on it upside down (a strut, lambda < 0); the resting
    ball is held by the floor, and nothing calls it a zero or infinite inertia."""
    from systems.scene import load_scene

    lines, _ = equilibria_sentences(derive(load_scene("cartesian_pendulum")), digits=4)
    assert lines == [
        "x = 0, y = -1: stable, \u03c9 = 3.132; constraint force \u03bb\u2081 = 4.905",
        "x = 0, y = 1: unstable (maximum); constraint force \u03bb\u2081 = -4.905",
    ]
    (line,), _ = equilibria_sentences(derive(load_scene("bouncing_ball")), digits=4)
    assert line.startswith("x = 0, y = 0: stable, without oscillation")
    assert "\u03bb\u2081 = -9.81" in line and "inertia" not in line
