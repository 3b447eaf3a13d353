"""Every catalogue scene opens in the window and data arrives in each panel.

One window opens the scenes one after another, as a user switching scenes does (and a
window made per scene cost about 4 s each to build and shut down); a scene that fails
is named, and the others still run."""

from __future__ import annotations

import numpy as np

from systems.scene import catalogue
from tests.explorer.conftest import wait_for_points

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
    window.store.mark_dirty()
    window._on_redraw_timer_timeout()
    main = window.store.main
    assert main.status in ("running", "ok"), main.message
    assert np.isfinite(main.y.data).all()
    phase = window.phase_view
    assert phase._curves[0].point_count() >= 8
    conserved = window.conserved_view
    assert conserved._energy_curves[0].point_count() >= 8
    for i in conserved.conserved_momenta:
        assert conserved._momentum_curves[i].point_count() >= 8
    configuration = window.configuration_view
    if window.compiled.mechanics.scene.drawing is not None:
        x, y = configuration._bobs.getData()
        fixed_x, _ = configuration._fixed.getData()
        assert len(x) >= 1 and np.isfinite(x).all() and np.isfinite(y).all()
        assert len(x) + len(fixed_x) == len(window.compiled.point_names)
    if window.compiled.n >= 2:
        assert configuration._path.point_count() >= 8
    # the editor shows the scene and its classification card
    assert window.editor.title_edit.text() == window.compiled.mechanics.scene.title
    assert "conserv" in window.editor.classification_card.text()
