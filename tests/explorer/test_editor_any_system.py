"""The editor builds any system (issue 10, deliverable 2).

New scene; coordinates that bring the initial-state table and the force rows along;
parameter names checked (no duplicate from a second "Add"); a Drawing section with inline
errors; a drawing or view that no longer fits is left out with a warning, never blocking;
multi-line expression fields; the wheel leaves unfocused controls alone; the document the
editor holds is what Save writes, buildable or not, and reads back to itself.

Most tests drive the editor alone and build its document the way the builder reads it
(``scene_from_dict(..., drop_unfit=True)`` and ``derive``, without compiling); two run
the whole window.
"""

from __future__ import annotations

import html
import re
from types import SimpleNamespace

import pytest
from hypothesis import HealthCheck, Phase, settings
from hypothesis import strategies as st
from hypothesis.stateful import (
    RuleBasedStateMachine,
    invariant,
    rule,
    run_state_machine_as_test,
)
from PySide6.QtCore import QMimeData, QPoint, QPointF, Qt
from PySide6.QtGui import QWheelEvent
from PySide6.QtTest import QTest
from PySide6.QtWidgets import QApplication, QComboBox, QScrollArea, QSpinBox, QVBoxLayout, QWidget

from explorer.builder import Built, failure_from
from explorer.editor.editor_panel import NEW_SCENE, SystemEditorPanel
from explorer.editor.fields import MAX_LINES, ExpressionField, excerpt
from explorer.editor.parameters_table import NAME, VALUE
from explorer.wheel_guard import install_wheel_guard
from systems.scene import SceneError, catalogue, load_scene, parse_scene, scene_from_dict
from tests.conftest import examples
from tests.explorer.conftest import wait_for_points

CATALOGUE = [entry.name for entry in catalogue()]


# -- helpers -----------------------------------------------------------------------------------


@pytest.fixture
def editor(qtbot):
    panel = SystemEditorPanel()
    qtbot.addWidget(panel)
    panel.emitted = []
    panel.scene_edited.connect(panel.emitted.append)
    yield panel
    panel.shutdown()


def _type(field: ExpressionField, text: str) -> None:
    """Replace a field's text as a user would (``edited`` goes out)."""
    field.edit.selectAll()
    field.edit.insertPlainText(text)


def _build(editor: SystemEditorPanel) -> None:
    """What the window does with the editor's document: read it as the builder does,
    derive it, and hand the result (or the failure) back to the editor."""
    from systems.mechanics import DerivationError, derive

    editor.flush()
    try:
        scene = scene_from_dict(editor.document(), source="<editor>", drop_unfit=True)
        mechanics = derive(scene)
    except (SceneError, DerivationError) as exc:
        editor.show_failure(failure_from(exc, 0))
        return
    compiled = SimpleNamespace(mechanics=mechanics)
    editor.show_built(Built(0, scene, compiled, "rk4", "a test", 0.01))


def _plain(label) -> str:
    """A label's text without its markup."""
    return html.unescape(re.sub(r"<[^>]+>", "", label.text()))


def _initial(editor: SystemEditorPanel) -> list[tuple[str, str]]:
    return editor._initial_rows()


def _set_parameter_name(editor: SystemEditorPanel, row: int, name: str) -> None:
    editor.parameter_table.item(row, NAME).setText(name)


def _pendulum(editor: SystemEditorPanel):
    scene = load_scene("simple_pendulum")
    editor.show_scene(scene)
    return scene


def test_a_scene_with_particles_is_given_by_its_particles_not_by_an_empty_t(editor):
    editor.show_scene(load_scene("double_pendulum"))
    assert editor.kind_combo.currentData() == "particles"
    assert not editor.fields["kinetic"].isVisibleTo(editor)
    assert editor.particles.isVisibleTo(editor) and editor.fields["potential"].isVisibleTo(editor)
    assert editor.particles.names() == ["bob1", "bob2"]
    document = editor.document()
    assert "kinetic" not in document["system"] and set(document["particles"]) == {
        "bob1",
        "bob2",
    }
    # a scene that gives T: T and V again, without particles
    _pendulum(editor)
    assert editor.kind_combo.currentData() == "energies"
    assert editor.fields["kinetic"].text() and not editor.particles.isVisibleTo(editor)


# -- New scene -----------------------------------------------------------------------------


