"""Rows with a name the user types: particles and symmetries.

A row's name is taken as it is typed, letter by letter, whatever it is: a name the scene
cannot use (``2bob``) goes into the document as typed, and the build says what is wrong
with it under the name. Only a name that another row already has is not taken, because
the document is a table and one of the two would be lost: the row keeps its last name
(``accepted_name``), says so under the name field, and takes the typed one as soon as it
is free.
"""

from __future__ import annotations

from collections.abc import Iterable

from PySide6.QtWidgets import QFrame, QLabel, QLineEdit, QPushButton

from explorer.editor.fields import error_html, never_widens


def free_name(prefix: str, taken: Iterable[str]) -> str:
    """``prefix1``, ``prefix2``, ...: the first that is not in ``taken``."""
    taken = set(taken)
    return next(f"{prefix}{i}" for i in range(1, len(taken) + 2) if f"{prefix}{i}" not in taken)


class NamedRow(QFrame):
    """A framed row with a name field, a line for problems with the name and a Remove button.

    Attributes
    ----------
    accepted_name : str
        The name the row has in the document.
    """

    def __init__(self, name: str, what: str):
        super().__init__()
        self.setFrameShape(QFrame.Shape.StyledPanel)
        self.what = what
        self.accepted_name = name
        self.name_edit = QLineEdit(name)
        self.name_edit.setMaximumWidth(140)
        self.name_edit.setToolTip(f"The {what}'s name")
        self.remove_button = QPushButton("Remove")
        self.remove_button.setToolTip(f"Remove this {what}")
        self.name_error = QLabel()
        never_widens(self.name_error)
        self.name_error.setVisible(False)

    def typed_name(self) -> str:
        """The name as typed (spaces around it left out)."""
        return self.name_edit.text().strip()

    def show_name_error(self, text: str) -> None:
        """Show ``text`` under the name."""
        self.name_error.setText(error_html(text, None, None))
        self.name_error.setVisible(True)

    def clear_name_error(self) -> None:
        """Remove the problem shown under the name."""
        self.name_error.clear()
        self.name_error.setVisible(False)


def take_typed_name(row: NamedRow, rows: Iterable[NamedRow]) -> None:
    """Take the name typed in ``row`` unless another of ``rows`` has it (then say so)."""
    name = row.typed_name()
    other = next((r for r in rows if r is not row and r.accepted_name == name), None)
    if other is None:
        row.accepted_name = name
        row.clear_name_error()
        return
    row.show_name_error(
        f"{name!r} is already the name of another {row.what}: choose another name "
        f"(until then this {row.what} stays {row.accepted_name!r})"
    )


def row_for_field(rows: Iterable[NamedRow], rest: str) -> tuple[NamedRow | None, str]:
    """The row whose name starts ``rest`` (``"bob.mass"``), and what follows the name.

    The longest name that fits wins, so ``bob`` and ``bob.x`` (a typed name that the scene
    refuses) are told apart.
    """
    for row in sorted(rows, key=lambda r: -len(r.accepted_name)):
        name = row.accepted_name
        if rest == name or (rest.startswith(name) and rest[len(name)] in ".["):
            return row, rest[len(name) :]
    return None, rest
