"""The derivation typeset in the window, copied as LaTeX and exported (issue 25, item 2).

The Derivation tab shows each equation as an image of the mathematics (the glyph outlines
``systems.typeset`` made in a worker, scaled to the view's font and painted in its
palette's colour), with "Copy as LaTeX" on each; the whole derivation exports to PDF,
SVG and LaTeX, from the window and from ``derive --out``. Screenshot tests at 1280 x 720
and 1366 x 768 (offscreen, a process per screen size) look at the real window: the
derivation is shown as images of equations, in sight, none clipped by its neighbour.
The screenshots are in the test's temporary folder (``derivation-<W>x<H>*.png``).
"""

from __future__ import annotations

import json
import os
import sys
from pathlib import Path

import pytest
from PySide6.QtCore import QPoint, QRectF, Qt
from PySide6.QtGui import QColor, QFont, QPalette

from systems.mechanics import derive
from systems.scene import load_scene
from systems.typeset import Formula, typeset_derivation

SCREENS = [(1280, 720), (1366, 768)]


@pytest.fixture(scope="module")
def pendulum():
    return typeset_derivation(derive(load_scene("double_pendulum")))


@pytest.fixture
def view(qtbot, pendulum):
    from explorer.editor.derivation_view import DerivationView

    view = DerivationView()
    qtbot.addWidget(view)
    view.resize(420, 600)
    view.show()
    view.set_typeset(pendulum)
    qtbot.waitExposed(view)
    return view


def ink(image, rect: QRectF, background: QColor) -> int:
    """Pixels of ``image`` in ``rect`` that differ from ``background``."""
    count = 0
    r = rect.toRect().intersected(image.rect())
    for y in range(r.top(), r.bottom(), 2):
        for x in range(r.left(), r.right(), 2):
            if image.pixelColor(x, y) != background:
                count += 1
    return count


def test_the_equations_are_drawn_as_images_in_the_view_s_colour(view):
    rects = view.formula_rects()
    assert len(rects) == len([f for f in view.typeset.formulas if f.outline is not None])
    image = view.viewport().grab().toImage()
    background = view.palette().color(QPalette.ColorRole.Base)
    in_sight = [r for r in rects if r.bottom() < view.viewport().height()]
    assert len(in_sight) >= 3
    for rect in in_sight:
        assert ink(image, rect, background) > 10, rect
    # formulas never overlap each other
    ordered = sorted(rects, key=lambda r: r.top())
    for above, below in zip(ordered, ordered[1:], strict=False):
        assert above.bottom() <= below.top() + 0.5
    from explorer.equations import _PIXMAPS

    assert _PIXMAPS  # drawn from cached images


def test_the_equations_follow_the_font_and_the_palette(view):
    """Presentation mode's larger font makes the equations larger; a dark palette draws
    them light."""
    small = view.formula_rects()[0].height()
    font = QFont(view.font())
    font.setPointSizeF(font.pointSizeF() * 1.6)
    view.setFont(font)
    assert view.formula_rects()[0].height() > 1.4 * small
    palette = QPalette(view.palette())
    palette.setColor(QPalette.ColorRole.Base, QColor("#202020"))
    palette.setColor(QPalette.ColorRole.Text, QColor("#f0f0f0"))
    view.setPalette(palette)
    image = view.viewport().grab().toImage()
    rect = view.formula_rects()[0].toRect().intersected(image.rect())
    lightest = max(
        image.pixelColor(x, y).lightness()
        for y in range(rect.top(), rect.bottom())
        for x in range(rect.left(), rect.right())
    )
    assert lightest > 200


def test_copy_as_latex_on_each_equation(qtbot, view):
    from PySide6.QtWidgets import QApplication

    rect = view.formula_rects()[2]
    point = QPoint(int(rect.left() + 30), int(rect.center().y()))
    index, formula = view.formula_at(point)
    menu = view.context_menu(point)
    actions = {a.text(): a for a in menu.actions()}
    assert {"Copy as LaTeX", "Copy as text", "Export derivation…"} <= set(actions)
    actions["Copy as LaTeX"].trigger()
    assert QApplication.clipboard().text() == formula.latex
    assert "\\" in formula.latex or "=" in formula.latex
    actions["Copy as text"].trigger()
    assert QApplication.clipboard().text() == formula.text
    # a click selects the equation; Ctrl+C copies its LaTeX
    view.selected = -1
    qtbot.mouseClick(view.viewport(), Qt.MouseButton.LeftButton, pos=point)
    assert view.selected == index
    QApplication.clipboard().clear()
    qtbot.keyClick(view, Qt.Key.Key_C, Qt.KeyboardModifier.ControlModifier)
    assert QApplication.clipboard().text() == formula.latex
    menu = view.context_menu(QPoint(2, 2))  # the title: no equation there
    texts = [a.text() for a in menu.actions()]
    assert "Copy as LaTeX" not in texts and "Copy the derivation as LaTeX" in texts


def test_an_equation_mathtext_refused_is_shown_as_text(qtbot, view, pendulum):
    import dataclasses

    parts = list(pendulum.parts)
    first = next(i for i, p in enumerate(parts) if isinstance(p, Formula))
    parts[first] = dataclasses.replace(parts[first], outline=None)
    view.set_typeset(dataclasses.replace(pendulum, parts=tuple(parts)))
    kinds = {p.index: p.kind for p in view.layout_.placed}
    assert kinds[first] == "text"
    view.viewport().grab()  # paints without raising