def test_new_scene_is_a_template_to_type_over(editor):
    _pendulum(editor)
    editor.new_scene()
    assert len(editor.emitted) == 1  # the window builds it from this
    document = editor.emitted[0]
    assert document == editor.document()
    scene = scene_from_dict(document)  # strictly: a complete, valid scene
    assert len(scene.coordinates) == 1 and scene.kind == "energies"
    assert 1 <= len(scene.parameters) <= 2 and scene.drawing is None
    assert editor.coordinates.text() == "x"
    assert [editor.drawing.point_names(), editor.drawing.links.text()] == [[], ""]
    assert not editor.undo_button.isEnabled()
    assert editor.info_label.isVisibleTo(editor)
    _build(editor)
    assert editor.buildable
    # an opening refused later goes back to what was there before
    assert editor.restore_previous()
    assert editor.coordinates.text() == "theta"
    assert NEW_SCENE["system"]["coordinates"] == ["x"]  # the template itself is untouched


def test_new_scene_typed_as_a_two_coordinate_system_with_its_drawing(editor):
    editor.new_scene()
    _type(editor.coordinates, "x, y")
    _type(editor.fields["kinetic"], "m*(x_dot**2 + y_dot**2)/2")
    _type(editor.fields["potential"], "k*(x**2 + 4*y**2)/2")
    editor.flush()
    assert [name for name, _ in _initial(editor)] == ["x", "x_dot", "y", "y_dot"]
    assert list(editor.force_fields) == ["x", "y"]
    row = editor.drawing.add_point()
    row.name_edit.setText("mass")
    row.name_edit.editingFinished.emit()
    _type(row.x, "x")
    _type(row.y, "y")
    _type(editor.drawing.links, "origin-mass")
    _type(editor.drawing.trace, "mass")
    editor.initial_table.item(2, 1).setText("0.5")
    _build(editor)
    assert editor.build_status == "built", editor.general_error.text()
    scene = editor._built_scene
    assert scene.coordinates == ("x", "y") and scene.warnings == ()
    assert scene.drawing.points == (("mass", "x", "y"),)
    assert scene.drawing.links == (("origin", "mass"),) and scene.drawing.trace == ("mass",)
    assert scene.initial_values == {"x": 1.0, "x_dot": 0.0, "y": 0.5}
    assert not editor.warning_label.isVisibleTo(editor)


# -- coordinates bring the initial state and the forces along -----------------------------------


def test_editing_coordinates_updates_the_initial_state_and_the_forces(editor):
    _pendulum(editor)
    assert _initial(editor) == [("theta", "1.2"), ("theta_dot", "0")]
    _type(editor.force_fields["theta"], "A*cos(t)")
    _type(editor.coordinates, "theta, phi")
    editor.flush()
    assert _initial(editor) == [("theta", "1.2"), ("theta_dot", "0"), ("phi", ""), ("phi_dot", "")]
    assert list(editor.force_fields) == ["theta", "phi"]
    assert editor.force_fields["theta"].text() == "A*cos(t)"
    editor.initial_table.item(2, 1).setText("0.3")
    # theta goes: its rows and force go with it, phi keeps its value
    _type(editor.coordinates, "phi")
    editor.flush()
    assert _initial(editor) == [("phi", "0.3"), ("phi_dot", "")]
    assert list(editor.force_fields) == ["phi"]
    assert "theta" not in editor.document()["initial"]
    # and they come back as they were when theta returns
    _type(editor.coordinates, "phi, theta")
    editor.flush()
    assert dict(_initial(editor)) == {"phi": "0.3", "phi_dot": "", "theta": "1.2", "theta_dot": "0"}
    assert editor.force_fields["theta"].text() == "A*cos(t)"
    # blank values are left out of the document (they are 0)
    assert editor.document()["initial"] == {"phi": 0.3, "theta": 1.2, "theta_dot": 0.0}


def test_a_coordinate_renamed_in_place_keeps_its_values(editor):
    _pendulum(editor)
    for typed in ("p", "ps", "psi"):  # as the debounce may see it while typing
        _type(editor.coordinates, typed)
        editor.flush()
    assert _initial(editor) == [("psi", "1.2"), ("psi_dot", "0")]


def test_a_hamiltonian_scene_gets_momenta_for_new_coordinates(editor):
    editor.show_scene(load_scene("henon_heiles"))
    _type(editor.coordinates, "x, y, z")
    editor.flush()
    assert [name for name, _ in _initial(editor)][-2:] == ["z", "p_z"]


def test_the_initial_table_keeps_every_digit(editor):
    scene = load_scene("figure_eight")
    editor.show_scene(scene)
    assert dict(_initial(editor))["x1"] == "0.97000436"
    assert editor.document()["initial"] == dict(scene.initial)


# -- parameter names ------------------------------------------------------------------------------


