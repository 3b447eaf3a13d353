"""The editor's Particles, Constraints and Symmetries sections.

Every catalogue scene with particles or constraints goes through the editor unchanged;
a pendulum typed as a particle with gravity derives and runs; a mistake in any of the new
fields is shown under that field and its text is kept; switching the kind of system away
from particles and back, undo, and renaming a coordinate keep what was typed.

Most tests drive the editor alone and build its document the way the window's builder
reads it (``scene_from_dict(..., drop_unfit=True)`` and ``derive``); one runs the window.
"""

from __future__ import annotations

from types import SimpleNamespace

import pytest
import sympy

from explorer.editor.editor_panel import KINDS, SystemEditorPanel
from explorer.editor.particles_section import gravity_value, split_components
from systems.scene import catalogue, load_scene, parse_scene
from tests.explorer.conftest import wait_for_points
from tests.explorer.test_editor_any_system import _build, _plain, _type


def _has_new_tables(scene) -> bool:
    constraints = ("holonomic", "nonholonomic", "unilateral")
    return bool(
        scene.particles
        or scene.gravity is not None
        or scene.symmetries
        or any(getattr(scene, f"{kind}_constraints") for kind in constraints)
    )


WITH_NEW_TABLES = [entry.name for entry in catalogue() if _has_new_tables(load_scene(entry.name))]

HELIX = """title = "Bead on a helix"
[system]
coordinates = ["r", "phi", "z"]
parameters = { m = 1.0, k = 1.0, e = 0.5, c = 0.3 }
kinetic = "m*(r_dot**2 + r**2*phi_dot**2 + z_dot**2)/2"
potential = "k*(r - 1)**2 + e*cos(phi - c*z)"

[symmetries]
screw = { z = "1", phi = "c" }
twist = { phi = "1" }
"""

ROLLING = """title = "Everything at once"
[system]
coordinates = ["x", "y", "phi"]
parameters = { m = 1.0, g = 9.81, R = 0.5 }
gravity = ["0", "-g"]

[particles]
disc = { mass = "m", position = ["x", "y"] }
rim = { mass = 1.0, position = ["x + R*cos(phi)", "y + R*sin(phi)"] }

[constraints]
holonomic = ["y - R"]
nonholonomic = ["x_dot - R*phi_dot"]
unilateral = ["y"]

[symmetries]
slide = { x = "1" }
"""


@pytest.fixture
def editor(qtbot):
    panel = SystemEditorPanel()
    qtbot.addWidget(panel)
    panel.emitted = []
    panel.scene_edited.connect(panel.emitted.append)
    yield panel
    panel.shutdown()


def _kind(editor: SystemEditorPanel, kind: str) -> None:
    editor.kind_combo.setCurrentIndex([k for k, _ in KINDS].index(kind))


def _pendulum_from_a_particle(editor: SystemEditorPanel) -> None:
    """Type a simple pendulum as a particle with gravity over the New scene template."""
    editor.new_scene()
    _type(editor.coordinates, "theta")
    for name in ("g", "l"):
        assert editor.parameter_table.add_parameter(name) == name
    _kind(editor, "particles")
    _type(editor.fields["potential"], "")
    editor.particles.add_button.click()
    bob = editor.particles.rows[0]
    bob.name_edit.setText("bob")
    bob.name_edit.textEdited.emit("bob")
    _type(bob.mass, "m")
    _type(bob.axes["x"], "l*sin(theta)")
    _type(bob.axes["y"], "-l*cos(theta)")
    _type(editor.particles.gravity, "g")
    _type(editor.drawing.links, "origin-bob")
    editor.initial_table.item(0, 1).setText("0.5")


# -- catalogue scenes go through the editor unchanged -------------------------------------------


def test_some_catalogue_scenes_have_the_new_tables():
    assert "bead_on_rotating_hoop" in WITH_NEW_TABLES and "cartesian_pendulum" in WITH_NEW_TABLES


