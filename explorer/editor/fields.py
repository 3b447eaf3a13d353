"""An expression field: a line edit with an inline error under it that points at the position."""

from __future__ import annotations

import html

from PySide6.QtCore import Signal
from PySide6.QtWidgets import QLabel, QLineEdit, QVBoxLayout, QWidget

ERROR_STYLE = "QLineEdit { border: 1px solid #d62728; background: #fff3f3; }"


def error_html(reason: str, text: str | None, position: int | None) -> str:
    """The reason, and when a position is known the text with a caret under that column."""
    lines = [f"<span style='color:#b00020'>{html.escape(reason)}</span>"]
    if text is not None and position:
        caret = " " * (position - 1) + "^"
        lines.append(
            "<pre style='margin:0; color:#b00020'>"
            f"{html.escape(text)}\n{caret} position {position}</pre>"
        )
    return "".join(lines)


class ExpressionField(QWidget):
    """A labelled line edit for an expression; ``show_error`` keeps the text as typed."""

    edited = Signal()

    def __init__(self, placeholder: str = "", parent: QWidget | None = None):
        super().__init__(parent)
        self.edit = QLineEdit()
        self.edit.setPlaceholderText(placeholder)
        font = self.edit.font()
        font.setFamily("monospace")
        self.edit.setFont(font)
        self.error_label = QLabel()
        self.error_label.setWordWrap(True)
        self.error_label.setVisible(False)
        layout = QVBoxLayout(self)
        layout.setContentsMargins(0, 0, 0, 0)
        layout.setSpacing(1)
        layout.addWidget(self.edit)
        layout.addWidget(self.error_label)
        self.edit.textEdited.connect(self._on_edit_text_edited)

    def text(self) -> str:
        return self.edit.text()

    def set_text(self, text: str | None) -> None:
        self.edit.setText(text or "")

    def show_error(self, reason: str, position: int | None = None) -> None:
        self.error_label.setText(error_html(reason, self.edit.text(), position))
        self.error_label.setVisible(True)
        self.edit.setStyleSheet(ERROR_STYLE)  # the cursor stays put: the user may be typing

    def clear_error(self) -> None:
        self.error_label.setVisible(False)
        self.error_label.clear()
        self.edit.setStyleSheet("")

    @property
    def has_error(self) -> bool:
        return not self.error_label.isHidden()

    def _on_edit_text_edited(self, _text: str) -> None:
        self.edited.emit()
