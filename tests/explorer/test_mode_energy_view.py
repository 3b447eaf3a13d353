"""The normal-mode energy view: shown with its curves for a lattice, hidden for a pendulum,
a reason instead of numbers where modes do not apply, and cheap curves however long the run."""

from __future__ import annotations

import numpy as np
import pytest

from explorer.panels.mode_energy_view import MAX_CURVES, ModeEnergyView, PeakBuckets
from systems import processes
from systems.compiled import compile_system
from systems.families import fpu_chain
from systems.mechanics import derive
from systems.scene import load_scene, parse_scene
from tests.explorer.conftest import wait_for_points
from tests.slow_work import gone

WAIT_MS = 30000
"""How long a test waits at most for a worker (a busy machine; never a measurement)."""


def _opened(qtbot, window, scene) -> None:
    """Open ``scene`` and wait until it runs and its modes are analysed."""
    request = window.open_scene(scene)
    qtbot.waitUntil(
        lambda: window.built is not None and window.built.request == request, timeout=120000
    )
    qtbot.waitUntil(lambda: window.mode_view.analysis is not None, timeout=30000)


def _drawn(view) -> list[int]:
    return [0 if c.xData is None else len(c.xData) for c in view._curves]


@pytest.fixture
def lattice_window(qtbot):
    """The main window opened on an FPU chain of 8 particles, shown; closed after."""
    from explorer.app import create_window

    win = create_window(parse_scene(fpu_chain(8)))
    win.show()
    qtbot.waitUntil(lambda: win.compiled is not None, timeout=120000)
    qtbot.waitUntil(lambda: win.mode_view.analysis is not None, timeout=30000)
    yield win
    win.close()
    win.deleteLater()
    qtbot.wait(10)


def test_a_lattice_shows_its_mode_energies_and_a_pendulum_hides_them(qtbot, lattice_window):
    window = lattice_window
    dock, view = window.docks["modes"], window.mode_view
    action = dock.toggleViewAction()
    assert view.analysis.applies, view.analysis.reason
    assert dock.isVisible() and action.isEnabled()
    assert len(view._curves) == MAX_CURVES and len(view.legend.entries()) == MAX_CURVES
    wait_for_points(qtbot, window, 30)
    qtbot.waitUntil(lambda: min(_drawn(view)) >= 10, timeout=20000)
    # at the start all the energy is in mode 1, and the energies add up to about H
    main = window.store.main
    energies = view.modes.energies(main.y.data[:1])[0]
    H0 = window.compiled.hamiltonian(0.0, main.y.data[:1])[0]
    assert energies[0] == pytest.approx(H0, rel=1e-3) and np.all(energies[1:] < 1e-12 * H0)
    x, y = view._dots.getData()
    assert len(x) == 8 and np.all(np.isfinite(y))
    view.log_box.setChecked(True)  # the other scale redraws at once, without errors
    assert min(_drawn(view)) >= 10
    _opened(qtbot, window, "simple_pendulum")
    assert dock.isHidden() and not action.isEnabled()
    wait_for_points(qtbot, window, 5)
    assert window.error_details == ""


def test_where_modes_do_not_apply_the_view_says_why(qtbot, window):
    dock, view = window.docks["modes"], window.mode_view
    _opened(qtbot, window, "planetary_motion")
    assert not view.analysis.applies
    assert dock.isHidden() and not dock.toggleViewAction().isEnabled()
    window.reset_layout()  # the docks that apply come back, not this one
    assert dock.isHidden()
    dock.show()  # if shown all the same: the reason, not numbers
    assert view.stack.currentWidget() is view.message
    assert "does not depend on theta" in view.message.text()
    assert view._curves == []


def test_peak_buckets_keep_two_points_per_column_and_every_extreme():
    buckets = PeakBuckets(2, target=100)
    t = np.linspace(0.0, 1000.0, 200001)
    values = np.stack([np.sin(t), np.cos(3 * t)], axis=1)
    values[123456, 0] = 5.0  # a single spike survives any merging
    for start in range(0, len(t), 997):  # frames of any size
        buckets.add(t[start : start + 997], values[start : start + 997])
    assert 100 <= len(buckets) <= 200
    x, y = buckets.points(0)
    assert len(x) == 2 * len(buckets) and np.all(np.diff(x) >= 0)
    assert y.max() == 5.0 and y.min() == pytest.approx(-1.0, abs=1e-6)
    assert x[-1] <= 1000.0


def test_the_modes_come_from_a_worker_that_a_new_system_or_closing_ends(qtbot, monkeypatch):
    view = ModeEnergyView()
    qtbot.addWidget(view)
    pendulum = compile_system(derive(load_scene("double_pendulum")), ())
    chain = compile_system(derive(parse_scene(fpu_chain(8))), ())
    # nothing from the disk (an analysis remembered by another test): every one a worker's
    monkeypatch.setenv("PHASE_EXPLORER_DERIVATION_CACHE", "0")
    view.set_system(pendulum)
    first = view._job.pid
    view.set_system(chain)  # the first analysis is no longer wanted: its worker ends
    qtbot.waitUntil(lambda: view.analysis is not None, timeout=WAIT_MS)
    qtbot.waitUntil(lambda: gone(first), timeout=WAIT_MS)
    assert view.analysis.applies and view.modes.n == 8
    assert len(view._curves) == MAX_CURVES
    view.set_system(pendulum)
    pid = view._job.pid
    view.shutdown()
    qtbot.waitUntil(lambda: gone(pid), timeout=WAIT_MS)
    # the job is let go by its waiting thread, which a busy machine may keep a moment
    qtbot.waitUntil(lambda: pid not in {job.pid for job in processes.running()}, timeout=WAIT_MS)
    qtbot.wait(50)
    assert view.analysis is None  # nothing is delivered after closing


def test_modes_analysed_before_come_from_the_disk_without_a_worker(qtbot, tmp_path, monkeypatch):
    """The analysis is remembered (``derivation_cache.remembered_job``): a system analysed
    before gets its modes at once, with no worker, and the same ones."""
    monkeypatch.setenv("PHASE_EXPLORER_CACHE", str(tmp_path))
    pendulum = compile_system(derive(load_scene("double_pendulum")), ())
    views = []
    for _ in range(2):
        view = ModeEnergyView()
        qtbot.addWidget(view)
        view.set_system(pendulum)
        views.append((view, view._job.pid))
        qtbot.waitUntil(lambda view=view: view.analysis is not None, timeout=WAIT_MS)
    (first, first_pid), (second, second_pid) = views
    assert first_pid is not None and second_pid is None
    assert repr(second.analysis) == repr(first.analysis)
    for view, _ in views:
        view.shutdown()