def test_add_twice_makes_no_duplicate_parameter(editor):
    _pendulum(editor)
    editor.add_button.click()
    editor.add_button.click()
    names = [name for name, _ in editor.parameter_table.parameters()]
    assert len(names) == len(set(names)) == 5
    assert list(editor.document()["system"]["parameters"]) == names
    # giving the second new one the first one's name is refused, and it keeps its own
    _set_parameter_name(editor, 4, names[3])
    assert editor.parameter_table.item(4, NAME).text() == names[4]
    message = _plain(editor.parameter_error)
    assert f"'{names[3]}' is already a parameter" in message and f"kept '{names[4]}'" in message
    # adding a name that is taken is refused too
    assert editor.parameter_table.add_parameter("g") is None
    assert "'g' is already a parameter" in _plain(editor.parameter_error)
    assert len(editor.parameter_table.parameters()) == 5


@pytest.mark.parametrize(
    "name, words",
    [
        ("theta", "the coordinate theta"),
        ("theta_dot", "the velocity of theta"),
        ("p_theta", "the momentum of theta"),
        ("t", "built-in name"),
        ("sin", "built-in name"),
        ("2x", "not a valid name"),
        ("lambda", "reserved word"),
        ("", "needs a name"),
    ],
)
def test_a_parameter_name_that_cannot_be_used_is_refused(editor, name, words):
    _pendulum(editor)
    edits = len(editor.emitted)
    _set_parameter_name(editor, 0, name)
    assert editor.parameter_table.item(0, NAME).text() == "m"
    assert words in _plain(editor.parameter_error)
    assert editor.parameter_error.isVisibleTo(editor)
    editor.flush()
    assert len(editor.emitted) == edits  # nothing changed, nothing to build


def test_a_parameter_renamed_to_a_free_name_is_taken(editor):
    _pendulum(editor)
    _set_parameter_name(editor, 0, "mass")
    editor.flush()
    # in the table's order: the document goes out as it is (not as a sorted QVariantMap)
    assert list(editor.emitted[-1]["system"]["parameters"]) == ["mass", "g", "l"]
    # a new coordinate's velocity is no parameter name either
    _type(editor.coordinates, "theta, a")
    editor.flush()
    _set_parameter_name(editor, 0, "a_dot")
    assert "the velocity of a" in _plain(editor.parameter_error)


def test_an_unknown_name_can_be_added_as_a_parameter_from_its_error(editor):
    _pendulum(editor)
    _type(editor.fields["potential"], "-m*g*l*cos(theta) + c*theta**4")
    _build(editor)
    field = editor.fields["potential"]
    assert field.has_error and "Add c as a parameter" in _plain(field.error_label)
    field.error_label.linkActivated.emit("add-parameter:c")
    assert [name for name, _ in editor.parameter_table.parameters()][-1] == "c"
    _build(editor)
    assert editor.buildable and not field.has_error
    # a name that was a coordinate a moment ago is not offered as a parameter
    _type(editor.coordinates, "phi")
    _build(editor)
    assert "unknown name 'theta_dot'" in _plain(editor.fields["kinetic"].error_label)
    assert "as a parameter" not in _plain(editor.fields["kinetic"].error_label)


# -- the Drawing section, and what does not fit --------------------------------------------------


def test_a_drawing_that_no_longer_fits_is_left_out_with_a_warning(editor):
    _pendulum(editor)
    _type(editor.coordinates, "phi")
    _type(editor.fields["kinetic"], "m*l**2*phi_dot**2/2")
    _type(editor.fields["potential"], "-m*g*l*cos(phi)")
    _build(editor)
    assert editor.build_status == "built"  # the drawing and view did not block it
    scene = editor._built_scene
    assert scene.drawing is None and "phase" not in scene.view and scene.view["t_end"] == 20.0
    bob = editor.drawing.rows[0]
    assert bob.x.has_error and "unknown name 'theta'" in _plain(bob.x.error_label)
    assert "position 7" in _plain(bob.x.error_label)
    assert bob.y.has_error
    assert editor.drawing.left_out.isVisibleTo(editor)
    warning = _plain(editor.warning_label)
    assert editor.warning_label.isVisibleTo(editor)
    assert "drawing" in warning and "view.phase" in warning and "view.ranges.theta" in warning
    assert "warnings" in editor.state_label.text()
    # the document still holds the drawing and the view as they were
    document = editor.document()
    assert document["drawing"]["points"]["bob"] == ["l*sin(theta)", "-l*cos(theta)"]
    assert document["view"]["phase"] == ["theta", "p_theta"]
    # fixing the drawing brings it back
    _type(bob.x, "l*sin(phi)")
    _type(bob.y, "-l*cos(phi)")
    _build(editor)
    assert editor._built_scene.drawing is not None
    assert not bob.x.has_error and not editor.drawing.left_out.isVisibleTo(editor)
    assert "drawing" not in _plain(editor.warning_label)
    # the view settings that do not fit can be removed with one click, and undone
    before = len(editor.emitted)
    editor.warning_label.linkActivated.emit("remove-view")
    assert len(editor.emitted) == before + 1
    assert editor.document()["view"] == {"t_end": 20.0}
    _build(editor)
    assert not editor.warning_label.isVisibleTo(editor)
    editor.undo()
    assert editor.document()["view"]["phase"] == ["theta", "p_theta"]


