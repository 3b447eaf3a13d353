"""Random sequences of user actions on one window, with invariants after every step.

A hypothesis ``RuleBasedStateMachine`` drives the window as a user would (through its
widgets and menu slots): open any catalogue scene, toggle the Poincaré section, launch
and delete orbits, clear, change method, step and speed, pause, step, reset, edit a field
(valid and invalid text), switch the kind of system (T and V, particles, L, H), type into
or add and remove entries of the Particles, Constraints and Symmetries sections, start a
new scene, change tab. After every step, once the window has settled:

- no exception reached the window's error reporter;
- every panel names the running system's coordinates (phase axes and pair list,
  configuration titles and axes, conserved momenta);
- what Save writes is exactly the editor's document, and it holds what the new sections
  show;
- nothing typed is lost: every text typed into a field of the new sections is still in
  that field (until the field is removed or another scene is opened).

One window serves every example (a window per example would cost most of the run);
each example starts from where the last one left it, which only widens what is tried.
Shrinking is off for the same reason: a failure prints the steps that led to it.
"""

from __future__ import annotations

import os
import time

import pytest
from hypothesis import HealthCheck, Phase, settings
from hypothesis import strategies as st
from hypothesis.stateful import RuleBasedStateMachine, invariant, rule

from explorer.labels import coordinate_label, momentum_label
from systems.scene import catalogue
from tests.conftest import examples

# 80 examples of 4 steps (about 320 user actions; the rarest rules, editing a field and
# deleting an orbit, still run several times) by default; PHASE_EXPLORER_THOROUGH=1 runs
# 200, GUI_MODEL_EXAMPLES=N any number.
EXAMPLES = int(os.environ.get("GUI_MODEL_EXAMPLES") or examples(80, 200))
STEPS = 4
SETTLE_SECONDS = 60.0
CATALOGUE = [entry.name for entry in catalogue()]
PICK = st.integers(0, 63)  # an index into a list the window decides (taken modulo its length)

_window = None  # the window every example drives (set by the test)
_bot = None
_folder = None


def _settle(build: bool = False) -> None:
    """Let the window work for a moment; after an action that builds, until it is built."""
    _bot.wait(15)
    if not build:
        return
    deadline = time.monotonic() + SETTLE_SECONDS
    editor = _window.editor
    while time.monotonic() < deadline:
        idle = not _window.busy_bar.isVisible() and editor.build_status != "pending"
        if idle and _window.built is not None:
            break
        _bot.wait(10)
    else:
        pytest.fail("the window did not finish building within a minute")
    _bot.wait(15)


def _type(key: str, text: str) -> None:
    field = _window.editor.fields[key]
    field.set_text(text)
    field.edited.emit()
    _window.editor.flush()


def _section_fields(what: str) -> list:
    """The expression fields of one of the editor's new sections."""
    editor = _window.editor
    if what == "particle":
        return [f for row in editor.particles.rows for f in row.fields()]
    if what == "constraint":
        return [f for entries in editor.constraints.lists.values() for f in entries.fields]
    return [f for row in editor.symmetries.rows for f in row.components.values()]


