"""taylor in the automatic choice where H is not conserved (issue 28 item 2): damped,
driven and rheonomic scenes have no energy to measure accuracy by, so the pilots' states
are measured against a tight reference, and taylor is taken where its counted work is
less at the same accuracy."""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pytest

from systems.compiled import compile_system
from systems.integrators import choose_method, get_stepper
from systems.integrators import measured as measured_module
from systems.integrators.measured import (
    MARGIN,
    RATE_CHECKPOINTS,
    STATE_CHECKPOINTS,
    chosen_tolerance,
    measured_choice,
    taylor_equivalents,
    taylor_order,
)
from systems.integrators.stepsize import ENERGY_TARGET
from systems.mechanics import derive
from systems.scene import load_scene
from systems.simulation import Run, Sampler, run_to_end
from systems.taylor.compiled import decomposition_of
from tests.systems import scenes

USER_SYSTEMS = Path(__file__).resolve().parents[2] / "user_systems"


def _compiled(scene):
    return compile_system(derive(scene), ("rhs", "hamiltonian"))


def _choice(compiled, t_end: float, **options) -> tuple[str, str]:
    method, reason = choose_method(compiled.mechanics)
    assert method == "dop853"  # the classification's choice where H is not conserved
    return measured_choice(
        compiled, method, reason, 0.0, compiled.initial_state(), t_end, **options
    )


def _states(compiled, method: str, times: np.ndarray, **setting) -> np.ndarray:
    """The states at ``times`` (k,) of a run at the method's default setting (as ``run``
    takes it) or ``setting``, shape (k, 2n)."""
    run = Run(compiled, method=method, t_end=float(times[-1]), max_points=2, **setting)
    sampler = Sampler(run, times)
    chunks = list(sampler.chunks())[1:]
    assert sampler.last.status == "ok", sampler.last.message
    t = np.concatenate([c[0] for c in chunks])
    assert np.array_equal(t, times)
    return np.concatenate([c[1] for c in chunks])


def _checkpoints(t_end: float) -> np.ndarray:
    return t_end * 2.0 ** -np.arange(STATE_CHECKPOINTS - 1, -1, -1, dtype=float)


def _over_run(states: np.ndarray, exact: np.ndarray, times: np.ndarray, t_end: float) -> float:
    """The largest error per unit time (relative to the state's size, at least 1), times
    ``t_end``: what the choice measures."""
    scale = np.maximum(1.0, np.max(np.abs(exact), axis=1))
    error = np.max(np.abs(states - exact), axis=1) / scale / times
    return float(np.max(error[-RATE_CHECKPOINTS:]) * t_end)


def _priced(compiled, method: str, t_end: float) -> float:
    """A whole run's counted work at the method's default setting: DOP853's evaluations,
    taylor's steps times ``taylor_equivalents``."""
    _, last = run_to_end(compiled, method=method, t_end=t_end, max_points=2)
    assert last.status == "ok", last.message
    if method != "taylor":
        return float(last.rhs_evaluations)
    order = taylor_order(last.setting_value)
    return last.steps * taylor_equivalents(decomposition_of(compiled.mechanics), order)


def _claimed(why: str) -> tuple[float, float]:
    """(taylor's error, dop853's) as the reason gives them."""
    ours = re.search(r"keep it to (\S+) in", why)
    theirs = re.search(r"needs \S+ for (\S+)$", why)
    assert ours and theirs, why
    return float(ours.group(1)), float(theirs.group(1))


def test_a_damped_oscillator_gets_taylor_and_meets_the_target_against_its_exact_solution():
    """x'' + 0.2 x' + x = 0 from x = 1 at rest: x = e^(-t/10) (cos wt + sin(wt)/(10 w)).
    The chosen run's states keep the target against the exact ones; the error the choice
    measured for DOP853 (against its own reference, no exact solution) is the exact one's
    within a factor 2, and taylor's counted work over the whole run is the smaller."""
    compiled = _compiled(scenes.scene(scenes.DAMPED_OSCILLATOR))
    t_end = 10.0
    chosen, why = _choice(compiled, t_end)
    assert chosen == "taylor", why
    assert why.startswith(f"measured on this system over t = {t_end:g}, by the state's error")
    assert "Taylor series of order 20 (tolerance 2.2e-16, machine epsilon)" in why
    times = _checkpoints(t_end)
    gamma, w = 0.1, math.sqrt(1.0 - 0.01)
    decay = np.exp(-gamma * times)
    x = decay * (np.cos(w * times) + gamma / w * np.sin(w * times))
    p = -decay * (w + gamma**2 / w) * np.sin(w * times)
    exact = np.column_stack([x, p])
    ours, theirs = _claimed(why)
    taylor_error = _over_run(_states(compiled, chosen, times), exact, times, t_end)
    assert taylor_error <= MARGIN * ENERGY_TARGET
    assert taylor_error <= max(10 * ours, 1e-14)
    dop853_error = _over_run(_states(compiled, "dop853", times), exact, times, t_end)
    assert 0.5 <= dop853_error / theirs <= 2.0, (dop853_error, theirs)
    assert _priced(compiled, "taylor", t_end) < _priced(compiled, "dop853", t_end)


