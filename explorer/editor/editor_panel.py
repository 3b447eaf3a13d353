"""The system editor: pick from the catalogue or type a system; see what it derives to.

Edits are debounced (``DEBOUNCE_MS``) and sent as the tables of a scene document to the
builder, which derives and compiles in the background; errors come back with their field
and position and are shown under that field, leaving the typed text as it was. Every
debounced edit is a step of the undo history.

A parameter value goes out (``parameters_changed``) only once ``parameter_check`` (set by
the window) finds nothing wrong with it; a refused value is put back in the table and the
reason shown under it.
"""

from __future__ import annotations

import html
from collections.abc import Callable

from PySide6.QtCore import Qt, QTimer, Signal
from PySide6.QtGui import QFont
from PySide6.QtWidgets import (
    QCheckBox,
    QComboBox,
    QFormLayout,
    QGroupBox,
    QHBoxLayout,
    QHeaderView,
    QLabel,
    QLineEdit,
    QListWidget,
    QListWidgetItem,
    QPushButton,
    QScrollArea,
    QTableWidget,
    QTableWidgetItem,
    QTabWidget,
    QTextBrowser,
    QVBoxLayout,
    QWidget,
)

from explorer.editor.fields import ExpressionField, error_html
from explorer.editor.parameters_table import ParameterTableView
from explorer.labels import coordinate_label

DEBOUNCE_MS = 400
KINDS = (
    ("energies", "T and V"),
    ("lagrangian", "Lagrangian L"),
    ("hamiltonian", "Hamiltonian H"),
)


def data_from_scene(scene) -> dict:
    """The editor's snapshot of a scene: the tables of its TOML document."""
    system: dict = {
        "coordinates": list(scene.coordinates),
        "parameters": dict(scene.parameters),
    }
    for key in ("kinetic", "potential", "lagrangian", "hamiltonian"):
        value = getattr(scene, key)
        if value is not None:
            system[key] = value
    data: dict = {"title": scene.title, "description": scene.description, "system": system}
    effects: dict = {}
    if scene.dissipation is not None:
        effects["dissipation"] = scene.dissipation
    if scene.forces:
        effects["forces"] = dict(scene.forces)
    if scene.disabled:
        effects["disabled"] = sorted(scene.disabled)
    if effects:
        data["effects"] = effects
    data["initial"] = dict(scene.initial)
    if scene.drawing is not None:
        drawing = {"points": {name: [x, y] for name, x, y in scene.drawing.points}}
        if scene.drawing.links:
            drawing["links"] = [list(link) for link in scene.drawing.links]
        if scene.drawing.trace:
            drawing["trace"] = list(scene.drawing.trace)
        data["drawing"] = drawing
    if scene.view:
        data["view"] = dict(scene.view)
    return data


def _number_or_text(text: str):
    try:
        return float(text)
    except ValueError:
        return text