class WindowModel(RuleBasedStateMachine):
    """The window as a user drives it; see the module docstring."""

    def __init__(self):
        super().__init__()
        self.typed: list[tuple[object, str]] = []  # (field, text typed into it)

    @rule(name=st.sampled_from(CATALOGUE))
    def open_scene(self, name):
        _window.open_scene(name)
        self.typed = []
        _settle(build=True)

    @rule()
    def toggle_section(self):
        box = _window.phase_view.poincare_box
        if box.isEnabled():
            box.click()
        _settle()

    @rule(x=st.floats(0.05, 0.95), y=st.floats(0.05, 0.95))
    def launch(self, x, y):
        (x0, x1), (y0, y1) = _window.phase_view.plot.viewRange()
        _window.phase_view.launch_at(x0 + x * (x1 - x0), y0 + y * (y1 - y0))
        _settle()

    @rule(pick=PICK)
    def delete_orbit(self, pick):
        keys = [t.key for t in _window.store if t.key != 0]
        if keys:
            _window.phase_view.request_delete(keys[pick % len(keys)])
        _settle()

    @rule()
    def clear(self):
        _window.controls.clear_button.click()
        _settle()

    @rule(pick=PICK)
    def choose_method(self, pick):
        combo = _window.controls.method_combo
        enabled = [i for i in range(combo.count()) if combo.model().item(i).isEnabled()]
        combo.setCurrentIndex(enabled[pick % len(enabled)])
        _settle()

    @rule(step=st.sampled_from(["", "0.01", "0.05", "1e-6", "0.3"]))
    def type_step(self, step):
        edit = _window.controls.step_edit
        edit.setText(step)
        edit.editingFinished.emit()
        _settle()

    @rule(index=st.integers(0, 8))
    def choose_speed(self, index):
        _window.controls.speed_combo.setCurrentIndex(index)
        _settle()

    @rule()
    def play_or_pause(self):
        _window.controls.play_button.click()
        _settle()

    @rule()
    def single_step(self):
        if _window.controls.step_button.isEnabled():
            _window.controls.step_button.click()
        _settle()

    @rule()
    def reset(self):
        _window.controls.reset_button.click()
        _settle()

    @rule(valid=st.booleans(), key=st.sampled_from(["kinetic", "potential", "hamiltonian"]))
    def edit_field(self, valid, key):
        field = _window.editor.fields[key]
        if not field.isVisibleTo(_window.editor) or not field.text().strip():
            return
        text = field.text()
        for suffix in (" + (", " + 0"):
            text = text.removesuffix(suffix)
        if not valid:
            text += " + ("
        elif text == field.text():
            text += " + 0"
        _type(key, text)
        _settle(build=True)

    @rule(pick=PICK)
    def switch_kind(self, pick):
        combo = _window.editor.kind_combo
        combo.setCurrentIndex(pick % combo.count())
        _window.editor.flush()
        _settle(build=True)

    @rule(
        what=st.sampled_from(["particle", "constraint", "symmetry"]),
        action=st.sampled_from(["type", "type", "add", "remove"]),
        valid=st.booleans(),
        pick=PICK,
    )
    def edit_section(self, what, action, valid, pick):
        editor = _window.editor
        if what == "particle" and editor.kind_combo.currentData() != "particles":
            return
        fields = _section_fields(what)
        if action == "add":
            q = editor.coordinates.text().split(",")[0].strip()
            if what == "particle":
                editor.particles.add_particle(mass="m", position=(f"{q}", "0"))
            elif what == "constraint":
                editor.constraints.lists["holonomic"].add_entry(f"{q}**2 - 1")
            else:
                editor.symmetries.add_symmetry(**{q: "1"} if q.isidentifier() else {})
        elif action == "remove" and fields:
            if what == "particle":
                rows = editor.particles.rows
                editor.particles.remove_particle(rows[pick % len(rows)])
            elif what == "constraint":
                field = fields[pick % len(fields)]
                entries = [e for e in editor.constraints.lists.values() if field in e.fields]
                entries[0].remove_entry(field)
            else:
                rows = editor.symmetries.rows
                editor.symmetries.remove_symmetry(rows[pick % len(rows)])
            gone = {id(f) for f in fields} - {id(f) for f in _section_fields(what)}
            self.typed = [(f, t) for f, t in self.typed if id(f) not in gone]
        elif action == "type" and fields:
            field = fields[pick % len(fields)]
            text = field.text().removesuffix(" + (").removesuffix(" + 0") or "1"
            text += " + 0" if valid else " + ("
            field.set_text(text)
            field.edited.emit()
            self.typed = [(f, t) for f, t in self.typed if f is not field] + [(field, text)]
        editor.flush()
        _settle(build=True)

    @rule()
    def new_scene(self):
        _window.new_scene()
        self.typed = []
        _settle(build=True)

    @rule()
    def save(self):
        path = _folder / "saved.toml"
        assert _window.save_scene(path)
        assert path.read_text(encoding="utf-8") == _window.editor.document_text()
        _settle()

    @rule(pick=PICK)
    def change_tab(self, pick):
        names = sorted(_window.tab_names())
        _window.show_tab(names[pick % len(names)])
        _settle()

    # -- invariants ---------------------------------------------------------------------------

    @invariant()
    def no_unexpected_error(self):
        assert _window.error_details == "", _window.error_details

    @invariant()
    def panels_name_the_running_system(self):
        compiled = _window.compiled
        if compiled is None:
            return
        coordinates = compiled.mechanics.scene.coordinates
        labels = {coordinate_label(q) for q in coordinates}
        view = _window.phase_view
        bottom = view.plot.getAxis("bottom").labelText
        left = view.plot.getAxis("left").labelText
        assert bottom in labels, (bottom, coordinates)
        q = coordinates[[coordinate_label(c) for c in coordinates].index(bottom)]
        assert left == momentum_label(q)
        assert view.pair_combo.count() == len(coordinates)
        configuration = _window.configuration_view
        path_plot = getattr(configuration, "path_plot", None)
        if path_plot is not None and len(coordinates) > 1:
            assert path_plot.getAxis("bottom").labelText in labels
            assert path_plot.getAxis("left").labelText in labels
        conserved = _window.conserved_view
        assert all(i < len(coordinates) for i in conserved.conserved_momenta)

    @invariant()
    def the_document_is_what_the_editor_shows(self):
        from systems.scene import read_document

        editor = _window.editor
        tables = read_document(editor.document_text(), "<editor>")
        system = tables["system"]
        shown = [name.strip() for name in editor.coordinates.text().split(",") if name.strip()]
        assert system["coordinates"] == shown
        for key, field in editor.fields.items():
            if field.isVisibleTo(editor) and field.text().strip():
                assert system[key] == field.text().strip(), key
        assert set(system["parameters"]) == set(editor.parameter_table.values())
        if editor.kind_combo.currentData() == "particles":
            assert tables.get("particles", {}) == editor.particles.table()
        assert tables.get("constraints", {}) == editor.constraints.table()
        assert tables.get("symmetries", {}) == editor.symmetries.table()

    @invariant()
    def nothing_typed_is_lost(self):
        for field, text in self.typed:
            assert field.text() == text


def test_random_sequences_of_user_actions(qtbot, window, tmp_path):
    global _window, _bot, _folder
    _window, _bot, _folder = window, qtbot, tmp_path
    machine_settings = settings(
        max_examples=EXAMPLES,
        stateful_step_count=STEPS,
        deadline=None,
        derandomize=True,
        database=None,
        phases=[Phase.explicit, Phase.generate],
        suppress_health_check=list(HealthCheck),
    )
    try:
        from hypothesis.stateful import run_state_machine_as_test

        run_state_machine_as_test(WindowModel, settings=machine_settings)
    finally:
        _window = _bot = _folder = None