def test_links_and_trace_problems_show_under_their_fields(editor):
    _pendulum(editor)
    _type(editor.drawing.links, "origin-bob, bob-tip")
    _type(editor.drawing.trace, "bob, tip")
    _build(editor)
    assert editor.buildable and editor._built_scene.drawing is None
    links, trace = editor.drawing.links, editor.drawing.trace
    assert "unknown point 'tip'" in _plain(links.error_label)
    assert "position 13" in _plain(links.error_label)  # where "bob-tip" starts
    assert "unknown point 'tip'" in _plain(trace.error_label)
    assert "position 6" in _plain(trace.error_label)
    # a pair typed wrong is kept as typed, and said so
    _type(editor.drawing.links, "origin-bob, bob")
    _type(editor.drawing.trace, "")
    editor.flush()
    assert editor.document()["drawing"]["links"] == [["origin", "bob"], ["bob"]]
    _build(editor)
    assert "must be a pair of point names" in _plain(links.error_label)


def test_points_are_added_renamed_and_removed_with_their_links(editor):
    _pendulum(editor)
    tip = editor.drawing.add_point()
    assert tip.accepted_name == "point1"
    _type(tip.x, "2*l*sin(theta)")
    _type(tip.y, "-2*l*cos(theta)")
    _type(editor.drawing.links, "origin-bob, bob-point1")
    _type(editor.drawing.trace, "point1")
    # a rename is carried into the links and the trace
    tip.name_edit.setText("tip")
    tip.name_edit.editingFinished.emit()
    assert editor.drawing.links.text() == "origin-bob, bob-tip"
    assert editor.drawing.trace.text() == "tip"
    _build(editor)
    assert editor._built_scene.drawing.links == (("origin", "bob"), ("bob", "tip"))
    # a name that is taken, or not a name, is refused and the old one kept
    for name, words in (("bob", "already a point"), ("to p", "not a valid name")):
        tip.name_edit.setText(name)
        tip.name_edit.editingFinished.emit()
        assert tip.accepted_name == "tip" and tip.name_edit.text() == "tip"
        assert words in _plain(tip.name_error)
    # removing a point removes the links and trace that use it
    editor.drawing.remove_point(editor.drawing.rows[0])
    assert editor.drawing.point_names() == ["tip"]
    assert editor.drawing.links.text() == "" and editor.drawing.trace.text() == "tip"
    _build(editor)
    assert editor._built_scene.drawing.points == (("tip", "2*l*sin(theta)", "-2*l*cos(theta)"),)


# -- the document: what Save writes ----------------------------------------------------------------


@pytest.mark.parametrize("name", CATALOGUE)
def test_document_text_reads_back_to_the_same_document(qtbot, editor, name):
    scene = load_scene(name)
    editor.show_scene(scene)
    text = editor.document_text()
    # an untouched catalogue scene's document is that scene
    again = parse_scene(text, source=scene.source, name=scene.name)
    assert again == scene and dict(again.view) == dict(scene.view)
    other = SystemEditorPanel()
    qtbot.addWidget(other)
    assert other.show_document(text, source=f"{name}.toml") == []
    assert other.document_text() == text
    assert other.document() == editor.document()
    other.shutdown()


def test_symmetries_and_constraints_are_kept_through_save_and_a_rebuild(qtbot, editor):
    """[symmetries] and [constraints] go through their sections into Save and into the
    document the window builds from, in the order they were read."""
    text = (
        'title = "Bead on a helix"\n[system]\ncoordinates = ["r", "phi", "z"]\n'
        "parameters = { m = 1.0, k = 1.0, e = 0.5, c = 0.3 }\n"
        'kinetic = "m*(r_dot**2 + r**2*phi_dot**2 + z_dot**2)/2"\n'
        'potential = "k*(r - 1)**2 + e*cos(phi - c*z)"\n'
        '[symmetries]\nscrew = { z = "1", phi = "c" }\n'
    )
    assert editor.show_document(text, source="helix.toml") == []
    scene = scene_from_dict(editor.document(), source="<editor>", drop_unfit=True)
    assert scene.symmetries == (("screw", (("z", "1"), ("phi", "c"))),)
    assert "[symmetries]" in editor.document_text()
    editor.show_scene(load_scene("cartesian_pendulum"))
    again = scene_from_dict(editor.document(), source="<editor>", drop_unfit=True)
    assert again.holonomic_constraints == load_scene("cartesian_pendulum").holonomic_constraints
    assert "[constraints]" in editor.document_text()


