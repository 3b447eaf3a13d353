"""Fill section…: many orbits' crossings at the section's energy drawn as a layer of the
phase view; values checked (every point on the section at the energy), stopping, the
layer cleared with the section, exports, and the refusal where it cannot run."""

from __future__ import annotations

import gc

import numpy as np
import pyqtgraph as pg
import pytest
from PySide6.QtGui import QKeySequence

from explorer.orbit_colours import orbit_colour
from explorer.panels import section_fill_layer
from explorer.panels.phase_view import PhaseView
from systems.compiled import compile_system
from systems.mechanics import derive
from systems.scene import load_scene


def _compiled(name: str):
    return compile_system(derive(load_scene(name)), ("rhs", "hamiltonian", "separable"))


@pytest.fixture
def view(qtbot, monkeypatch):
    monkeypatch.setattr(section_fill_layer, "T_END", 200.0)
    view = PhaseView()
    qtbot.addWidget(view)
    compiled = _compiled("henon_heiles")
    view.set_system(compiled, compiled.initial_state())
    yield view
    view.fill_layer.shutdown()


def _filled(qtbot, layer) -> None:
    qtbot.waitUntil(lambda: not layer.running, timeout=60000)
    assert layer.portrait is not None, layer.view.hint.text()


def test_fill_draws_every_orbit_on_the_section_at_the_energy(qtbot, view):
    layer = view.fill_layer
    assert not layer.button.isEnabled()  # the phase plane: no section yet
    assert "turn on the Poincaré section" in layer.button.toolTip()
    view.set_mode("poincare")
    assert layer.button.isEnabled() and layer.fill_action.isEnabled()
    messages = []
    layer.message.connect(lambda text, _ms: messages.append(text))
    layer.start(8)
    assert messages[0].startswith("filling section: 8 orbits at H = ")
    assert layer.stop_action.isEnabled() and not layer.button.isEnabled()
    _filled(qtbot, layer)
    portrait = layer.portrait
    energy = view.section_energy
    assert portrait.energy == energy and len(portrait.starts) == 8
    assert portrait.trusted.all() and list(layer.kept) == list(range(8))
    points = layer.points()
    assert len(points) == portrait.crossings > 8 * 10
    compiled, section = view.compiled, view.section
    H = compiled.hamiltonian(0.0, points)
    assert np.max(np.abs(H - energy)) <= 1e-8
    n = compiled.n
    assert np.allclose(points[:, section.coordinate], section.value, atol=1e-12)
    assert (points[:, n + section.coordinate] > 0).all()  # upwards
    # what is drawn: those points, in (shown, p_shown), each orbit in its own colour
    item = layer.item
    assert item in view.plot.items and item.zValue() < 0
    x, y = item.getData()
    assert np.array_equal(x, points[:, section.shown])
    assert np.array_equal(y, points[:, n + section.shown])
    colours = {brush.color().name() for brush in item.data["brush"]}
    assert colours == {orbit_colour(r, 8) for r in range(8)}
    names = [label.text for _, label in view.legend.items]
    assert any(name.startswith("section fill: 8 orbits at H = ") for name in names)
    assert messages[-1].startswith("section filled: 8 of 8 orbits")
    # a layer's legend is placed at once (an export right after renders it, before Qt's
    # posted layout request): no label on another
    view.set_layer_legend([(pg.ScatterPlotItem(), "another layer's entry")], key="probe")
    labels = [label.mapRectToScene(label.boundingRect()) for _, label in view.legend.items]
    assert len(labels) == 3  # the forbidden region, the fill, the probe
    assert not any(a.intersects(b) for k, a in enumerate(labels) for b in labels[k + 1 :])
    view.set_layer_legend([], key="probe")
    assert view.hint.text() == f"8 of 8 orbits filled, {len(points)} crossings"
    assert "Last fill: section filled: 8 of 8 orbits" in layer.button.toolTip()
    assert layer.button.isEnabled() and not layer.stop_action.isEnabled()
    # another energy (a new start), then another mode: the layer goes
    y0 = compiled.initial_state().copy()
    y0[n + section.shown] *= 0.5
    view.set_system(compiled, y0)
    assert layer.item is None and layer.portrait is None
    assert not any(label.text.startswith("section fill") for _, label in view.legend.items)
    layer.start(4)
    _filled(qtbot, layer)
    assert np.max(np.abs(compiled.hamiltonian(0.0, layer.points()) - view.section_energy)) <= 1e-8
    view.set_mode("phase")
    assert layer.item is None and layer.item not in view.plot.items
    assert not layer.button.isEnabled()


def test_orbits_failing_the_energy_check_are_left_out(qtbot, view, monkeypatch):
    from systems import section_orbits

    real = section_orbits.section_portrait

    def strict(*args, **kwargs):  # nothing passes a check of 0: every orbit is left out
        return real(*args, **{**kwargs, "energy_tolerance": 0.0})

    monkeypatch.setattr(section_orbits, "section_portrait", strict)
    layer = view.fill_layer
    messages = []
    layer.message.connect(lambda text, _ms: messages.append(text))
    view.set_mode("poincare")
    layer.start(3)
    _filled(qtbot, layer)
    assert len(layer.kept) == 0 and len(layer.points()) == 0 and len(layer.item.getData()[0]) == 0
    assert view.hint.text() == "0 of 3 orbits filled, 0 crossings; 3 left out"
    text = messages[-1]
    assert text.startswith("section filled: 0 of 3 orbits") and "; 3 left out" in text
    assert "orbit 0: the energy error reached" in text and text in layer.button.toolTip()


