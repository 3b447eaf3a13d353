"""The Equilibria tab and the phase-view markers for gyroscopic, degenerate and continuous
equilibria: one row per set, what decided the stability, and dots along a set."""

from __future__ import annotations

import math
from types import SimpleNamespace

import pyqtgraph as pg

from explorer.textbook.equilibria_view import (
    EquilibriaView,
    EquilibriumMarkers,
    frequency_text,
    kind_text,
    mode_text,
)
from systems.mechanics import derive
from systems.scene import parse_scene
from systems.textbook import jobs
from systems.textbook.equilibria import search_equilibria
from tests.systems.textbook.test_equilibria_gyroscopic import (
    HAT,
    ROTATING,
    _rotating_frame_omega_squared,
    _scene,
)


def _result(text: str) -> jobs.EquilibriaResult:
    mechanics = derive(parse_scene(text))
    return jobs.EquilibriaResult(search_equilibria(mechanics), tuple(mechanics.scene.coordinates))


def test_the_mexican_hat_is_one_row_and_a_ring_of_dots(qtbot):
    result = _result(_scene(HAT))
    view = EquilibriaView(runner=None)
    qtbot.addWidget(view)
    view._on_search_done(result, view.generation)
    rows = view.row_texts()
    assert len(rows) == 2
    ring = next(" | ".join(row) for row in rows if "circle" in " | ".join(row))
    assert "stable set: the circle x² + y² = 1, neutral along it" in ring
    assert "ω = 1.41421" in ring and "across the set" in ring
    assert "1 equilibrium and 1 set of them" in view.status.text()

    widget = pg.PlotWidget()
    qtbot.addWidget(widget)
    markers = EquilibriumMarkers(widget.getPlotItem())
    markers.show_result(result)
    dots = [s for s in markers.spots() if s["size"] == 6]
    assert len(dots) > 30  # along the circle, projected on (x, p_x)
    assert all(-1 - 1e-9 <= s["pos"][0] <= 1 + 1e-9 and s["pos"][1] == 0.0 for s in dots)
    assert len([s for s in markers.spots() if s["size"] == 14]) == 1  # the top of the hat


def test_gyroscopic_and_degenerate_rows_say_what_decided(qtbot):
    rotating = _result(ROTATING.replace("W = 0.7", "W = 2.0")).search.equilibria[0]
    assert kind_text(rotating) == "stable (gyroscopic; maximum of U)"
    assert frequency_text(rotating).startswith("ω₁ = 0.394603")
    assert "with the gyroscopic terms" in frequency_text(rotating)
    shapes = mode_text(rotating, ("x", "y"))
    assert shapes.count("(") == 2 and "i" in shapes  # x and y a quarter period apart

    band = _result(ROTATING.replace("W = 0.7", "W = 1.55")).search.equilibria[0]
    assert kind_text(band) == "unstable (saddle of U)"
    rate = math.sqrt(-_rotating_frame_omega_squared(1.55, 2.0, 3.0)[0].real)
    assert frequency_text(band) == f"unstable: grows at rate λ = {rate:.4g}"

    quartic = _result(_scene("x**4/4", ("x",)))
    view = EquilibriaView(runner=None)
    qtbot.addWidget(view)
    view.compiled = SimpleNamespace(mechanics=derive(parse_scene(_scene("x**4/4", ("x",)))))
    view._on_search_done(quartic, view.generation)
    (row,) = view.row_texts()
    assert "stable (degenerate minimum, order 4)" in row
    assert "— (no linear oscillation)" in row
    assert any("the linearisation is degenerate" in cell for cell in row)
    (inflection,) = _result(_scene("x**3", ("x",))).search.equilibria
    assert kind_text(inflection) == "unstable (degenerate, order 3)"
