"""The system editor: pick from the catalogue or type a system; see what it derives to.

The editor holds a scene *document*: the tables of a scene file, as typed, whether or
not they make a valid scene (``document``, ``document_text``). Edits are debounced
(``DEBOUNCE_MS``) and the document is sent (``scene_edited``) to the builder, which reads
it with ``drop_unfit=True``, derives and compiles in the background. Errors come back
with their field and position and are shown under that field, leaving the typed text as
it was; a drawing or ``[view]`` setting that does not fit the system is left out of the
build and shown as a warning (``Scene.warnings``). Every debounced edit is a step of the
undo history.

Editing the coordinates brings the initial-state table and the force rows along: rows
of coordinates that remain keep their values, rows of new coordinates are added (blank:
0), and the values of coordinates that were removed are remembered in case they return.

The kinds of system: T and V, particles (their positions give T; ``[particles]`` and
``system.gravity``) and V, L, or H. The fields of the kinds not chosen keep their text
(also through undo: a history step holds them under ``editor_hidden``), so switching the
kind back and forth loses nothing; the document holds only the chosen kind's.
``[constraints]`` and ``[symmetries]`` have sections of their own (``ConstraintsSection``,
``SymmetriesSection``), whatever the kind.

A parameter value goes out (``parameters_changed``) only once ``parameter_check`` (set by
the window) finds nothing wrong with it; a refused value is put back in the table and the
reason shown under it. A parameter name is checked as it is typed (see
``ParameterTableView.name_problem``).
"""

from __future__ import annotations

import html
import re
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

from PySide6.QtCore import Qt, QTimer, Signal
from PySide6.QtWidgets import (
    QCheckBox,
    QComboBox,
    QFileDialog,
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
    QVBoxLayout,
    QWidget,
)

from explorer.editor.constraints_section import ConstraintsSection
from explorer.editor.derivation_view import DerivationView
from explorer.editor.drawing_section import DrawingSection
from explorer.editor.fields import ExpressionField, error_html, never_widens
from explorer.editor.parameters_table import ParameterTableView, fit_rows, number_text
from explorer.editor.particles_section import ParticlesSection
from explorer.editor.scroll_anchor import ScrollAnchor
from explorer.editor.symmetries_section import SymmetriesSection
from explorer.inline_math import MathLabel
from explorer.labels import coordinate_label, momentum_label
from systems.typeset import Typeset

DEBOUNCE_MS = 400
KINDS = (
    ("energies", "T and V"),
    ("particles", "Particles and V"),
    ("lagrangian", "Lagrangian L"),
    ("hamiltonian", "Hamiltonian H"),
)
DOCUMENT_KEYS = (
    "title",
    "description",
    "system",
    "particles",
    "constraints",
    "symmetries",
    "effects",
    "initial",
    "drawing",
    "view",
)
SYSTEM_KEYS = (
    "coordinates",
    "parameters",
    "kinetic",
    "potential",
    "lagrangian",
    "hamiltonian",
    "gravity",
)
EFFECT_KEYS = ("dissipation", "forces", "disabled")

NEW_SCENE: dict = {
    "title": "New scene",
    "system": {
        "coordinates": ["x"],
        "parameters": {"m": 1.0, "k": 1.0},
        "kinetic": "m*x_dot**2/2",
        "potential": "k*x**2/2",
    },
    "initial": {"x": 1.0, "x_dot": 0.0},
}
"""The template of File > New scene: a mass on a spring, to be typed over."""

