"""Views that fit (issue 10, item 3): clean starts, fitted ranges, wrapped angles, a
configuration view that keeps the mechanism in view, deleting an orbit, legends beside
the data, and a pair list for many coordinates."""

from __future__ import annotations

import math

import numpy as np
import pytest
from PySide6.QtCore import QPoint, QPointF, QRectF, Qt

from explorer.labels import coordinate_label
from explorer.trajectories import TrajectoryStore
from systems.scene import parse_scene
from tests.explorer.conftest import wait_for_points

PLAIN_PENDULUM = """
title = "Plain pendulum"
[system]
coordinates = ["theta"]
parameters = { m = 1.0, g = 9.81, l = 1.0 }
kinetic = "m*l**2*theta_dot**2/2"
potential = "-m*g*l*cos(theta)"
[initial]
theta = 2.0
[drawing]
points = { bob = ["l*sin(theta)", "-l*cos(theta)"] }
links = [["origin", "bob"]]
"""

PLAIN_OSCILLATOR = """
title = "Plain oscillator"
[system]
coordinates = ["x"]
parameters = { m = 1.0, k = 1.0 }
kinetic = "m*x_dot**2/2"
potential = "k*x**2/2"
[initial]
x = 0.5
"""


def _open(qtbot, window, scene) -> None:
    request = window.open_scene(scene)
    qtbot.waitUntil(
        lambda: window.built is not None and window.built.request == request, timeout=90000
    )
    if not window.controls.playing:
        window.controls.play_button.setChecked(True)


def _redraw(window) -> None:
    window.store.mark_dirty()
    window._on_redraw_timer_timeout()


def _labels_match(window) -> None:
    """The phase view's axis, title and pair box all name the current system's pair."""
    phase = window.phase_view
    scene = window.compiled.mechanics.scene
    assert phase.scene is scene
    shown = phase.section.shown if phase.mode == "poincare" else phase.index
    q = scene.coordinates[shown]
    assert phase.plot.getAxis("bottom").labelText == coordinate_label(q)
    assert coordinate_label(q) in phase.plot.titleLabel.text
    if phase.mode == "phase":
        assert phase.pair_combo.currentText().startswith(coordinate_label(q))


def _compiled(name_or_text):
    from explorer.builder import build
    from systems.scene import load_scene

    scene = parse_scene(name_or_text) if "\n" in name_or_text else load_scene(name_or_text)
    return build(scene).compiled


def _configuration(qtbot, text_or_name, size=(500, 700)):
    """A configuration view of the scene, shown at ``size`` with its start drawn."""
    from explorer.panels.configuration_view import ConfigurationView

    compiled = _compiled(text_or_name)
    view = ConfigurationView()
    qtbot.addWidget(view)
    view.resize(*size)
    view.show()
    view.set_system(compiled)
    store = TrajectoryStore(n_points=len(compiled.point_names))
    store.add(compiled.initial_state())
    view.refresh(store)
    return view, compiled


# -- clean starts -------------------------------------------------------------------------


def test_section_then_planetary_then_one_coordinate_is_a_clean_start(qtbot, window):
    _open(qtbot, window, "henon_heiles")
    phase = window.phase_view
    phase.poincare_box.setChecked(True)
    qtbot.waitUntil(lambda: len(phase.section_points(0)) >= 5, timeout=60000)
    _open(qtbot, window, "planetary_motion")
    wait_for_points(qtbot, window, 10)
    for _ in range(5):
        _redraw(window)
    assert window.error_details == ""
    _labels_match(window)
    assert phase.saddles == [] and phase.grid is None  # nothing left of Hénon–Heiles
    assert "forbidden" not in " ".join(phase.legend.entries())
    assert window.conserved_view.conserved_momenta == [1]  # p_theta
    # to a one-coordinate scene: the momentum plot goes, nothing fails at every frame
    _open(qtbot, window, "simple_pendulum")
    wait_for_points(qtbot, window, 10)
    for _ in range(25):
        _redraw(window)
        qtbot.wait(5)
    assert window.error_details == ""
    conserved = window.conserved_view
    assert conserved.momentum_plot is None and conserved._momentum_curves == {}
    _labels_match(window)
    assert len(phase.saddles) == 2


