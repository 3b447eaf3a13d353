"""Typeset equations everywhere they are shown (issue 25 item 2).

- The Derivation tab breaks a long equation across lines (before the terms of a sum,
  continuation lines aligned after its relation) or draws it smaller, never wider than
  the dock: no horizontal scroll bar for a double pendulum's or a 5-link chain's
  Hamilton equations, at the window's font and presentation mode's.
- The formulas in sentences (the classification card, the equilibria, the Textbook
  tabs' notes, plot titles and table cells) are set in type by the same machinery
  (``explorer.inline_math``: mathtext in a worker process), each copyable as LaTeX.
- At 1280 x 720 and 1366 x 768 (a process per screen, offscreen) the real window shows
  them so; its screenshots are in the test's temporary folder
  (``typeset-<W>x<H>-<tab>.png``).
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

import pytest
from PySide6.QtGui import QFont

from systems.mechanics import derive
from systems.scene import load_scene
from systems.typeset import typeset_derivation

SCREENS = [(1280, 720), (1366, 768)]
CHAIN = "tests/user_systems/chain5.toml"


@pytest.fixture(scope="module")
def derivations():
    return {
        name: typeset_derivation(derive(load_scene(name))) for name in ("double_pendulum", CHAIN)
    }


def wait_for_type(qtbot) -> None:
    from explorer.inline_math import store

    qtbot.waitUntil(lambda: not store().pending, timeout=60000)
    qtbot.wait(20)  # the ready signal is queued


@pytest.mark.parametrize("scene", ["double_pendulum", CHAIN])
@pytest.mark.parametrize("scale", [1.0, 1.6], ids=["window", "presentation"])
def test_long_equations_break_within_the_dock_never_past_it(qtbot, derivations, scene, scale):
    from explorer.editor.derivation_view import DerivationView
    from explorer.equations import DerivationLayout

    view = DerivationView()
    qtbot.addWidget(view)
    font = QFont(view.font())
    font.setPointSizeF(font.pointSizeF() * scale)
    view.setFont(font)
    view.resize(380, 600)  # the editor dock at 1366 x 768
    view.show()
    view.set_typeset(derivations[scene])
    qtbot.waitExposed(view)
    width = view.viewport().width()
    assert view.horizontalScrollBar().maximum() == 0
    formulas = [p for p in view.layout_.placed if p.kind == "formula"]
    assert all(p.rect.right() <= width for p in formulas)
    broken = [p for p in formulas if len(p.rows) > 1]
    assert len(broken) >= 4
    for placed in broken:
        assert placed.scale >= DerivationLayout.LEAST_SCALE
        starts = [start for start, held, _ in placed.rows[1:] if held]
        assert len(set(starts)) <= 1  # continuation lines aligned
        pieces = [i for _, held, _ in placed.rows for i in held]
        assert pieces == list(range(len(placed.part.pieces)))  # each piece once, in order
        baselines = [baseline for _, _, baseline in placed.rows]
        assert baselines == sorted(baselines)
    # at the window's font most equations are drawn at their size: only the widest
    # pieces are scaled
    if scale == 1.0:
        assert sum(p.scale == 1.0 for p in formulas) >= 0.6 * len(formulas)


@pytest.mark.parametrize(
    "text, found",
    [
        ("Driven system: period T = 6.28319.", ["T = 6.28319"]),
        (
            "multipliers 1.77, 0.56; tr M = 2.3361; det M = 1 (Liouville)",
            ["tr M = 2.3361", "det M = 1"],
        ),
        ("θ₁ = 0, θ₂ = 3.142: unstable (saddle)", ["θ₁ = 0", "θ₂ = 3.142"]),
        ("at p<sub>θ</sub> = 1.225", ["p<sub>θ</sub> = 1.225"]),
        (
            "the Routhian R = L − Σ p<sub>c</sub> q̇<sub>c</sub>.",
            ["R = L − Σ p<sub>c</sub> q̇<sub>c</sub>"],
        ),
        ("<a href='remove-view'>x = 1</a> and version 2.5.1", []),
        ("Newton did not converge in 12 steps", []),
    ],
)
def test_the_formulas_of_a_sentence_are_found_and_nothing_else(text, found):
    from explorer.inline_math import formula_spans
    from systems.typeset import outline

    spans = formula_spans(text)
    assert [span.text for span in spans] == found
    assert all(outline(span.latex) is not None for span in spans)  # mathtext sets each


def test_formulas_whose_worker_was_ended_are_set_when_next_asked(qtbot):
    """A window closing ends every worker (``processes.cancel_all``): the formulas it was
    setting are asked for again by the next label that shows them."""
    from explorer.inline_math import MathStore

    store = MathStore()
    latex = r"\alpha_{7} = \beta"
    # a batch of seconds of work, so that the worker is ended before it answers
    many = [
        " + ".join(rf"\frac{{x_{{{i}}}^{{{k}}}}}{{y_{{{k}}}}}" for k in range(12))
        for i in range(300)
    ]
    for text in [latex, *many]:
        assert store.outline(text) is None
    qtbot.waitUntil(lambda: bool(store.jobs), timeout=5000)
    store.cancel()
    qtbot.waitUntil(lambda: latex not in store._asked, timeout=10000)
    with qtbot.waitSignal(store.ready, timeout=60000):
        assert store.outline(latex) is None
    assert store.outline(latex) is not None


def test_a_classification_card_s_formulas_are_set_and_copied_as_latex(qtbot):
    from PySide6.QtWidgets import QApplication

    from explorer.inline_math import MathLabel

    text = (
        "<b>Pendulum</b><br>● holonomic: every constraint is an equation f(q, t) = 0"
        "<br>● H = T + V, the mechanical energy<br>θ = 0: stable, ω = 3.132"
    )
    label = MathLabel(text)
    qtbot.addWidget(label)
    label.resize(400, 200)
    label.show()
    assert label.text() == text
    assert [span.latex for span in label.spans] == [
        "f(q, t) = 0",
        "H = T + V",
        r"\theta = 0",
        r"\omega = 3.132",
    ]
    wait_for_type(qtbot)
    assert label.formulas_set() == 4 and "data:image/png" in label.shown_html()
    assert label.text() == text  # what the window wrote, for tests and copies
    label._on_link_hovered("tex:1")
    menu = label.context_menu()
    menu.actions()[0].trigger()  # Copy as LaTeX
    assert QApplication.clipboard().text() == "H = T + V"


def test_the_card_names_conserved_momenta_as_momenta_set_in_type():
    from explorer.editor.editor_panel import classification_html
    from explorer.inline_math import formula_spans

    card = classification_html(derive(load_scene("spherical_pendulum")), "", "")
    assert "conserved: H, p<sub>φ</sub>" in card and "p_phi" not in card
    assert r"p_{\phi}" in [span.latex for span in formula_spans(card)]


def test_the_derivation_s_card_and_sentences_hold_copyable_formulas(qtbot, derivations):
    from PySide6.QtCore import QPointF

    from explorer.editor.derivation_view import DerivationView

    view = DerivationView()
    qtbot.addWidget(view)
    view.resize(420, 600)
    view.show()
    view.set_typeset(derivations["double_pendulum"])
    view.set_card("<b>Double pendulum</b><br>separable: H = T(p) + V(q)")
    wait_for_type(qtbot)
    rich = [p for p in view.layout_.placed if p.kind == "rich"]
    assert rich  # the classification's sentences: "H = T + V, the mechanical energy"
    from systems.typeset import Heading

    parts = view.typeset.parts
    assert any(isinstance(parts[p.index], Heading) for p in rich)  # "p = dL/dq̇"
    card = next(p for p in view.layout_.placed if p.kind == "card")
    assert card.part.spans and "data:image/png" in card.part.toHtml()
    # the formula under the mouse is found for the context menu's Copy as LaTeX
    found = None
    rect = card.rect
    for y in range(int(rect.top()), int(rect.bottom()), 3):
        for x in range(int(rect.left()), int(rect.right()), 3):
            found = found or view.layout_.inline_at(QPointF(x, y))
    assert found is not None and found.latex == "H = T(p) + V(q)"


def test_textbook_notes_titles_and_table_cells_set_their_formulas(qtbot):
    from explorer.inline_math import MathDelegate, MathLabel
    from explorer.textbook.plots import make_plot, note_label

    note = note_label("H is conserved, dH/dt = 0. Stable when |tr M| &lt; 2.")
    qtbot.addWidget(note)
    assert isinstance(note, MathLabel)
    plot = make_plot("dH/dt = −∂L/∂t + Σ q̇ᵢ Qᵢ along the motion", "t", "rate")
    qtbot.addWidget(plot)
    plot.plot([0, 1], [0, 1], name="dH/dt = −∂L/∂t (the formula)")
    from PySide6.QtWidgets import QTableWidget, QTableWidgetItem

    table = QTableWidget(1, 1)
    qtbot.addWidget(table)
    delegate = MathDelegate(table)
    table.setItemDelegate(delegate)
    table.setItem(0, 0, QTableWidgetItem("ω₁ = 2.3972  (ω² = 5.74656, period 2.6211)"))
    table.show()
    wait_for_type(qtbot)
    assert note.formulas_set() == 2
    title = plot.getPlotItem().titleLabel
    assert "data:image/png" in title.item.toHtml()
    assert plot.getPlotItem().math_title.text.startswith("dH/dt")
    (_, entry), *_ = plot.getPlotItem().legend.items
    assert "data:image/png" in entry.item.toHtml()
    assert entry.text == "dH/dt = −∂L/∂t (the formula)"  # as written, for restyling
    from PySide6.QtWidgets import QStyleOptionViewItem

    option = QStyleOptionViewItem()
    option.font = table.font()
    option.palette = table.palette()
    document = delegate._document(option, table.model().index(0, 0))
    assert document is not None and "data:image/png" in document.toHtml()
    assert len(document.toHtml().split("data:image/png")) == 3  # ω₁ = …, ω² = …


def test_an_equilibrium_s_closed_form_is_one_formula_in_its_cell(qtbot):
    from types import SimpleNamespace

    from PySide6.QtWidgets import QStyleOptionViewItem

    from explorer.inline_math import LATEX_ROLE
    from explorer.textbook.equilibria_view import EquilibriaView
    from systems.textbook import jobs
    from systems.textbook.equilibria import search_equilibria

    mechanics = derive(load_scene("bead_on_rotating_hoop"))
    result = jobs.EquilibriaResult(search_equilibria(mechanics), tuple(mechanics.scene.coordinates))
    view = EquilibriaView(runner=None)
    qtbot.addWidget(view)
    view.compiled = SimpleNamespace(mechanics=mechanics)
    view._on_search_done(result, view.generation)
    table = view.table
    column = [table.horizontalHeaderItem(c).text() for c in range(table.columnCount())].index(
        "closed form (sympy)"
    )
    forms = [table.item(r, column) for r in range(table.rowCount())]
    latex = [item.data(LATEX_ROLE) for item in forms if item.text()]
    assert len(latex) == 2 and all(r"\operatorname{acos}" in form for form in latex), latex
    assert all(r"\mathrm{mod}" in form for form in latex)  # theta is an angle
    assert any("acos(g/(a·ω²))" in item.text() for item in forms)  # its text, as before
    table.show()
    wait_for_type(qtbot)
    option = QStyleOptionViewItem()
    option.font = table.font()
    option.palette = table.palette()
    row = next(r for r in range(table.rowCount()) if forms[r].text())
    document = table.itemDelegate()._document(option, table.model().index(row, column))
    assert document is not None and document.toHtml().count("data:image/png") == 1


def measure(folder: str) -> dict:
    """Open the window on the double pendulum as ``main.py`` does, show its derivation
    and its equilibria, and measure (run in a process whose screen has the size)."""
    from explorer.app import application, create_window
    from explorer.inline_math import store
    from tests.explorer.screens import spin

    app = application()
    window = create_window("double_pendulum")
    window.show()
    spin(app, lambda: window.compiled is not None and window.store.main is not None, 120)
    editor = window.editor
    spin(app, lambda: "Equilibria" in editor.classification_card.text(), 120)
    window.show_tab("derivation")
    window.show_tab("equilibria")
    spin(app, lambda: window.textbook.equilibria.result is not None, 120)
    spin(app, lambda: False, 1.0)
    spin(app, lambda: not store().pending, 60)
    spin(app, lambda: False, 0.5)
    size = app.primaryScreen().availableGeometry()
    path = Path(folder) / f"typeset-{size.width()}x{size.height()}.png"
    window.grab().save(str(path))
    view = editor.derived
    formulas = [p for p in view.layout_.placed if p.kind == "formula"]
    report = {
        "horizontal": view.horizontalScrollBar().maximum(),
        "viewport": view.viewport().width(),
        "right": max(p.rect.right() for p in formulas),
        "formulas": len(formulas),
        "broken": sum(len(p.rows) > 1 for p in formulas),
        "card": editor.classification_card.formulas_set(),
        "status": window.textbook.equilibria.status.formulas_set(),
    }
    window.close()
    return report


@pytest.fixture(scope="module")
def reports(tmp_path_factory):
    from tests.explorer.screens import measure_screens

    return measure_screens(__file__, SCREENS, tmp_path_factory.mktemp("typeset"))


@pytest.mark.soak  # screen-size tests, as tests/explorer/test_window_fits_screen.py
@pytest.mark.parametrize("size", SCREENS, ids=lambda s: f"{s[0]}x{s[1]}")
def test_on_a_laptop_screen_the_window_shows_every_formula_set_and_in_the_dock(reports, size):
    report = reports[size]
    assert report["horizontal"] == 0 and report["right"] <= report["viewport"], report
    assert report["formulas"] >= 20 and report["broken"] >= 4, report
    assert report["card"] >= 2 and report["status"] >= 2, report


if __name__ == "__main__":
    import json

    print(json.dumps(measure(sys.argv[1])), flush=True)
    # the report is out, whole: leave without Python's teardown of a QApplication that
    # still holds the closed window (it crashed once with SIGSEGV there, at load, after a
    # complete report; the app's own exit is tested by the sessions' `--exit` replays)
    os._exit(0)
