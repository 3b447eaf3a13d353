"""The editor's Particles section: the bodies whose positions give T, and gravity.

Each particle is a row: its name, its mass and the components x, y and (blank in the
plane) z of its position, as expressions. The gravity field takes a magnitude along -y
(``g``) or a vector (``0, 0, -g``, brackets optional); blank is no field. Everything is
kept as typed; the scene's own checks (``parse_scene``) say what is wrong, and
``show_problem`` puts that under the field it names (``particles.bob.position[1]``,
``system.gravity[2]``).
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from typing import Any

from PySide6.QtCore import Qt, Signal
from PySide6.QtWidgets import (
    QGridLayout,
    QGroupBox,
    QHBoxLayout,
    QLabel,
    QPushButton,
    QVBoxLayout,
    QWidget,
)

from explorer.editor.fields import ExpressionField, error_html, never_widens
from explorer.editor.named_rows import NamedRow, free_name, row_for_field, take_typed_name

AXES = ("x", "y", "z")


def split_components(text: str) -> list[tuple[str, int]]:
    """The comma-separated components of a vector typed as ``0, 0, -g`` or ``[0, 0, -g]``,
    stripped, with their 1-based columns in ``text``; commas inside brackets do not split.
    """
    start, end = 0, len(text)
    stripped = text.strip()
    if stripped.startswith("[") and stripped.endswith("]") and len(stripped) >= 2:
        start = text.index("[") + 1
        end = text.rindex("]")
    items, depth, begin = [], 0, start
    for i in range(start, end + 1):
        c = text[i] if i < end else ","
        if c in "([":
            depth += 1
        elif c in ")]":
            depth -= 1
        elif c == "," and depth <= 0:
            item = text[begin:i]
            items.append((item.strip(), begin + len(item) - len(item.lstrip()) + 1))
            begin = i + 1
    return items


def gravity_value(text: str) -> str | list[str] | None:
    """``system.gravity`` typed as text: None (blank), a magnitude, or a vector."""
    if not text.strip():
        return None
    items = split_components(text)
    if len(items) == 1 and not text.strip().startswith("["):
        return items[0][0]
    return [item for item, _ in items]


def gravity_text(value: Any) -> str:
    """The text of a ``system.gravity`` value (a vector joined by commas)."""
    if value is None:
        return ""
    if isinstance(value, list | tuple):
        return ", ".join(_expression_text(v) for v in value)
    return _expression_text(value)


def _expression_text(value: Any) -> str:
    """An expression of a document as text, as the scene reads it (``1.0`` stays ``1.0``)."""
    if isinstance(value, bool):
        return str(value).lower()
    if isinstance(value, list | tuple):
        return ", ".join(_expression_text(v) for v in value)
    return "" if value is None else str(value)


class ParticleRow(NamedRow):
    """One particle: name, mass, Remove, and the x, y and z of its position."""

    def __init__(self, name: str, mass: str, position: list[str]):
        super().__init__(name, "particle")
        self.name_edit.setToolTip("The particle's name: its point in the drawing has it too")
        self.mass = ExpressionField("m (numbers and parameters)")
        self.mass.set_text(mass)
        self.axes = {
            "x": ExpressionField("x(q, t), e.g. l*sin(theta)"),
            "y": ExpressionField("y(q, t), e.g. -l*cos(theta)  (y is up)"),
            "z": ExpressionField("z(q, t); blank: the particle moves in the plane (x, y)"),
        }
        components = [*position[:2], ", ".join(position[2:])]
        for axis, text in zip(AXES, components, strict=False):
            self.axes[axis].set_text(text)
        self.position_error = QLabel()
        never_widens(self.position_error)
        self.position_error.setVisible(False)
        layout = QGridLayout(self)
        layout.setContentsMargins(4, 4, 4, 4)
        layout.setVerticalSpacing(2)
        head = QHBoxLayout()
        head.setSpacing(6)
        head.addWidget(QLabel("Particle"))
        head.addWidget(self.name_edit, 1)
        head.addWidget(QLabel("mass"))
        head.addWidget(self.mass, 1)
        head.addWidget(self.remove_button, 0, Qt.AlignmentFlag.AlignTop)
        layout.addLayout(head, 0, 0, 1, 2)
        layout.addWidget(self.name_error, 1, 0, 1, 2)
        for row, axis in enumerate(AXES, start=2):
            tag = QLabel(f"{axis} =")
            tag.setAlignment(Qt.AlignmentFlag.AlignRight | Qt.AlignmentFlag.AlignTop)
            layout.addWidget(tag, row, 0)
            layout.addWidget(self.axes[axis], row, 1)
        layout.addWidget(self.position_error, 5, 0, 1, 2)
        layout.setColumnStretch(1, 1)

    def fields(self) -> tuple[ExpressionField, ...]:
        return (self.mass, *self.axes.values())

    def entry(self) -> dict:
        """The particle's ``{mass, position}`` as typed (z left out when blank)."""
        position = [self.axes[a].text().strip() for a in ("x", "y")]
        z = self.axes["z"].text().strip()
        if z:
            position.append(z)
        return {"mass": self.mass.text().strip(), "position": position}

    def clear_errors(self) -> None:
        self.clear_name_error()
        self.position_error.clear()
        self.position_error.setVisible(False)
        for field in self.fields():
            field.clear_error()