def test_an_unbuildable_document_is_written_and_read_back_as_typed(qtbot, editor):
    _pendulum(editor)
    _type(editor.coordinates, "theta, 2y")
    _type(editor.fields["kinetic"], "m*l**2*theta_dot**2/2 + (")
    _type(editor.drawing.links, "origin-bob, bob")
    editor.initial_table.item(0, 1).setText("pi/3")
    _build(editor)
    assert editor.build_status == "failed" and not editor.buildable
    assert "system.coordinates" in editor.build_problem
    text = editor.document_text()
    assert 'coordinates = ["theta", "2y"]' in text
    assert 'kinetic = "m*l**2*theta_dot**2/2 + ("' in text
    assert 'theta = "pi/3"' in text
    assert 'links = [["origin", "bob"], ["bob"]]' in text
    other = SystemEditorPanel()
    qtbot.addWidget(other)
    other.show_document(text)
    assert other.document_text() == text
    assert other.fields["kinetic"].text() == "m*l**2*theta_dot**2/2 + ("
    other.shutdown()


def test_document_text_takes_an_edit_waiting_for_the_debounce(editor):
    _pendulum(editor)
    _type(editor.fields["potential"], "-m*g*l*cos(theta)*2")
    assert editor.debounce.isActive()
    assert 'potential = "-m*g*l*cos(theta)*2"' in editor.document_text()
    assert not editor.debounce.isActive()
    assert editor.emitted[-1]["system"]["potential"] == "-m*g*l*cos(theta)*2"


def test_show_document_names_what_it_could_not_keep(editor):
    text = load_scene("simple_pendulum").to_toml().replace("[system]", "colour = 3\n[system]")
    ignored = editor.show_document(text, source="mine.toml")
    assert ignored == ["colour"]
    assert "colour" in _plain(editor.info_label)
    assert "colour" not in editor.document_text()
    with pytest.raises(SceneError, match="not valid TOML"):
        editor.show_document("title = ", source="broken.toml")
    assert editor.coordinates.text() == "theta"  # nothing changed


def test_build_status_follows_the_document(editor):
    _pendulum(editor)
    assert editor.build_status == "pending" and not editor.buildable
    _build(editor)
    assert editor.buildable and editor.build_problem == ""
    _type(editor.fields["potential"], "-m*g*l*cos(theta")
    assert editor.build_status == "pending"  # typed, not built yet
    _build(editor)
    assert editor.build_status == "failed"
    assert "never closed" in editor.build_problem
    _type(editor.fields["potential"], "-m*g*l*cos(theta)")
    editor.flush()
    assert editor.build_status == "pending"
    _build(editor)
    assert editor.buildable
    assert not editor.modified  # back to what was opened
    editor.title_edit.setText("Mine")
    assert editor.modified
    editor.mark_saved()
    assert not editor.modified


# -- multi-line expression fields -----------------------------------------------------------------


def test_a_long_expression_wraps_and_the_field_grows_to_a_few_lines(qtbot):
    field = ExpressionField()
    qtbot.addWidget(field)
    field.resize(300, 40)
    field.show()
    qtbot.waitExposed(field)
    one_line = field.edit.height()
    field.set_text(" + ".join(f"a{i}*x**{i}" for i in range(12)))
    qtbot.waitUntil(lambda: field.edit.height() > one_line)
    line = field.edit.fontMetrics().lineSpacing()
    assert field.edit.height() <= one_line + (MAX_LINES - 1) * line + 2
    field.set_text(" + ".join(f"a{i}*x**{i}" for i in range(200)))
    qtbot.waitUntil(lambda: field.edit.verticalScrollBar().maximum() > 0)
    assert field.edit.height() <= one_line + (MAX_LINES - 1) * line + 2
    field.set_text("x")
    qtbot.waitUntil(lambda: field.edit.height() == one_line)


def test_an_expression_field_stays_one_line_of_text(qtbot):
    field = ExpressionField()
    qtbot.addWidget(field)
    edits = []
    field.edited.connect(lambda: edits.append(field.text()))
    field.set_text("m*x")
    assert edits == []  # set_text is not an edit
    qtbot.keyClicks(field.edit, "*2")
    assert field.text() == "m*x*2"  # typing goes on at the end
    qtbot.keyClick(field.edit, Qt.Key.Key_Return)
    assert field.text() == "m*x*2"
    pasted = QMimeData()
    pasted.setText(" + k\n*x**2")
    field.edit.insertFromMimeData(pasted)
    assert field.text() == "m*x*2 + k *x**2"
    assert edits[-1] == field.text()


