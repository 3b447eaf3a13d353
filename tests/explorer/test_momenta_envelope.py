"""The conserved momenta at max speed drawn as min/max envelopes (issue 25 item 6).

At "max" speed the worker hands the store only a bounded number of rows a second; a line
through them is a sawtooth that hides what the steps did. As for H, the worker sums the
conserved momenta and Noether charges up at every step in bins of time
(``explorer.envelope.summarize_series``), and the conserved view draws each bin as a
vertical from its lowest to its highest value.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from explorer.envelope import INDEX, Envelope, conserved_quantities, summarize_series
from explorer.trajectories import is_gap
from explorer.worker import RunSettings
from tests.explorer.test_max_speed import Feed, every_step


def test_a_series_envelope_holds_every_value_of_every_quantity_through_merges():
    rng = np.random.default_rng(7)
    t = np.sort(rng.uniform(0.0, 50.0, 4000))
    values = rng.normal(size=(4000, 3))
    values[17, 1] = np.nan  # a value that is not finite is left out of its bin only
    envelope = Envelope(capacity=32, quantities=3)
    for piece in np.array_split(np.arange(4000), 23):
        exponent = -5 if piece[0] < 2000 else -1
        envelope.add(exponent, summarize_series(t[piece], values[piece], 0.0, exponent))
    bins = envelope.data
    assert len(bins) <= 32 and envelope.revision > 0 and bins.shape[1] == 3 + 2 * 3
    index = np.floor(np.ldexp(t, -envelope.exponent))
    at = np.searchsorted(bins[:, INDEX], index)
    assert np.array_equal(bins[at, INDEX], index)
    for j in range(3):
        low, high = bins[at, 2 + 2 * j], bins[at, 3 + 2 * j]
        good = np.isfinite(values[:, j])
        assert (low[good] <= values[good, j]).all() and (values[good, j] <= high[good]).all()
        assert np.isfinite(low).all() and np.isfinite(high).all()
        x, y = envelope.polyline(quantity=j)
        assert np.array_equal(y, np.stack([bins[:, 2 + 2 * j], bins[:, 3 + 2 * j]], 1).ravel())


@pytest.fixture(scope="module")
def figure_eight():
    from explorer.builder import build
    from systems.scene import load_scene

    built = build(load_scene("figure_eight"))
    return built, built.compiled


def test_conserved_quantities_are_the_view_s_momenta_in_its_order(figure_eight):
    from explorer.builder import build
    from systems.scene import load_scene

    _, compiled = figure_eight
    assert [name for name, _ in conserved_quantities(compiled)] == ["L_z", "P_x", "P_y"]
    planetary = build(load_scene("planetary_motion")).compiled
    (name, function), *_ = conserved_quantities(planetary)
    y = np.array([[1.0, 0.5, 0.2, 0.7], [2.0, 1.5, 0.3, 0.9]])
    assert name == "p_theta" and np.array_equal(function(np.zeros(2), y), y[:, 3])


@pytest.mark.soak  # a run at max speed, every step's charges recomputed (about 10 s)
def test_the_momentum_plot_at_max_speed_holds_every_steps_value_in_bins(qtbot, figure_eight):
    from explorer.panels.conserved_view import ConservedView

    _, compiled = figure_eight
    settings = RunSettings(
        method="gauss_legendre6",  # a step in t (``every_step`` runs it again)
        speed=math.inf,
        diagnostics=("H", "momenta"),
        rows_per_second=64.0,
    )
    charges = conserved_quantities(compiled)
    with Feed(compiled, settings) as feed:
        main = feed.store.main
        qtbot.waitUntil(lambda: is_gap(main.y.data).sum() >= 3 and main.last_t > 20, timeout=60000)
    t, y, _ = every_step(compiled, main, settings)
    envelope = main.momenta
    assert envelope is not None and envelope.quantities == 3
    bins = envelope.data
    index = np.floor(np.ldexp(t - main.t0, -envelope.exponent))
    at = np.searchsorted(bins[:, INDEX], index)
    assert np.array_equal(bins[at, INDEX], index)
    for j, (_, charge) in enumerate(charges):
        values = charge(t, y)
        assert (bins[at, 2 + 2 * j] <= values).all() and (values <= bins[at, 3 + 2 * j]).all()
    # the view draws the bins (a vertical each), not a line through the sparse rows
    view = ConservedView()
    qtbot.addWidget(view)
    view.resize(1400, 300)
    view.show()
    qtbot.waitExposed(view)
    view.set_system(compiled)
    view.refresh(feed.store)
    curve = view._charge_curves["L_z"]
    assert np.array_equal(curve._x, np.repeat(bins[:, 1], 2))
    assert np.array_equal(curve._y, bins[:, 2:4].ravel())
    assert len(curve._x) > 4 * (~is_gap(main.y.data)).sum() // 4  # bins, not rows