def test_panels_switched_between_systems_directly_keep_nothing(qtbot):
    """The panels alone, switched while in the Poincaré mode and refreshed with a store
    of the previous system (a frame that arrives before the store is replaced)."""
    from explorer.panels.configuration_view import ConfigurationView
    from explorer.panels.conserved_view import ConservedView
    from explorer.panels.phase_view import PhaseView

    henon, kepler, pendulum = (
        _compiled(name) for name in ("henon_heiles", "planetary_motion", "simple_pendulum")
    )
    phase, conserved, configuration = PhaseView(), ConservedView(), ConfigurationView()
    for panel in (phase, conserved, configuration):
        qtbot.addWidget(panel)
    phase.set_system(henon, henon.initial_state())
    phase.set_mode("poincare")
    old = TrajectoryStore(n_points=len(kepler.point_names))
    old.add(kepler.initial_state())
    # Kepler has a section too: the cut is its angle, shown in (r, p_r)
    phase.set_system(kepler, kepler.initial_state())
    assert phase.mode == "poincare"
    assert kepler.mechanics.scene.coordinates[phase.section.coordinate] == "theta"
    assert phase.plot.getAxis("bottom").labelText == "r"
    conserved.set_system(kepler)
    configuration.set_system(kepler)
    for panel in (phase, conserved, configuration):
        panel.refresh(old)
    phase.set_system(pendulum, pendulum.initial_state())
    conserved.set_system(pendulum)
    configuration.set_system(pendulum)
    assert phase.mode == "phase" and not phase.poincare_box.isEnabled()
    assert not phase.pair_combo.isEnabled()
    for panel in (phase, conserved, configuration):
        panel.refresh(old)  # the two-coordinate store of the previous system: no IndexError
    assert conserved.momentum_plot is None and conserved._momentum_curves == {}
    assert configuration.path_plot is None
    assert phase.plot.getAxis("bottom").labelText == coordinate_label("theta")


def test_a_section_through_a_singular_line_is_drawn_without_dividing_by_zero(qtbot):
    from explorer import poincare
    from explorer.panels.phase_view import PhaseView

    kepler = _compiled("planetary_motion")
    section = poincare.Section(coordinate=0, value=0.0, shown=1)  # r = 0
    energy = float(kepler.hamiltonian(0.0, kepler.initial_state()[None])[0])
    q = np.linspace(-1.0, 1.0, 7)
    mask = poincare.forbidden(kepler, section, energy, q, np.zeros(7))
    assert mask.shape == (7,) and mask.all()  # nothing reaches r = 0 at negative energy
    phase = PhaseView()
    qtbot.addWidget(phase)
    phase.set_system(kepler, kepler.initial_state())
    phase.section = section
    phase.set_mode("poincare")
    assert phase.mode == "poincare"


# -- ranges --------------------------------------------------------------------------------


def _inside(values: np.ndarray, span) -> bool:
    values = values[np.isfinite(values)]
    return bool(values.min() >= span[0] and values.max() <= span[1])


def test_a_scene_without_view_fits_orbit_separatrix_and_equilibria(qtbot, window):
    _open(qtbot, window, parse_scene(PLAIN_PENDULUM))
    phase = window.phase_view
    q_span, p_span = phase.plot.getViewBox().viewRange()
    separatrix = 2.0 * math.sqrt(9.81)  # p at the bottom of the separatrix
    assert p_span[0] < -separatrix and p_span[1] > separatrix  # not [-1, 1]
    assert p_span[1] < 2.0 * separatrix  # fitted, not lost in a huge range
    assert q_span[0] < -math.pi and q_span[1] > math.pi  # theta is an angle: (-pi, pi]
    assert sorted(round(abs(s.q), 3) for s in phase.saddles) == [round(math.pi, 3)] * 2
    assert any(abs(q) < 1e-6 and abs(p) < 1e-6 for q, p in phase.centres)
    qtbot.waitUntil(lambda: window.store.main.last_t > 2.5, timeout=60000)  # one period
    _redraw(window)
    data = window.store.main.y.data
    assert np.nanmax(np.abs(data[:, 1])) > 5.0  # p reaches 5.3
    assert _inside(data[:, 1], p_span)
    # not jittering: once the orbit has closed the ranges stay put
    before = phase.plot.getViewBox().viewRange()
    for _ in range(10):
        qtbot.wait(20)
        _redraw(window)
    assert phase.plot.getViewBox().viewRange() == before


def test_ranges_grow_with_a_launched_orbit_and_level_sets_follow(qtbot, window):
    _open(qtbot, window, parse_scene(PLAIN_OSCILLATOR))
    phase = window.phase_view
    q_span, p_span = phase.plot.getViewBox().viewRange()
    assert q_span[1] < 2.0 and p_span[1] < 2.0  # fits the small orbit
    assert phase.angles.tolist() == [False]
    phase.launch_at(0.0, 3.0)  # amplitude 3
    qtbot.waitUntil(lambda: len(window.store) == 2, timeout=5000)
    qtbot.waitUntil(lambda: window.store.trajectories[1].last_t > 7.0, timeout=60000)
    _redraw(window)
    q_span, p_span = phase.plot.getViewBox().viewRange()
    orbit = window.store.trajectories[1].y.data
    assert _inside(orbit[:, 0], q_span) and _inside(orbit[:, 1], p_span)
    assert phase.grid.qs[-1] >= 3.0 and phase.grid.ps[-1] >= 3.0  # redrawn over the new range


