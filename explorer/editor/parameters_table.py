"""The parameters table: name, value, a slider over [min, max], and the range itself.

Each value cell remembers the last value that was accepted. A typed value that is not a
finite number is refused at once (the cell goes back to that value and ``value_refused``
says why); the editor may refuse a finite one too (a zero length), with ``revert``.

Each name cell remembers its last accepted name too. A typed name that is not a valid
name, is ``t`` or a built-in, is already another parameter's, or is a coordinate, velocity
or momentum of the system (``set_reserved``) is refused the same way (``name_refused``).
"Add" picks a name that is free, so adding twice never makes a duplicate.
"""

from __future__ import annotations

import math
import string

from PySide6.QtCore import Qt, Signal
from PySide6.QtWidgets import QHeaderView, QSlider, QTableWidget, QTableWidgetItem, QWidget

from systems.expressions import ExpressionError, check_name

SLIDER_STEPS = 1000
NAME, VALUE, SLIDER, LOW, HIGH = range(5)
ACCEPTED = Qt.ItemDataRole.UserRole  # on a value or name cell: its last accepted text


def parse_value(name: str, text: str) -> tuple[float | None, str]:
    """A typed parameter value: ``(value, "")``, or ``(None, why it is refused)``."""
    try:
        value = float(text)
    except ValueError:
        return None, f"{name} = {text!r} refused: a parameter value must be a number"
    if not math.isfinite(value):
        return None, f"{name} = {text} refused: a parameter value must be a finite number"
    return value, ""


def number_text(value: float) -> str:
    """A number as it is shown in a cell: every digit kept, no trailing ``.0``."""
    text = repr(float(value))
    return text[:-2] if text.endswith(".0") else text


def fit_rows(table: QTableWidget, least: int = 1, most: int = 8) -> None:
    """Make ``table`` exactly as tall as its rows (at least ``least``, at most ``most``
    rows; beyond that it scrolls), so a short table leaves no empty band."""
    rows = min(max(table.rowCount(), least), most)
    header = table.horizontalHeader()
    height = rows * table.verticalHeader().defaultSectionSize() + 2 * table.frameWidth()
    if not header.isHidden():
        height += header.sizeHint().height()
    table.setFixedHeight(height)


def default_range(value) -> tuple[float, float]:
    if not isinstance(value, int | float):
        return -1.0, 1.0
    if value > 0:
        return 0.0, 2.0 * value
    if value < 0:
        return 2.0 * value, 0.0
    return -1.0, 1.0


