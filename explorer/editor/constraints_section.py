"""The editor's Constraints section: holonomic, nonholonomic and unilateral lists.

Each kind of ``systems.scene.CONSTRAINT_KINDS`` is a list of expression fields with Add
and Remove. A blank entry is left out of the document (it is nothing typed), so entry
``i`` of the document is the ``i``-th entry that is not blank: that is how an error of
field ``constraints.holonomic[1]`` finds its field. An error of a whole kind
(``constraints.nonholonomic``: not supported yet, not independent) is shown under the
kind's title; the entries keep their text.
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from typing import Any

from PySide6.QtCore import Qt, Signal
from PySide6.QtWidgets import QHBoxLayout, QLabel, QPushButton, QVBoxLayout, QWidget

from explorer.editor.collapsible import CollapsibleSection
from explorer.editor.fields import ExpressionField, error_html, never_widens

TITLES = {
    "holonomic": "Holonomic: f(q, t) = 0",
    "nonholonomic": "Nonholonomic: a(q, t)·q̇ + b(q, t) = 0",
    "unilateral": "Unilateral: g(q, t) ≥ 0",
}


def _kinds() -> dict[str, tuple[str, str]]:
    from systems.scene import CONSTRAINT_KINDS

    return CONSTRAINT_KINDS


class ConstraintList(QWidget):
    """The entries of one kind of constraint.

    Signals
    -------
    edited()                an entry was typed, added or removed
    action_requested(str)   the quick-fix link of an error shown in an entry was clicked
    """

    edited = Signal()
    action_requested = Signal(str)

    def __init__(self, kind: str, meaning: str, example: str, parent: QWidget | None = None):
        super().__init__(parent)
        self.kind = kind
        self.example = example
        self.fields: list[ExpressionField] = []
        self._rows: list[QWidget] = []
        self._filling = False
        title = QLabel(f"<b>{TITLES.get(kind, kind)}</b>")
        title.setWordWrap(True)
        title.setToolTip(f"{kind}: {meaning}, e.g. {example}")
        self.error = QLabel()
        never_widens(self.error)
        self.error.setVisible(False)
        self.entries = QVBoxLayout()
        self.entries.setSpacing(2)
        self.add_button = QPushButton(f"Add {kind}")
        self.add_button.setToolTip(f"Add a {kind} constraint: {meaning}")
        self.add_button.clicked.connect(lambda: self.add_entry())
        buttons = QHBoxLayout()
        buttons.addWidget(self.add_button)
        buttons.addStretch(1)
        layout = QVBoxLayout(self)
        layout.setContentsMargins(0, 0, 0, 0)
        layout.setSpacing(2)
        layout.addWidget(title)
        layout.addWidget(self.error)
        layout.addLayout(self.entries)
        layout.addLayout(buttons)

    def set_entries(self, texts: list[str]) -> None:
        """Show ``texts``, one field each."""
        self._filling = True
        try:
            while self.fields:
                self._drop(0)
            for text in texts:
                self._add(text)
        finally:
            self._filling = False

    def texts(self) -> list[str]:
        """The entries that are not blank, as typed (stripped)."""
        return [f.text().strip() for f in self.fields if f.text().strip()]

    def add_entry(self, text: str = "") -> ExpressionField:
        """Add an entry (blank: left out of the document until something is typed)."""
        field = self._add(text)
        field.edit.setFocus()
        if text.strip():
            self._on_edited()
        return field

    def remove_entry(self, field: ExpressionField) -> None:
        """Remove an entry."""
        self._drop(self.fields.index(field))
        self._on_edited()

    def _add(self, text: str) -> ExpressionField:
        field = ExpressionField(f"e.g. {self.example}")
        field.set_text(text)
        field.edited.connect(self._on_edited)
        field.action_requested.connect(self.action_requested)
        remove = QPushButton("Remove")
        remove.setToolTip("Remove this constraint")
        remove.clicked.connect(lambda _checked=False, f=field: self.remove_entry(f))
        row = QWidget()
        layout = QHBoxLayout(row)
        layout.setContentsMargins(0, 0, 0, 0)
        layout.addWidget(field, 1)
        layout.addWidget(remove, 0, Qt.AlignmentFlag.AlignTop)
        self.fields.append(field)
        self._rows.append(row)
        self.entries.addWidget(row)
        return field

    def _drop(self, index: int) -> None:
        self.fields.pop(index)
        row = self._rows.pop(index)
        self.entries.removeWidget(row)
        row.hide()
        row.deleteLater()

    def _on_edited(self) -> None:
        if not self._filling:
            self.edited.emit()

    def clear_errors(self) -> None:
        self.error.clear()
        self.error.setVisible(False)
        for field in self.fields:
            field.clear_error()

    def show_problem(
        self, rest: str, reason: str, position: int | None, action: tuple[str, str] | None
    ) -> None:
        """Show a problem of ``constraints.<kind><rest>`` (``rest``: ``""`` or ``"[i]"``)."""
        match = re.fullmatch(r"\[(\d+)\]", rest)
        typed = [f for f in self.fields if f.text().strip()]
        if match is not None and int(match.group(1)) < len(typed):
            typed[int(match.group(1))].show_error(reason, position, action)
            return
        self.error.setText(error_html(reason, None, None))
        self.error.setVisible(True)


class ConstraintsSection(CollapsibleSection):
    """``[constraints]``: a list per kind, folded while empty.

    Signals
    -------
    edited()                an entry was typed, added or removed
    action_requested(str)   the quick-fix link of an error shown in an entry was clicked
    """

    edited = Signal()
    action_requested = Signal(str)

    def __init__(self, parent: QWidget | None = None):
        super().__init__("Constraints", parent)
        self.toggle.setToolTip("Equations and inequalities that tie the coordinates together")
        self.lists: dict[str, ConstraintList] = {}
        self.general_error = QLabel()
        never_widens(self.general_error)
        self.general_error.setVisible(False)
        self.content.addWidget(self.general_error)
        for kind, (meaning, example) in _kinds().items():
            entries = ConstraintList(kind, meaning, example)
            entries.edited.connect(self._on_edited)
            entries.action_requested.connect(self.action_requested)
            self.lists[kind] = entries
            self.content.addWidget(entries)

    def set_constraints(self, table: Any) -> None:
        """Show a ``[constraints]`` table; unfolded if it has entries."""
        table = table if isinstance(table, Mapping) else {}
        for kind, entries in self.lists.items():
            value = table.get(kind, [])
            texts = value if isinstance(value, list) else [value]
            entries.set_entries([_text(v) for v in texts])
        self.clear_errors()
        self._update_summary()
        self.set_expanded(any(entries.fields for entries in self.lists.values()))

    def table(self) -> dict:
        """The ``[constraints]`` table as typed: the kinds with entries, in order."""
        return {kind: e.texts() for kind, e in self.lists.items() if e.texts()}

    def clear_errors(self) -> None:
        self.general_error.clear()
        self.general_error.setVisible(False)
        for entries in self.lists.values():
            entries.clear_errors()

    def show_problem(
        self,
        field: str,
        reason: str,
        position: int | None = None,
        action: tuple[str, str] | None = None,
    ) -> bool:
        """Show a problem of field ``constraints...`` at its entry; False if not one."""
        if field != "constraints" and not field.startswith("constraints."):
            return False
        self.set_expanded(True)
        rest = field[len("constraints.") :]
        kind = next((k for k in self.lists if rest == k or rest.startswith(f"{k}[")), None)
        if kind is None:
            self.general_error.setText(error_html(f"{field}: {reason}", None, None))
            self.general_error.setVisible(True)
        else:
            self.lists[kind].show_problem(rest[len(kind) :], reason, position, action)
        return True

    def _on_edited(self) -> None:
        self._update_summary()
        self.edited.emit()

    def _update_summary(self) -> None:
        counts = [(kind, len(e.texts())) for kind, e in self.lists.items()]
        self.set_summary(", ".join(f"{n} {kind}" for kind, n in counts if n))


def _text(value: Any) -> str:
    if isinstance(value, bool):
        return str(value).lower()
    return "" if value is None else str(value)
