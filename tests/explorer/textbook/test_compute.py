"""The Textbook tabs' computations, without windows."""

from __future__ import annotations

import math

import numpy as np
import pytest

from explorer.builder import build
from explorer.textbook import compute
from explorer.textbook.energy_view import explanation
from systems.scene import load_scene


def _compiled(name: str):
    return build(load_scene(name)).compiled


def test_level_curve_closes_an_ellipse_at_the_turning_points():
    q = np.linspace(-2.0, 2.0, 401)
    half = np.full_like(q, 0.5)
    x, y = compute.level_curve(q, half, np.zeros_like(q), q**2 / 2, 0.5)  # p² + q² = 1
    finite = np.isfinite(x)
    assert np.allclose(x[finite] ** 2 + y[finite] ** 2, 1.0, atol=1e-3)
    assert x[finite].min() == pytest.approx(-1.0, abs=1e-3)
    assert x[finite].max() == pytest.approx(1.0, abs=1e-3)
    assert (x[finite][0], y[finite][0]) == pytest.approx((x[finite][-1], y[finite][-1]))
    # above every value of the potential: two open branches, no turning point
    x, y = compute.level_curve(q, half, np.zeros_like(q), q**2 / 2, 10.0)
    assert np.isnan(x).sum() >= 1 and np.nanmin(np.abs(y)) > 3.0


def test_rheonomic_energy_theorem_in_words():
    result = compute.energy(_compiled("variable_length_pendulum"), 5.0)
    assert result.explicit_time
    b = result.balance
    assert np.max(np.abs(b.rate - b.predicted)) < 1e-2 * np.max(np.abs(b.rate))
    assert "only</i> through the explicit time dependence" in explanation(result)


def test_action_angle_refuses_what_does_not_qualify():
    assert "one-degree" in compute.action_angle_reason(_compiled("planetary_motion"))
    assert "effects" in compute.action_angle_reason(_compiled("damped_pendulum"))
    hoop = _compiled("bead_on_rotating_hoop")  # its constraint moves, but H has no t
    assert compute.action_angle_reason(hoop) == ""


def test_planetary_reduction_portrait_and_turning_points():
    compiled = _compiled("planetary_motion")
    setup = compute.reduction_setup(compiled)
    assert setup.reduction.cyclic == ("theta",) and setup.quadratic is not None
    curves = compute.reduction_curves(setup, compute.parameters_of(compiled), setup.p_cyclic)
    assert curves.energy == pytest.approx(-0.25)
    assert curves.turning == pytest.approx([1.0, 3.0], rel=1e-8)
    x, y = curves.orbit  # the orbit's level set: p_r² / 2 + V_eff(r) = E
    finite = np.isfinite(x)
    V = 1.5 / (2 * x[finite] ** 2) - 1 / x[finite]
    assert np.allclose(y[finite] ** 2 / 2 + V, -0.25, atol=1e-9)
    assert x[finite].min() == pytest.approx(1.0, abs=1e-3)
    assert x[finite].max() == pytest.approx(3.0, abs=1e-3)
    assert len(curves.lines) == len(curves.levels) > 5


def test_pendulum_period_matches_the_elliptic_integral():
    compiled = _compiled("simple_pendulum")
    found = compute.equilibria(compiled)
    result = compute.action_angle_data(compiled, found.search, count=40)
    below = np.isfinite(result.exact)
    assert below.sum() > 10
    assert np.allclose(result.period[below], result.exact[below], rtol=1e-8)
    assert result.small_period == pytest.approx(2 * math.pi / math.sqrt(9.81))