@pytest.mark.parametrize("name", WITH_NEW_TABLES)
def test_a_catalogue_scene_opened_applied_and_saved_is_the_same_scene(qtbot, editor, name):
    scene = load_scene(name)
    editor.show_scene(scene)
    expected = "particles" if scene.particles else "energies"
    assert editor.kind_combo.currentData() == expected
    assert editor.particles.names() == [p.name for p in scene.particles]
    kinds = ("holonomic", "nonholonomic", "unilateral")
    constraints = {k: list(getattr(scene, f"{k}_constraints")) for k in kinds}
    assert editor.constraints.table() == {k: v for k, v in constraints.items() if v}
    assert editor.constraints.expanded == any(constraints.values())
    _build(editor)
    if editor.build_status == "built":  # a kind of constraint may not derive yet
        built = editor._built_scene
        assert built.particles == scene.particles and built.gravity == scene.gravity
        assert built.symmetries == scene.symmetries
    else:
        assert "not supported yet" in editor.build_problem
        assert not editor.general_error.isVisibleTo(editor)
    text = editor.document_text()
    again = parse_scene(text, source=scene.source, name=scene.name)
    assert again == scene
    # and opening what was saved shows the same document again
    other = SystemEditorPanel()
    qtbot.addWidget(other)
    assert other.show_document(text, source=f"{name}.toml") == []
    assert other.document() == editor.document() and other.document_text() == text
    other.shutdown()


@pytest.mark.parametrize("text", [HELIX, ROLLING], ids=["symmetries", "every-table"])
def test_a_document_with_every_new_table_reads_back_to_itself(qtbot, editor, text):
    editor.show_document(text, source="mine.toml")
    expected = parse_scene(text, source="mine.toml")
    again = parse_scene(editor.document_text(), source="mine.toml")
    assert again == expected
    assert editor.symmetries.expanded and editor.symmetries.names() == [
        name for name, _ in expected.symmetries
    ]
    other = SystemEditorPanel()
    qtbot.addWidget(other)
    other.show_document(editor.document_text())
    assert other.document_text() == editor.document_text()
    other.shutdown()


def test_every_constraint_kind_is_in_its_list(editor):
    editor.show_document(ROLLING)
    lists = editor.constraints.lists
    assert {kind: entries.texts() for kind, entries in lists.items()} == {
        "holonomic": ["y - R"],
        "nonholonomic": ["x_dot - R*phi_dot"],
        "unilateral": ["y"],
    }
    assert "1 holonomic, 1 nonholonomic, 1 unilateral" in editor.constraints.toggle.text()
    assert editor.particles.gravity.text() == "0, -g"
    assert editor.document()["system"]["gravity"] == ["0", "-g"]
    assert editor.document()["particles"]["rim"]["mass"] == "1.0"


# -- typing a particle scene -----------------------------------------------------------------------


def test_a_pendulum_typed_as_a_particle_with_gravity_derives(editor):
    _pendulum_from_a_particle(editor)
    _build(editor)
    assert editor.build_status == "built", _plain(editor.general_error)
    scene = editor._built_scene
    assert scene.particles[0].name == "bob" and scene.gravity == "g"
    assert scene.kinetic is None and scene.potential is None
    kinetic, potential = scene.energies()
    symbols = scene.symbols
    m, g, l, theta = (symbols[n] for n in ("m", "g", "l", "theta"))
    assert (potential + m * g * l * sympy.cos(theta)).simplify() == 0
    assert (kinetic - m * l**2 * symbols["theta_dot"] ** 2 / 2).simplify() == 0
    assert scene.drawing.links == (("origin", "bob"),)


def test_window_runs_a_pendulum_typed_as_a_particle(qtbot, window):
    _pendulum_from_a_particle(window.editor)
    window.editor.flush()
    qtbot.waitUntil(
        lambda: window.built is not None and window.built.scene.particles != (), timeout=60000
    )
    assert window.editor.buildable and window.compiled.n == 1
    wait_for_points(qtbot, window, 20)
    assert window.store.main.y.data[0, 0] == pytest.approx(0.5)


# -- mistakes are shown at their field, and the text stays --------------------------------------


def _bob(editor):
    return editor.particles.rows[0]


def _holonomic(editor):
    return editor.constraints.lists["holonomic"].fields[0]


def _gravity(editor):
    return editor.particles.gravity


