"""The editor's Symmetries section: named generators, one component per coordinate.

A symmetry is a row: its name and a field xi_q for each coordinate (blank: 0, left out of
the document). The fields follow the coordinates: a coordinate renamed in place takes its
component along; a component typed for a coordinate that is gone stays, with the build's
error under it ("'theta' is not a coordinate"), until it is cleared or the coordinate
returns, so nothing typed disappears without a word. The document keeps each generator's
keys in the order they were read or first typed.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from PySide6.QtCore import Signal
from PySide6.QtWidgets import (
    QFormLayout,
    QHBoxLayout,
    QLabel,
    QPushButton,
    QVBoxLayout,
    QWidget,
)

from explorer.editor.collapsible import CollapsibleSection
from explorer.editor.fields import ExpressionField, error_html
from explorer.editor.named_rows import NamedRow, free_name, row_for_field, take_typed_name
from explorer.labels import coordinate_label


class SymmetryRow(NamedRow):
    """One generator: name, Remove, and a component field per coordinate."""

    def __init__(self, name: str, texts: dict[str, str], coordinates: tuple[str, ...]):
        super().__init__(name, "symmetry")
        self.name_edit.setToolTip(
            "The name of the conserved charge, if this is a symmetry (not H, L_x ... P_z or p_...)"
        )
        self.order = list(texts)  # the keys in the document's order
        self.components: dict[str, ExpressionField] = {}
        self.form = QFormLayout()
        self.form.setFieldGrowthPolicy(QFormLayout.FieldGrowthPolicy.AllNonFixedFieldsGrow)
        self.form.setContentsMargins(0, 0, 0, 0)
        head = QHBoxLayout()
        head.addWidget(QLabel("Symmetry"))
        head.addWidget(self.name_edit, 1)
        head.addStretch(1)
        head.addWidget(self.remove_button)
        layout = QFormLayout(self)
        layout.setContentsMargins(4, 4, 4, 4)
        layout.addRow(head)
        layout.addRow(self.name_error)
        layout.addRow(self.form)
        self.set_components(texts, coordinates)

    def texts(self) -> dict[str, str]:
        """Every component field's text, as typed."""
        return {q: field.text() for q, field in self.components.items()}

    def entry(self) -> dict[str, str]:
        """The generator as typed: the components that are not blank, in document order."""
        typed = {q: t.strip() for q, t in self.texts().items() if t.strip()}
        keys = [q for q in self.order if q in typed] + [q for q in typed if q not in self.order]
        return {q: typed[q] for q in keys}

    def set_components(self, texts: dict[str, str], coordinates: tuple[str, ...]) -> None:
        """A field for each coordinate and for each other key with text (kept as typed)."""
        keys = [*coordinates, *(q for q, t in texts.items() if t.strip() and q not in coordinates)]
        if keys == list(self.components) and texts == self.texts():
            return
        while self.form.rowCount():
            self.form.removeRow(0)
        self.components = {}
        for q in keys:
            field = ExpressionField(f"ξ for {q}(q); blank: 0")
            field.set_text(texts.get(q, ""))
            label = coordinate_label(q) if q.isidentifier() else q
            self.form.addRow(f"ξ<sub>{label}</sub> =", field)
            self.components[q] = field

    def clear_errors(self) -> None:
        self.clear_name_error()
        for field in self.components.values():
            field.clear_error()


