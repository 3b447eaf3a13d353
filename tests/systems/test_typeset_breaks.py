"""Long equations cut where a line may break (issue 25 item 2: nothing cut off, no
horizontal scroll): before the terms of a sum, after the commas of a tuple, before the
terms of a fraction's long numerator (set as 1/D times a bracket), and a wide term
before its fractions. Side by side the pieces read as the whole equation."""

from __future__ import annotations

import pytest

from systems.mechanics import derive
from systems.scene import load_scene
from systems.typeset import (
    BREAK_EMS,
    break_pieces,
    joined,
    outline,
    set_in_type,
    typeset_derivation,
)


def test_a_sum_breaks_before_its_terms_and_the_pieces_join_to_the_whole():
    latex = r"H = \frac{p^{2}}{2 m} + m g l \cos{\left(\theta \right)} - k x"
    pieces, lead = break_pieces(latex)
    assert lead == 1 and pieces[0] == "H ={}"
    assert pieces[1:] == [
        r"{}\frac{p^{2}}{2 m}",
        r"{}+ m g l \cos{\left(\theta \right)}",
        r"{}- k x",
    ]
    whole = outline(latex)
    together = joined(tuple(outline(piece) for piece in pieces))
    assert together.width == pytest.approx(whole.width, abs=0.05)
    assert together.ascent == pytest.approx(whole.ascent, abs=0.05)


def test_sums_inside_brackets_are_not_broken_but_a_tuple_breaks_after_its_commas():
    # only after the relation: the right side may go to the next line whole
    assert break_pieces(r"V = - g \left(a + b\right)") == (
        ["V ={}", r"{}- g \left(a + b\right)"],
        1,
    )
    pieces, lead = break_pieces(r"\mathbf{r} = \left(a + b, - c\right)")
    assert lead == 1 and len(pieces) == 3
    assert pieces[1].startswith(r"{}\left(\right.") and pieces[2].endswith(r"\left.\right)")
    assert all(outline(piece) is not None for piece in pieces)


def test_a_long_numerator_is_set_as_one_over_the_denominator_times_its_terms():
    pieces, _ = break_pieces(r"\dot{x} = \frac{a b + c d - e}{f g}")
    assert pieces[1] == r"{}\dfrac{1}{f g}" and pieces[2].startswith(r"\,\left(\right.a b")
    assert [piece.split()[0] for piece in pieces[3:]] == ["{}+", "{}-"]
    assert all(outline(piece) is not None for piece in pieces)


def test_a_matrix_or_a_single_term_without_a_relation_has_nowhere_to_break():
    assert break_pieces(r"M = \left[\begin{matrix}a & b\\c & d\end{matrix}\right]") is None
    assert break_pieces(r"a b c") is None


@pytest.mark.parametrize("scene", ["double_pendulum", "tests/user_systems/chain5.toml"])
def test_every_wide_equation_of_a_chain_has_pieces_no_wider_than_a_dock(scene):
    typeset = typeset_derivation(derive(load_scene(scene)))
    wide = [f for f in typeset.formulas if f.outline is not None and f.outline.width > 40]
    assert wide
    for formula in wide:
        assert formula.pieces, formula.latex
        # what must stay on one line is at most 34 ems (about 600 px at 10 points: the
        # window scales it to the dock; a fraction's product numerator cannot break)
        assert max(piece.width for piece in formula.pieces) < 34.0, formula.latex
        assert 1 <= formula.lead < len(formula.pieces)
    narrow = [f for f in typeset.formulas if f.outline is not None and f.outline.width < 10]
    assert all(not f.pieces for f in narrow)
    assert set_in_type("x = 1")["pieces"] == () and BREAK_EMS > 10