def test_an_error_far_along_a_long_expression_shows_its_stretch(qtbot):
    text = " + ".join(f"a{i}*x**{i}" for i in range(30)) + " + cos(x"
    shown, column = excerpt(text, len(text) - 3)
    assert len(shown) <= 46 and shown.startswith("…")
    assert shown[column - 1] == text[len(text) - 4]
    field = ExpressionField()
    qtbot.addWidget(field)
    field.set_text(text)
    field.show_error("'(' is never closed", len(text) - 4)
    label = _plain(field.error_label)
    assert f"position {len(text) - 4}" in label and "…" in label
    assert len(field.edit.extraSelections()) == 1  # the character is marked in the field
    qtbot.keyClicks(field.edit, ")")
    assert field.edit.extraSelections() == []  # the mark goes with the next keystroke
    field.clear_error()
    assert not field.has_error


# -- the wheel ---------------------------------------------------------------------------------


def _wheel(widget: QWidget, dy: int = -120) -> None:
    centre = QPointF(widget.rect().center())
    event = QWheelEvent(
        centre,
        QPointF(widget.mapToGlobal(centre.toPoint())),
        QPoint(0, 0),
        QPoint(0, dy),
        Qt.MouseButton.NoButton,
        Qt.KeyboardModifier.NoModifier,
        Qt.ScrollPhase.NoScrollPhase,
        False,
    )
    QApplication.sendEvent(widget, event)


def test_the_wheel_scrolls_the_editor_and_leaves_unfocused_controls_alone(qtbot, editor):
    _pendulum(editor)
    editor.resize(440, 400)
    editor.show()
    qtbot.waitExposed(editor)
    outside = QComboBox()  # not under the guarded root: the wheel changes it, as Qt does
    outside.addItems(["a", "b", "c"])
    qtbot.addWidget(outside)
    guard = install_wheel_guard(editor)
    assert install_wheel_guard(editor) is guard  # once per root
    _wheel(outside)
    assert outside.currentIndex() == 1
    bar = editor._scroll.verticalScrollBar()
    kind = editor.kind_combo.currentIndex()
    _wheel(editor.kind_combo)
    assert editor.kind_combo.currentIndex() == kind
    assert bar.value() > 0  # the page scrolled instead
    assert editor.kind_combo.focusPolicy() == Qt.FocusPolicy.StrongFocus
    # a slider in the parameter table, made after the guard was installed
    editor.add_button.click()
    name = editor.parameter_table.parameters()[-1][0]
    slider = editor.parameter_table.slider(name)
    value = editor.parameter_table.item(3, VALUE).text()
    position = slider.value()
    _wheel(slider)
    assert slider.value() == position and editor.parameter_table.item(3, VALUE).text() == value
    # a control the user has clicked (focused) takes the wheel as usual
    editor.kind_combo.setFocus()
    qtbot.waitUntil(editor.kind_combo.hasFocus)
    _wheel(editor.kind_combo)
    assert editor.kind_combo.currentIndex() == kind + 1
    editor.kind_combo.setCurrentIndex(kind)


def test_the_wheel_guard_covers_spin_boxes_and_spares_scroll_bars(qtbot):
    root = QWidget()
    qtbot.addWidget(root)
    scroll = QScrollArea(root)
    page = QWidget()
    layout = QVBoxLayout(page)
    spin = QSpinBox()
    layout.addWidget(spin)
    for _ in range(30):
        layout.addWidget(QComboBox())
    scroll.setWidget(page)
    scroll.resize(200, 150)
    root.resize(220, 170)
    root.show()
    qtbot.waitExposed(root)
    install_wheel_guard(root)
    _wheel(spin, dy=120)
    assert spin.value() == 0
    bar = scroll.verticalScrollBar()
    _wheel(bar)  # a scroll bar is not guarded: it scrolls under the wheel
    assert bar.value() > 0


# -- in the window: built, compiled and running ----------------------------------------------------


def _built_with(qtbot, window, check, timeout: int = 60000) -> None:
    """Wait until the window runs a system for which ``check(scene)`` holds."""
    qtbot.waitUntil(lambda: window.built is not None and check(window.built.scene), timeout=timeout)


