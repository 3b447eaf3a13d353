"""Work-precision sweeps: references, monotone curves, progress and cancellation."""

import math

import numpy as np
import pytest

from systems.compiled import compile_system
from systems.mechanics import derive
from systems.scene import load_scene
from systems.workprecision import WorkPrecision, default_methods, reference_state, sweep

WANTS = ("rhs", "hamiltonian", "separable")


@pytest.fixture(scope="module")
def oscillator():
    return compile_system(derive(load_scene("coupled_oscillators")), WANTS)


def test_linear_systems_use_the_matrix_exponential(oscillator):
    y0 = oscillator.initial_state()
    y_ref, t_end, text = reference_state(oscillator, y0, 7.0)
    assert t_end == 7.0 and "matrix exponential" in text
    from systems.simulation import stream

    last = list(stream(oscillator, method="yoshida8", y0=y0, dt=0.01, t_end=7.0))[-1]
    np.testing.assert_allclose(last.y[-1], y_ref, atol=1e-10)


def test_kepler_reference_is_whole_periods():
    compiled = compile_system(derive(load_scene("kepler_cartesian")), WANTS)
    y0 = compiled.initial_state()
    y_ref, t_end, text = reference_state(compiled, y0, 40.0)
    period = 2 * math.pi * 2**1.5  # the catalogue orbit has a = 2
    assert t_end == pytest.approx(round(40.0 / period) * period)
    assert "whole Kepler periods" in text
    np.testing.assert_array_equal(y_ref, y0)


def test_sweep_curves_improve_with_cost_and_report_progress(oscillator):
    calls = []
    result = sweep(
        oscillator,
        ["leapfrog", "yoshida4", "dop853"],
        t_end=5.0,
        levels=3,
        progress=lambda done, total, text: calls.append((done, total, text)),
    )
    assert isinstance(result, WorkPrecision) and not result.cancelled
    assert calls[0][:2] == (0, 9) and calls[-1] == (9, 9, "done")
    for method in result.methods:
        curve = result.curve(method)
        assert len(curve) == 3
        errors = [p.final_error for p in curve]
        assert errors[0] > errors[1] > errors[2], method
        assert all(p.energy_error is not None and p.wall_s > 0 for p in curve)
    assert {p.setting for p in result.points} == {"dt", "tol"}


def test_sweep_can_be_cancelled(oscillator):
    seen = []

    def cancelled():
        seen.append(1)
        return len(seen) > 3

    result = sweep(oscillator, ["leapfrog", "dop853"], t_end=5.0, levels=4, cancelled=cancelled)
    assert result.cancelled
    assert len(result.points) < 8


def test_default_methods_fit_the_structure():
    separable = default_methods(derive(load_scene("henon_heiles")))
    assert "yoshida4" in separable and "leapfrog" in separable
    polar = default_methods(derive(load_scene("planetary_motion")))
    assert "leapfrog" not in polar and "gauss_legendre4" in polar and "dop853" in polar
    driven = default_methods(derive(load_scene("driven_damped_pendulum")))
    assert driven[0] == "dop853"


def test_a_chaotic_reference_is_cut_where_two_runs_still_agree():
    """The double pendulum is chaotic by t = 30: two tight DOP853 runs part, so the sweep
    measures errors at the last time they agree, and says why."""
    from systems.workprecision import AGREEMENT, CHECK_TOL, REFERENCE_TOL, _states_at

    compiled = compile_system(derive(load_scene("double_pendulum")), ("rhs", "hamiltonian"))
    y0 = compiled.initial_state()
    y_ref, t_end, reference = reference_state(compiled, y0, 30.0)
    assert 0 < t_end < 30.0
    assert "not to 30" in reference and "chaotic" in reference
    # at the chosen time a third, independent run agrees with the reference
    times = np.array([t_end])
    for tol in (CHECK_TOL, REFERENCE_TOL * 10):
        other = _states_at(compiled, "dop853", y0, times, tol)[0]
        assert np.max(np.abs(other - y_ref)) <= AGREEMENT * max(1.0, np.max(np.abs(y_ref)))


def test_a_regular_reference_keeps_the_whole_horizon():
    compiled = compile_system(derive(load_scene("simple_pendulum")), ("rhs", "hamiltonian"))
    _, t_end, reference = reference_state(compiled, compiled.initial_state(), 10.0)
    assert t_end == 10.0 and "not to" not in reference