PARTICLE = "particle_pendulum"
MISTAKES = [
    # (scene, where, text typed, words of the message)
    (PARTICLE, lambda e: _bob(e).mass, "m*theta", "a mass is a constant"),
    (PARTICLE, lambda e: _bob(e).axes["y"], "-L*cos(theta)", "unknown name 'L'"),
    (PARTICLE, lambda e: _bob(e).axes["z"], "theta_dot", "velocity"),
    (PARTICLE, _gravity, "g*theta", "field of gravity"),
    (PARTICLE, _gravity, "0, -g, 0", "3 components"),
    ("cartesian_pendulum", _holonomic, "l - 1", "no motion"),
    ("cartesian_pendulum", _holonomic, "x*x_dot", "nonholonomic"),
    ("cartesian_pendulum", _holonomic, "x**2 + (", "never closed"),
]


def _particle_pendulum(editor):
    """The simple pendulum given by a particle (there is no such catalogue scene)."""
    text = load_scene("simple_pendulum").to_toml()
    text = text.replace('kinetic = "m*l**2*theta_dot**2/2"\n', "")
    text = text.replace('potential = "-m*g*l*cos(theta)"', 'gravity = "g"')
    bob = 'bob = { mass = "m", position = ["l*sin(theta)", "-l*cos(theta)"] }'
    text = text.replace("[initial]", f"[particles]\n{bob}\n\n[initial]")
    editor.show_document(text, source="particle_pendulum.toml")
    _build(editor)
    assert editor.buildable, _plain(editor.general_error)


def _open(editor, scene):
    if scene == PARTICLE:
        _particle_pendulum(editor)
    else:
        editor.show_scene(load_scene(scene))
        _build(editor)
        assert editor.buildable


@pytest.mark.parametrize("scene, where, text, words", MISTAKES)
def test_a_mistake_is_shown_at_its_field_and_the_text_stays(editor, scene, where, text, words):
    _open(editor, scene)
    field = where(editor)
    _type(field, text)
    _build(editor)
    assert editor.build_status == "failed"
    assert field.has_error and field.isVisibleTo(editor), editor.build_problem
    assert words in _plain(field.error_label)
    assert field.text() == text
    saved = editor.document_text()
    assert text in saved or str(gravity_value(text)).replace("'", '"') in saved
    assert not editor.general_error.isVisibleTo(editor)


def test_a_gravity_component_error_points_into_the_vector(editor):
    _particle_pendulum(editor)
    _type(editor.particles.gravity, "[0, -g*theta]")
    _build(editor)
    gravity = editor.particles.gravity
    assert "field of gravity" in _plain(gravity.error_label)
    assert "position 8" in _plain(gravity.error_label)  # where theta is, in the whole text
    assert split_components("[0, -g*theta]") == [("0", 2), ("-g*theta", 5)]
    assert gravity_value("max(a, b)") == "max(a, b)" and gravity_value("  ") is None
    assert gravity_value("0, -g") == ["0", "-g"] and gravity_value("[g]") == ["g"]


def test_a_particle_name_the_scene_refuses_is_kept_and_shown(editor):
    _particle_pendulum(editor)
    bob = _bob(editor)
    bob.name_edit.setText("2bob")
    bob.name_edit.textEdited.emit("2bob")
    _build(editor)
    assert "not a valid name" in _plain(bob.name_error)
    assert bob.name_edit.text() == "2bob" and "2bob" in editor.document()["particles"]


def test_a_name_taken_by_another_row_is_said_and_kept_in_its_field(editor):
    _particle_pendulum(editor)
    second = editor.particles.add_particle()
    assert second.accepted_name == "particle1"
    second.name_edit.setText("bob")
    second.name_edit.textEdited.emit("bob")
    assert second.name_edit.text() == "bob" and second.accepted_name == "particle1"
    assert "already the name of another particle" in _plain(second.name_error)
    assert list(editor.document()["particles"]) == ["bob", "particle1"]
    # once the other one is gone, the typed name is taken
    editor.particles.remove_particle(_bob(editor))
    assert second.accepted_name == "bob" and not second.name_error.isVisibleTo(editor)


