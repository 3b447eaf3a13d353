"""A run the energy cannot check is checked by a finer run (``systems.run_check``): its
verdict agrees with the true error, on exact solutions and against tight references."""

import math

import numpy as np
import pytest

from systems.compiled import compile_system
from systems.mechanics import derive
from systems.run_check import ACCURACY, check_final_state
from systems.scene import load_scene, parse_scene
from systems.simulation import Run, run_to_end
from tests.systems.scenes import DAMPED_OSCILLATOR as SHARED_DAMPED

# c = 0.1: the exact solution below
DAMPED_OSCILLATOR = SHARED_DAMPED.replace("c = 0.2", "c = 0.1")


def _exact_oscillator(t: float) -> np.ndarray:
    """x(t), p(t) of DAMPED_OSCILLATOR (m = k = 1, c = 0.1, x(0) = 1, p(0) = 0)."""
    gamma = 0.05
    w = math.sqrt(1.0 - gamma**2)
    e = math.exp(-gamma * t)
    x = e * (math.cos(w * t) + gamma / w * math.sin(w * t))
    p = -e * (1.0 + gamma**2 / w**2) * w * math.sin(w * t)
    return np.array([x, p])


def _end(compiled, method, t_end, **options):
    run = Run(compiled, method=method, t_end=t_end, **options)
    last = run.advance(math.inf)
    while not run.finished:
        last = run.advance(math.inf)
    assert last.status == "ok", last.message
    return last


@pytest.mark.parametrize(
    "method", ["euler", "rk4", "implicit_midpoint", "gauss_legendre4", "gauss_legendre6", "dop853"]
)
def test_the_estimate_matches_the_exact_error_of_a_damped_oscillator(method):
    compiled = compile_system(derive(parse_scene(DAMPED_OSCILLATOR)), ("rhs", "hamiltonian"))
    t_end = 20.0
    last = _end(compiled, method, t_end)
    true = float(np.max(np.abs(last.y[-1] - _exact_oscillator(t_end))))
    y0 = compiled.initial_state()
    check = check_final_state(
        compiled, method, last.setting, last.setting_value, 0.0, y0, t_end, last.y[-1]
    )
    assert check.accurate == (check.error <= ACCURACY * check.scale)
    if true > 1e-12:  # above round-off the estimate is the error's size
        assert true / 3 <= check.error <= 3 * true, (true, check.error)
    else:
        assert check.error < 1e-10
    assert check.accurate == (method not in ("euler", "implicit_midpoint")), check.message


@pytest.mark.parametrize("scene", ["damped_pendulum", "variable_length_pendulum"])
@pytest.mark.parametrize(
    "method", ["euler", "rk4", "implicit_midpoint", "gauss_legendre6", "gauss_legendre6_tt"]
)
def test_the_verdict_agrees_with_a_tight_reference(scene, method):
    """Never accurate where the final state is wrong by more than ten times the accuracy,
    never inaccurate where it is right to a tenth of it."""
    mechanics = derive(load_scene(scene))
    compiled = compile_system(mechanics, ("rhs", "hamiltonian", "velocities"))
    t_end = float(mechanics.scene.view.get("t_end", 10.0))
    last = _end(compiled, method, t_end)
    _, reference = run_to_end(compiled, method="dop853", t_end=t_end, tol=1e-14)
    true = float(np.max(np.abs(last.y[-1] - reference.y[-1])))
    y0 = compiled.initial_state()
    check = check_final_state(
        compiled, method, last.setting, last.setting_value, 0.0, y0, t_end, last.y[-1]
    )
    bound = ACCURACY * check.scale
    assert not (check.accurate and true > 10 * bound), (true, check.error)
    assert not (not check.accurate and true < bound / 10), (true, check.error)


def test_chaos_is_told_from_a_coarse_step():
    """The driven damped pendulum by its scene's t_end: two tight DOP853 runs end far
    apart, and the message names both possible reasons."""
    mechanics = derive(load_scene("driven_damped_pendulum"))
    compiled = compile_system(mechanics, ("rhs", "hamiltonian"))
    last = _end(compiled, "dop853", 300.0)
    check = check_final_state(
        compiled, "dop853", "tol", last.setting_value, 0.0, compiled.initial_state(), 300.0,
        last.y[-1],
    )  # fmt: skip
    assert not check.accurate
    assert "dop853 at tol = 1e-14" == check.against
    assert "chaos" in check.message and "--tol" in check.message


def test_a_check_that_cannot_finish_says_the_state_is_unchecked():
    compiled = compile_system(derive(parse_scene(DAMPED_OSCILLATOR)), ("rhs", "hamiltonian"))
    last = _end(compiled, "rk4", 20.0, dt=0.01)
    check = check_final_state(
        compiled, "rk4", "dt", 0.01, 0.0, compiled.initial_state(), 20.0, last.y[-1],
        max_steps=1000,
    )  # fmt: skip
    assert check.error is None and not check.accurate
    assert "unchecked" in check.message and "budget" in check.message
