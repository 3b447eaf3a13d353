"""An expression field: text that wraps over a few lines, with an inline error under it.

The field grows with its text from one line to ``MAX_LINES`` lines (then it scrolls), so a
long T or V stays in sight. An expression is one line of text: Enter inserts nothing and
pasted line breaks become spaces, so positions in error messages are columns of that line.
An error is shown under the field (the reason, and the stretch of text around the position
with a caret under it) and the character at that position is marked in the field itself.
Error text wraps to the width the field has and never asks for more (``never_widens``):
the stretch shown is cut to what fits, so a long message cannot widen the editor.
"""

from __future__ import annotations

import html

from PySide6.QtCore import QMimeData, Qt, Signal
from PySide6.QtGui import (
    QColor,
    QFontMetrics,
    QKeyEvent,
    QTextCharFormat,
    QTextCursor,
    QTextOption,
)
from PySide6.QtWidgets import QFrame, QLabel, QSizePolicy, QTextEdit, QVBoxLayout, QWidget

ERROR_STYLE = "QTextEdit { border: 1px solid #d62728; background: #fff3f3; }"
MAX_LINES = 4
"""Lines a field grows to before it scrolls."""
EXCERPT = 44
"""Characters of the text shown around an error's position under a field, at most."""
EXCERPT_LEAST = 12
"""... and at least, however narrow the field."""


def never_widens(label: QLabel) -> QLabel:
    """Make ``label`` wrap to the width its layout gives it and never ask for more: a long
    message, even one unbroken word, cannot widen the editor (and add a scroll bar)."""
    policy = label.sizePolicy()
    policy.setHorizontalPolicy(QSizePolicy.Policy.Ignored)
    label.setSizePolicy(policy)
    label.setWordWrap(True)
    return label


def error_html(
    reason: str,
    text: str | None,
    position: int | None,
    action: tuple[str, str] | None = None,
    width: int = EXCERPT,
) -> str:
    """The reason, and when a position is known the text with a caret under that column.

    A text longer than ``width`` characters is cut to the stretch around the position
    (``…`` marks a cut), so the caret stays in sight in a narrow panel. ``action`` is a
    ``(link, label)`` offered under it as a link (a quick fix).
    """
    where = f" (position {position})" if text is not None and position else ""
    lines = [f"<span style='color:#b00020'>{html.escape(reason)}{where}</span>"]
    if text is not None and position:
        shown, column = excerpt(text, position, width)
        caret = " " * (column - 1) + "^"
        lines.append(f"<pre style='margin:0; color:#b00020'>{html.escape(shown)}\n{caret}</pre>")
    if action is not None:
        link, label = action
        lines.append(f"<a href='{html.escape(link)}'>{html.escape(label)}</a>")
    return "".join(lines)


