"""The Derivation tab's view: the classification card and the derivation, typeset.

One scroll area (no nested scroll boxes): the derivation's headings, sentences and
equations, then the classification card (the method, the equilibria), as
``explorer.equations.DerivationLayout`` places them in the view's width, in the view's
font (presentation mode's larger font included) and its palette's text colour. Only
what is in sight is painted, each equation from its cached image. A click selects an
equation; Ctrl+C or the context menu copies it as LaTeX
(or as text); the menu also copies the whole derivation and exports it (PDF, SVG, LaTeX).
"""

from __future__ import annotations

from PySide6.QtCore import QEvent, QPointF, QRectF, Qt, Signal
from PySide6.QtGui import QKeySequence, QPainter, QPalette
from PySide6.QtWidgets import QAbstractScrollArea, QApplication, QMenu, QSizePolicy

from explorer.equations import DerivationLayout, write_derivation
from systems.typeset import Formula, Typeset


class DerivationView(QAbstractScrollArea):
    """The classification card and the typeset derivation, scrolled as one.

    Signals
    -------
    export_requested()   the user chose "Export derivation…" in the context menu
    copied(str)          what was put on the clipboard
    """

    export_requested = Signal()
    copied = Signal(str)

    def __init__(self, parent=None):
        super().__init__(parent)
        self.layout_ = DerivationLayout(self.font(), self.palette())
        self.selected = -1
        self.setFocusPolicy(Qt.FocusPolicy.StrongFocus)
        self.setHorizontalScrollBarPolicy(Qt.ScrollBarPolicy.ScrollBarAsNeeded)
        self.setVerticalScrollBarPolicy(Qt.ScrollBarPolicy.ScrollBarAsNeeded)
        self.setSizePolicy(QSizePolicy.Policy.Ignored, QSizePolicy.Policy.Expanding)
        self.setMinimumHeight(120)
        self.viewport().setBackgroundRole(QPalette.ColorRole.Base)
        self.viewport().setAutoFillBackground(True)
        self.setToolTip("Right-click an equation to copy it as LaTeX")
        from explorer.inline_math import store

        store().ready.connect(self._relayout)  # the card's and sentences' formulas set

    # what is shown ----------------------------------------------------------------
    @property
    def typeset(self) -> Typeset | None:
        return self.layout_.typeset

    def set_typeset(self, typeset: Typeset | None) -> None:
        """Show a typeset derivation (an earlier one of the same scene is replaced,
        the scroll position kept)."""
        self.layout_.typeset = typeset
        self.layout_.plain = ""
        self.selected = -1
        self._relayout()

    def set_plain(self, text: str) -> None:
        """Show ``text`` instead of a derivation (``deriving…``, why it failed)."""
        self.layout_.typeset = None
        self.layout_.plain = text
        self.selected = -1
        self._relayout()

    def set_card(self, html: str) -> None:
        self.layout_.set_card(html)
        self._relayout()

    def card_html(self) -> str:
        return self.layout_.card_html

    def plain_text(self) -> str:
        """What is shown, as text: the derivation's text, or the message shown instead."""
        typeset = self.layout_.typeset
        return typeset.text if typeset is not None else self.layout_.plain

    def state(self) -> tuple:
        """What ``restore`` puts back (the window's refused opening shows it again)."""
        return (self.layout_.typeset, self.layout_.plain)

    def restore(self, state: tuple) -> None:
        typeset, plain = state
        if typeset is not None:
            self.set_typeset(typeset)
        else:
            self.set_plain(plain)

    def formula_at(self, point) -> tuple[int, Formula] | None:
        """The equation at a viewport point: its index in the typeset and itself."""
        placed = self.layout_.at(self._to_content(QPointF(point)))
        if placed is None or not isinstance(placed.part, Formula):
            return None
        return placed.index, placed.part

    def formula_rects(self) -> list[QRectF]:
        """Where the typeset equations are, in content coordinates (for tests)."""
        return [p.rect for p in self.layout_.placed if p.kind == "formula"]

    # copying and exporting ------------------------------------------------------------
    def copy_formula(self, formula: Formula, latex: bool = True) -> str:
        """Put ``formula`` on the clipboard as LaTeX (its text where it has none)."""
        text = formula.latex if latex and formula.latex is not None else formula.text
        return self._copy(text)

    def copy_all(self, latex: bool = True) -> str:
        """Put the whole derivation on the clipboard: a LaTeX document, or its text."""
        typeset = self.layout_.typeset
        if typeset is None:
            return self._copy(self.layout_.plain)
        return self._copy(typeset.latex_document() if latex else typeset.text)

    def _copy(self, text: str) -> str:
        QApplication.clipboard().setText(text)
        self.copied.emit(text)
        return text

    def export(self, path) -> None:
        """Write the derivation shown to ``path`` (.pdf, .svg or .tex)."""
        typeset = self.layout_.typeset
        if typeset is None:
            raise ValueError("there is no derivation to export yet")
        write_derivation(typeset, path, self.layout_.card_html, self.font())

    # layout ---------------------------------------------------------------------------
    def _relayout(self) -> None:
        layout = self.layout_
        layout.set_font(self.font())
        layout.set_palette(self.palette())
        layout.ratio = self.devicePixelRatioF() or 1.0
        width = max(self.viewport().width(), 80)
        layout.layout(width)
        bar = self.verticalScrollBar()
        bar.setRange(0, max(0, int(layout.height - self.viewport().height())))
        bar.setPageStep(self.viewport().height())
        bar.setSingleStep(max(8, int(layout.em)))
        across = self.horizontalScrollBar()
        across.setRange(0, max(0, int(layout.content_width - width)))
        across.setPageStep(width)
        self.viewport().update()

    def _to_content(self, point: QPointF) -> QPointF:
        return point + QPointF(self.horizontalScrollBar().value(), self.verticalScrollBar().value())

    def resizeEvent(self, event) -> None:
        super().resizeEvent(event)
        self._relayout()

    def changeEvent(self, event) -> None:
        super().changeEvent(event)
        if event.type() in (QEvent.Type.FontChange, QEvent.Type.PaletteChange):
            self._relayout()

    def scrollContentsBy(self, dx: int, dy: int) -> None:
        self.viewport().update()

    def paintEvent(self, event) -> None:
        painter = QPainter(self.viewport())
        try:
            dx, dy = self.horizontalScrollBar().value(), self.verticalScrollBar().value()
            painter.translate(-dx, -dy)
            exposed = QRectF(event.rect()).translated(dx, dy)
            self.layout_.paint(painter, exposed, self.selected)
        except Exception:  # noqa: BLE001 - painting never raises into Qt
            pass
        finally:
            painter.end()

    # the mouse and the keyboard ------------------------------------------------------
    def mousePressEvent(self, event) -> None:
        found = self.formula_at(event.position())
        self.selected = found[0] if found else -1
        self.viewport().update()
        super().mousePressEvent(event)

    def keyPressEvent(self, event) -> None:
        if event.matches(QKeySequence.StandardKey.Copy):
            formula = self.selected_formula()
            if formula is not None:
                self.copy_formula(formula)
            else:
                self.copy_all()
            return
        super().keyPressEvent(event)

    def selected_formula(self) -> Formula | None:
        typeset = self.layout_.typeset
        if typeset is None or not 0 <= self.selected < len(typeset.parts):
            return None
        part = typeset.parts[self.selected]
        return part if isinstance(part, Formula) else None

    def context_menu(self, point) -> QMenu:
        """The menu at a viewport point: the equation's copies there, then the whole's."""
        menu = QMenu(self)
        found = self.formula_at(point)
        inline = self.layout_.inline_at(self._to_content(QPointF(point)))
        if found is None and inline is not None:
            latex = menu.addAction("Copy as LaTeX")
            latex.triggered.connect(lambda: self._copy(inline.latex))
            text = menu.addAction("Copy as text")
            text.triggered.connect(lambda: self._copy(inline.text))
            menu.addSeparator()
        if found is not None:
            index, formula = found
            self.selected = index
            self.viewport().update()
            latex = menu.addAction("Copy as LaTeX")
            latex.triggered.connect(lambda: self.copy_formula(formula))
            latex.setEnabled(formula.latex is not None)
            text = menu.addAction("Copy as text")
            text.triggered.connect(lambda: self.copy_formula(formula, latex=False))
            menu.addSeparator()
        whole = self.layout_.typeset is not None
        action = menu.addAction("Copy the derivation as LaTeX")
        action.triggered.connect(lambda: self.copy_all())
        action.setEnabled(whole)
        action = menu.addAction("Copy the derivation as text")
        action.triggered.connect(lambda: self.copy_all(latex=False))
        action = menu.addAction("Export derivation…")
        action.triggered.connect(self.export_requested.emit)
        action.setEnabled(whole)
        return menu

    def contextMenuEvent(self, event) -> None:
        self.context_menu(event.pos()).exec(event.globalPos())
