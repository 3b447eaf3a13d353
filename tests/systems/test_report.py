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