def excerpt(text: str, position: int, width: int = EXCERPT) -> tuple[str, int]:
    """``(stretch, column)``: at most ``width`` characters of ``text`` around the 1-based
    ``position``, and the position's column in that stretch (``…`` marks a cut)."""
    text = text.replace("\n", " ")
    if len(text) <= width:
        return text, position
    start = max(0, min(position - 1 - width // 2, len(text) - width))
    shown = text[start : start + width]
    column = position - start
    if start > 0:
        shown, column = "…" + shown, column + 1
    if start + width < len(text):
        shown += "…"
    return shown, column


class ExpressionEdit(QTextEdit):
    """Plain text that wraps and grows to ``MAX_LINES`` lines; Enter inserts nothing."""

    def __init__(self, parent: QWidget | None = None):
        super().__init__(parent)
        self.setAcceptRichText(False)
        self.setTabChangesFocus(True)
        self.setLineWrapMode(QTextEdit.LineWrapMode.WidgetWidth)
        self.setWordWrapMode(QTextOption.WrapMode.WrapAtWordBoundaryOrAnywhere)
        self.setHorizontalScrollBarPolicy(Qt.ScrollBarPolicy.ScrollBarAlwaysOff)
        self.setVerticalScrollBarPolicy(Qt.ScrollBarPolicy.ScrollBarAsNeeded)
        self.setSizePolicy(QSizePolicy.Policy.Expanding, QSizePolicy.Policy.Fixed)
        self.document().setDocumentMargin(2)
        self.document().contentsChanged.connect(self._fit_height)
        self._fit_height()

    def _line_height(self) -> int:
        return self.fontMetrics().lineSpacing()

    def _frame(self) -> int:
        margins = self.contentsMargins()
        document = round(2 * self.document().documentMargin())
        return margins.top() + margins.bottom() + document

    def _fit_height(self) -> None:
        self.document().setTextWidth(self.viewport().width())
        lines = round(self.document().size().height() - 2 * self.document().documentMargin())
        line = self._line_height()
        wanted = min(max(lines, line), MAX_LINES * line)
        height = wanted + self._frame()
        if height != self.height() or self.minimumHeight() != height:
            self.setFixedHeight(height)

    def resizeEvent(self, event) -> None:  # noqa: N802 - Qt's name
        super().resizeEvent(event)
        self._fit_height()

    def keyPressEvent(self, event: QKeyEvent) -> None:  # noqa: N802 - Qt's name
        if event.key() in (Qt.Key.Key_Return, Qt.Key.Key_Enter):
            event.ignore()  # an expression is one line: Enter is left to the dialog or form
            return
        super().keyPressEvent(event)

    def insertFromMimeData(self, source: QMimeData) -> None:  # noqa: N802 - Qt's name
        text = source.text().replace("\r\n", " ").replace("\n", " ").replace("\r", " ")
        self.insertPlainText(text)


class ExpressionField(QWidget):
    """An expression's text and its inline error; ``show_error`` keeps the text as typed.

    Signals
    -------
    edited()                the user changed the text (not emitted by ``set_text``)
    action_requested(str)   the quick-fix link of the error shown was clicked: its link
    """

    edited = Signal()
    action_requested = Signal(str)

    def __init__(self, placeholder: str = "", parent: QWidget | None = None):
        super().__init__(parent)
        self.edit = ExpressionEdit()
        self.edit.setPlaceholderText(placeholder)
        font = self.edit.font()
        font.setFamily("monospace")
        font.setStyleHint(font.StyleHint.Monospace)
        self.edit.setFont(font)
        self.edit._fit_height()
        self.error_label = never_widens(QLabel())
        self.error_label.setVisible(False)
        self.error_label.setTextInteractionFlags(
            Qt.TextInteractionFlag.TextSelectableByMouse
            | Qt.TextInteractionFlag.LinksAccessibleByMouse
        )
        self.error_label.setFrameShape(QFrame.Shape.NoFrame)
        self.error_label.linkActivated.connect(self.action_requested)
        layout = QVBoxLayout(self)
        layout.setContentsMargins(0, 0, 0, 0)
        layout.setSpacing(1)
        layout.addWidget(self.edit)
        layout.addWidget(self.error_label)
        self._setting = False
        self._error: tuple | None = None  # (reason, position, action) shown, to fit again
        self.edit.textChanged.connect(self._on_edit_text_changed)

    def text(self) -> str:
        """The text as typed."""
        return self.edit.toPlainText()

    def set_text(self, text: str | None) -> None:
        """Show ``text`` (None: empty) without emitting ``edited``; the cursor goes to the end."""
        text = text or ""
        if text == self.text():
            return
        self._setting = True
        try:
            self.edit.setPlainText(text)
            self.edit.moveCursor(QTextCursor.MoveOperation.End)
        finally:
            self._setting = False

    def show_error(
        self, reason: str, position: int | None = None, action: tuple[str, str] | None = None
    ) -> None:
        """Show ``reason`` under the field and mark ``position`` (1-based) in the text;
        ``action`` (link, label) is offered as a quick fix (``action_requested``)."""
        self._error = (reason, position, action)
        self._show_error_text()
        self.error_label.setVisible(True)
        self.edit.setStyleSheet(ERROR_STYLE)  # the cursor stays put: the user may be typing
        self._mark(position)

    def _excerpt_width(self) -> int:
        """The characters of text the error's stretch may show in the field's width."""
        font = self.edit.font()
        advance = max(QFontMetrics(font).horizontalAdvance("m"), 1)
        fits = (self.width() - 8) // advance - 2  # the two ``…`` of a cut
        return max(EXCERPT_LEAST, min(EXCERPT, fits))

    def _show_error_text(self) -> None:
        reason, position, action = self._error
        width = self._excerpt_width()
        self._error_width = width
        self.error_label.setText(error_html(reason, self.text(), position, action, width))

    def resizeEvent(self, event) -> None:  # noqa: N802 - Qt's name
        super().resizeEvent(event)
        if self._error is not None and self._excerpt_width() != self._error_width:
            self._show_error_text()

    def clear_error(self) -> None:
        """Remove the error under the field and its mark."""
        self._error = None
        self.error_label.setVisible(False)
        self.error_label.clear()
        self.edit.setStyleSheet("")
        self._mark(None)

    @property
    def has_error(self) -> bool:
        """Whether an error is shown under the field."""
        return not self.error_label.isHidden()

    def _mark(self, position: int | None) -> None:
        selections = []
        length = len(self.text())
        if position and length:
            cursor = QTextCursor(self.edit.document())
            index = min(position, length) - 1
            cursor.setPosition(index)
            cursor.setPosition(index + 1, QTextCursor.MoveMode.KeepAnchor)
            marked = QTextEdit.ExtraSelection()
            marked.cursor = cursor
            style = QTextCharFormat()
            style.setBackground(QColor("#ffb3b3"))
            style.setUnderlineStyle(QTextCharFormat.UnderlineStyle.WaveUnderline)
            style.setUnderlineColor(QColor("#b00020"))
            marked.format = style
            selections.append(marked)
        self.edit.setExtraSelections(selections)

    def _on_edit_text_changed(self) -> None:
        if self._setting:
            return
        self._mark(None)  # the mark would drift as the text changes
        self.edited.emit()