def test_window_new_scene_typed_as_two_coordinates_with_a_drawing_runs(qtbot, window):
    editor = window.editor
    editor.new_scene()
    _built_with(qtbot, window, lambda s: s.title == "New scene")
    assert window.compiled.n == 1 and editor.buildable
    _type(editor.coordinates, "x, y")
    _type(editor.fields["kinetic"], "m*(x_dot**2 + y_dot**2)/2")
    _type(editor.fields["potential"], "k*(x**2 + 4*y**2)/2")
    point = editor.drawing.add_point("mass", "x", "y")
    assert point is not None
    _type(editor.drawing.links, "origin-mass")
    _type(editor.drawing.trace, "mass")
    _built_with(qtbot, window, lambda s: s.coordinates == ("x", "y") and s.drawing is not None)
    assert window.built.scene.warnings == ()
    assert window.compiled.n == 2 and "drawing" in window.compiled.wanted
    assert editor.buildable and not editor.warning_label.isVisibleTo(editor)
    wait_for_points(qtbot, window, 20)
    assert window.store.main.y.data.shape[1] == 4
    # what Save would write is what the editor holds, and it is this system
    text = editor.document_text()
    assert parse_scene(text).coordinates == ("x", "y")


def test_window_pendulum_with_new_coordinates_runs_without_its_drawing(qtbot, window):
    editor = window.editor
    wait_for_points(qtbot, window, 5)
    _type(editor.coordinates, "phi")
    _type(editor.fields["kinetic"], "m*l**2*phi_dot**2/2")
    _type(editor.fields["potential"], "-m*g*l*cos(phi)")
    _built_with(qtbot, window, lambda s: s.coordinates == ("phi",))
    scene = window.built.scene
    assert scene.drawing is None
    assert {w.part for w in scene.warnings} == {"drawing", "view.phase", "view.ranges"}
    assert "drawing" not in window.compiled.wanted
    assert editor.warning_label.isVisibleTo(editor)
    assert editor.drawing.rows[0].x.has_error
    assert editor.buildable
    wait_for_points(qtbot, window, 20)
    # the initial angle came along with the renamed coordinate
    assert window.store.main.y.data[0, 0] == pytest.approx(
        load_scene("simple_pendulum").initial_values["theta"]
    )


def test_a_parameter_value_in_force_keeps_the_document_built(editor):
    _pendulum(editor)
    _build(editor)
    editor.parameter_table.set_value("l", 1.5)  # accepted: in force without a new build
    assert editor.buildable and not editor.debounce.isActive()
    assert editor.document()["system"]["parameters"]["l"] == 1.5
    # after a failed build, a value that moves is tried again
    _type(editor.fields["potential"], "-m*g*l*cos(theta")
    _build(editor)
    assert editor.build_status == "failed"
    editor.parameter_table.set_value("l", 2.0)
    assert editor.debounce.isActive()
    editor.flush()


# -- builds that finish while the user types (issue 25, item 3) --------------------------------