NEW_SCENE_NOTE = (
    "A new scene, starting as a mass on a spring: type your coordinates, T and V (or the "
    "particles and their positions, or L, or H), the parameters, the initial state, and "
    "points to draw it."
)
WARNING_STYLE = (
    "QLabel { background: #fff8e1; border: 1px solid #e0a800; border-radius: 4px; padding: 4px; }"
)
INFO_STYLE = (
    "QLabel { background: #f4f7fb; border: 1px solid #c9d6e6; border-radius: 4px; padding: 4px; }"
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
    if scene.gravity is not None:
        system["gravity"] = scene.gravity if isinstance(scene.gravity, str) else [*scene.gravity]
    data: dict = {"title": scene.title, "description": scene.description, "system": system}
    if scene.particles:
        data["particles"] = {
            p.name: {"mass": p.mass, "position": list(p.position)} for p in scene.particles
        }
    constraints = {
        kind: list(getattr(scene, f"{kind}_constraints"))
        for kind in ("holonomic", "nonholonomic", "unilateral")
        if getattr(scene, f"{kind}_constraints")
    }
    if constraints:
        data["constraints"] = constraints
    if scene.symmetries:
        data["symmetries"] = {name: dict(entries) for name, entries in scene.symmetries}
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
        own = {(p.name, p.position[0], p.position[1]) for p in scene.particles}
        drawing = {  # a particle's own point comes from [particles], not from [drawing]
            "points": {
                name: [x, y] for name, x, y in scene.drawing.points if (name, x, y) not in own
            }
        }
        if scene.drawing.links:
            drawing["links"] = [list(link) for link in scene.drawing.links]
        if scene.drawing.trace:
            drawing["trace"] = list(scene.drawing.trace)
        data["drawing"] = drawing
    if scene.view:
        data["view"] = dict(scene.view)
    return data


KIND_FIELDS = {
    "energies": ("kinetic", "potential"),
    "particles": ("potential",),
    "lagrangian": ("lagrangian",),
    "hamiltonian": ("hamiltonian",),
}
"""The expression fields each kind of system shows (and writes into the document)."""


def document_kind(data: Mapping) -> str:
    """How a document gives its system: a key of ``KINDS``.

    A Lagrangian or Hamiltonian wins (a document that also has particles is refused by
    the scene, which says why); then ``[particles]``, then T and V.
    """
    system = _table(data.get("system"))
    for kind in ("lagrangian", "hamiltonian"):
        if kind in system:
            return kind
    return "particles" if "particles" in data else "energies"


def _number_or_text(text: str):
    try:
        return float(text)
    except ValueError:
        return text


def _text(value: Any) -> str:
    """A document value shown in a field: numbers without a trailing .0, lists joined."""
    if value is None:
        return ""
    if isinstance(value, bool):
        return str(value).lower()
    if isinstance(value, int | float):
        return number_text(value)
    if isinstance(value, list | tuple):
        return ", ".join(_text(v) for v in value)
    return str(value)


def split_names(text: str) -> list[str]:
    """Names typed as a list: separated by commas, semicolons or spaces."""
    return [name for name in re.split(r"[\s,;]+", text) if name]


def _owner(name: str, coordinates) -> str | None:
    """The coordinate whose value, velocity or momentum ``name`` is, or None."""
    for q in coordinates:
        if name in (q, f"{q}_dot", f"p_{q}"):
            return q
    return None


def _renames(old: tuple[str, ...], new: tuple[str, ...]) -> dict[str, str]:
    """Coordinates renamed in place: same count, a name at the same index replaced by one
    that was not there before (old name -> new name)."""
    if len(old) != len(new):
        return {}
    return {a: b for a, b in zip(old, new, strict=True) if a != b and a not in new and b not in old}


def _shape(document: dict) -> dict:
    """A document with its parameter values left out (their names kept)."""
    system = _table(document.get("system"))
    parameters = list(_table(system.get("parameters")))
    return {**document, "system": {**system, "parameters": parameters}}


def _table(value: Any) -> Mapping:
    return value if isinstance(value, Mapping) else {}


class SystemEditorPanel(QWidget):
    """Catalogue, system fields, parameters, effects, initial state, drawing, derived results.

    Signals
    -------
    scene_edited(dict)        the document to build: after a debounced edit, an undo or
                              redo, ``new_scene`` and ``show_document``
    catalogue_selected(str)   a catalogue scene name was chosen
    parameters_changed(dict)  a parameter value moved (no re-derivation needed)
    parameter_refused(str)    a typed or dragged value, or a parameter name, was refused
                              and put back; why

    Attributes
    ----------
    parameter_check : callable or None
        ``check(values) -> reason or None``, asked before ``parameters_changed`` goes out
        with ``values`` (name -> float); a reason refuses them.
    """

    scene_edited = Signal(object)  # a dict: Signal(dict) would sort its keys (QVariantMap)
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
        self._synced: tuple[str, ...] = ()  # the coordinates the rows were made for
        self._initial_memory: dict[str, str] = {}  # values of removed coordinates
        self._force_memory: dict[str, tuple[str, bool]] = {}
        self._requested: dict | None = None  # the document of the last build asked for
        self._outcome: tuple[str, dict | None, str] = ("", None, "")
        self._saved: dict | None = None  # the document as opened or last saved
        self._view_warnings: list = []
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
        self.coordinates = ExpressionField("names, e.g. theta, phi")
        self.kind_combo = QComboBox()
        for key, label in KINDS:
            self.kind_combo.addItem(label, key)
        self.kind_combo.setToolTip(
            "Give the system by its energies T and V, by its particles (T from their "
            "positions) and V, by L, or by H"
        )
        self.kind_combo.currentIndexChanged.connect(self._on_kind_index_changed)
        self.fields = {
            "kinetic": ExpressionField("T(q, q_dot, t), e.g. m*l**2*theta_dot**2/2"),
            "potential": ExpressionField("V(q, t), e.g. -m*g*l*cos(theta)"),
            "lagrangian": ExpressionField("L(q, q_dot, t)"),
            "hamiltonian": ExpressionField("H(q, p_q, t)"),
        }
        system_box = QGroupBox("System")
        self.system_form = QFormLayout(system_box)
        self.system_form.setFieldGrowthPolicy(QFormLayout.FieldGrowthPolicy.AllNonFixedFieldsGrow)
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
        self.particles = ParticlesSection()  # in place of T, above V
        self.system_form.insertRow(self.system_form.rowCount() - 3, self.particles)

        self.parameter_table = ParameterTableView()
        self.parameter_table.values_changed.connect(self._on_parameter_values_changed)
        self.parameter_table.value_refused.connect(self._on_parameter_value_refused)
        self.parameter_table.name_refused.connect(self._on_parameter_value_refused)
        self.parameter_table.structure_changed.connect(self._on_parameter_structure_changed)
        self.parameter_error = QLabel()
        never_widens(self.parameter_error)
        self.add_button = QPushButton("Add")
        self.add_button.setToolTip("Add a parameter with a free name; edit its name and value")
        self.add_button.clicked.connect(lambda: self.parameter_table.add_parameter())
        self.remove_button = QPushButton("Remove")
        self.remove_button.setToolTip("Remove the selected parameters")
        self.remove_button.clicked.connect(self.parameter_table.remove_selected)
        parameters_box = QGroupBox("Parameters")
        parameters_layout = QVBoxLayout(parameters_box)
        parameters_layout.addWidget(self.parameter_table)
        buttons = QHBoxLayout()
        buttons.addWidget(self.add_button)
        buttons.addWidget(self.remove_button)
        buttons.addStretch(1)
        parameters_layout.addLayout(buttons)
        parameters_layout.addWidget(self.parameter_error)

        self.effects_box = QGroupBox("Effects (switch on or off)")
        self.effects_form = QFormLayout(self.effects_box)
        self.effects_form.setFieldGrowthPolicy(QFormLayout.FieldGrowthPolicy.AllNonFixedFieldsGrow)
        self.dissipation = ExpressionField("R(q, q_dot, t), e.g. b*x_dot**2/2")
        self.dissipation_switch = QCheckBox("on")
        self.dissipation_switch.setChecked(True)
        self.dissipation_switch.toggled.connect(self._on_field_edited)
        self.force_fields: dict[str, ExpressionField] = {}
        self.force_switches: dict[str, QCheckBox] = {}
        self.effects_form.addRow(
            "R =", self._with_switch(self.dissipation, self.dissipation_switch)
        )

        self.initial_table = QTableWidget(0, 2)
        self.initial_table.setHorizontalHeaderLabels(["name", "value (blank: 0)"])
        self.initial_table.verticalHeader().setVisible(False)
        self.initial_table.horizontalHeader().setSectionResizeMode(QHeaderView.ResizeMode.Stretch)
        fit_rows(self.initial_table, least=2)
        self.initial_table.itemChanged.connect(self._on_field_edited)
        self.initial_error = QLabel()
        never_widens(self.initial_error)
        initial_box = QGroupBox("Initial state (q and q_dot, or p_q)")
        initial_layout = QVBoxLayout(initial_box)
        initial_layout.addWidget(self.initial_table)
        initial_layout.addWidget(self.initial_error)

        self.drawing = DrawingSection()
        self.drawing.edited.connect(self._on_field_edited)
        self.constraints = ConstraintsSection()
        self.symmetries = SymmetriesSection()

        self.general_error = QLabel()  # at the top: a refused file or build is seen at once
        never_widens(self.general_error)
        self.general_error.setVisible(False)
        self.general_error.setStyleSheet(
            "QLabel { background: #fff3f3; border: 1px solid #d62728; border-radius: 4px;"
            " padding: 4px; }"
        )
        self.warning_label = QLabel()  # what was left out of the build, and why
        never_widens(self.warning_label)
        self.warning_label.setVisible(False)
        self.warning_label.setTextFormat(Qt.TextFormat.RichText)
        self.warning_label.setStyleSheet(WARNING_STYLE)
        self.warning_label.linkActivated.connect(self._on_warning_link_activated)
        self.info_label = QLabel()  # a note that goes with the first edit
        never_widens(self.info_label)
        self.info_label.setVisible(False)
        self.info_label.setStyleSheet(INFO_STYLE)
        self.undo_button = QPushButton("Undo")
        self.undo_button.clicked.connect(self.undo)
        self.redo_button = QPushButton("Redo")
        self.redo_button.clicked.connect(self.redo)
        self.state_label = QLabel("")
        never_widens(self.state_label)
        history = QHBoxLayout()
        history.addWidget(self.undo_button)
        history.addWidget(self.redo_button)
        history.addWidget(self.state_label, 1)

        self.classification_card = MathLabel()  # its formulas set in type
        never_widens(self.classification_card)
        self.classification_card.setTextFormat(Qt.TextFormat.RichText)
        self.classification_card.setStyleSheet(
            "QLabel { background: #f4f7fb; border: 1px solid #c9d6e6; border-radius: 6px;"
            " padding: 6px; }"
        )
        # the card and the derivation, typeset, in one scroll area that follows the
        # window's font (presentation mode) and palette
        self.derived = DerivationView()
        self.derived.export_requested.connect(self._on_derived_export_requested)

        content = QWidget()
        layout = QVBoxLayout(content)
        layout.addWidget(self.general_error)
        layout.addWidget(self.warning_label)
        layout.addWidget(self.info_label)
        layout.addWidget(QLabel("<b>Catalogue</b>"))
        layout.addWidget(self.catalogue)
        layout.addWidget(system_box)
        layout.addLayout(history)
        layout.addWidget(parameters_box)
        layout.addWidget(self.constraints)
        layout.addWidget(self.effects_box)
        layout.addWidget(self.symmetries)
        layout.addWidget(initial_box)
        layout.addWidget(self.drawing)
        layout.addWidget(QLabel("<b>Classification</b>"))
        layout.addWidget(self.classification_card)
        layout.addStretch(1)
        scroll = QScrollArea()
        scroll.setWidgetResizable(True)
        scroll.setWidget(content)
        self._scroll = scroll
        # a build finishing never moves the page under the hand
        self.scroll_anchor = ScrollAnchor(scroll)
        derivation = QWidget()
        derivation_layout = QVBoxLayout(derivation)
        derivation_layout.setContentsMargins(0, 0, 0, 0)
        derivation_layout.setSpacing(2)
        buttons = QHBoxLayout()
        buttons.setContentsMargins(4, 4, 4, 0)
        self.copy_latex_button = QPushButton("Copy LaTeX")
        self.copy_latex_button.setToolTip(
            "The selected equation as LaTeX (click one), or the whole derivation; "
            "right-click an equation for more"
        )
        self.copy_latex_button.clicked.connect(self._on_copy_latex_button_clicked)
        self.export_derivation_button = QPushButton("Export derivation…")
        self.export_derivation_button.setToolTip("The derivation as PDF, SVG or LaTeX")
        self.export_derivation_button.clicked.connect(self._on_derived_export_requested)
        buttons.addWidget(self.copy_latex_button)
        buttons.addWidget(self.export_derivation_button)
        buttons.addStretch(1)
        derivation_layout.addLayout(buttons)
        derivation_layout.addWidget(self.derived, 1)
        self.tabs = QTabWidget()
        self.tabs.addTab(scroll, "System")
        self.tabs.addTab(derivation, "Derivation")
        outer = QVBoxLayout(self)
        outer.setContentsMargins(0, 0, 0, 0)
        outer.addWidget(self.tabs)

        for field in (self.coordinates, *self.fields.values(), self.dissipation):
            field.edited.connect(self._on_field_edited)
            field.action_requested.connect(self._on_field_action_requested)
        for section in (self.particles, self.constraints, self.symmetries):
            section.edited.connect(self._on_field_edited)
            section.action_requested.connect(self._on_field_action_requested)
        self.particles.renamed.connect(self._on_particle_renamed)
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

    def _select_catalogue(self, name: str | None) -> None:
        for i in range(self.catalogue.count()):
            item = self.catalogue.item(i)
            item.setSelected(item.data(Qt.ItemDataRole.UserRole) == name)

    # -- opening: a scene, a new one, a document --------------------------------------------

    def show_scene(self, scene) -> None:
        """Show a scene's fields and start a fresh undo history (the caller builds it).

        What was shown before is kept until the next opening, for ``restore_previous``.
        """
        self._open(data_from_scene(scene), catalogue_name=scene.name)

    def new_scene(self) -> None:
        """Start a new scene from the ``NEW_SCENE`` template and ask for its build.

        A fresh undo history; what was shown before is kept for ``restore_previous``.
        ``scene_edited`` goes out at once (the window builds the scene from it).
        """
        import copy

        self._open(copy.deepcopy(NEW_SCENE), catalogue_name=None)
        self._show_info(NEW_SCENE_NOTE)
        self._emit(self._history[0])

    def show_document(self, text: str, source: str = "<text>") -> list[str]:
        """Show a scene document (TOML text), valid as a scene or not, and ask for its build.

        This opens what ``document_text`` saved, however unfinished: every table is shown
        as written. Keys the editor has no place for (not part of the scene format) are
        left out and named in a note; they are returned. ``scene_edited`` goes out at once.

        Raises
        ------
        systems.scene.SceneError
            If ``text`` is not TOML (or is too long or nested too deeply); nothing changes.
        """
        from systems.scene import read_document

        tables = read_document(text, source)
        ignored = [key for key in tables if key not in DOCUMENT_KEYS]
        ignored += [f"system.{k}" for k in _table(tables.get("system")) if k not in SYSTEM_KEYS]
        ignored += [f"effects.{k}" for k in _table(tables.get("effects")) if k not in EFFECT_KEYS]
        for key in ("system", "effects", "initial", "drawing", "view"):
            if key in tables and not isinstance(tables[key], Mapping):
                ignored.append(key)
        name = Path(source).stem if source.endswith(".toml") else None
        self._open(tables, catalogue_name=name)
        if ignored:
            self._show_info(
                f"Not kept from {source} (the scene format has no such keys): " + ", ".join(ignored)
            )
        self._emit(self._history[0])
        return ignored

    def _open(self, data: dict, catalogue_name: str | None) -> None:
        self.debounce.stop()
        self._previous = None
        if self._history:
            self._previous = (
                self.snapshot(),
                self._history,
                self._index,
                self.derived.state(),
                self._built_scene.name if self._built_scene is not None else None,
                self._requested,
                self._outcome,
                self._saved,
            )
        self._initial_memory.clear()
        self._force_memory.clear()
        self._fill(data)
        snapshot = self.snapshot()
        self._history = [snapshot]
        self._index = 0
        self._requested = self.document()
        self._outcome = ("", None, "")
        self._saved = self.document()
        self._update_history_buttons()
        self.derived.set_plain("deriving…")
        self.state_label.setText("deriving…")
        self._select_catalogue(catalogue_name)

    def restore_previous(self) -> bool:
        """Show again what was shown before the last opening (a refused opening).

        Returns False if there was nothing before (the first scene).
        """
        if self._previous is None:
            return False
        data, history, index, derived, name, requested, outcome, saved = self._previous
        self._previous = None
        self.debounce.stop()
        self._fill(data)
        self._history, self._index = history, index
        self._requested, self._outcome, self._saved = requested, outcome, saved
        self._update_history_buttons()
        self.derived.restore(derived)
        self.state_label.setText("")
        self._select_catalogue(name)
        return True

    def _fill(self, data: dict) -> None:
        """Show a document (tolerant of wrong types: what cannot be shown is left out)."""
        self._filling = True
        try:
            self._data = data
            system = _table(data.get("system"))
            self.title_edit.setText(_text(data.get("title", "")))
            coordinates = system.get("coordinates", [])
            self.coordinates.set_text(_text(coordinates))
            kind = document_kind(data)
            self.kind_combo.setCurrentIndex([k for k, _ in KINDS].index(kind))
            hidden = _table(data.get("editor_hidden"))  # a history step: the hidden fields too
            texts = _table(hidden.get("texts"))
            for key, field in self.fields.items():
                field.set_text(texts[key] if key in texts else _text(system.get(key)))
            if kind == "particles" or "particles" not in hidden:
                self.particles.set_particles(data.get("particles"), system.get("gravity"))
            else:
                self.particles.set_particles(hidden["particles"], hidden.get("gravity"))
            self._show_kind(kind)
            names = split_names(self.coordinates.text())
            self.constraints.set_constraints(data.get("constraints"))
            self.symmetries.set_symmetries(data.get("symmetries"), self._row_coordinates(names))
            ranges = {
                name: tuple(value) for name, value in _table(data.get("editor_ranges")).items()
            }
            self.parameter_table.set_parameters(
                list(_table(system.get("parameters")).items()), ranges
            )
            effects = _table(data.get("effects"))
            disabled = effects.get("disabled", [])
            disabled = {str(d) for d in disabled} if isinstance(disabled, list) else set()
            self.dissipation.set_text(_text(effects.get("dissipation")))
            self.dissipation_switch.setChecked("dissipation" not in disabled)
            forces = {
                str(q): (_text(text), f"forces.{q}" not in disabled)
                for q, text in _table(effects.get("forces")).items()
            }
            self._set_force_rows(names, forces)
            for q, entry in forces.items():  # a force on no coordinate: back if q comes
                if q not in names:
                    self._force_memory[q] = entry
            self._set_initial_rows(
                [(str(k), _text(v)) for k, v in _table(data.get("initial")).items()]
            )
            self._synced = ()
            self._sync_rows(names)
            self.drawing.set_drawing(data.get("drawing"))
            self.clear_errors()
        finally:
            self._filling = False

    # -- rows that follow the coordinates --------------------------------------------------

    def _row_coordinates(self, names: list[str]) -> tuple[str, ...]:
        """The names rows are made for: the valid ones, each once."""
        return tuple(dict.fromkeys(n for n in names if n.isidentifier()))

    def _sync_rows(self, names: list[str]) -> None:
        """Bring the initial-state table, the force rows and the parameter checks in line
        with the coordinates ``names``."""
        coordinates = self._row_coordinates(names)
        self.parameter_table.set_reserved(coordinates)
        if coordinates == self._synced:
            return
        old, self._synced = self._synced, coordinates
        filling, self._filling = self._filling, True
        try:
            self._sync_initial(old, coordinates)
            renamed = _renames(old, coordinates)
            typed = {
                renamed.get(q, q): (f.text(), self.force_switches[q].isChecked())
                for q, f in self.force_fields.items()
            }
            for q, entry in typed.items():
                if q not in coordinates and entry[0].strip():
                    self._force_memory[q] = entry
            forces = {q: typed.get(q) or self._force_memory.pop(q, ("", True)) for q in coordinates}
            self._set_force_rows(coordinates, forces)
            self.symmetries.set_coordinates(coordinates, renamed)
        finally:
            self._filling = filling

    def _sync_initial(self, old: tuple[str, ...], new: tuple[str, ...]) -> None:
        renamed = _renames(old, new)
        rows = []
        for name, value in self._initial_rows():
            q = _owner(name, tuple(renamed))
            if q is not None:  # a coordinate renamed in place keeps its values
                r = renamed[q]
                name = r if name == q else f"{r}_dot" if name == f"{q}_dot" else f"p_{r}"
            if _owner(name, new) is None and _owner(name, old) is not None:
                if value:
                    self._initial_memory[name] = value  # its coordinate went away
            else:
                rows.append((name, value))  # of a coordinate, or typed: the build checks it
        present = {name for name, _ in rows}
        momenta = any(n.startswith("p_") and _owner(n, new) for n in present)
        velocities = any(n.endswith("_dot") and _owner(n, new) for n in present)
        use_momenta = momenta or (not velocities and self.kind_combo.currentData() == "hamiltonian")
        memory = self._initial_memory
        for q in new:
            if q not in present:
                rows.append((q, memory.pop(q, "")))
            v, p = f"{q}_dot", f"p_{q}"
            if v in present or p in present:
                continue
            if p in memory:
                rows.append((p, memory.pop(p)))
            elif v in memory:
                rows.append((v, memory.pop(v)))
            else:
                rows.append((p if use_momenta else v, ""))
        self._set_initial_rows(rows)

    def _initial_rows(self) -> list[tuple[str, str]]:
        rows = []
        for row in range(self.initial_table.rowCount()):
            name_item, value_item = self.initial_table.item(row, 0), self.initial_table.item(row, 1)
            name = name_item.text().strip() if name_item else ""
            value = value_item.text().strip() if value_item else ""
            if name or value:
                rows.append((name, value))
        return rows

    def _set_initial_rows(self, rows: list[tuple[str, str]]) -> None:
        filling, self._filling = self._filling, True
        try:
            self.initial_table.setRowCount(0)
            for name, value in rows:
                row = self.initial_table.rowCount()
                self.initial_table.insertRow(row)
                self.initial_table.setItem(row, 0, QTableWidgetItem(name))
                self.initial_table.setItem(row, 1, QTableWidgetItem(value))
            fit_rows(self.initial_table, least=2)
        finally:
            self._filling = filling

    def _set_force_rows(self, coordinates, forces: dict[str, tuple[str, bool]]) -> None:
        """One force field per coordinate, below the dissipation row (which stays)."""
        while self.effects_form.rowCount() > 1:
            self.effects_form.removeRow(1)
        self.force_fields.clear()
        self.force_switches.clear()
        for q in self._row_coordinates(list(coordinates)):
            field = ExpressionField(f"force on {q}: Q(q, q_dot, t)")
            text, on = forces.get(q, ("", True))
            field.set_text(text)
            field.edited.connect(self._on_field_edited)
            field.action_requested.connect(self._on_field_action_requested)
            switch = QCheckBox("on")
            switch.setChecked(on)
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
        visible = KIND_FIELDS[kind]
        for key, field in self.fields.items():
            self.system_form.setRowVisible(field, key in visible)
        self.system_form.setRowVisible(self.particles, kind == "particles")

    # -- the document ------------------------------------------------------------------------

    def document(self) -> dict:
        """The tables of the scene document the editor holds, as typed (see ``document_text``)."""
        coordinates = split_names(self.coordinates.text())
        kind = self.kind_combo.currentData()
        system: dict = {"coordinates": coordinates}
        system["parameters"] = {
            name: _number_or_text(value) for name, value in self.parameter_table.parameters()
        }
        keys = KIND_FIELDS[kind]
        for key in keys:
            text = self.fields[key].text().strip()
            if text or (key == keys[0] and kind != "particles"):  # T, L or H is required
                system[key] = text
        data: dict = {"title": self.title_edit.text(), "system": system}
        if kind == "particles":
            gravity = self.particles.gravity_value()
            if gravity is not None:
                system["gravity"] = gravity
            data["particles"] = self.particles.table()
        constraints = self.constraints.table()
        if constraints:
            data["constraints"] = constraints
        symmetries = self.symmetries.table()
        if symmetries:
            data["symmetries"] = symmetries
        if self._data.get("description"):
            data["description"] = _text(self._data["description"])
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
        data["initial"] = {
            name: _number_or_text(value) for name, value in self._initial_rows() if value
        }
        drawing = self.drawing.table()
        if drawing is not None:
            data["drawing"] = drawing
        if isinstance(self._data.get("view"), Mapping) and self._data["view"]:
            data["view"] = dict(self._data["view"])
        return data

    def data(self) -> dict:
        """The same as ``document`` (the name the window used first)."""
        return self.document()

    def follow_coordinates(self) -> None:
        """Bring the initial-state rows, force rows and symmetries in line with the
        coordinates typed, as the next debounced edit would (a session replays lines
        typed after that)."""
        self._sync_rows(split_names(self.coordinates.text()))

    def replace_table(self, key: str, value: Any) -> None:
        """Replace a part of the document as one edit, as typing it all would (a
        session's ``edit`` line).

        ``key`` is ``particles``, ``constraints``, ``symmetries``, ``drawing`` or
        ``view`` (``value``: the table, None for none) or ``gravity`` (its text).
        """
        self.follow_coordinates()
        if key == "particles":
            self.particles.set_particles(value, self.particles.gravity_value())
        elif key == "gravity":
            self.particles.gravity.set_text(value or "")
        elif key == "constraints":
            self.constraints.set_constraints(value)
        elif key == "symmetries":
            self.symmetries.set_symmetries(value, self._synced)
        elif key == "drawing":
            self.drawing.set_drawing(value)
        elif key == "view":
            self._data = {**self._data, "view": dict(value or {})}
        else:
            raise KeyError(f"no table {key!r} in the editor")
        self._on_field_edited()

    def snapshot(self) -> dict:
        """``document``, the sliders' ranges and the text of the fields the chosen kind
        hides: one step of the undo history."""
        data = self.document()
        data["editor_ranges"] = {k: list(v) for k, v in self.parameter_table.ranges().items()}
        data["editor_hidden"] = {
            "texts": {key: field.text() for key, field in self.fields.items()},
            "particles": self.particles.table(),
            "gravity": self.particles.gravity_value(),
        }
        return data

    def document_text(self) -> str:
        """Exactly what the editor holds, as scene TOML, whether it builds or not.

        This is what Save writes. An edit still waiting for its debounce is taken first
        (its build is asked for now). ``show_document`` of the text shows the same
        document again. Whether it built: ``build_status``.
        """
        from systems.scene import document_toml

        self.flush()
        return document_toml(self.document())

    def scene_text(self) -> str:
        """The same as ``document_text`` (kept for callers of the old name)."""
        return self.document_text()

    def flush(self) -> None:
        """Take an edit still waiting for the debounce now (history, build request)."""
        if self.debounce.isActive():
            self.debounce.stop()
            self._on_debounce_timeout()

    @property
    def build_status(self) -> str:
        """``"built"`` if the document as it is now was built, ``"failed"`` if its build
        failed (``build_problem`` says why), ``"pending"`` while it is not known yet.

        Parameter values are not part of the comparison: a value the window accepted is
        in force without a new build (a failed build is tried again when one moves).
        """
        kind, document, _ = self._outcome
        if kind and document is not None and _shape(document) == _shape(self.document()):
            return kind
        return "pending"

    @property
    def buildable(self) -> bool:
        """Whether the document as it is now was built successfully."""
        return self.build_status == "built"

    @property
    def build_problem(self) -> str:
        """Why the document as it is now does not build ("" if it does or is not known)."""
        return self._outcome[2] if self.build_status == "failed" else ""

    @property
    def modified(self) -> bool:
        """Whether the document differs from what was opened or last ``mark_saved``."""
        return self._saved is not None and self.document() != self._saved

    @property
    def typed_changes(self) -> bool:
        """Whether the document differs from what was opened or saved in more than the
        numbers of parameters and initial state (which sliders and tables change): what
        replacing it without saving would lose of what the user typed."""
        if self._saved is None:
            return False
        return _without_numbers(self.document()) != _without_numbers(self._saved)

    def mark_saved(self) -> None:
        """The document as it is now was written to a file: it is no longer modified."""
        self._saved = self.document()

    # -- results from the builder -----------------------------------------------------------------

    def clear_errors(self, keep_refusal: bool = False) -> None:
        """Hide every error and warning; ``keep_refusal`` keeps a refused parameter's
        message (it is about what the user typed, not about the build)."""
        keep = keep_refusal and self._refusal_shown
        for field in (
            self.coordinates,
            *self.fields.values(),
            self.dissipation,
            *self.force_fields.values(),
        ):
            field.clear_error()
        self.drawing.clear_errors()
        for section in (self.particles, self.constraints, self.symmetries):
            section.clear_errors()
        labels = [self.initial_error, self.general_error, self.warning_label]
        for label in labels if keep else [self.parameter_error, *labels]:
            label.clear()
            label.setVisible(False)
        self._view_warnings = []
        self._refusal_shown = keep

    def show_built(self, built) -> None:
        """A successful build: clear the errors, show the warnings and the classification."""
        self._built_scene = built.scene
        self._outcome = ("built", self._requested, "")
        self.clear_errors(keep_refusal=True)
        mechanics = built.compiled.mechanics
        warnings = tuple(getattr(built.scene, "warnings", ()))
        note = ""
        if warnings:
            note = f" — {len(warnings)} warning{'s' if len(warnings) > 1 else ''}, see above"
        self.state_label.setText(f"derived and compiled in {built.seconds:.2f} s{note}")
        self._show_warnings(warnings)
        card = classification_html(mechanics, built.method, built.reason)
        self._card = card
        self.classification_card.setText(card)
        self.derived.set_card(card)

    def _show_warnings(self, warnings) -> None:
        """Drawing problems under their fields; a summary of what was left out at the top."""
        drawing = [w for w in warnings if w.part == "drawing"]
        view = [w for w in warnings if w.part != "drawing"]
        for warning in drawing:
            self.drawing.show_problem(warning.field, warning.reason, warning.position)
        if drawing:
            self.drawing.show_left_out(len(drawing))
        self._view_warnings = view
        if not warnings:
            return
        items = []
        if drawing:
            count = "1 problem" if len(drawing) == 1 else f"{len(drawing)} problems"
            items.append(
                f"<li>the <b>drawing</b>: {count}, shown under its fields in the Drawing "
                "section</li>"
            )
        for warning in view:
            items.append(
                f"<li><b>{html.escape(warning.field)}</b>: {html.escape(warning.reason)}</li>"
            )
        remove = (
            "<br><a href='remove-view'>Remove these view settings from the scene</a>"
            if view
            else ""
        )
        self.warning_label.setText(
            "<b>Built without what does not fit the system:</b>"
            f"<ul style='margin:0'>{''.join(items)}</ul>{remove}"
        )
        self.warning_label.setVisible(True)

    def _on_warning_link_activated(self, link: str) -> None:
        if link == "remove-view":
            self.remove_unfit_view()

    def remove_unfit_view(self) -> None:
        """Delete from the document the ``[view]`` settings the last build left out.

        One step of the undo history; the scene is built again.
        """
        if not self._view_warnings:
            return
        view = dict(_table(self._data.get("view")))
        for warning in self._view_warnings:
            parts = warning.field.split(".")
            key = parts[1] if len(parts) > 1 else ""
            ranges = view.get("ranges")
            if key == "ranges" and len(parts) > 2 and isinstance(ranges, Mapping):
                view["ranges"] = {k: v for k, v in ranges.items() if k != parts[2]}
                if not view["ranges"]:
                    del view["ranges"]
            else:
                view.pop(key, None)
        self._data = {**self._data, "view": view}
        self._view_warnings = []
        self.debounce.stop()
        self._on_debounce_timeout()

    def show_equilibria(self, lines: list[str]) -> None:
        """Add the equilibria (virtual work, small oscillations) to the classification card."""
        items = "".join(f"<li>{html.escape(line)}</li>" for line in lines)
        card = (
            getattr(self, "_card", "")
            + "<p style='margin-top:4px'><b>Equilibria</b> (dV/dq = 0)</p>"
            + f"<ul style='margin:0'>{items}</ul>"
        )
        self.classification_card.setText(card)
        self.derived.set_card(card)

    def show_derivation(self, derivation) -> None:
        """Show the derivation: a ``systems.typeset.Typeset`` (typeset, or its equations
        still as text until their outlines come), or a text (why there is none)."""
        if isinstance(derivation, Typeset):
            self.derived.set_typeset(derivation)
        else:
            self.derived.set_plain(str(derivation))

    def _on_copy_latex_button_clicked(self) -> None:
        formula = self.derived.selected_formula()
        if formula is not None:
            self.derived.copy_formula(formula)
        else:
            self.derived.copy_all()

    def _on_derived_export_requested(self) -> None:
        """Ask where to write the derivation (PDF, SVG or LaTeX) and write it; a failure
        is said under the buttons, never raised."""
        if self.derived.typeset is None:
            self.state_label.setText("no derivation to export yet: it is being laid out")
            return
        title = self.derived.typeset.title or "derivation"
        name = "".join(c if c.isalnum() else "_" for c in title).strip("_").lower()
        path, _ = QFileDialog.getSaveFileName(
            self,
            "Export derivation",
            f"{name or 'derivation'}.pdf",
            "PDF (*.pdf);;SVG (*.svg);;LaTeX (*.tex)",
        )
        if path:
            self.export_derivation(path)

    def export_derivation(self, path: str) -> bool:
        """Write the derivation shown to ``path`` (.pdf, .svg or .tex); says in the
        state line what happened. Returns True if written."""
        try:
            self.derived.export(path)
        except (OSError, ValueError) as exc:
            self.state_label.setText(f"derivation not exported: {exc}")
            return False
        self.state_label.setText(f"derivation exported to {path}")
        return True

    def show_failure(self, failure) -> None:
        """Show a build failure at its field, with its position; the text stays as typed."""
        self._outcome = ("failed", self._requested, failure.message)
        self.clear_errors(keep_refusal=True)
        field = failure.field or ""
        reason = failure.reason or failure.message
        target = self._field_for(field)
        action = self._quick_fix(reason)
        sections = (self.particles, self.constraints, self.symmetries)
        if target is not None:
            target.show_error(reason, failure.position, action)
        elif any(s.show_problem(field, reason, failure.position, action) for s in sections):
            pass
        elif field.startswith("drawing"):
            self.drawing.show_problem(field, reason, failure.position)
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

    def _show_info(self, text: str) -> None:
        self.info_label.setText(text)
        self.info_label.setVisible(True)

    def _quick_fix(self, reason: str) -> tuple[str, str] | None:
        """For an unknown name that could be a parameter: the link that adds it."""
        match = re.match(r"unknown name '([A-Za-z]\w*)'", reason)
        if match is None or self.parameter_table.name_problem(match.group(1)) is not None:
            return None
        name = match.group(1)
        for step in self._history:  # a coordinate of a moment ago is no parameter
            coordinates = _table(step.get("system")).get("coordinates", ())
            if isinstance(coordinates, list) and _owner(name, coordinates) is not None:
                return None
        return f"add-parameter:{name}", f"Add {name} as a parameter (value 1)"

    def _on_field_action_requested(self, link: str) -> None:
        if link.startswith("add-parameter:"):
            self.parameter_table.add_parameter(link.split(":", 1)[1])

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

    # -- edits and history ----------------------------------------------------------------

    def _on_field_edited(self, *_args) -> None:
        if not self._filling:
            self.info_label.setVisible(False)
            self.debounce.start()

    def _on_particle_renamed(self, old: str, new: str) -> None:
        others = set(self.particles.names()) - {new}
        self.drawing.rename_references(old, new, others)

    def _on_kind_index_changed(self, _index: int) -> None:
        self._show_kind(self.kind_combo.currentData())
        self._on_field_edited()

    def _on_parameter_structure_changed(self) -> None:
        if self._refusal_shown:
            self._refusal_shown = False
            self.parameter_error.clear()
            self.parameter_error.setVisible(False)
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
        if self._outcome[0] == "failed":
            self.debounce.start()  # the value may be what failed (a zero mass): try again
        self.parameters_changed.emit(values)

    def _on_parameter_value_refused(self, message: str) -> None:
        self._refuse(message)

    def _refuse(self, message: str) -> None:
        self._show_label(self.parameter_error, message)
        self._refusal_shown = True
        self.last_refusal = message
        self.parameter_refused.emit(message)

    def _on_debounce_timeout(self) -> None:
        self._sync_rows(split_names(self.coordinates.text()))
        data = self.snapshot()
        if self._index >= 0 and self._history[self._index] == data:
            return
        del self._history[self._index + 1 :]
        self._history.append(data)
        self._index = len(self._history) - 1
        self._update_history_buttons()
        self._emit(data)

    def _emit(self, data: dict) -> None:
        self.state_label.setText("deriving…")
        document = {k: v for k, v in data.items() if not k.startswith("editor_")}
        self._requested = document
        self.scene_edited.emit(document)

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
    """The classification card: the textbook's words, cyclic coordinates, the method.

    The chapter's classes first (constraints, forces, simple or general), then what
    follows for the equations and H. A question with no answer (H against an energy that
    cannot be named) gets a neutral mark.
    """
    from systems import classification as words

    cls = mechanics.classification
    scene = mechanics.scene

    def badge(ok: bool | None, text: str) -> str:
        colour = {True: "#1b7f3b", False: "#a15c00", None: "#666666"}[ok]
        mark = {True: "●", False: "○", None: "◌"}[ok]
        return f"<span style='color:{colour}'>{mark}</span> {html.escape(text)}"

    rows = [
        badge(not cls.rheonomic, words.describe_rheonomic(cls.rheonomic)),
        badge(cls.holonomic, words.describe_holonomic(cls.holonomic)),
        badge(cls.bilateral, words.describe_bilateral(cls.bilateral)),
        badge(cls.conservative, words.describe_conservative(cls.conservative)),
        badge(cls.simple, words.describe_simple(cls.simple)),
        badge(
            not cls.time_dependent or cls.gauge_time,
            words.describe_time_dependent(cls.time_dependent, gauge_time=cls.gauge_time),
        ),
        badge(
            cls.hamiltonian_conserved,
            words.describe_hamiltonian_conserved(
                cls.hamiltonian_conserved, gauge_time=cls.gauge_time
            ),
        ),
        badge(cls.hamiltonian_is_energy, words.describe_energy(cls.hamiltonian_is_energy)),
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
    coordinates = set(scene.coordinates)

    def quantity(name: str) -> str:  # p_phi as p<sub>φ</sub>, set in type on the card
        if name.startswith("p_") and name[2:] in coordinates:
            return momentum_label(name[2:])
        return html.escape(name)

    conserved = ", ".join(quantity(name) for name in mechanics.conserved) or "none"
    rows.append(f"conserved: {conserved}")
    if method:
        rows.append(f"integrator: <b>{html.escape(method)}</b> — {html.escape(reason)}")
    title = html.escape(scene.title)
    return f"<b>{title}</b><br>" + "<br>".join(rows)


def _without_numbers(document: dict) -> dict:
    """A document with its parameter values and initial state left out."""
    document = dict(document)
    system = dict(document.get("system") or {})
    parameters = system.get("parameters")
    if isinstance(parameters, Mapping):
        system["parameters"] = sorted(parameters)
    document["system"] = system
    document.pop("initial", None)
    return document
