"""The chaos map under the Poincaré section: the button in the section mode, progress,
an image of MEGNO under the points, a click on a pixel starts that orbit, and a new
mode or system (or Cancel) removes it; nothing keeps running."""

from __future__ import annotations

import numpy as np
import pyqtgraph as pg
import pytest

from explorer.panels import chaos_map_layer
from explorer.panels.phase_view import PhaseView
from systems.compiled import compile_system
from systems.mechanics import derive
from systems.scene import load_scene


@pytest.fixture
def view(qtbot, monkeypatch):
    monkeypatch.setattr(chaos_map_layer, "GRID", 16)
    monkeypatch.setattr(chaos_map_layer, "T_END", 100.0)
    view = PhaseView()
    qtbot.addWidget(view)
    compiled = compile_system(
        derive(load_scene("henon_heiles")), ("rhs", "hamiltonian", "separable")
    )
    view.set_system(compiled, compiled.initial_state())
    yield view
    view.map_layer.shutdown()


def test_a_map_under_the_section_and_a_click_on_a_pixel(qtbot, view):
    layer = view.map_layer
    assert not layer.button.isEnabled()  # the phase plane: no section to map
    view.set_mode("poincare")
    assert layer.button.isEnabled()
    layer.button.click()
    assert not layer.progress.isHidden() or layer.result is not None
    qtbot.waitUntil(lambda: layer.result is not None, timeout=120000)
    assert layer.progress.isHidden() and layer.button.isEnabled()
    result = layer.result
    assert result.grid.energy == pytest.approx(view.section_energy)
    assert result.megno.shape == (16, 16) and np.isfinite(result.megno[result.status == 0]).all()
    assert layer.image is not None and layer.image in view.plot.items
    assert layer.image.zValue() < 0  # under the section's points
    assert "chaotic" in view.hint.text()
    # its colour key in the legend (so in exports too), in the image's colours
    names = [label.text for _, label in view.legend.items]
    keys = [name for name in names if name.startswith("MEGNO")]
    assert keys == ["MEGNO 2: regular", "MEGNO 4: the threshold", "MEGNO 8 and more: chaotic"]
    top = chaos_map_layer.map_image(type("R", (), {"megno": np.array([[8.0]])})())[0, 0]
    swatch = next(s.item for s, label in view.legend.items if label.text == keys[-1])
    colour = pg.mkBrush(swatch.opts["brush"]).color()
    assert (colour.red(), colour.green(), colour.blue()) == tuple(top[:3])
    # a pixel of the map: the orbit it was computed from
    rows, cols = np.nonzero(result.status == 0)
    y, p_y = result.grid.xs[cols[0]], result.grid.ys[rows[0]]
    launched = []
    view.launch_requested.connect(launched.append)
    view.launch_at(y, p_y)
    start = result.grid.starts[rows[0] * 16 + cols[0]]
    assert np.allclose(launched[0], start, atol=1e-12)
    # another mode: the map goes
    view.set_mode("phase")
    assert layer.image is None and layer.result is None and not layer.button.isEnabled()
    assert not any(label.text.startswith("MEGNO") for _, label in view.legend.items)


def test_cancel_stops_the_map_and_keeps_nothing(qtbot, view, monkeypatch):
    monkeypatch.setattr(chaos_map_layer, "T_END", 5000.0)
    monkeypatch.setattr(chaos_map_layer, "CHUNK", 4)
    layer = view.map_layer
    view.set_mode("poincare")
    layer.start()
    qtbot.waitUntil(
        lambda: layer._thread is not None and layer.progress.maximum() > 0, timeout=120000
    )
    thread = layer._thread
    layer.cancel_button.click()
    assert not thread.is_alive() and layer.result is None and layer.image is None
    assert layer.button.isEnabled() and layer.cancel_button.isHidden()
