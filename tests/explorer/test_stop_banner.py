"""A run that stops says why above the plots, with the energy guard at hand (issue 25, 5).

The bead on a rotating wire (r = cosh(w t)) used to stop at t = 14 with "the energy error
reached 0.0111 ... reduce the step" in the status bar, over the time readout, kept after
a rebuild, with the button still saying Pause. Now the stop is named as an unbounded
motion in a banner above the plots, whose energy guard continues the run, and the button
says Play.
"""

from __future__ import annotations

import pytest

from tests.explorer.conftest import wait_for_points
from tests.systems.test_unbounded import BEAD

MAX_SPEED = 8  # the speed list's "max"


@pytest.fixture
def bead_window(qtbot, window, tmp_path):
    path = tmp_path / "bead.toml"
    path.write_text(BEAD + "[view]\nt_end = 30.0\n", encoding="utf-8")
    window.controls.speed_combo.setCurrentIndex(MAX_SPEED)
    window.open_scene(str(path))
    qtbot.waitUntil(lambda: window.built.scene.title.startswith("Bead"), timeout=60000)
    return window


def _wait_for_stop(qtbot, window) -> None:
    qtbot.waitUntil(window.stop_banner.isVisible, timeout=60000)
    window._on_redraw_timer_timeout()


def _assert_stopped_as_unbounded(window) -> None:
    main = window.store.main
    banner = window.stop_banner
    assert main.status == "unbounded", main.message
    assert banner.title.text() == "The motion is unbounded"
    assert banner.message.text().startswith("r grew to ") and "e^(" in banner.message.text()
    # Play/Pause shows the worker's real state: nothing runs
    assert not window.controls.playing and window.controls.play_button.text() == "Play"
    assert window.worker.paused and window.rate_label.text() == "stopped"
    # one place for the reason: not the status bar, whose readouts it cannot cover
    assert not window.statusBar().currentMessage().startswith("stopped")
    banner_box = banner.rect().translated(banner.mapTo(window, banner.rect().topLeft()))
    bar = window.statusBar()
    assert not banner_box.intersects(bar.geometry())
    assert banner.guard_edit.isVisible() and banner.off_button.isVisible()


def test_the_bead_stops_as_unbounded_and_the_guard_continues_it(qtbot, bead_window):
    window = bead_window
    _wait_for_stop(qtbot, window)
    _assert_stopped_as_unbounded(window)
    stop_t = window.store.main.last_t
    assert 14.0 < stop_t < 15.0
    assert window.stop_banner.guard_edit.text() == "0.01"
    assert "(0.01)" in window.energy_guard_action.text()

    # Play after a stop starts over, playing
    window.controls.play_button.click()
    assert window.controls.playing and window.controls.play_button.text() == "Pause"
    assert not window.stop_banner.isVisible()
    assert window.store.main.t.data[0] == 0.0 and window.store.main.status == "running"
    _wait_for_stop(qtbot, window)
    _assert_stopped_as_unbounded(window)

    # raising the guard there goes on from the stop, playing
    window.stop_banner.raise_button.click()
    assert window.energy_tolerance == pytest.approx(0.1)
    assert "(0.1)" in window.energy_guard_action.text()
    assert window.controls.playing and not window.stop_banner.isVisible()
    wait_for_points(qtbot, window, len(window.store.main.t) + 3)
    assert window.store.main.last_t > stop_t
    _wait_for_stop(qtbot, window)  # a million times further again
    _assert_stopped_as_unbounded(window)
    assert window.store.main.last_t > 2 * stop_t - 1

    # a value typed into the banner applies as well; off follows the growth on
    window.stop_banner.guard_edit.setText("off")
    window.stop_banner.guard_edit.returnPressed.emit()
    assert window.energy_tolerance is None and window.controls.playing
    assert window.stop_banner.guard_edit.text() == "off"
    assert "(off)" in window.energy_guard_action.text()
    qtbot.waitUntil(lambda: window.store.main.last_t > 40.0, timeout=30000)

    # a rebuild (here a new scene) clears whatever the banner said
    window.stop_banner.show_stop("energy_error", "from the last system", 0.01)
    window.open_scene("simple_pendulum")
    qtbot.waitUntil(lambda: window.built.scene.name == "simple_pendulum", timeout=60000)
    assert not window.stop_banner.isVisible()
    assert window.controls.playing


def test_reset_clears_the_stop(qtbot, bead_window):
    window = bead_window
    _wait_for_stop(qtbot, window)
    window.stop_banner.restart_button.click()  # Start over: Reset
    assert not window.stop_banner.isVisible()
    assert window.store.main.t.data[0] == 0.0


@pytest.mark.qt_no_exception_capture
def test_a_replay_waiting_past_the_stop_says_why(qtbot, bead_window):
    from explorer.session import Player
    from explorer.session.script import parse

    window = bead_window
    _wait_for_stop(qtbot, window)
    player = Player(window, parse("run-until 100", "t.session"), source="t.session")
    player.start()
    qtbot.waitUntil(lambda: player.status is not None, timeout=30000)
    assert player.status == 2
    assert "the run stopped at t = 14." in player.message
    assert "before t = 100: unbounded: r grew to" in player.message