def test_plain_text_and_restore(view, pendulum):
    state = view.state()
    view.set_plain("deriving…")
    assert view.plain_text() == "deriving…" and view.typeset is None
    view.viewport().grab()
    view.restore(state)
    assert view.typeset is pendulum


@pytest.mark.parametrize("suffix", [".pdf", ".svg", ".tex"])
def test_export_the_derivation(view, tmp_path, suffix):
    path = tmp_path / f"derivation{suffix}"
    view.export(path)
    data = path.read_bytes()
    assert len(data) > 1000
    if suffix == ".pdf":
        assert data.startswith(b"%PDF")
    elif suffix == ".svg":
        assert b"<svg" in data and b"<path" in data
    else:
        assert data.decode().count(r"\begin{equation*}") == len(view.typeset.formulas)


def test_the_editor_shows_text_or_a_typeset_derivation(qtbot, pendulum, tmp_path):
    from explorer.editor.editor_panel import SystemEditorPanel

    editor = SystemEditorPanel()
    qtbot.addWidget(editor)
    editor.show_derivation("L = ...\n" * 3)
    assert editor.derived.plain_text() == "L = ...\n" * 3
    editor.show_derivation(pendulum)
    assert editor.derived.typeset is pendulum
    assert editor.export_derivation(str(tmp_path / "d.pdf"))
    assert not editor.export_derivation(str(tmp_path / "no" / "such" / "d.pdf"))
    assert "not exported" in editor.state_label.text()
    editor.shutdown()


def test_derive_prints_latex_and_writes_handouts(tmp_path, capsys):
    from explorer.cli import main

    assert main(["derive", "simple_pendulum", "--latex"]) == 0
    out = capsys.readouterr().out
    assert r"\ddot{\theta} = - \frac{g \sin{\left(\theta \right)}}{l}" in out
    for suffix in (".pdf", ".svg", ".tex", ".txt"):
        path = tmp_path / f"pendulum{suffix}"
        assert main(["derive", "simple_pendulum", "--out", str(path)]) == 0
        assert path.stat().st_size > 100
    assert "Lagrange's equations" in (tmp_path / "pendulum.txt").read_text()
    assert main(["derive", "simple_pendulum", "--out", str(tmp_path / "p.doc")]) == 2
    assert main(["derive", "simple_pendulum", "--json", "--out", str(tmp_path / "p.pdf")]) == 2
    assert not (tmp_path / "p.pdf").exists()


# -- screenshots of the window ------------------------------------------------------------


def shoot(scene: str, folder: str) -> dict:
    """Open the window as ``main.py`` does, bring the Derivation tab forward, wait for
    the equations set in type, and look (run in a process whose screen has the size)."""
    from explorer.app import application, create_window
    from tests.explorer.screens import spin

    app = application()
    window = create_window(scene)
    window.show()
    editor = window.editor
    editor.tabs.setCurrentIndex(1)
    view = editor.derived

    def typeset() -> bool:
        return view.typeset is not None and all(
            f.outline is not None for f in view.typeset.formulas
        )

    spin(app, typeset, 180)
    spin(app, lambda: False, 0.5)
    available = app.primaryScreen().availableGeometry()
    name = f"derivation-{available.width()}x{available.height()}"
    window.grab().save(str(Path(folder) / f"{name}.png"))
    view.grab().save(str(Path(folder) / f"{name}-tab.png"))
    image = view.viewport().grab().toImage()
    background = view.palette().color(QPalette.ColorRole.Base)
    height = view.viewport().height()
    drawn = [
        [rect.height(), ink(image, rect, background)]
        for rect in view.formula_rects()
        if rect.bottom() <= height
    ]
    top_left = view.mapToGlobal(QPoint(0, 0))
    report = {
        "typeset": typeset(),
        "available": available.getRect(),
        "view": [top_left.x(), top_left.y(), view.width(), view.height()],
        "visible": view.isVisible(),
        "drawn": drawn,
        "em": view.layout_.em,
        "font_pixels": view.fontInfo().pixelSize(),
    }
    window.close()
    return report


@pytest.fixture(scope="module")
def screenshots(tmp_path_factory):
    from tests.explorer.screens import measure_screens

    folder = tmp_path_factory.mktemp("derivation")
    return measure_screens(__file__, SCREENS, folder, ["double_pendulum", str(folder)])


@pytest.mark.soak  # screen-size tests, as tests/explorer/test_window_fits_screen.py
@pytest.mark.parametrize("size", SCREENS, ids=lambda s: f"{s[0]}x{s[1]}")
def test_the_window_shows_the_derivation_as_images_of_equations(screenshots, size):
    report = screenshots[size]
    assert report["typeset"] and report["visible"]
    ax, ay, aw, ah = report["available"]
    x, y, w, h = report["view"]
    assert ax <= x and ay <= y and x + w <= ax + aw and y + h <= ay + ah, report
    assert w >= 250 and h >= 150, report
    drawn = report["drawn"]
    assert len(drawn) >= 2, report  # equations in sight as soon as the tab is shown
    assert all(ink > 10 for _, ink in drawn), report
    # as large as the text around them: readable at this screen size
    assert report["em"] >= report["font_pixels"], report
    assert all(height >= report["font_pixels"] for height, _ in drawn), report


if __name__ == "__main__":
    print(json.dumps(shoot(sys.argv[1], sys.argv[2])), flush=True)
    # the report is out, whole: leave without Python's teardown of a QApplication that
    # still holds the closed window (it crashed once with SIGSEGV there, at load, after a
    # complete report; the app's own exit is tested by the sessions' `--exit` replays)
    os._exit(0)