class SymmetriesSection(CollapsibleSection):
    """``[symmetries]``: named generators, folded while there are none.

    Signals
    -------
    edited()                a component or a name was typed, a symmetry added or removed
    action_requested(str)   the quick-fix link of an error shown in a field was clicked
    """

    edited = Signal()
    action_requested = Signal(str)

    def __init__(self, parent: QWidget | None = None):
        super().__init__("Symmetries", parent)
        self.toggle.setToolTip("Continuous symmetries q -> q + eps xi(q), each with its charge")
        self.rows: list[SymmetryRow] = []
        self.coordinates: tuple[str, ...] = ()
        self._filling = False
        note = QLabel(
            "A generator ξ(q), one component per coordinate in the coordinates, numbers "
            "and parameters; its charge Σ p ξ is listed when L and the effects keep it."
        )
        note.setWordWrap(True)
        note.setStyleSheet("QLabel { color: #555; }")
        self.general_error = QLabel()
        self.general_error.setWordWrap(True)
        self.general_error.setVisible(False)
        self.add_button = QPushButton("Add symmetry")
        self.add_button.setToolTip("Add a generator; then type its components")
        self.add_button.clicked.connect(lambda: self.add_symmetry())
        buttons = QHBoxLayout()
        buttons.addWidget(self.add_button)
        buttons.addStretch(1)
        self.content.addWidget(note)
        self.content.addWidget(self.general_error)
        self.rows_box = QWidget()
        self.rows_layout = QVBoxLayout(self.rows_box)
        self.rows_layout.setContentsMargins(0, 0, 0, 0)
        self.rows_layout.setSpacing(4)
        self.content.addWidget(self.rows_box)
        self.content.addLayout(buttons)

    def set_symmetries(self, table: Any, coordinates: tuple[str, ...]) -> None:
        """Show a ``[symmetries]`` table for ``coordinates``; unfolded if it has entries."""
        self._filling = True
        try:
            for row in list(self.rows):
                self._drop_row(row)
            self.coordinates = tuple(coordinates)
            for name, entry in (table if isinstance(table, Mapping) else {}).items():
                entry = entry if isinstance(entry, Mapping) else {}
                self._add_row(str(name), {str(q): _text(v) for q, v in entry.items()})
            self.clear_errors()
        finally:
            self._filling = False
        self._update_summary()
        self.set_expanded(bool(self.rows))

    def set_coordinates(self, coordinates: tuple[str, ...], renamed: dict[str, str]) -> None:
        """Follow new coordinates; ``renamed`` (old -> new) take their components along."""
        self.coordinates = tuple(coordinates)
        for row in self.rows:
            texts = {renamed.get(q, q): t for q, t in row.texts().items()}
            row.order = [renamed.get(q, q) for q in row.order]
            row.set_components(texts, self.coordinates)
            self._connect(row)

    def table(self) -> dict:
        """The ``[symmetries]`` table as typed: name -> {coordinate: xi}."""
        return {row.accepted_name: row.entry() for row in self.rows}

    def names(self) -> list[str]:
        return [row.accepted_name for row in self.rows]

    def add_symmetry(self, name: str | None = None, **components: str) -> SymmetryRow:
        """Add a symmetry (``name`` None: a free name) with ``components`` (q -> xi)."""
        if name is None or name in self.names():
            name = free_name(name or "symmetry", self.names())
        row = self._add_row(name, dict(components))
        self.set_expanded(True)
        self._on_edited()
        return row

    def remove_symmetry(self, row: SymmetryRow) -> None:
        """Remove a symmetry."""
        self._drop_row(row)
        for other in self.rows:
            if other.typed_name() != other.accepted_name:
                take_typed_name(other, self.rows)
        self._on_edited()

    def _add_row(self, name: str, texts: dict[str, str]) -> SymmetryRow:
        row = SymmetryRow(name, texts, self.coordinates)
        row.name_edit.textEdited.connect(lambda _text, r=row: self._on_name_edited(r))
        row.remove_button.clicked.connect(lambda _checked=False, r=row: self.remove_symmetry(r))
        self._connect(row)
        self.rows.append(row)
        self.rows_layout.addWidget(row)
        return row

    def _connect(self, row: SymmetryRow) -> None:
        for field in row.components.values():
            if not field.property("connected"):
                field.edited.connect(self._on_edited)
                field.action_requested.connect(self.action_requested)
                field.setProperty("connected", True)

    def _drop_row(self, row: SymmetryRow) -> None:
        self.rows.remove(row)
        self.rows_layout.removeWidget(row)
        row.hide()
        row.deleteLater()

    def _on_name_edited(self, row: SymmetryRow) -> None:
        take_typed_name(row, self.rows)
        self._on_edited()

    def _on_edited(self) -> None:
        self._update_summary()
        if not self._filling:
            self.edited.emit()

    def _update_summary(self) -> None:
        count = len(self.rows)
        self.set_summary(f"{count} generator{'s' if count != 1 else ''}" if count else "")

    # -- problems -----------------------------------------------------------------------

    def clear_errors(self) -> None:
        self.general_error.clear()
        self.general_error.setVisible(False)
        for row in self.rows:
            row.clear_errors()

    def show_problem(
        self,
        field: str,
        reason: str,
        position: int | None = None,
        action: tuple[str, str] | None = None,
    ) -> bool:
        """Show a problem of field ``symmetries...`` where it belongs; False if not one."""
        if field != "symmetries" and not field.startswith("symmetries."):
            return False
        self.set_expanded(True)
        row, rest = row_for_field(self.rows, field[len("symmetries.") :])
        if row is None:
            self.general_error.setText(error_html(f"{field}: {reason}", None, None))
            self.general_error.setVisible(True)
        elif rest.startswith(".") and rest[1:] in row.components:
            row.components[rest[1:]].show_error(reason, position, action)
        else:
            row.show_name_error(f"{field}: {reason}" if rest else reason)
        return True


def _text(value: Any) -> str:
    if isinstance(value, bool):
        return str(value).lower()
    return "" if value is None else str(value)
