"""The derivation typeset (issue 25, item 2): LaTeX of every equation, within mathtext.

``systems.typeset`` turns ``systems.report``'s parts into formulas with their LaTeX
(sympy's printer with the scene's names) and glyph outlines (matplotlib's mathtext, no
TeX). The text stays exactly the report's; every equation of the catalogue's textbook
scenes is accepted by mathtext; what it refuses is shown as text, never raised.
"""

from __future__ import annotations

import pickle

import pytest
import sympy

from systems.display import latex_name
from systems.mechanics import derive
from systems.report import derivation_text, readable
from systems.scene import load_scene
from systems.typeset import (
    Formula,
    Heading,
    mathtext_of,
    outline,
    typeset_derivation,
    with_outlines,
)

TEXTBOOK = [
    "simple_pendulum",
    "double_pendulum",
    "spherical_pendulum",
    "atwood_machine",
    "rolling_disk",
    "planetary_motion",
    "bead_on_rotating_hoop",
    "cartesian_pendulum",
]


@pytest.mark.parametrize(
    ("name", "accent", "latex"),
    [
        ("theta1", "", r"\theta_{1}"),
        ("theta_1", "dot", r"\dot{\theta}_{1}"),
        ("x", "ddot", r"\ddot{x}"),
        ("lam", "", r"\lambda"),
        ("k_B", "", "k_{B}"),
        ("mass", "", r"\mathrm{mass}"),
        ("Omega", "dot", r"\dot{\Omega}"),
    ],
)
def test_latex_names_are_the_textbook_s(name, accent, latex):
    assert latex_name(name, accent) == latex


@pytest.mark.parametrize("scene", TEXTBOOK)
def test_every_equation_is_typeset_and_the_text_is_the_report_s(scene):
    mechanics = derive(load_scene(scene))
    typeset = typeset_derivation(mechanics)
    assert typeset.text == derivation_text(mechanics)
    formulas = typeset.formulas
    assert formulas
    refused = [f.latex for f in formulas if f.outline is None]
    assert refused == []
    for f in formulas:
        assert f.latex and f.text
        assert f.outline.width > 0 and f.outline.ascent > 0
        assert len(f.outline.vertices) == len(f.outline.codes) > 0
    assert isinstance(typeset.parts[0], Heading) and typeset.parts[0].level == 0
    assert pickle.loads(pickle.dumps(typeset)).text == typeset.text  # crosses processes


def test_the_pendulum_s_equations_in_latex():
    typeset = typeset_derivation(derive(load_scene("simple_pendulum")), outlines=False)
    latex = [f.latex for f in typeset.formulas]
    assert r"\ddot{\theta} = - \frac{g \sin{\left(\theta \right)}}{l}" in latex
    assert any(x.startswith(r"\dot{p}_{\theta} = ") for x in latex)  # Hamilton's equations
    assert any(x.startswith(r"p_{\theta} = ") for x in latex)
    lagrange = [f for f in typeset.formulas if f.tag == "(1)"]
    assert len(lagrange) == 1 and r"\ddot{\theta}" in lagrange[0].latex
    assert all(f.outline is None for f in typeset.formulas)
    assert all(f.outline is not None for f in with_outlines(typeset).formulas)


def test_latex_outside_mathtext_is_rewritten_or_shown_as_text():
    x, y = sympy.symbols("x y")
    latex = sympy.latex(sympy.atan2(y, x))
    assert r"\operatorname{atan}_{2}" in latex  # sympy's odd atan2
    assert r"\mathrm{atan2}" in mathtext_of(latex)
    assert outline(latex) is not None
    assert outline(r"\begin{matrix} 1 & 2 \end{matrix}") is None  # refused: no exception
    assert outline(r"\frac{1}{") is None
    assert outline("x + " * 400) is None  # too long for one line


def test_the_latex_document_has_every_equation():
    mechanics = derive(load_scene("double_pendulum"))
    typeset = typeset_derivation(mechanics, equilibria=True, outlines=False)
    document = typeset.latex_document()
    assert document.startswith(r"\documentclass{article}")
    assert document.rstrip().endswith(r"\end{document}")
    assert document.count(r"\begin{equation*}") == len(typeset.formulas)
    for f in typeset.formulas:
        assert f.latex in document
    assert r"\tag*{(2)}" in document
    assert "Equilibria" in document  # equilibria=True, as readable
    assert typeset.text == readable(mechanics)


def test_large_systems_are_typeset_in_part_and_the_rest_is_text():
    """A ten-link chain: the equations too long for one line keep their text (and, up to
    ``LATEX_NODES``, their LaTeX); nothing raises."""
    typeset = typeset_derivation(derive(load_scene("pendulum_chain")), outlines=False)
    formulas = [p for p in typeset.parts if isinstance(p, Formula)]
    assert len(formulas) > 50
    assert all(f.text for f in formulas)
    assert any(outline(f.latex) is not None for f in formulas[:10] if f.latex)


def test_a_typeset_from_the_cache_is_the_one_set(tmp_path, monkeypatch):
    # the window's layout (typeset_as_text, then with_outlines) is remembered on disk:
    # a second opening reads it instead of seconds of sympy and mathtext
    import numpy as np

    from systems import typeset as module

    monkeypatch.setenv("PHASE_EXPLORER_CACHE", str(tmp_path))
    mechanics = derive(load_scene("double_pendulum"))
    first = module.with_outlines(module.typeset_as_text(mechanics))
    module.outline.cache_clear()
    monkeypatch.setattr(module, "typeset_derivation", None)  # a second computation fails
    monkeypatch.setattr(module, "_outline", None)
    again = module.with_outlines(module.typeset_as_text(mechanics))
    assert again.text == first.text and len(again.parts) == len(first.parts)
    for a, b in zip(again.formulas, first.formulas, strict=True):
        assert (a.text, a.latex, a.lead, len(a.pieces)) == (b.text, b.latex, b.lead, len(b.pieces))
        for x, y in zip((a.outline, *a.pieces), (b.outline, *b.pieces), strict=True):
            assert np.array_equal(x.vertices, y.vertices) and np.array_equal(x.codes, y.codes)
            assert (x.width, x.ascent, x.descent) == (y.width, y.ascent, y.descent)