def test_stopping_a_fill_and_closing(qtbot, view, monkeypatch):
    monkeypatch.setattr(section_fill_layer, "T_END", 2e4)
    layer = view.fill_layer
    view.set_mode("poincare")
    assert layer.stop_action.shortcut() == QKeySequence("Esc")
    layer.start(400)
    qtbot.waitUntil(lambda: layer.progress.maximum() > 0, timeout=60000)  # a chunk is done
    thread = layer._thread
    assert thread is not None and 0 < layer.progress.value() < 400
    layer.stop_action.trigger()  # Esc
    qtbot.waitUntil(lambda: not thread.is_alive(), timeout=30000)
    assert layer.portrait is None and layer.item is None and not layer.running
    assert view.hint.text() == "section fill stopped"
    assert layer.button.isEnabled() and layer.cancel_button.isHidden()
    # usable again; and a fill under way when the view goes ends as well
    monkeypatch.setattr(section_fill_layer, "T_END", 50.0)
    layer.start(2)
    _filled(qtbot, layer)
    monkeypatch.setattr(section_fill_layer, "T_END", 2e4)
    layer.start(400)
    qtbot.waitUntil(lambda: layer.progress.maximum() > 0, timeout=60000)
    thread = layer._thread
    pendulum = _compiled("simple_pendulum")  # another scene (as the window opens one)
    view.set_system(pendulum, pendulum.initial_state())
    assert not layer.running and layer.portrait is None
    assert view.hint.text() == "Click to launch a trajectory."  # the new view's own hint
    qtbot.waitUntil(lambda: not thread.is_alive(), timeout=30000)
    henon = _compiled("henon_heiles")
    view.set_system(henon, henon.initial_state())
    view.set_mode("poincare")
    layer.start(400)
    qtbot.waitUntil(lambda: layer.progress.maximum() > 0, timeout=60000)
    thread = layer._thread
    layer.shutdown()  # the window closing
    qtbot.waitUntil(lambda: not thread.is_alive(), timeout=30000)
    assert not layer.button.isEnabled()


def test_the_fill_thread_leaves_garbage_to_the_gui_thread(qtbot, view, monkeypatch):
    """The fill's thread writes its batch IR (about 10^5 objects): with the interpreter's
    own collection on, it freed there the Qt objects an earlier view had left in cycles,
    and hung (tests/explorer/conftest.py, ``GuiThreadCollection``)."""
    from systems import section_orbits

    collecting = []
    starts = section_orbits.default_starts

    def watched(*args):
        collecting.append(gc.isenabled())
        return starts(*args)

    monkeypatch.setattr(section_orbits, "default_starts", watched)
    view.set_mode("poincare")
    view.fill_layer.start(2)
    _filled(qtbot, view.fill_layer)
    assert collecting == [False]


def test_refused_where_there_is_no_section_or_taylor_does_not_apply(qtbot):
    view = PhaseView()
    qtbot.addWidget(view)
    layer = view.fill_layer
    assert not layer.button.isEnabled()
    pendulum = _compiled("simple_pendulum")
    view.set_system(pendulum, pendulum.initial_state())
    view.set_mode("poincare")
    assert view.mode == "phase" and not layer.button.isEnabled()
    assert "needs two degrees of freedom" in layer.button.toolTip()
    constrained = compile_system(
        derive(load_scene("cartesian_pendulum")), ("rhs", "hamiltonian", "separable")
    )
    view.set_system(constrained, constrained.initial_state())
    view.set_mode("poincare")
    assert view.mode == "poincare" and view.section is not None
    assert not layer.button.isEnabled() and not layer.fill_action.isEnabled()
    assert "runs the taylor family in batch" in layer.button.toolTip()
    assert "constraints" in layer.fill_action.statusTip()
    messages = []
    layer.message.connect(lambda text, _ms: messages.append(text))
    layer.start(5)  # as a session's line or the menu: says why; nothing runs
    assert not layer.running and "Fill button's tip says why" in view.hint.text()
    assert messages == [f"Cannot fill the section: {layer.refusal()}"]


def test_the_button_and_the_menu_ask_for_the_number_of_orbits(qtbot, view, monkeypatch):
    asked = []

    def get_int(_parent, _title, _label, value, low, high):
        asked.append((value, low, high))
        return (5, True) if len(asked) == 1 else (7, False)

    monkeypatch.setattr(section_fill_layer.QInputDialog, "getInt", get_int)
    layer = view.fill_layer
    view.set_mode("poincare")
    layer.button.click()
    assert asked == [(30, 1, 10_000)] and layer.running
    _filled(qtbot, layer)
    assert len(layer.portrait.starts) == 5
    layer.fill_action.trigger()  # Run > Fill section…, cancelled in its dialog
    assert len(asked) == 2 and not layer.running and len(layer.portrait.starts) == 5