def test_time_axes_fit_the_data(qtbot, window):
    qtbot.waitUntil(lambda: window.store.main.last_t > 1.0, timeout=60000)
    _redraw(window)
    conserved = window.conserved_view
    t_last = window.store.main.last_t
    t_span = conserved.energy_plot.getViewBox().viewRange()[0]
    assert t_span[1] >= 0.99 * t_last
    assert t_span[1] <= 1.1 * t_last  # not twice the data


# -- angles --------------------------------------------------------------------------------


def _no_unbroken_jump(x: np.ndarray) -> bool:
    steps = np.abs(np.diff(x))
    return bool(np.nanmax(steps) < math.pi) if np.isfinite(steps).any() else True


def test_double_pendulum_angles_wrap_and_its_section_fills(qtbot, window):
    _open(qtbot, window, "double_pendulum")
    window.controls.speed_combo.setCurrentIndex(window.controls.speed_combo.count() - 1)
    phase = window.phase_view
    assert phase.angles.tolist() == [True, True]

    def turned() -> bool:
        main = window.store.main
        return main is not None and np.nanmax(np.abs(main.y.data[:, 1])) > 3 * math.pi

    qtbot.waitUntil(turned, timeout=120000)
    _redraw(window)
    x, y = phase.shown_data(0)
    finite = np.isfinite(x)
    assert finite.sum() > 100 and np.abs(x[finite]).max() <= math.pi + 1e-9
    assert np.isnan(x).any() and _no_unbroken_jump(x)
    path = window.configuration_view._path.items
    shown = np.concatenate([item.xData for item in path if item.xData is not None])
    assert np.nanmax(np.abs(shown)) <= math.pi + 1e-9
    # the section at theta1 = 0 counts every turn of theta1
    phase.poincare_box.setChecked(True)
    qtbot.waitUntil(lambda: len(phase.section_points(0)) >= 40, timeout=120000)
    points = phase.section_points(0)
    assert np.allclose(np.mod(points[:, 0] + math.pi, 2 * math.pi) - math.pi, 0.0, atol=1e-8)
    _redraw(window)
    x, _ = phase.shown_data(0)
    assert np.abs(x).max() <= math.pi + 1e-9


# -- the configuration view ----------------------------------------------------------------


@pytest.mark.parametrize(
    "size, angles",
    [
        ((260, 900), (math.pi / 2, math.pi / 2)),  # tall and narrow, rods out sideways
        ((900, 220), (0.0, 0.0)),  # wide and flat, hanging straight down
        ((500, 500), (-math.pi / 2, math.pi)),
    ],
)
def test_configuration_keeps_the_mechanism_in_view_when_resized(qtbot, tmp_path, size, angles):
    from explorer.export import export_widget

    view, compiled = _configuration(qtbot, "double_pendulum", (500, 500))
    view.resize(*size)
    qtbot.waitUntil(lambda: view.mechanism.getViewBox().width() > 0, timeout=2000)
    qtbot.wait(50)
    # then the mechanism reaches further than at the start (the view has to grow)
    state = compiled.initial_state()
    state[:2] = angles
    later = TrajectoryStore(n_points=len(compiled.point_names))
    later.add(state)
    view.refresh(later)
    qtbot.wait(50)

    def in_view() -> bool:
        (x0, x1), (y0, y1) = view.mechanism.getViewBox().viewRange()
        points = np.vstack([compiled.drawing(0.0, state[None])[0], [[0.0, 0.0]]])
        inside_x = (points[:, 0] >= x0) & (points[:, 0] <= x1)
        inside_y = (points[:, 1] >= y0) & (points[:, 1] <= y1)
        return bool((inside_x & inside_y).all())

    assert in_view()
    # another change of shape keeps it in view too, and an export renders that view
    view.resize(size[1], size[0])
    qtbot.wait(50)
    assert in_view()
    out = export_widget(view.export_target(), tmp_path / "configuration.png")
    assert out.exists() and out.stat().st_size > 0


# -- deleting an orbit ---------------------------------------------------------------------


def _pixel(phase, x: float, y: float) -> QPoint:
    scene_point = phase.plot.getViewBox().mapViewToScene(QPointF(x, y))
    return phase.plot_widget.mapFromScene(scene_point)