class EditorUnderTheHand(RuleBasedStateMachine):
    """The user scrolls, clicks into a field and types while builds finish in the
    background with any outcome (built, with warnings, failed at any field, equilibria
    found, a derivation laid out). Invariants: what the user looks at stays where it is
    on screen until the user scrolls (the focused field keeps its focus and its place;
    without one, the widget at the top of the view, or the top of the page), and every
    keystroke stays in its field."""

    editor: SystemEditorPanel
    built: Built

    def __init__(self):
        super().__init__()
        editor = self.editor
        editor.show_scene(self.built.scene)
        editor.show_built(self.built)
        QApplication.processEvents()
        editor._scroll.verticalScrollBar().setValue(0)
        self.typed: dict = {}  # field -> its text as the user left it
        self.seen: tuple | None = None  # (scroll value, focus, its top) after the user

    def _fields(self) -> list[ExpressionField]:
        editor = self.editor
        fields = [editor.coordinates, *editor.fields.values(), editor.dissipation]
        fields += list(editor.force_fields.values())
        return [f for f in fields if f.isVisibleTo(editor)]

    def _settle(self) -> None:
        """Events until what the user sees stops changing (a restore is a zero-time timer,
        which other widgets' pending events may delay past a fixed count of rounds)."""
        look = None
        for _ in range(50):
            QApplication.processEvents()
            now = (self._look(), self.editor._scroll.verticalScrollBar().value())
            if now == look:
                return
            look = now

    def _look(self) -> tuple:
        """What the user sees: the focused field and where it is on screen; without one,
        the widget at the top of the view and where it is (at the top of the page: the
        top of the page)."""
        bar = self.editor._scroll.verticalScrollBar()
        content = self.editor._scroll.widget()
        focus = QApplication.focusWidget()
        if focus is not None and content.isAncestorOf(focus):
            top = focus.mapTo(content, QPoint(0, 0)).y() - bar.value()
            if -focus.height() < top < self.editor._scroll.viewport().height():
                return focus, top  # the field the user types in, in sight
        if bar.value() == 0:
            return ("page top",)
        widget = content.childAt(QPoint(12, bar.value() + 2))
        if widget is None:  # between widgets: the scroll position is what stays
            return ("scrolled to", bar.value())
        return widget, widget.mapTo(content, QPoint(0, 0)).y() - bar.value()

    @rule(fraction=st.floats(0, 1))
    def scroll(self, fraction):
        bar = self.editor._scroll.verticalScrollBar()
        bar.setValue(round(fraction * bar.maximum()))
        self._settle()
        self.seen = self._look()

    @rule(pick=st.integers(0, 63), text=st.sampled_from(["r", " + 0", "*x", "("]))
    def click_and_type(self, pick, text):
        fields = self._fields()
        field = fields[pick % len(fields)]
        self.editor._scroll.ensureWidgetVisible(field)  # the user scrolls to it first
        field.edit.setFocus()
        self._settle()
        QTest.keyClicks(field.edit, text)
        self.typed[field] = field.text()
        self._settle()
        self.seen = self._look()

    @rule(
        outcome=st.sampled_from(["built", "warned", "failed", "equilibria", "derivation"]),
        pick=st.integers(0, 63),
        lines=st.integers(0, 12),
    )
    def a_build_finishes(self, outcome, pick, lines):
        editor = self.editor
        if outcome == "built":
            editor.show_built(self.built)
        elif outcome == "warned":
            warning = SimpleNamespace(part="view", field="view.pair", reason="no such pair " * 9)
            scene = SimpleNamespace(**{**vars(self.built.scene), "warnings": (warning,)})
            editor.show_built(Built(0, scene, self.built.compiled, "rk4", "a test", 0.5))
        elif outcome == "failed":
            fields = ["system.kinetic", "system.potential", "system.coordinates", "", "initial.x"]
            failure = SimpleNamespace(
                field=fields[pick % len(fields)],
                reason="syntax error: a long reason that wraps " * (1 + pick % 4),
                position=1 + pick % 5,
                message="the scene does not build " * 6,
            )
            editor.show_failure(failure)
        elif outcome == "equilibria":
            editor.show_equilibria([f"theta = {k}: stable, omega = 3.13" for k in range(lines)])
        else:
            editor.show_derivation("L = ...\n" * lines)
        self._settle()

    @invariant()
    def nothing_moves_under_the_hand(self):
        if self.seen is not None:
            assert self._look() == self.seen

    @invariant()
    def nothing_typed_is_lost(self):
        for field, text in self.typed.items():
            assert field.text() == text


def test_builds_finishing_mid_typing_never_move_the_editor(qtbot):
    from dataclasses import replace

    from systems.mechanics import derive

    panel = SystemEditorPanel()
    qtbot.addWidget(panel)
    panel.resize(380, 460)
    panel.show()
    qtbot.waitExposed(panel)
    scene = replace(load_scene("simple_pendulum"), dissipation="b*theta_dot**2/2")
    scene = replace(scene, parameters=(*scene.parameters, ("b", 0.1)))
    mechanics = derive(scene)
    EditorUnderTheHand.editor = panel
    EditorUnderTheHand.built = Built(0, scene, SimpleNamespace(mechanics=mechanics), "rk4", "", 0.1)
    run_state_machine_as_test(
        EditorUnderTheHand,
        settings=settings(
            max_examples=examples(25, 100),
            stateful_step_count=12,
            deadline=None,
            derandomize=True,
            database=None,
            phases=[Phase.explicit, Phase.generate],  # one editor for all: no shrinking
            suppress_health_check=list(HealthCheck),
        ),
    )
    panel.shutdown()


def test_a_long_error_wraps_and_never_widens_the_editor(qtbot):
    panel = SystemEditorPanel()
    qtbot.addWidget(panel)
    panel.resize(360, 500)
    panel.show()
    _pendulum(panel)
    content = panel._scroll.widget()
    qtbot.waitUntil(lambda: content.width() <= panel._scroll.viewport().width())
    text = "m*l**2*theta_dot**2/2 + " + " + ".join(f"a{i}*theta**{i}" for i in range(40))
    panel.fields["kinetic"].set_text(text + " + (")
    unbroken = "no_such_name_" * 12
    panel.fields["kinetic"].show_error(f"unknown name '{unbroken}'", len(text) + 3)
    panel._show_label(panel.general_error, f"not opened: /a/{unbroken}/scene.toml")
    qtbot.waitUntil(lambda: panel.fields["kinetic"].error_label.height() > 40)
    assert content.width() <= panel._scroll.viewport().width()
    assert not panel._scroll.horizontalScrollBar().isVisible()
    label = panel.fields["kinetic"].error_label
    assert label.width() <= panel.fields["kinetic"].width()
    assert f"position {len(text) + 3}" in _plain(label)
