"""The conserved-quantities panel plots the Noether charges (systems.symmetries)."""

from __future__ import annotations

import numpy as np

from tests.explorer.conftest import wait_for_points


def _rect(item):
    return item.mapRectToScene(item.boundingRect())


def test_cartesian_kepler_shows_an_angular_momentum_curve(qtbot, window):
    request = window.open_scene("kepler_cartesian")
    qtbot.waitUntil(
        lambda: window.built is not None and window.built.request == request, timeout=90000
    )
    wait_for_points(qtbot, window, 40, timeout=60000)
    for _ in range(3):
        window.store.mark_dirty()
        window._on_redraw_timer_timeout()
        qtbot.wait(20)
    conserved = window.conserved_view
    assert conserved.conserved_momenta == [] and conserved.conserved_charges == ["L_z"]
    assert conserved.momentum_plot is not None
    assert "L<sub>z</sub>" in conserved.momentum_plot.titleLabel.text
    assert [label.text for _, label in conserved.momentum_legend.items] == ["L<sub>z</sub>"]
    curve = conserved._charge_curves["L_z"]
    assert curve.point_count() >= 8
    main = window.store.main
    (name, charge), *_ = conserved._quantities
    y = main.y.data
    values = charge(main.t.data, y)
    expected = y[:, 0] * y[:, 3] - y[:, 1] * y[:, 2]  # x p_y - y p_x
    shown = np.isfinite(expected)
    assert name == "L_z" and shown.sum() >= 8
    assert np.array_equal(np.isfinite(values), shown)
    assert np.abs(values[shown] - expected[shown]).max() <= 1e-14
    # the plot draws L_z's range over every step (the worker's envelope, issue 25 item 6)
    bins = main.momenta.data
    assert len(bins) and np.abs(bins[:, 2:4] - np.sqrt(1.5)).max() <= 1e-12
    drawn = curve._y[np.isfinite(curve._y)]
    assert len(drawn) and np.abs(drawn - np.sqrt(1.5)).max() <= 1e-12
    # the legend sits beside the plot, not on the curve
    assert not _rect(conserved.momentum_legend).intersects(
        _rect(conserved.momentum_plot.getViewBox())
    )
    # back to a scene without charges: the plot and its curves go
    request = window.open_scene("simple_pendulum")
    qtbot.waitUntil(
        lambda: window.built is not None and window.built.request == request, timeout=90000
    )
    assert conserved.conserved_charges == [] and conserved._charge_curves == {}
    assert conserved.momentum_plot is None
    # ... hidden, but still in the panel's layout, where Qt owns them and deletes them
    # with the window: taken out of it and kept, they were Python's, and the garbage
    # collector freeing them after the window had gone crashed (SIGSEGV)
    plot, legend, _ = conserved._kept_momentum
    layout = conserved.layout_widget.ci
    assert plot in layout.items and legend in layout.items
    assert not plot.isVisible() and not legend.isVisible()
    qtbot.waitUntil(  # laid out again: the energy plot takes the room
        lambda: conserved.energy_plot.width() > 0.8 * conserved.layout_widget.width(),
        timeout=10000,
    )
    # and shown again for the next scene with a conserved quantity
    request = window.open_scene("kepler_cartesian")
    qtbot.waitUntil(
        lambda: window.built is not None and window.built.request == request, timeout=90000
    )
    assert conserved.momentum_plot is plot and plot.isVisible()
    qtbot.waitUntil(lambda: plot.width() > 0.2 * conserved.layout_widget.width(), timeout=10000)