class ParticlesSection(QGroupBox):
    """The particles and the gravity field of a scene given by ``[particles]``.

    Signals
    -------
    edited()                something of the particles or gravity was typed, added or removed
    action_requested(str)   the quick-fix link of an error shown in a field was clicked
    renamed(str, str)       a particle's name in the document changed (old, new), before
                            ``edited``
    """

    edited = Signal()
    action_requested = Signal(str)
    renamed = Signal(str, str)

    def __init__(self, parent: QWidget | None = None):
        super().__init__("Particles", parent)
        self.rows: list[ParticleRow] = []
        self._filling = False
        note = QLabel(
            "T = Σ m|v|²/2 is derived from the positions (in the coordinates, t and "
            "parameters); gravity's V = -Σ m g·r is added to V."
        )
        note.setWordWrap(True)
        note.setStyleSheet("QLabel { color: #555; }")
        self.general_error = QLabel()
        self.general_error.setWordWrap(True)
        self.general_error.setVisible(False)
        self.rows_box = QVBoxLayout()
        self.rows_box.setSpacing(4)
        self.add_button = QPushButton("Add particle")
        self.add_button.setToolTip("Add a particle of mass 1 at the origin; then type its position")
        self.add_button.clicked.connect(lambda: self.add_particle())
        self.gravity = ExpressionField("g (along -y), or a vector, e.g. 0, 0, -g; blank: none")
        self.gravity.setToolTip(
            "A uniform field: a magnitude along -y (y is up), or a vector with as many "
            "components as the positions"
        )
        self.gravity.edited.connect(self._on_edited)
        self.gravity.action_requested.connect(self.action_requested)
        buttons = QHBoxLayout()
        buttons.addWidget(self.add_button)
        buttons.addStretch(1)
        gravity_row = QHBoxLayout()
        tag = QLabel("Gravity")
        tag.setAlignment(Qt.AlignmentFlag.AlignRight | Qt.AlignmentFlag.AlignTop)
        gravity_row.addWidget(tag)
        gravity_row.addWidget(self.gravity, 1)
        layout = QVBoxLayout(self)
        layout.setContentsMargins(4, 4, 4, 4)
        layout.addWidget(note)
        layout.addWidget(self.general_error)
        layout.addLayout(self.rows_box)
        layout.addLayout(buttons)
        layout.addLayout(gravity_row)

    # -- content ------------------------------------------------------------------------

    def set_particles(self, table: Any, gravity: Any) -> None:
        """Show a ``[particles]`` table and a ``system.gravity`` value (None: none)."""
        self._filling = True
        try:
            for row in list(self.rows):
                self._drop_row(row)
            for name, entry in (table if isinstance(table, Mapping) else {}).items():
                entry = entry if isinstance(entry, Mapping) else {}
                position = entry.get("position", [])
                if isinstance(position, list | tuple):
                    position = [_expression_text(v) for v in position]
                else:
                    position = [_expression_text(position)]
                self._add_row(str(name), _expression_text(entry.get("mass")), position)
            self.gravity.set_text(gravity_text(gravity))
            self.clear_errors()
        finally:
            self._filling = False

    def table(self) -> dict:
        """The ``[particles]`` table as typed: name -> ``{mass, position}``."""
        return {row.accepted_name: row.entry() for row in self.rows}

    def gravity_value(self) -> str | list[str] | None:
        """``system.gravity`` as typed: None (blank), a magnitude or a vector."""
        return gravity_value(self.gravity.text())

    def names(self) -> list[str]:
        return [row.accepted_name for row in self.rows]

    def add_particle(
        self, name: str | None = None, mass: str = "1", position: tuple[str, ...] = ("0", "0")
    ) -> ParticleRow:
        """Add a particle (``name`` None: a free name, particle1, particle2, ...)."""
        if name is None or name in self.names():
            name = free_name(name or "particle", self.names())
        row = self._add_row(name, mass, list(position))
        self._on_edited()
        return row

    def remove_particle(self, row: ParticleRow) -> None:
        """Remove a particle."""
        self._drop_row(row)
        for other in self.rows:  # a name refused as taken may be free now
            if other.typed_name() != other.accepted_name:
                take_typed_name(other, self.rows)
        self._on_edited()

    def _add_row(self, name: str, mass: str, position: list[str]) -> ParticleRow:
        row = ParticleRow(name, mass, position)
        for field in row.fields():
            field.edited.connect(self._on_edited)
            field.action_requested.connect(self.action_requested)
        row.name_edit.textEdited.connect(lambda _text, r=row: self._on_name_edited(r))
        row.remove_button.clicked.connect(lambda _checked=False, r=row: self.remove_particle(r))
        self.rows.append(row)
        self.rows_box.addWidget(row)
        return row

    def _drop_row(self, row: ParticleRow) -> None:
        self.rows.remove(row)
        self.rows_box.removeWidget(row)
        row.hide()
        row.deleteLater()

    def _on_name_edited(self, row: ParticleRow) -> None:
        old = row.accepted_name
        take_typed_name(row, self.rows)
        if row.accepted_name != old:
            self.renamed.emit(old, row.accepted_name)
        self._on_edited()

    def _on_edited(self) -> None:
        if not self._filling:
            self.edited.emit()

    # -- problems -----------------------------------------------------------------------

    def clear_errors(self) -> None:
        for row in self.rows:
            row.clear_errors()
        self.gravity.clear_error()
        self.general_error.clear()
        self.general_error.setVisible(False)

    def show_problem(
        self,
        field: str,
        reason: str,
        position: int | None = None,
        action: tuple[str, str] | None = None,
    ) -> bool:
        """Show a problem of field ``particles...`` or ``system.gravity...`` where it
        belongs; False if the field is not one of this section's."""
        if field == "system.gravity" or field.startswith("system.gravity["):
            match = re.fullmatch(r"system\.gravity\[(\d+)\]", field)
            at = position
            if match is not None:
                items = split_components(self.gravity.text())
                index = int(match.group(1))
                column = items[index][1] if index < len(items) else None
                at = column + (position or 1) - 1 if column is not None else None
            self.gravity.show_error(reason, at, action)
            return True
        if field != "particles" and not field.startswith("particles."):
            return False
        row, rest = row_for_field(self.rows, field[len("particles.") :])
        if row is None:
            self._show_general(f"{field}: {reason}" if field != "particles" else reason)
            return True
        match = re.fullmatch(r"\.position\[(\d+)\]", rest)
        if rest == ".mass":
            row.mass.show_error(reason, position, action)
        elif match is not None:
            axis = AXES[min(int(match.group(1)), 2)]
            row.axes[axis].show_error(reason, position, action)
        elif rest == ".position":
            row.position_error.setText(error_html(f"position: {reason}", None, None))
            row.position_error.setVisible(True)
        else:
            row.show_name_error(f"{field}: {reason}" if rest else reason)
        return True

    def _show_general(self, text: str) -> None:
        self.general_error.setText(error_html(text, None, None))
        self.general_error.setVisible(True)