class SystemEditorPanel(QWidget):
    """Catalogue, system fields, parameters, effects, initial conditions, derived results.

    Signals
    -------
    scene_edited(dict)        debounced: the tables of the edited scene, to build
    catalogue_selected(str)   a catalogue scene name was chosen
    parameters_changed(dict)  a parameter value moved (no re-derivation needed)
    parameter_refused(str)    a typed or dragged value was refused and put back; why

    Attributes
    ----------
    parameter_check : callable or None
        ``check(values) -> reason or None``, asked before ``parameters_changed`` goes out
        with ``values`` (name -> float); a reason refuses them.
    """

    scene_edited = Signal(dict)
    catalogue_selected = Signal(str)
    parameters_changed = Signal(dict)
    parameter_refused = Signal(str)

    def __init__(self, parent: QWidget | None = None):
        super().__init__(parent)
        self._data: dict = {}
        self._history: list[dict] = []
        self._index = -1
        self._filling = False
        self._built_scene = None
        self._previous: tuple | None = None
        self._refusal_shown = False
        self.last_refusal = ""  # the message of the last refused parameter value
        self.parameter_check: Callable[[dict], str | None] | None = None
        self.debounce = QTimer(self)
        self.debounce.setSingleShot(True)
        self.debounce.setInterval(DEBOUNCE_MS)
        self.debounce.timeout.connect(self._on_debounce_timeout)

        self.catalogue = QListWidget()
        self.catalogue.setMaximumHeight(150)
        self.catalogue.itemActivated.connect(self._on_catalogue_item_activated)
        self.catalogue.itemClicked.connect(self._on_catalogue_item_activated)
        self._fill_catalogue()

        self.title_edit = QLineEdit()
        self.title_edit.textEdited.connect(self._on_field_edited)
        self.coordinates = ExpressionField("theta, phi")
        self.kind_combo = QComboBox()
        for key, label in KINDS:
            self.kind_combo.addItem(label, key)
        self.kind_combo.currentIndexChanged.connect(self._on_kind_index_changed)
        self.fields = {
            "kinetic": ExpressionField("T(q, q_dot, t), e.g. m*l**2*theta_dot**2/2"),
            "potential": ExpressionField("V(q, t), e.g. -m*g*l*cos(theta)"),
            "lagrangian": ExpressionField("L(q, q_dot, t)"),
            "hamiltonian": ExpressionField("H(q, p_q, t)"),
        }
        system_box = QGroupBox("System")
        self.system_form = QFormLayout(system_box)
        self.system_form.addRow("Title", self.title_edit)
        self.system_form.addRow("Coordinates", self.coordinates)
        self.system_form.addRow("Given by", self.kind_combo)
        for key, label in (
            ("kinetic", "T ="),
            ("potential", "V ="),
            ("lagrangian", "L ="),
            ("hamiltonian", "H ="),
        ):
            self.system_form.addRow(label, self.fields[key])

        self.parameter_table = ParameterTableView()
        self.parameter_table.setMinimumHeight(110)
        self.parameter_table.values_changed.connect(self._on_parameter_values_changed)
        self.parameter_table.value_refused.connect(self._on_parameter_value_refused)
        self.parameter_table.structure_changed.connect(self._on_field_edited)
        self.parameter_error = QLabel()
        self.parameter_error.setWordWrap(True)
        add_button = QPushButton("Add")
        add_button.clicked.connect(lambda: self.parameter_table.add_parameter())
        remove_button = QPushButton("Remove")
        remove_button.clicked.connect(self.parameter_table.remove_selected)
        parameters_box = QGroupBox("Parameters")
        parameters_layout = QVBoxLayout(parameters_box)
        parameters_layout.addWidget(self.parameter_table)
        buttons = QHBoxLayout()
        buttons.addWidget(add_button)
        buttons.addWidget(remove_button)
        buttons.addStretch(1)
        parameters_layout.addLayout(buttons)
        parameters_layout.addWidget(self.parameter_error)

        self.effects_box = QGroupBox("Effects (switch on or off)")
        self.effects_form = QFormLayout(self.effects_box)
        self.dissipation = ExpressionField("Rayleigh function R, e.g. b*theta_dot**2/2")
        self.dissipation_switch = QCheckBox("on")
        self.dissipation_switch.setChecked(True)
        self.dissipation_switch.toggled.connect(self._on_field_edited)
        self.force_fields: dict[str, ExpressionField] = {}
        self.force_switches: dict[str, QCheckBox] = {}
        self.effects_form.addRow(
            "R =", self._with_switch(self.dissipation, self.dissipation_switch)
        )

        self.initial_table = QTableWidget(0, 2)
        self.initial_table.setHorizontalHeaderLabels(["name", "value"])
        self.initial_table.verticalHeader().setVisible(False)
        self.initial_table.horizontalHeader().setSectionResizeMode(QHeaderView.ResizeMode.Stretch)
        self.initial_table.setMinimumHeight(90)
        self.initial_table.itemChanged.connect(self._on_field_edited)
        self.initial_error = QLabel()
        self.initial_error.setWordWrap(True)
        initial_box = QGroupBox("Initial conditions (q and q_dot, or p_q)")
        initial_layout = QVBoxLayout(initial_box)
        initial_layout.addWidget(self.initial_table)
        initial_layout.addWidget(self.initial_error)

        self.general_error = QLabel()  # at the top: a refused file or build is seen at once
        self.general_error.setWordWrap(True)
        self.general_error.setVisible(False)
        self.general_error.setStyleSheet(
            "QLabel { background: #fff3f3; border: 1px solid #d62728; border-radius: 4px;"
            " padding: 4px; }"
        )
        self.undo_button = QPushButton("Undo")
        self.undo_button.clicked.connect(self.undo)
        self.redo_button = QPushButton("Redo")
        self.redo_button.clicked.connect(self.redo)
        self.state_label = QLabel("")
        history = QHBoxLayout()
        history.addWidget(self.undo_button)
        history.addWidget(self.redo_button)
        history.addStretch(1)
        history.addWidget(self.state_label)

        self.classification_card = QLabel()
        self.classification_card.setWordWrap(True)
        self.classification_card.setTextFormat(Qt.TextFormat.RichText)
        self.classification_card.setStyleSheet(
            "QLabel { background: #f4f7fb; border: 1px solid #c9d6e6; border-radius: 6px;"
            " padding: 6px; }"
        )
        self.derived = QTextBrowser()
        self.derived.setMinimumHeight(200)
        font = QFont("DejaVu Sans Mono")
        font.setStyleHint(QFont.StyleHint.Monospace)
        font.setPointSize(9)
        self.derived.setFont(font)
        self.derived.setLineWrapMode(QTextBrowser.LineWrapMode.NoWrap)

        content = QWidget()
        layout = QVBoxLayout(content)
        layout.addWidget(self.general_error)
        layout.addWidget(QLabel("<b>Catalogue</b>"))
        layout.addWidget(self.catalogue)
        layout.addWidget(system_box)
        layout.addWidget(parameters_box)
        layout.addWidget(self.effects_box)
        layout.addWidget(initial_box)
        layout.addLayout(history)
        layout.addWidget(QLabel("<b>Classification</b>"))
        layout.addWidget(self.classification_card)
        scroll = QScrollArea()
        scroll.setWidgetResizable(True)
        scroll.setWidget(content)
        self._scroll = scroll
        derivation = QWidget()
        derivation_layout = QVBoxLayout(derivation)
        self.derivation_card = QLabel()
        self.derivation_card.setWordWrap(True)
        self.derivation_card.setStyleSheet(self.classification_card.styleSheet())
        derivation_layout.addWidget(self.derivation_card)
        derivation_layout.addWidget(self.derived, 1)
        self.tabs = QTabWidget()
        self.tabs.addTab(scroll, "System")
        self.tabs.addTab(derivation, "Derivation")
        outer = QVBoxLayout(self)
        outer.setContentsMargins(0, 0, 0, 0)
        outer.addWidget(self.tabs)

        for field in (self.coordinates, *self.fields.values(), self.dissipation):
            field.edited.connect(self._on_field_edited)
        self._update_history_buttons()

    # -- catalogue ------------------------------------------------------------------------

    def _fill_catalogue(self) -> None:
        from systems.scene import catalogue

        for entry in catalogue():
            item = QListWidgetItem(entry.title)
            item.setData(Qt.ItemDataRole.UserRole, entry.name)
            item.setToolTip(entry.description)
            self.catalogue.addItem(item)

    def catalogue_names(self) -> list[str]:
        return [
            self.catalogue.item(i).data(Qt.ItemDataRole.UserRole)
            for i in range(self.catalogue.count())
        ]

    def _on_catalogue_item_activated(self, item: QListWidgetItem) -> None:
        self.catalogue_selected.emit(item.data(Qt.ItemDataRole.UserRole))

    # -- filling the fields ---------------------------------------------------------------------

    def show_scene(self, scene) -> None:
        """Show a scene's fields and start a fresh undo history.

        What was shown before is kept until the next call, for ``restore_previous``.
        """
        self._previous = None
        if self._history:
            self._previous = (
                self.snapshot(),
                self._history,
                self._index,
                self.derived.toPlainText(),
                self._built_scene.name if self._built_scene is not None else None,
            )
        data = data_from_scene(scene)
        self._fill(data)
        self._history = [data]
        self._index = 0
        self._update_history_buttons()
        self.derived.setPlainText("deriving…")
        for i in range(self.catalogue.count()):
            item = self.catalogue.item(i)
            item.setSelected(item.data(Qt.ItemDataRole.UserRole) == scene.name)

    def restore_previous(self) -> bool:
        """Show again what was shown before the last ``show_scene`` (a refused opening).

        Returns False if there was nothing before (the first scene).
        """
        if self._previous is None:
            return False
        data, history, index, derived, name = self._previous
        self._previous = None
        self.debounce.stop()
        self._fill(data)
        self._history, self._index = history, index
        self._update_history_buttons()
        self.derived.setPlainText(derived)
        self.state_label.setText("")
        for i in range(self.catalogue.count()):
            item = self.catalogue.item(i)
            item.setSelected(item.data(Qt.ItemDataRole.UserRole) == name)
        return True

    def _fill(self, data: dict) -> None:
        self._filling = True
        try:
            self._data = data
            system = data.get("system", {})
            self.title_edit.setText(str(data.get("title", "")))
            self.coordinates.set_text(", ".join(system.get("coordinates", [])))
            kind = next((k for k in ("lagrangian", "hamiltonian") if k in system), "energies")
            self.kind_combo.setCurrentIndex([k for k, _ in KINDS].index(kind))
            for key, field in self.fields.items():
                field.set_text(system.get(key))
            self._show_kind(kind)
            ranges = {
                name: tuple(value) for name, value in (data.get("editor_ranges") or {}).items()
            }
            self.parameter_table.set_parameters(
                list(system.get("parameters", {}).items()),
                ranges,
            )
            effects = data.get("effects", {})
            disabled = set(effects.get("disabled", []))
            self.dissipation.set_text(effects.get("dissipation"))
            self.dissipation_switch.setChecked("dissipation" not in disabled)
            self._rebuild_force_rows(
                system.get("coordinates", []), effects.get("forces", {}), disabled
            )
            self.initial_table.setRowCount(0)
            for name, value in data.get("initial", {}).items():
                row = self.initial_table.rowCount()
                self.initial_table.insertRow(row)
                self.initial_table.setItem(row, 0, QTableWidgetItem(name))
                self.initial_table.setItem(
                    row, 1, QTableWidgetItem(f"{value:g}" if not isinstance(value, str) else value)
                )
            self.clear_errors()
        finally:
            self._filling = False

    def _rebuild_force_rows(self, coordinates, forces: dict, disabled: set) -> None:
        """One force field per coordinate, below the dissipation row (which stays)."""
        typed = {
            q: (f.text(), self.force_switches[q].isChecked()) for q, f in self.force_fields.items()
        }
        while self.effects_form.rowCount() > 1:
            self.effects_form.removeRow(1)
        self.force_fields.clear()
        self.force_switches.clear()
        for q in coordinates:
            field = ExpressionField(f"generalized force Q on {q}")
            text, on = typed.get(q, (None, True))
            field.set_text(forces.get(q, text))
            field.edited.connect(self._on_field_edited)
            switch = QCheckBox("on")
            switch.setChecked(f"forces.{q}" not in disabled if q in forces else on)
            switch.toggled.connect(self._on_field_edited)
            self.force_fields[q] = field
            self.force_switches[q] = switch
            self.effects_form.addRow(
                f"Q<sub>{coordinate_label(q)}</sub> =", self._with_switch(field, switch)
            )

    @staticmethod
    def _with_switch(field: ExpressionField, switch: QCheckBox) -> QWidget:
        row = QWidget()
        layout = QHBoxLayout(row)
        layout.setContentsMargins(0, 0, 0, 0)
        layout.addWidget(field, 1)
        layout.addWidget(switch, 0, Qt.AlignmentFlag.AlignTop)
        return row

    def _show_kind(self, kind: str) -> None:
        visible = {"energies": ("kinetic", "potential")}.get(kind, (kind,))
        for key, field in self.fields.items():
            self.system_form.setRowVisible(field, key in visible)

    # -- reading the fields --------------------------------------------------------------------

    def data(self) -> dict:
        """The fields as the tables of a scene document (what the builder reads)."""
        coordinates = [
            c.strip() for c in self.coordinates.text().replace(";", ",").split(",") if c.strip()
        ]
        kind = self.kind_combo.currentData()
        system: dict = {"coordinates": coordinates}
        system["parameters"] = {
            name: _number_or_text(value) for name, value in self.parameter_table.parameters()
        }
        keys = ("kinetic", "potential") if kind == "energies" else (kind,)
        for key in keys:
            text = self.fields[key].text().strip()
            if text or key == "kinetic":
                system[key] = text
        data: dict = {"title": self.title_edit.text(), "system": system}
        if self._data.get("description"):
            data["description"] = self._data["description"]
        effects: dict = {}
        disabled = []
        if self.dissipation.text().strip():
            effects["dissipation"] = self.dissipation.text().strip()
            if not self.dissipation_switch.isChecked():
                disabled.append("dissipation")
        forces = {}
        for q, field in self.force_fields.items():
            if field.text().strip() and q in coordinates:
                forces[q] = field.text().strip()
                if not self.force_switches[q].isChecked():
                    disabled.append(f"forces.{q}")
        if forces:
            effects["forces"] = forces
        if disabled:
            effects["disabled"] = disabled
        if effects:
            data["effects"] = effects
        initial = {}
        for row in range(self.initial_table.rowCount()):
            name_item, value_item = self.initial_table.item(row, 0), self.initial_table.item(row, 1)
            if name_item and value_item and name_item.text().strip():
                initial[name_item.text().strip()] = _number_or_text(value_item.text().strip())
        data["initial"] = initial
        for key in ("drawing", "view"):
            if key in self._data:
                data[key] = self._data[key]
        return data

    def snapshot(self) -> dict:
        data = self.data()
        data["editor_ranges"] = {k: list(v) for k, v in self.parameter_table.ranges().items()}
        return data

    # -- results from the builder -----------------------------------------------------------------

    def clear_errors(self) -> None:
        for field in (
            self.coordinates,
            *self.fields.values(),
            self.dissipation,
            *self.force_fields.values(),
        ):
            field.clear_error()
        for label in (self.parameter_error, self.initial_error, self.general_error):
            label.clear()
            label.setVisible(False)
        self._refusal_shown = False

    def show_built(self, built) -> None:
        """A successful build: clear the errors, show the classification card."""
        self._built_scene = built.scene
        self.clear_errors()
        mechanics = built.compiled.mechanics
        self.state_label.setText(f"derived and compiled in {built.seconds:.2f} s")
        card = classification_html(mechanics, built.method, built.reason)
        self._card = card
        self.classification_card.setText(card)
        self.derivation_card.setText(card)

    def show_equilibria(self, lines: list[str]) -> None:
        """Add the equilibria (virtual work, small oscillations) to the classification card."""
        items = "".join(f"<li>{html.escape(line)}</li>" for line in lines)
        card = (
            getattr(self, "_card", "")
            + "<p style='margin-top:4px'><b>Equilibria</b> (dV/dq = 0)</p>"
            + f"<ul style='margin:0'>{items}</ul>"
        )
        self.classification_card.setText(card)
        self.derivation_card.setText(card)

    def show_derivation(self, text: str) -> None:
        self.derived.setPlainText(text)

    def show_failure(self, failure) -> None:
        """Show a build failure at its field, with its position; the text stays as typed."""
        self.clear_errors()
        field = failure.field or ""
        reason = failure.reason or failure.message
        target = self._field_for(field)
        if target is not None:
            target.show_error(reason, failure.position)
        elif field.startswith("system.parameters"):
            self._show_label(self.parameter_error, f"{field}: {reason}")
        elif field.startswith("initial"):
            self._show_label(self.initial_error, f"{field}: {reason}")
        else:
            self._show_label(self.general_error, failure.message)
        self.state_label.setText("not derived: see the error")

    def show_failure_message(self, message: str) -> None:
        """Show ``message`` at the top of the System tab (an error that belongs to no field),
        and bring it into view."""
        self.clear_errors()
        self._show_label(self.general_error, message)
        self.tabs.setCurrentIndex(0)
        self._scroll.verticalScrollBar().setValue(0)

    @staticmethod
    def _show_label(label: QLabel, text: str) -> None:
        label.setText(error_html(text, None, None))
        label.setVisible(True)

    def _field_for(self, field: str) -> ExpressionField | None:
        if field == "system.coordinates":
            return self.coordinates
        if field.startswith("system.") and field[7:] in self.fields:
            return self.fields[field[7:]]
        if field == "effects.dissipation":
            return self.dissipation
        if field.startswith("effects.forces."):
            return self.force_fields.get(field[len("effects.forces.") :])
        return None

    def scene_text(self) -> str:
        """The last built system with the current parameter values, as scene TOML."""
        if self._built_scene is None:
            raise RuntimeError("nothing has been derived yet")
        values = {
            k: v
            for k, v in self.parameter_table.values().items()
            if k in self._built_scene.parameter_values
        }
        return self._built_scene.with_parameters(**values).to_toml()

    # -- edits and history ----------------------------------------------------------------

    def _on_field_edited(self, *_args) -> None:
        if not self._filling:
            self.debounce.start()

    def _on_kind_index_changed(self, _index: int) -> None:
        self._show_kind(self.kind_combo.currentData())
        self._on_field_edited()

    def _on_parameter_values_changed(self, values: dict) -> None:
        if self._filling:
            return
        reason = self.parameter_check(values) if self.parameter_check is not None else None
        if reason:
            accepted = self.parameter_table.accepted_values()
            changed = [k for k, v in values.items() if accepted.get(k) != v]
            typed = ", ".join(f"{k} = {values[k]:g}" for k in changed) or "the values"
            kept = ", ".join(f"{k} = {accepted[k]:g}" for k in changed if k in accepted)
            self.parameter_table.revert()
            self._refuse(f"{typed} refused{f' (kept {kept})' if kept else ''}: {reason}")
            return
        self.parameter_table.accept()
        if self._refusal_shown:
            self._refusal_shown = False
            self.parameter_error.clear()
            self.parameter_error.setVisible(False)
        self.parameters_changed.emit(values)

    def _on_parameter_value_refused(self, message: str) -> None:
        self._refuse(message)

    def _refuse(self, message: str) -> None:
        self._show_label(self.parameter_error, message)
        self._refusal_shown = True
        self.last_refusal = message
        self.parameter_refused.emit(message)

    def _on_debounce_timeout(self) -> None:
        data = self.snapshot()
        coordinates = data["system"]["coordinates"]
        if set(coordinates) != set(self.force_fields):
            effects = data.get("effects", {})
            self._filling = True
            self._rebuild_force_rows(
                coordinates, effects.get("forces", {}), set(effects.get("disabled", []))
            )
            self._filling = False
        if self._index >= 0 and self._history[self._index] == data:
            return
        del self._history[self._index + 1 :]
        self._history.append(data)
        self._index = len(self._history) - 1
        self._update_history_buttons()
        self._emit(data)

    def _emit(self, data: dict) -> None:
        self.state_label.setText("deriving…")
        self.scene_edited.emit({k: v for k, v in data.items() if k != "editor_ranges"})

    def undo(self) -> None:
        if self._index > 0:
            self.debounce.stop()
            self._index -= 1
            self._restore()

    def redo(self) -> None:
        if self._index < len(self._history) - 1:
            self.debounce.stop()
            self._index += 1
            self._restore()

    def _restore(self) -> None:
        data = self._history[self._index]
        self._fill(data)
        self._update_history_buttons()
        self._emit(data)

    def _update_history_buttons(self) -> None:
        self.undo_button.setEnabled(self._index > 0)
        self.redo_button.setEnabled(self._index < len(self._history) - 1)

    def shutdown(self) -> None:
        self.debounce.stop()