def test_mixed_dimensions_are_shown_at_the_position(editor):
    _particle_pendulum(editor)
    second = editor.particles.add_particle("tip", "m", ("0", "0", "1"))
    _build(editor)
    assert "all particles move in the same plane" in _plain(second.position_error)
    assert second.axes["z"].text() == "1"


@pytest.mark.parametrize("kind", ["nonholonomic", "unilateral"])
def test_a_constraint_kind_being_implemented_builds_or_says_so_at_its_list(editor, kind):
    """Deriving these kinds may still be refused as not supported yet: then the message is
    under the kind's list (or entry), the text stays, and nothing else is in the way."""
    editor.show_scene(load_scene("cartesian_pendulum"))
    text = {"nonholonomic": "x_dot + y_dot", "unilateral": "-y"}[kind]
    entries = editor.constraints.lists[kind]
    field = entries.add_entry()
    _type(field, text)
    _build(editor)
    assert field.text() == text and editor.document()["constraints"][kind] == [text]
    assert not editor.general_error.isVisibleTo(editor)
    if editor.build_status == "built":
        return
    shown = _plain(entries.error) if entries.error.isVisibleTo(editor) else ""
    shown += _plain(field.error_label) if field.has_error else ""
    assert shown
    if "not supported yet" in editor.build_problem:
        assert "not supported yet" in shown


def test_a_whole_kind_error_is_shown_under_its_list(editor):
    editor.show_scene(load_scene("cartesian_pendulum"))
    entries = editor.constraints.lists["nonholonomic"]
    _type(entries.add_entry(), "x_dot")
    editor.constraints.set_expanded(False)
    reason = "nonholonomic constraints are not supported yet"
    field = "constraints.nonholonomic"
    editor.show_failure(
        SimpleNamespace(
            field=field, position=None, reason=reason, message=f"<editor>: {field}: {reason}"
        )
    )
    assert editor.constraints.expanded and entries.error.isVisibleTo(editor)
    assert "not supported yet" in _plain(entries.error)
    assert entries.fields[0].text() == "x_dot"


def test_symmetry_mistakes_are_shown_at_their_fields(editor):
    editor.show_document(HELIX)
    _build(editor)
    assert editor.buildable, editor.build_problem
    screw = editor.symmetries.rows[0]
    _type(screw.components["z"], "t")
    _build(editor)
    assert "not 't'" in _plain(screw.components["z"].error_label)
    _type(screw.components["z"], "1")
    screw.name_edit.setText("H")
    screw.name_edit.textEdited.emit("H")
    _build(editor)
    assert "choose another name" in _plain(screw.name_error)
    assert screw.name_edit.text() == "H"


# -- renaming a coordinate ----------------------------------------------------------------------


def test_a_renamed_coordinate_shows_its_error_at_the_position_and_moves_generators(editor):
    _particle_pendulum(editor)
    editor.symmetries.add_symmetry("turn", theta="1")
    _type(editor.coordinates, "phi")
    _build(editor)
    x = _bob(editor).axes["x"]
    assert x.has_error and "unknown name 'theta'" in _plain(x.error_label)
    assert x.text() == "l*sin(theta)"
    assert editor.document()["symmetries"] == {"turn": {"phi": "1"}}  # renamed in place
    # a component of a coordinate that is gone stays, with the error under it
    _type(editor.coordinates, "phi, psi")
    editor.flush()
    turn = editor.symmetries.rows[0]
    _type(turn.components["psi"], "2")
    _type(editor.coordinates, "phi")
    for axis, text in (("x", "l*sin(phi)"), ("y", "-l*cos(phi)")):
        _type(_bob(editor).axes[axis], text)
    _build(editor)
    assert list(turn.components) == ["phi", "psi"]
    assert "'psi' is not a coordinate" in _plain(turn.components["psi"].error_label)
    _type(turn.components["psi"], "")
    _build(editor)
    assert editor.buildable, editor.build_problem


# -- switching the kind, undo, adding and removing ----------------------------------------------


