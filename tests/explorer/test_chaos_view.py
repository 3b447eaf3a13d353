"""The Chaos dock: running estimates of the maximal exponent, MEGNO and SALI that follow
the main orbit while it plays; refused with the reason where the variational equations
are not written; its thread and worker end with the system and the window."""

from __future__ import annotations

import threading

from tests.explorer.conftest import wait_for_points

WAIT_MS = 60000
"""How long a test waits at most (a busy machine; never a measurement)."""


def _opened(qtbot, window, scene) -> None:
    request = window.open_scene(scene)
    qtbot.waitUntil(
        lambda: window.built is not None and window.built.request == request, timeout=120000
    )


def _wait_until_still(qtbot, window) -> None:
    """Until the main orbit's last time stays the same over 0.3 s (the run has paused)."""
    before = None
    for _ in range(WAIT_MS // 300):
        t = float(window.store.main.t.data[-1])
        if t == before:
            return
        before = t
        qtbot.wait(300)
    raise AssertionError(f"the main orbit did not pause: t = {before}")


def _chaos_threads() -> list[threading.Thread]:
    return [t for t in threading.enumerate() if t.name == "chaos-estimates"]


def test_the_estimates_follow_the_run_and_converge_for_a_regular_orbit(qtbot, window):
    dock, view = window.docks["chaos"], window.chaos_view
    _opened(qtbot, window, "henon_heiles")
    assert dock.isHidden() and dock.toggleViewAction().isEnabled()
    assert view.reason is None and view.estimate is None  # nothing runs while hidden
    dock.show()
    dock.raise_()
    # 20x, not max: at max speed the orbit outran the estimates (a quarter of the time, three
    # times the work a step) so far that catching up on a busy machine took over a minute
    window.controls.speed_combo.setCurrentText("20×")
    wait_for_points(qtbot, window, 20)
    qtbot.waitUntil(lambda: view.estimate is not None and view.estimate.t > 50, timeout=WAIT_MS)
    window.controls.play_button.click()  # paused: the estimates catch up and stop
    _wait_until_still(qtbot, window)  # a block under way when the click came still lands
    qtbot.waitUntil(lambda: view.estimate.t >= float(window.store.main.t.data[-1]), timeout=WAIT_MS)
    estimate = view.estimate
    qtbot.wait(300)
    assert view.estimate is estimate  # nothing more while the run is paused
    main_t = float(window.store.main.t.data[-1])
    assert estimate.t <= main_t + 2.0  # at most an interval past it (2 / |eigenvalue|)
    assert len(estimate.exponents) == 4 and abs(sum(estimate.exponents)) < 1e-6
    assert 0 < estimate.megno < 4  # the catalogue's start is regular: <Y> heads for 2
    assert "MEGNO" in view.info.text() and len(view.curves["megno"].xData) >= 1
    assert len(_chaos_threads()) == 1
    _opened(qtbot, window, "cartesian_pendulum")  # constraints: refused, the thread ends
    assert view.reason is not None and "[constraints]" in view.reason
    assert "[constraints]" in view.message.text()
    assert not dock.toggleViewAction().isEnabled() or dock.isVisible()
    qtbot.waitUntil(lambda: not _chaos_threads(), timeout=5000)
    assert window.error_details == ""
    assert view.estimate is None  # a new system starts from nothing


def test_closing_the_window_ends_the_estimates(qtbot):
    from explorer.app import create_window

    win = create_window("henon_heiles")
    win.show()
    qtbot.waitUntil(lambda: win.compiled is not None, timeout=120000)
    win.docks["chaos"].show()
    qtbot.waitUntil(lambda: len(_chaos_threads()) == 1, timeout=WAIT_MS)
    win.close()
    win.deleteLater()
    qtbot.wait(10)
    qtbot.waitUntil(lambda: not _chaos_threads(), timeout=5000)