def classification_html(mechanics, method: str, reason: str) -> str:
    """The classification card: the textbook's words, cyclic coordinates, the method."""
    cls = mechanics.classification
    scene = mechanics.scene

    def badge(ok: bool, text: str) -> str:
        colour = "#1b7f3b" if ok else "#a15c00"
        return f"<span style='color:{colour}'>{'●' if ok else '○'}</span> {html.escape(text)}"

    rows = [
        badge(
            not cls.time_dependent,
            "scleronomic (no explicit t)"
            if not cls.time_dependent
            else "rheonomic (depends on t explicitly)",
        ),
        badge(
            cls.conservative,
            "conservative" if cls.conservative else "not conservative (effects act)",
        ),
        badge(
            cls.hamiltonian_conserved,
            "H is conserved" if cls.hamiltonian_conserved else "H is not conserved",
        ),
        badge(
            cls.hamiltonian_is_energy,
            "H = T + V (the energy)" if cls.hamiltonian_is_energy else "H ≠ T + V",
        ),
        badge(
            cls.natural, "natural: T quadratic in the velocities" if cls.natural else "not natural"
        ),
        badge(
            cls.separable,
            "separable: H = T(p) + V(q)" if cls.separable else "not separable: T depends on q",
        ),
    ]
    cyclic = ", ".join(coordinate_label(q) for q in mechanics.cyclic) or "none"
    rows.append(f"cyclic coordinates: {html.escape(cyclic)}")
    conserved = ", ".join(mechanics.conserved) or "none"
    rows.append(f"conserved: {html.escape(conserved)}")
    if method:
        rows.append(f"integrator: <b>{html.escape(method)}</b> — {html.escape(reason)}")
    title = html.escape(scene.title)
    return f"<b>{title}</b><br>" + "<br>".join(rows)
