"""The editor's Drawing section: named points with x and y expressions, links, trace.

Links are typed as pairs of point names joined by ``-`` (``origin-bob, bob-tip``), the trace
as a list of point names (``bob, tip``); ``origin`` is the point (0, 0). A point's name
takes effect when it is committed (Enter, or leaving the field): a name that is not valid
or is already used is refused and the previous one kept, and a rename is carried into the
links and the trace. Problems found when the system is built (a name that is not in the
system, an unknown point) are shown under the field they concern, as for T and V.
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from typing import Any

from PySide6.QtCore import Qt, Signal
from PySide6.QtWidgets import (
    QFrame,
    QGridLayout,
    QGroupBox,
    QHBoxLayout,
    QLabel,
    QLineEdit,
    QPushButton,
    QVBoxLayout,
    QWidget,
)

from explorer.editor.fields import ExpressionField, error_html, never_widens

LINK_JOINS = ("->", "→", "–", "—")
"""Also accepted between the two ends of a link, besides ``-``."""


def links_text(links: Any) -> str:
    """The text of a ``links`` list: ``[["origin", "bob"]]`` -> ``"origin-bob"``."""
    if not isinstance(links, list):
        return "" if links is None else str(links)
    parts = []
    for link in links:
        if isinstance(link, list | tuple):
            parts.append("-".join(str(end) for end in link))
        else:
            parts.append(str(link))
    return ", ".join(parts)


def _chunks(text: str) -> list[tuple[str, int]]:
    """The comma- or semicolon-separated items of ``text``, stripped, with their 1-based
    columns; empty items are skipped."""
    items = []
    for match in re.finditer(r"[^,;]+", text):
        item = match.group(0)
        if item.strip():
            items.append((item.strip(), match.start() + len(item) - len(item.lstrip()) + 1))
    return items


def parse_links(text: str) -> list[list[str]]:
    """The ``links`` list typed as ``"origin-bob, bob-tip"``.

    An item that is not two names joined by ``-`` is kept as the list of its parts (one,
    or three), so that what was typed survives and the scene reports it.
    """
    links = []
    for item, _ in _chunks(text):
        for join in LINK_JOINS:
            item = item.replace(join, "-")
        links.append([end.strip() for end in item.split("-")])
    return links


def parse_names(text: str) -> list[str]:
    """A list of names typed as ``"bob, tip"``."""
    return [item for item, _ in _chunks(text)]


class PointRow(QFrame):
    """One point: its name, its x and y expressions and a Remove button."""

    def __init__(self, name: str, x: str, y: str, parent: QWidget | None = None):
        super().__init__(parent)
        self.setFrameShape(QFrame.Shape.StyledPanel)
        self.accepted_name = name
        self.name_edit = QLineEdit(name)
        self.name_edit.setMaximumWidth(140)
        self.name_edit.setToolTip("The point's name, used in links and trace (Enter to apply)")
        self.remove_button = QPushButton("Remove")
        self.remove_button.setToolTip("Remove this point, and the links and trace that use it")
        self.x = ExpressionField("x(q, t), e.g. l*sin(theta)")
        self.y = ExpressionField("y(q, t), e.g. -l*cos(theta)")
        self.x.set_text(x)
        self.y.set_text(y)
        self.name_error = QLabel()
        never_widens(self.name_error)
        self.name_error.setVisible(False)
        layout = QGridLayout(self)
        layout.setContentsMargins(4, 4, 4, 4)
        layout.setVerticalSpacing(2)
        head = QHBoxLayout()
        head.setSpacing(6)
        head.addWidget(QLabel("Point"))
        head.addWidget(self.name_edit, 1)
        head.addStretch(1)
        head.addWidget(self.remove_button)
        layout.addLayout(head, 0, 0, 1, 2)
        layout.addWidget(self.name_error, 1, 0, 1, 2)
        for row, (label, field) in enumerate((("x =", self.x), ("y =", self.y)), start=2):
            tag = QLabel(label)
            tag.setAlignment(Qt.AlignmentFlag.AlignRight | Qt.AlignmentFlag.AlignTop)
            layout.addWidget(tag, row, 0)
            layout.addWidget(field, row, 1)
        layout.setColumnStretch(1, 1)

    def show_name_error(self, text: str) -> None:
        self.name_error.setText(error_html(text, None, None))
        self.name_error.setVisible(True)

    def clear_errors(self) -> None:
        self.name_error.clear()
        self.name_error.setVisible(False)
        self.x.clear_error()
        self.y.clear_error()


class DrawingSection(QGroupBox):
    """Points, links and trace of the mechanism drawing.

    Signals
    -------
    edited()   something that changes the drawing was typed, added, removed or renamed
    """

    edited = Signal()

    def __init__(self, parent: QWidget | None = None):
        super().__init__("Drawing", parent)
        self.rows: list[PointRow] = []
        self._filling = False
        self.note = QLabel(
            "Points in the plane (x right, y up) in the coordinates, t and parameters; "
            "origin is (0, 0)."
        )
        never_widens(self.note)
        self.note.setStyleSheet("QLabel { color: #555; }")
        self.left_out = QLabel()  # shown while the drawing is left out of the build
        never_widens(self.left_out)
        self.left_out.setVisible(False)
        self.left_out.setStyleSheet(
            "QLabel { background: #fff8e1; border: 1px solid #e0a800; border-radius: 4px;"
            " padding: 3px; }"
        )
        self.points_box = QVBoxLayout()
        self.points_box.setSpacing(4)
        self.add_button = QPushButton("Add point")
        self.add_button.setToolTip("Add a point at the origin; then type its x and y")
        self.add_button.clicked.connect(lambda: self.add_point())
        self.links = ExpressionField("pairs of points, e.g. origin-bob, bob-tip")
        self.trace = ExpressionField("points whose path is drawn, e.g. bob")
        self.links.edited.connect(self._on_edited)
        self.trace.edited.connect(self._on_edited)
        self.general_error = QLabel()
        never_widens(self.general_error)
        self.general_error.setVisible(False)
        form = QGridLayout()
        for row, (label, field) in enumerate((("Links", self.links), ("Trace", self.trace))):
            tag = QLabel(label)
            tag.setAlignment(Qt.AlignmentFlag.AlignRight | Qt.AlignmentFlag.AlignTop)
            form.addWidget(tag, row, 0)
            form.addWidget(field, row, 1)
        form.setColumnStretch(1, 1)
        buttons = QHBoxLayout()
        buttons.addWidget(self.add_button)
        buttons.addStretch(1)
        layout = QVBoxLayout(self)
        layout.addWidget(self.note)
        layout.addWidget(self.left_out)
        layout.addWidget(self.general_error)
        layout.addLayout(self.points_box)
        layout.addLayout(buttons)
        layout.addLayout(form)

    # -- content ------------------------------------------------------------------------

    def set_drawing(self, table: Any) -> None:
        """Show the ``[drawing]`` table of a document (None or empty: no drawing)."""
        self._filling = True
        try:
            for row in list(self.rows):
                self._drop_row(row)
            table = table if isinstance(table, Mapping) else {}
            points = table.get("points", {})
            if isinstance(points, Mapping):
                for name, xy in points.items():
                    if isinstance(xy, list | tuple) and len(xy) == 2:
                        x, y = (str(v) for v in xy)
                    else:  # shown as typed, so the scene can say what is wrong with it
                        x, y = links_text(xy) if isinstance(xy, list) else str(xy), ""
                    self._add_row(str(name), x, y)
            self.links.set_text(links_text(table.get("links")))
            trace = table.get("trace")
            self.trace.set_text(
                ", ".join(str(v) for v in trace) if isinstance(trace, list) else links_text(trace)
            )
            self.clear_errors()
        finally:
            self._filling = False

    def table(self) -> dict | None:
        """The ``[drawing]`` table as typed, or None when there is nothing to draw."""
        points = {
            row.accepted_name: [row.x.text().strip(), row.y.text().strip()] for row in self.rows
        }
        links = parse_links(self.links.text())
        trace = parse_names(self.trace.text())
        if not (points or links or trace):
            return None
        table: dict = {"points": points}
        if links:
            table["links"] = links
        if trace:
            table["trace"] = trace
        return table

    def point_names(self) -> list[str]:
        return [row.accepted_name for row in self.rows]

    def add_point(self, name: str | None = None, x: str = "0", y: str = "0") -> PointRow | None:
        """Add a point (``name`` None: a free name, point1, point2, ...); None if refused."""
        if name is None:
            taken = set(self.point_names())
            name = next(f"point{i}" for i in range(1, len(taken) + 2) if f"point{i}" not in taken)
        problem = self.name_problem(name, None)
        if problem:
            self._show_general(f"point {name!r} not added: {problem}")
            return None
        row = self._add_row(name, x, y)
        self._on_edited()
        return row

    def remove_point(self, row: PointRow) -> None:
        """Remove a point, the links that end at it and its trace."""
        name = row.accepted_name
        self._drop_row(row)
        links = [link for link in parse_links(self.links.text()) if name not in link]
        self.links.set_text(links_text(links))
        self.trace.set_text(", ".join(n for n in parse_names(self.trace.text()) if n != name))
        self._on_edited()

    def name_problem(self, name: str, row: PointRow | None) -> str | None:
        """Why ``name`` cannot name the point in ``row`` (None: a new point), or None."""
        if not name:
            return "a point needs a name (use Remove to delete the point)"
        if not name.isidentifier() or not name.isascii():
            return f"{name!r} is not a valid name: use letters, digits and underscores"
        if name == "origin":
            return "'origin' is the point (0, 0) and needs no definition"
        if any(other is not row and other.accepted_name == name for other in self.rows):
            return f"{name!r} is already a point; choose another name"
        return None

    def _add_row(self, name: str, x: str, y: str) -> PointRow:
        row = PointRow(name, x, y)
        row.x.edited.connect(self._on_edited)
        row.y.edited.connect(self._on_edited)
        row.name_edit.editingFinished.connect(lambda r=row: self._on_name_committed(r))
        row.remove_button.clicked.connect(lambda _checked=False, r=row: self.remove_point(r))
        self.rows.append(row)
        self.points_box.addWidget(row)
        return row

    def _drop_row(self, row: PointRow) -> None:
        self.rows.remove(row)
        self.points_box.removeWidget(row)
        row.hide()
        row.deleteLater()

    def _on_name_committed(self, row: PointRow) -> None:
        if row not in self.rows:
            return
        name = row.name_edit.text().strip()
        old = row.accepted_name
        if name == old:
            row.name_edit.setText(old)
            return
        problem = self.name_problem(name, row)
        if problem:
            row.name_edit.setText(old)
            row.show_name_error(f"point name {name!r} refused (kept {old!r}): {problem}")
            return
        row.name_error.setVisible(False)
        row.accepted_name = name
        row.name_edit.setText(name)
        self._rename_in_links_and_trace(old, name)
        self._on_edited()

    def rename_references(self, old: str, new: str, taken: set[str]) -> bool:
        """Carry a particle's new name into the links and the trace (a particle is a point
        of the drawing); True if something changed.

        Nothing is renamed if a point of the drawing has either name, or ``new`` is
        ``origin`` or one of ``taken`` (the other particles' names): two points must not
        merge into one.
        """
        names = set(self.point_names()) | set(taken) | {"origin"}
        if old in self.point_names() or new in names or not old or not new:
            return False
        if not self._rename_in_links_and_trace(old, new):
            return False
        self._on_edited()
        return True

    def _rename_in_links_and_trace(self, old: str, name: str) -> bool:
        changed = False
        links = parse_links(self.links.text())
        if any(old in link for link in links):
            renamed = [[name if end == old else end for end in link] for link in links]
            self.links.set_text(links_text(renamed))
            changed = True
        trace = parse_names(self.trace.text())
        if old in trace:
            self.trace.set_text(", ".join(name if n == old else n for n in trace))
            changed = True
        return changed

    def _on_edited(self) -> None:
        if not self._filling:
            self.edited.emit()

    # -- problems -----------------------------------------------------------------------

    def clear_errors(self) -> None:
        for row in self.rows:
            row.clear_errors()
        self.links.clear_error()
        self.trace.clear_error()
        self.general_error.clear()
        self.general_error.setVisible(False)
        self.left_out.clear()
        self.left_out.setVisible(False)

    def show_left_out(self, count: int) -> None:
        """Say that the drawing is not in the build until its ``count`` problems are fixed."""
        problems = "this problem is" if count == 1 else f"these {count} problems are"
        self.left_out.setText(
            f"The drawing is left out of the running system until {problems} fixed; "
            "the system runs without it."
        )
        self.left_out.setVisible(True)

    def show_problem(self, field: str, reason: str, position: int | None = None) -> None:
        """Show a problem of field ``drawing...`` under the widget it concerns."""
        rest = field[len("drawing") :].lstrip(".")
        if rest.startswith("points."):
            name, _, axis = rest[len("points.") :].rpartition(".")
            if axis not in ("x", "y"):
                name, axis = rest[len("points.") :], ""
            row = next((r for r in self.rows if r.accepted_name == name), None)
            if row is not None:
                if axis:
                    (row.x if axis == "x" else row.y).show_error(reason, position)
                else:
                    row.show_name_error(f"point {name}: {reason}")
                return
        if rest.startswith("links"):
            match = re.match(r"links\[(\d+)\]", rest)
            items = _chunks(self.links.text())
            index = int(match.group(1)) if match else None
            at = items[index][1] if index is not None and index < len(items) else None
            self.links.show_error(reason, at)
            return
        if rest.startswith("trace"):
            quoted = re.search(r"'([^']*)'", reason)
            at = None
            if quoted:
                at = next(
                    (c for item, c in _chunks(self.trace.text()) if item == quoted.group(1)), None
                )
            self.trace.show_error(reason, at)
            return
        self._show_general(f"{field}: {reason}")

    def _show_general(self, text: str) -> None:
        self.general_error.setText(error_html(text, None, None))
        self.general_error.setVisible(True)
