"""The Textbook tabs' computations on compiled systems (``systems.textbook.jobs``)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from systems.compiled import compile_system
from systems.mechanics import derive
from systems.scene import load_scene
from systems.textbook import jobs


def _compiled(name: str):
    return compile_system(derive(load_scene(name)), ("rhs", "hamiltonian", "velocities"))


def test_level_curve_closes_an_ellipse_at_the_turning_points():
    q = np.linspace(-2.0, 2.0, 401)
    half = np.full_like(q, 0.5)
    x, y = jobs.level_curve(q, half, np.zeros_like(q), q**2 / 2, 0.5)  # p² + q² = 1
    finite = np.isfinite(x)
    assert np.allclose(x[finite] ** 2 + y[finite] ** 2, 1.0, atol=1e-3)
    assert x[finite].min() == pytest.approx(-1.0, abs=1e-3)
    assert x[finite].max() == pytest.approx(1.0, abs=1e-3)
    assert (x[finite][0], y[finite][0]) == pytest.approx((x[finite][-1], y[finite][-1]))
    # above every value of the potential: two open branches, no turning point
    x, y = jobs.level_curve(q, half, np.zeros_like(q), q**2 / 2, 10.0)
    assert np.isnan(x).sum() >= 1 and np.nanmin(np.abs(y)) > 3.0


def test_rheonomic_energy_theorem_holds_along_the_run():
    result = jobs.energy(_compiled("variable_length_pendulum"), 5.0)
    assert result.explicit_time and result.rheonomic and not result.effects
    b = result.balance
    assert np.max(np.abs(b.rate - b.predicted)) < 1e-2 * np.max(np.abs(b.rate))


def test_action_angle_refuses_what_does_not_qualify():
    assert "one-degree" in jobs.action_angle_reason(_compiled("planetary_motion"))
    assert "effects" in jobs.action_angle_reason(_compiled("damped_pendulum"))
    hoop = _compiled("bead_on_rotating_hoop")  # its constraint moves, but H has no t
    assert jobs.action_angle_reason(hoop) == ""


def test_planetary_reduction_portrait_and_turning_points():
    compiled = _compiled("planetary_motion")
    setup = jobs.reduction_setup(compiled)
    assert setup.reduction.cyclic == ("theta",) and setup.quadratic is not None
    assert "/" in setup.expression and "**" not in setup.expression  # one line, for people
    curves = jobs.reduction_curves(setup, jobs.parameters_of(compiled), setup.p_cyclic)
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
    found = jobs.equilibria(compiled)
    result = jobs.action_angle_data(compiled, found.search, count=40)
    below = np.isfinite(result.exact)
    assert below.sum() > 10
    assert np.allclose(result.period[below], result.exact[below], rtol=1e-8)
    assert result.small_period == pytest.approx(2 * math.pi / math.sqrt(9.81))


def test_a_cancelled_job_stops():
    cancel = jobs.Cancel()
    cancel.set()
    with pytest.raises(jobs.Cancelled):
        jobs.integrate(_compiled("simple_pendulum"), 10.0, cancel=cancel)