def test_a_driven_pendulum_gets_taylor_whose_states_meet_the_target_against_a_tight_run():
    compiled = _compiled(scenes.scene(scenes.DRIVEN_DAMPED))
    t_end = 10.0
    chosen, why = _choice(compiled, t_end)
    assert chosen == "taylor", why
    times = _checkpoints(t_end)
    reference = _states(compiled, "dop853", times, tol=1e-15)  # another method altogether
    error = _over_run(_states(compiled, chosen, times), reference, times, t_end)
    assert error <= MARGIN * ENERGY_TARGET
    assert _priced(compiled, "taylor", t_end) < _priced(compiled, "dop853", t_end)


def test_where_the_motion_is_chaotic_the_error_is_measured_only_while_references_agree():
    """The driven damped pendulum (the catalogue's, chaotic) over its t = 300: two tight
    runs part long before the end, so the error per unit time is measured on a shorter
    stretch than the run (each method's, over the run, within the target)."""
    compiled = _compiled(load_scene("driven_damped_pendulum"))
    chosen, why = _choice(compiled, 300.0)
    assert chosen == "taylor", why
    stretch = float(re.search(r"per unit time up to t = (\S+), times 300", why).group(1))
    assert stretch < 300.0
    ours, theirs = _claimed(why)
    # where the references part is round-off's chance (dop853's claim was 4e-11 or
    # 2.4e-10 as the taylor loop's sums changed order): the choice keeps the target
    assert ours <= MARGIN * ENERGY_TARGET and ours < theirs


def test_the_same_scene_and_start_always_get_the_same_choice_and_numbers():
    """Counted, never timed: measured afresh (no memory, no disk) on two compiled
    systems, the text is the same to the last digit."""
    y0 = None
    texts = []
    for _ in range(2):
        compiled = _compiled(scenes.scene(scenes.DRIVEN_DAMPED))
        y0 = compiled.initial_state() if y0 is None else y0
        method, reason = choose_method(compiled.mechanics)
        texts.append(measured_module._measure(compiled, method, reason, 0.0, y0, 10.0))
    assert texts[0] == texts[1]
    assert texts[0][0] == "taylor"
    assert _choice(compiled, 10.0) == _choice(compiled, 10.0) == texts[0]


def test_a_looser_tolerance_is_taken_where_priced_well_below_and_reaches_the_run():
    """The shaken pendulum's series have too many terms for the unrolled order 20, so
    order 13 (1e-10) is priced well below it and still keeps the target: the run at
    taylor's default setting takes that tolerance."""
    compiled = _compiled(load_scene(str(USER_SYSTEMS / "shaken_pendulum.toml")))
    chosen, why = _choice(compiled, 10.0)
    assert chosen == "taylor", why
    assert "Taylor series of order 13 (tolerance 1.0e-10)" in why
    y0 = compiled.initial_state()
    assert chosen_tolerance(compiled, 0.0, y0, 10.0) == 1e-10
    assert get_stepper("taylor").default_setting(compiled, 0.0, y0, 10.0) == 1e-10
    ours, _ = _claimed(why)
    assert ours <= MARGIN * ENERGY_TARGET


def test_where_taylor_does_not_apply_the_choice_says_why_and_keeps_dop853():
    """Coulomb friction, -c x'/|x'|: taylor cannot follow the kink."""
    text = scenes.DAMPED_OSCILLATOR.replace("x = 1.0", "x = 1.0\nx_dot = 0.5")
    text = text.replace('"-c*x_dot"', '"-c*x_dot/Abs(x_dot)"')
    compiled = _compiled(scenes.scene(text))
    chosen, why = _choice(compiled, 10.0)
    assert chosen == "dop853"
    assert "; taylor is not priced: taylor cannot follow a kink" in why


@pytest.mark.parametrize("t_end", [math.inf, 10.0])
def test_the_window_s_endless_run_and_the_choice_without_taylor_keep_dop853(t_end):
    compiled = _compiled(scenes.scene(scenes.DAMPED_OSCILLATOR))
    method, reason = choose_method(compiled.mechanics)
    taylor = math.isinf(t_end)  # finite: the choice without taylor
    assert _choice(compiled, t_end, taylor=taylor) == (method, reason)


def test_where_the_references_differ_from_the_first_checkpoint_taylor_is_not_priced(
    monkeypatch,
):
    """No error can be measured against references that do not agree (here: made to
    disagree by asking for agreement beyond exact): DOP853 is kept and the reason says
    why."""
    monkeypatch.setattr(measured_module, "REFERENCE_SHARE", -1.0)
    compiled = _compiled(scenes.scene(scenes.DRIVEN_DAMPED))
    method, reason = choose_method(compiled.mechanics)
    chosen, why = measured_module._measure(
        compiled, method, reason, 0.0, compiled.initial_state(), 10.0
    )
    assert chosen == "dop853"
    assert why.startswith(reason + "; taylor is not priced: two tight references differ by")
