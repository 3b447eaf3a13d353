"""Every catalogue scene opens in the window and data arrives in each panel.

One window opens the scenes one after another, as a user switching scenes does (and a
window made per scene cost about 4 s each to build and shut down); a scene that fails
is named, and the others still run."""

from __future__ import annotations

from systems.scene import catalogue
from tests.explorer.conftest import assert_data_in_every_panel, wait_for_points

NAMES = [entry.name for entry in catalogue()]


def test_every_scene_opens_with_data_in_every_panel(qtbot, window):
    failures = {}
    for name in NAMES:
        try:
            _opens_with_data_in_every_panel(qtbot, window, name)
        except Exception as exc:  # noqa: BLE001 - every scene is tried, each failure named
            failures[name] = f"{type(exc).__name__}: {exc}"
    assert not failures, "\n".join(f"{name}: {why}" for name, why in failures.items())


def _opens_with_data_in_every_panel(qtbot, window, name):
    request = window.open_scene(name)
    qtbot.waitUntil(
        lambda: window.built is not None and window.built.request == request, timeout=90000
    )
    assert window.compiled.mechanics.scene.name == name
    wait_for_points(qtbot, window, 8, timeout=60000)
    qtbot.waitUntil(lambda: window.redraws > 2, timeout=5000)
    assert_data_in_every_panel(window)
    # the editor's classification card
    assert "conserv" in window.editor.classification_card.text()