class ParameterTableView(QTableWidget):
    """Parameters with sliders.

    Signals
    -------
    values_changed(dict)    a value moved (slider or typed): name -> value; no rebuild needed
    structure_changed()     a name was edited, or a row added or removed: rebuild the system
    value_refused(str)      a typed value was not a finite number and was put back; why
    name_refused(str)       a typed or added name was refused (and put back); why
    """

    values_changed = Signal(dict)
    structure_changed = Signal()
    value_refused = Signal(str)
    name_refused = Signal(str)

    def __init__(self, parent: QWidget | None = None):
        super().__init__(0, 5, parent)
        self.setHorizontalHeaderLabels(["name", "value", "", "min", "max"])
        header = self.horizontalHeader()
        header.setSectionResizeMode(SLIDER, QHeaderView.ResizeMode.Stretch)
        for column in (NAME, VALUE, LOW, HIGH):
            header.setSectionResizeMode(column, QHeaderView.ResizeMode.ResizeToContents)
        self.verticalHeader().setVisible(False)
        self._filling = False
        self._reserved: dict[str, str] = {}
        self.itemChanged.connect(self._on_item_changed)

    # -- content -------------------------------------------------------------------------

    def set_parameters(self, parameters, ranges: dict | None = None) -> None:
        """Fill from ``(name, value)`` pairs; ``ranges`` maps name -> (min, max)."""
        self._filling = True
        self.setRowCount(0)
        for name, value in parameters:
            lo, hi = (ranges or {}).get(name) or default_range(value)
            self._add_row(name, value, lo, hi)
        self._filling = False
        fit_rows(self, least=2)

    def set_reserved(self, coordinates) -> None:
        """The system's coordinates: their names, velocities and momenta are not parameters."""
        self._reserved = {}
        for q in coordinates:
            self._reserved[q] = f"the coordinate {q}"
            self._reserved[f"{q}_dot"] = f"the velocity of {q}"
            self._reserved[f"p_{q}"] = f"the momentum of {q}"

    def name_problem(self, name: str, row: int | None = None) -> str | None:
        """Why ``name`` cannot name the parameter in ``row`` (None: a new one), or None."""
        if not name:
            return "a parameter needs a name (use Remove to delete the row)"
        try:
            check_name(name, field="system.parameters")
        except ExpressionError as exc:
            return exc.reason
        if name in self._reserved:
            return f"{name!r} is {self._reserved[name]}; choose another name"
        for other in range(self.rowCount()):
            if other != row and self._accepted_name(other) == name:
                return f"{name!r} is already a parameter; choose another name"
        return None

    def fresh_name(self) -> str:
        """A name no parameter, coordinate, velocity or momentum has: a, b, c, ..., a1, ..."""
        letters = string.ascii_lowercase
        candidates = list(letters) + [f"{c}{i}" for i in range(1, 100) for c in letters]
        for name in candidates:
            if self.name_problem(name) is None:
                return name
        raise RuntimeError("no free parameter name")  # 2 600 parameters: not a real case

    def add_parameter(self, name: str | None = None, value: float = 1.0) -> str | None:
        """Add a row; ``name`` None picks a free one. Returns the name, or None if refused.

        A name that cannot be used (see ``name_problem``) adds nothing and emits
        ``name_refused`` with the reason.
        """
        if name is None:
            name = self.fresh_name()
        problem = self.name_problem(name)
        if problem is not None:
            self.name_refused.emit(f"parameter {name!r} not added: {problem}")
            return None
        self._filling = True
        self._add_row(name, value, *default_range(value))
        self._filling = False
        fit_rows(self, least=2)
        self.scrollToBottom()
        self.structure_changed.emit()
        return name

    def remove_selected(self) -> None:
        rows = sorted({index.row() for index in self.selectedIndexes()}, reverse=True)
        for row in rows:
            self.removeRow(row)
        fit_rows(self, least=2)
        if rows:
            self.structure_changed.emit()

    def _add_row(self, name: str, value: float, lo: float, hi: float) -> None:
        row = self.rowCount()
        self.insertRow(row)
        name_item = QTableWidgetItem(name)
        name_item.setData(ACCEPTED, name)
        self.setItem(row, NAME, name_item)
        numeric = isinstance(value, int | float) and not isinstance(value, bool)
        shown = number_text(value) if numeric else str(value)
        value_item = QTableWidgetItem(shown)
        value_item.setData(ACCEPTED, shown)
        self.setItem(row, VALUE, value_item)
        self.setItem(row, LOW, QTableWidgetItem(f"{lo:g}"))
        self.setItem(row, HIGH, QTableWidgetItem(f"{hi:g}"))
        slider = QSlider(Qt.Orientation.Horizontal)
        slider.setRange(0, SLIDER_STEPS)
        slider.setMinimumWidth(80)
        slider.valueChanged.connect(
            lambda position, s=slider: self._on_slider_value_changed(s, position)
        )
        self.setCellWidget(row, SLIDER, slider)
        self._place_slider(row)

    def _number(self, row: int, column: int) -> float | None:
        """The cell's finite number, or None (empty, not a number, nan or infinite)."""
        item = self.item(row, column)
        try:
            value = float(item.text()) if item is not None else None
        except ValueError:
            return None
        return value if value is not None and math.isfinite(value) else None

    def _name(self, row: int) -> str:
        item = self.item(row, NAME)
        return item.text().strip() if item is not None else ""

    def _accepted_name(self, row: int) -> str:
        item = self.item(row, NAME)
        accepted = item.data(ACCEPTED) if item is not None else None
        return str(accepted) if accepted is not None else self._name(row)

    def _widen(self, row: int) -> None:
        """Widen the slider's range to take a value typed beyond it (by the value's own
        default range): typing 9.81 for a g added at 1 pinned the slider at its end."""
        value, lo, hi = (self._number(row, c) for c in (VALUE, LOW, HIGH))
        if None in (value, lo, hi) or not math.isfinite(value) or lo <= value <= hi:
            return
        low, high = default_range(value)
        self._filling = True
        try:
            self.item(row, LOW).setText(f"{min(lo, low):g}")
            self.item(row, HIGH).setText(f"{max(hi, high):g}")
        finally:
            self._filling = False

    def _place_slider(self, row: int) -> None:
        slider = self.cellWidget(row, SLIDER)
        value, lo, hi = (self._number(row, c) for c in (VALUE, LOW, HIGH))
        if slider is None or None in (value, lo, hi) or hi <= lo:
            return
        slider.blockSignals(True)
        slider.setValue(round((min(max(value, lo), hi) - lo) / (hi - lo) * SLIDER_STEPS))
        slider.blockSignals(False)

    def parameters(self) -> list[tuple[str, str]]:
        """``(name, value text)`` per row, as typed."""
        rows = []
        for row in range(self.rowCount()):
            name = self.item(row, NAME).text().strip() if self.item(row, NAME) else ""
            value = self.item(row, VALUE).text().strip() if self.item(row, VALUE) else ""
            rows.append((name, value))
        return rows

    def ranges(self) -> dict[str, tuple[float, float]]:
        result = {}
        for row in range(self.rowCount()):
            lo, hi = self._number(row, LOW), self._number(row, HIGH)
            name = self.item(row, NAME).text().strip()
            if lo is not None and hi is not None and hi > lo:
                result[name] = (lo, hi)
        return result

    def values(self) -> dict[str, float]:
        """Parameter values that are valid (finite) numbers."""
        result = {}
        for row in range(self.rowCount()):
            value = self._number(row, VALUE)
            if value is not None:
                result[self._name(row)] = value
        return result

    def accepted_values(self) -> dict[str, float]:
        """The last accepted value of each row (what the running system uses)."""
        result = {}
        for row in range(self.rowCount()):
            item = self.item(row, VALUE)
            value, _ = parse_value("", str(item.data(ACCEPTED))) if item else (None, "")
            if value is not None:
                result[self._name(row)] = value
        return result

    def accept(self) -> None:
        """The values shown are in force: remember them as the ones to go back to."""
        for row in range(self.rowCount()):
            item = self.item(row, VALUE)
            if item is not None and self._number(row, VALUE) is not None:
                item.setData(ACCEPTED, item.text())

    def revert(self) -> None:
        """Put every value back to its last accepted one (no signal), sliders too."""
        self._filling = True
        try:
            for row in range(self.rowCount()):
                item = self.item(row, VALUE)
                accepted = item.data(ACCEPTED) if item is not None else None
                if accepted is not None and item.text() != accepted:
                    item.setText(str(accepted))
                self._place_slider(row)
        finally:
            self._filling = False

    def set_value(self, name: str, value: float) -> None:
        """Set a value as if typed (emits ``values_changed``)."""
        for row in range(self.rowCount()):
            if self.item(row, NAME).text().strip() == name:
                self.item(row, VALUE).setText(number_text(value))
                return
        raise KeyError(name)

    def slider(self, name: str) -> QSlider:
        for row in range(self.rowCount()):
            if self.item(row, NAME).text().strip() == name:
                return self.cellWidget(row, SLIDER)
        raise KeyError(name)

    # -- slots ----------------------------------------------------------------------------

    def _on_slider_value_changed(self, slider: QSlider, position: int) -> None:
        for row in range(self.rowCount()):
            if self.cellWidget(row, SLIDER) is slider:
                lo, hi = self._number(row, LOW), self._number(row, HIGH)
                if lo is None or hi is None or hi <= lo:
                    return
                value = lo + (hi - lo) * position / SLIDER_STEPS
                self._filling = True
                self.item(row, VALUE).setText(f"{value:.6g}")
                self._filling = False
                self.values_changed.emit(self.values())
                return

    def _on_item_changed(self, item: QTableWidgetItem) -> None:
        if self._filling:
            return
        if item.column() == NAME:
            name = item.text().strip()
            previous = self._accepted_name(item.row())
            if name == previous:
                return
            problem = self.name_problem(name, item.row())
            self._filling = True
            item.setText(previous if problem else name)
            if not problem:
                item.setData(ACCEPTED, name)
            self._filling = False
            if problem:
                self.name_refused.emit(
                    f"parameter name {name!r} refused (kept {previous!r}): {problem}"
                )
                return
            self.structure_changed.emit()
        elif item.column() == VALUE:
            _, refusal = parse_value(self._name(item.row()), item.text().strip())
            if refusal:
                accepted = item.data(ACCEPTED)
                self._filling = True
                item.setText("" if accepted is None else str(accepted))
                self._filling = False
                self._place_slider(item.row())
                self.value_refused.emit(refusal)
                return
            self._widen(item.row())
            self._place_slider(item.row())
            self.values_changed.emit(self.values())
        else:
            self._place_slider(item.row())