def _right_click_menu(qtbot, phase, x: float, y: float):
    phase.last_menu = None
    qtbot.mouseClick(
        phase.plot_widget.viewport(), Qt.MouseButton.RightButton, pos=_pixel(phase, x, y)
    )
    qtbot.waitUntil(lambda: phase.last_menu is not None, timeout=3000)
    menu = phase.last_menu
    texts = [(a.text(), a.isEnabled()) for a in menu.actions()]
    return menu, texts


def test_right_click_on_an_orbit_offers_to_delete_it(qtbot, window):
    wait_for_points(qtbot, window, 5)
    phase = window.phase_view
    phase.launch_at(0.5, 2.0)
    qtbot.waitUntil(lambda: len(window.store) == 2, timeout=5000)
    wait_for_points(qtbot, window, 20, key=1)
    _redraw(window)
    x, y = phase.shown_data(1)
    i = int(np.flatnonzero(np.isfinite(x))[len(x) // 2])
    assert phase.orbit_at(x[i], y[i]) == 1
    menu, texts = _right_click_menu(qtbot, phase, x[i], y[i])
    assert texts[0] == ("Delete this orbit (orbit 1)", True)
    assert any("View All" in t for t, _ in texts)  # pyqtgraph's own menu is still there
    with qtbot.waitSignal(phase.orbit_delete_requested, timeout=2000) as signal:
        menu.actions()[0].trigger()
    menu.close()
    assert signal.args == [1]
    assert all("Delete" not in a.text() for a in menu.actions())  # taken back on closing
    # the main orbit cannot be deleted; empty space offers no deletion
    x0, y0 = phase.shown_data(0)
    _, texts = _right_click_menu(qtbot, phase, x0[-1], y0[-1])
    assert texts[0][1] is False and "cannot be deleted" in texts[0][0]
    phase.last_menu.close()
    q_span, p_span = phase.plot.getViewBox().viewRange()
    _, texts = _right_click_menu(qtbot, phase, q_span[0] + 0.02, p_span[1] - 0.02)
    assert not any("Delete" in t or "deleted" in t for t, _ in texts)
    phase.last_menu.close()
    assert phase.request_delete(0) is False


# -- legends, tooltips, the pair list ------------------------------------------------------


def _rect(item) -> QRectF:
    return item.mapRectToScene(item.boundingRect())


def test_legends_sit_beside_the_data(qtbot, window):
    wait_for_points(qtbot, window, 5)
    phase = window.phase_view
    for q, p in ((0.3, 1.0), (-0.5, 2.5)):
        phase.launch_at(q, p)
    qtbot.waitUntil(lambda: len(window.store) == 3, timeout=5000)
    wait_for_points(qtbot, window, 5, key=2)
    _redraw(window)
    qtbot.wait(50)
    legend = phase.legend
    assert legend.entries()[:3] == ["orbit", "orbit 1", "orbit 2"]
    assert "level sets of H" in legend.entries()
    plot_area = _rect(phase.plot.getViewBox())
    assert not _rect(legend).intersects(plot_area)
    labels = [_rect(label).adjusted(1, 1, -1, -1) for _, label in legend.items]
    for a in range(len(labels)):  # entries never pile up on each other
        for b in range(a + 1, len(labels)):
            assert not labels[a].intersects(labels[b])
    conserved = window.conserved_view
    assert not _rect(conserved.energy_legend).intersects(_rect(conserved.energy_plot.getViewBox()))


def test_controls_say_what_they_do(qtbot, window):
    phase = window.phase_view
    assert "phase plane" in phase.pair_combo.toolTip()
    assert "two degrees of freedom" in phase.poincare_box.toolTip()
    _open(qtbot, window, "henon_heiles")
    assert "crosses" in phase.poincare_box.toolTip() or "cross" in phase.poincare_box.toolTip()
    assert "x = 0" in phase.poincare_box.toolTip()


def test_the_pair_list_is_searchable_for_many_coordinates(qtbot):
    from explorer.panels.phase_view import PhaseView
    from systems.compiled import compile_system
    from systems.mechanics import derive

    n = 64
    names = [f"x{i}" for i in range(n)]
    text = "\n".join(
        [
            'title = "Chain"',
            "[system]",
            "coordinates = [" + ", ".join(f'"{q}"' for q in names) + "]",
            "parameters = { k = 1.0 }",
            'kinetic = "' + " + ".join(f"{q}_dot**2/2" for q in names) + '"',
            'potential = "'
            + " + ".join(f"k*({a} - {b})**2/2" for a, b in zip(names, names[1:], strict=False))
            + '"',
        ]
    )
    compiled = compile_system(derive(parse_scene(text)), ("rhs", "hamiltonian"))
    phase = PhaseView()
    qtbot.addWidget(phase)
    phase.set_system(compiled, compiled.initial_state())
    combo = phase.pair_combo
    assert combo.count() == n  # one entry per coordinate, not n^2
    assert combo.isEditable() and combo.completer() is not None
    completer = combo.completer()
    assert completer.filterMode() == Qt.MatchFlag.MatchContains
    completer.setCompletionPrefix("x42")
    assert completer.completionCount() == 1
    assert "x42" in completer.currentCompletion()
    assert "search" in combo.toolTip()
    phase.set_pair(42)
    assert phase.index == 42 and coordinate_label("x42") in phase.plot.titleLabel.text
    combo.setEditText("nonsense")
    combo.lineEdit().editingFinished.emit()
    assert combo.currentText() == combo.itemText(42)


# -- drawings a student can read (issue 25 item 6) ---------------------------------------------

HOOKED_DOUBLE_PENDULUM = """
title = "Double pendulum hung from a hook at (0.5, 1), no [drawing]"
[system]
coordinates = ["theta1", "theta2"]
parameters = { m1 = 2.0, m2 = 0.5, l1 = 1.0, l2 = 0.8, g = 9.81 }
gravity = "g"
[particles]
bob1 = { mass = "m1", position = ["0.5 + l1*sin(theta1)", "1 - l1*cos(theta1)"] }
[particles.bob2]
mass = "m2"
position = ["0.5 + l1*sin(theta1) + l2*sin(theta2)", "1 - l1*cos(theta1) - l2*cos(theta2)"]
[initial]
theta1 = 1.0
"""


def test_a_scene_of_particles_without_a_drawing_has_rods_supports_and_sized_bodies(qtbot):
    from explorer.panels.configuration_view import BODY_PIXELS

    view, compiled = _configuration(qtbot, HOOKED_DOUBLE_PENDULUM)
    assert view.links == (("support", "bob1"), ("bob1", "bob2"))
    bob1, bob2 = compiled.drawing(0.0, compiled.initial_state()[None])[0]
    x, y = view._rods.getData()
    np.testing.assert_allclose(np.column_stack([x, y]), [[0.5, 1.0], bob1, bob1, bob2])
    # the hook: a small grey square; the bodies: discs whose area goes with the mass
    px, py = view._pivot.getData()
    assert view._pivot in view.mechanism.items and (list(px), list(py)) == ([0.5], [1.0])
    sizes = [point.size() for point in view._bobs.points()]
    assert sizes == pytest.approx([BODY_PIXELS, BODY_PIXELS / 2])  # m2 = m1/4
    # the path in two angles keeps one scale
    assert view.path_plot.getViewBox().state["aspectLocked"]


def test_fixed_and_massless_points_are_small_and_grey(qtbot):
    from explorer.panels.configuration_view import FIXED_BRUSH

    view, compiled = _configuration(qtbot, "atwood_machine")
    names = compiled.point_names
    bodies = [names[k] for k in np.flatnonzero(view._moving)]
    assert bodies == ["mass1", "mass2"]  # the pulley's spoke and rim, the floor: grey dots
    assert len(view._fixed.points()) == len(names) - 2
    assert view._fixed.opts["brush"].color() == FIXED_BRUSH.color()
    view, _ = _configuration(qtbot, "kapitza_pendulum")
    assert list(view._moving) == [True, False]  # the pivot has no mass


def test_the_rolling_disk_s_path_circle_is_round(qtbot):
    view, _ = _configuration(qtbot, "rolling_disk")
    box = view.path_plot.getViewBox()
    assert box.state["aspectLocked"]
    (x0, x1), (y0, y1) = box.viewRange()
    width, height = box.width(), box.height()
    assert (x1 - x0) / width == pytest.approx((y1 - y0) / height, rel=1e-6)


def test_a_legend_of_many_orbits_says_how_many_it_leaves_out():
    from explorer.panels.curves import LEGEND_ORBITS, legend_orbit_names

    few = legend_orbit_names([2, 0, 1])
    assert few == [(0, "orbit"), (1, "orbit 1"), (2, "orbit 2")]
    many = legend_orbit_names(range(30), main="main orbit")
    assert len(many) == LEGEND_ORBITS and many[0] == (0, "main orbit")
    assert many[-1] == (
        LEGEND_ORBITS - 1,
        f"orbit {LEGEND_ORBITS - 1} and {30 - LEGEND_ORBITS} more",
    )