def test_switching_the_kind_away_and_back_keeps_the_particles(editor):
    editor.show_scene(load_scene("double_pendulum"))
    document = editor.document()
    _type(editor.particles.rows[1].mass, "2*m")
    editor.flush()
    for kind in ("energies", "lagrangian", "hamiltonian"):
        _kind(editor, kind)
        editor.flush()
        assert "particles" not in editor.document() and "gravity" not in editor.document()["system"]
        assert not editor.particles.isVisibleTo(editor)
        assert editor.particles.names() == ["bob1", "bob2"]
    _kind(editor, "particles")
    editor.flush()
    assert editor.document()["particles"]["bob2"]["mass"] == "2*m"
    assert editor.document()["system"]["gravity"] == document["system"]["gravity"]
    # undo through the switches gives back the particles as they were at each step
    for _ in range(4):
        editor.undo()
        assert editor.particles.rows[1].mass.text() == "2*m"
    editor.undo()
    assert editor.document() == document
    editor.redo()
    assert editor.particles.rows[1].mass.text() == "2*m"


def test_particles_constraints_and_symmetries_are_added_and_removed(editor):
    editor.show_scene(load_scene("double_pendulum"))
    particles = editor.particles
    added = particles.add_particle()
    assert particles.names() == ["bob1", "bob2", "particle1"]
    assert editor.document()["particles"]["particle1"] == {"mass": "1", "position": ["0", "0"]}
    particles.remove_particle(particles.rows[0])
    assert particles.names() == ["bob2", "particle1"] and particles.rows[1] is added
    assert list(editor.document()["particles"]) == ["bob2", "particle1"]
    # a blank constraint is not in the document until something is typed in it
    holonomic = editor.constraints.lists["holonomic"]
    field = holonomic.add_entry()
    assert "constraints" not in editor.document()
    _type(field, "theta1 - theta2")
    second = holonomic.add_entry("theta1 + 1")
    assert editor.document()["constraints"] == {"holonomic": ["theta1 - theta2", "theta1 + 1"]}
    holonomic.remove_entry(field)
    assert editor.document()["constraints"] == {"holonomic": ["theta1 + 1"]}
    holonomic.remove_entry(second)
    assert "constraints" not in editor.document()
    # a symmetry gets a field per coordinate; blank ones are 0 and left out
    row = editor.symmetries.add_symmetry()
    assert row.accepted_name == "symmetry1" and list(row.components) == ["theta1", "theta2"]
    _type(row.components["theta2"], "1")
    assert editor.document()["symmetries"] == {"symmetry1": {"theta2": "1"}}
    editor.symmetries.remove_symmetry(row)
    assert "symmetries" not in editor.document()
    editor.flush()
    assert editor.undo_button.isEnabled()


def test_an_unknown_name_in_a_particle_field_can_be_added_as_a_parameter(editor):
    _particle_pendulum(editor)
    mass = _bob(editor).mass
    _type(mass, "M")
    _build(editor)
    assert "Add M as a parameter" in _plain(mass.error_label)
    mass.error_label.linkActivated.emit("add-parameter:M")
    assert [name for name, _ in editor.parameter_table.parameters()][-1] == "M"
    _build(editor)
    assert editor.buildable and not mass.has_error


def test_a_renamed_particle_takes_its_links_and_trace_along(editor):
    editor.show_scene(load_scene("double_pendulum"))
    links, trace = editor.drawing.links.text(), editor.drawing.trace.text()
    assert "bob2" in links and "bob2" in trace
    bob2 = editor.particles.rows[1]
    for typed in ("bob", "bo", "b", "ball"):  # letter by letter, as typed
        bob2.name_edit.setText(typed)
        bob2.name_edit.textEdited.emit(typed)
    assert bob2.accepted_name == "ball" and "already the name" not in _plain(bob2.name_error)
    assert editor.drawing.links.text() == links.replace("bob2", "ball")
    assert editor.drawing.trace.text() == trace.replace("bob2", "ball")
    _build(editor)
    assert editor.buildable and editor._built_scene.warnings == ()
    # a name that would merge two points is not carried: origin stays origin
    bob2.name_edit.setText("origin")
    bob2.name_edit.textEdited.emit("origin")
    assert editor.drawing.links.text() == links.replace("bob2", "ball")
    _build(editor)
    assert "origin" in _plain(bob2.name_error)
