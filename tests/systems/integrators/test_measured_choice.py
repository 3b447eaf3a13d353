"""The automatic choice measured on the compiled system (issue 23 part 5): the cheaper
method, in counted evaluations, among those that keep the energy target; never timed."""

from __future__ import annotations

import numpy as np
import pytest

from systems.compiled import compile_system
from systems.integrators import choose_method, get_stepper
from systems.integrators import measured as measured_module
from systems.integrators.measured import measured_choice
from systems.integrators.stepsize import ENERGY_TARGET, default_step
from systems.mechanics import derive
from systems.scene import load_scene
from systems.simulation import run_to_end


def _compiled(name: str):
    mechanics = derive(load_scene(name))
    wants = ("rhs", "hamiltonian")
    if mechanics.separable_parts is not None and mechanics.classification.separable:
        wants += ("separable",)
    return compile_system(mechanics, wants)


def _t_end(compiled) -> float:
    return float(compiled.mechanics.scene.view.get("t_end", 10.0))


def _energy_error_and_evaluations(compiled, method: str, t_end: float):
    """(relative energy error, evaluations) of a run at the method's default setting; a
    taylor step counts ``taylor_equivalents`` evaluations at the order its tolerance set."""
    blocks, last = run_to_end(compiled, method=method, t_end=t_end, diagnostics=("H",))
    assert last.status == "ok", last.message
    H0 = compiled.hamiltonian(0.0, compiled.initial_state()[None])[0]
    H = np.concatenate([b.diagnostics["H"] for b in blocks if len(b.t)])
    evaluations = last.rhs_evaluations
    if method == "taylor":
        from systems.taylor.compiled import decomposition_of

        order = measured_module.taylor_order(last.setting_value)
        decomposition = decomposition_of(compiled.mechanics)
        evaluations = last.steps * measured_module.taylor_equivalents(decomposition, order)
    return float(np.max(np.abs(H - H0)) / max(abs(H0), 1e-8)), evaluations


@pytest.mark.parametrize(
    "name", ["double_pendulum", "henon_heiles", "spherical_pendulum", "figure_eight"]
)
def test_the_measured_choice_keeps_the_energy_target_at_no_more_cost(name):
    compiled = _compiled(name)
    t_end = _t_end(compiled)
    method, reason = choose_method(compiled.mechanics)
    chosen, why = measured_choice(compiled, method, reason, 0.0, compiled.initial_state(), t_end)
    assert "measured" in why
    error, evaluations = _energy_error_and_evaluations(compiled, chosen, t_end)
    assert error <= ENERGY_TARGET, (chosen, error)
    if chosen != method:  # the classification's method would have cost more
        _, theirs = _energy_error_and_evaluations(compiled, method, t_end)
        factor = measured_module.PER_EVALUATION.get(get_stepper(method).family.kernel, 1.0)
        assert evaluations < theirs * factor


def test_the_choice_is_the_same_every_time(monkeypatch):
    """Counted, not timed: forgetting everything and measuring again gives the same."""
    monkeypatch.setenv("PHASE_EXPLORER_DERIVATION_CACHE", "0")
    compiled = _compiled("henon_heiles")
    method, reason = choose_method(compiled.mechanics)
    answers = set()
    for _ in range(3):
        measured_module._memory.clear()
        answers.add(measured_choice(compiled, method, reason, 0.0, compiled.initial_state(), 200))
    assert len(answers) == 1


def test_a_chain_whose_fast_mode_sets_the_fixed_step_goes_adaptive():
    """A chain's fastest mode sets a fixed step for the whole run: Gauss-Legendre paid
    tens of times DOP853's evaluations for an energy error far below the target."""
    compiled = _compiled("pendulum_chain")
    method, reason = choose_method(compiled.mechanics)
    assert method == "gauss_legendre6"
    chosen, why = measured_choice(compiled, method, reason, 0.0, compiled.initial_state(), 20.0)
    assert chosen == "dop853", why


def test_choices_that_are_not_measured_pass_through():
    """A stiff damped system's radau, and a damped one's dop853 in the choice without
    taylor (with it: ``test_state_choice``)."""
    from tests.systems import scenes

    text = scenes.DAMPED_OSCILLATOR.replace("c = 0.2", "c = 200.0")  # rates 0.005 and 200
    stiff = compile_system(derive(scenes.scene(text)), ("rhs", "hamiltonian"))
    damped = _compiled("damped_pendulum")
    for compiled, taylor in ((stiff, True), (damped, False)):
        method, reason = choose_method(compiled.mechanics)
        assert method == ("radau" if compiled is stiff else "dop853")
        y0 = compiled.initial_state()
        assert measured_choice(compiled, method, reason, 0.0, y0, 10.0, taylor=taylor) == (
            method,
            reason,
        )


@pytest.mark.parametrize("name", ["spherical_pendulum", "coupled_oscillators"])
def test_the_default_step_is_aimed_at_the_target_not_far_below(name):
    """Order 6 and 8 default steps land nearer 1e-10 (they overshot by orders of
    magnitude), and never above it."""
    compiled = _compiled(name)
    t_end = _t_end(compiled)
    method = "gauss_legendre6" if name == "spherical_pendulum" else "yoshida8"
    stepper = get_stepper(method)
    y0 = compiled.initial_state()
    plain = default_step(compiled, stepper, 0.0, y0, t_end, aim=False)
    aimed = default_step(compiled, stepper, 0.0, y0, t_end)
    assert aimed > plain
    error, _ = _energy_error_and_evaluations(compiled, method, t_end)
    assert error <= ENERGY_TARGET


@pytest.mark.parametrize("method", ["rk4", "gauss_legendre4", "gauss_legendre6"])
def test_a_damped_run_at_the_default_step_lands_near_the_target(method):
    """Where H is not conserved, the default fixed step of an order-4 or higher method is
    aimed at the state's error (Richardson from pilots): the damped oscillator ends
    within 1e-10 of its exact state at t = 10, where RK4 and Gauss-Legendre 4 at 300
    steps a period ended 4.7e-9 and 7.9e-10 from it, and Gauss-Legendre 6 (6e-15) now
    takes three times longer steps."""
    import math

    from systems.scene import parse_scene
    from tests.systems.scenes import DAMPED_OSCILLATOR  # m = k = 1, c = 0.2, x(0) = 1

    compiled = compile_system(
        derive(parse_scene(DAMPED_OSCILLATOR, source="<damped>")), ("rhs", "hamiltonian")
    )
    t_end = 10.0
    gamma = 0.1
    w = math.sqrt(1.0 - gamma**2)
    x = math.exp(-gamma * t_end) * (math.cos(w * t_end) + gamma / w * math.sin(w * t_end))
    stepper = get_stepper(method)
    y0 = compiled.initial_state()

    def error(dt: float) -> float:
        _, last = run_to_end(compiled, method=method, t_end=t_end, dt=dt, energy_tolerance=None)
        assert last.status == "ok", last.message
        return abs(float(last.y[-1][0]) - x)

    plain = default_step(compiled, stepper, 0.0, y0, t_end, aim=False)
    aimed = default_step(compiled, stepper, 0.0, y0, t_end)
    assert error(aimed) <= ENERGY_TARGET, (plain, aimed)
    if method == "gauss_legendre6":
        assert aimed > 2 * plain
    else:
        assert aimed < plain and error(plain) > ENERGY_TARGET


def test_euler_on_a_damped_scene_keeps_its_step_and_the_check_says_it_is_off():
    """Orders 1 and 2 are not aimed (10^4 to 10^6 steps a period): their default step
    stays, and the final-state check (``systems.run_check``) flags the run."""
    from systems.run_check import check_final_state
    from systems.scene import parse_scene
    from tests.systems.scenes import DAMPED_OSCILLATOR

    compiled = compile_system(
        derive(parse_scene(DAMPED_OSCILLATOR, source="<damped>")), ("rhs", "hamiltonian")
    )
    stepper = get_stepper("euler")
    y0 = compiled.initial_state()
    dt = default_step(compiled, stepper, 0.0, y0, 30.0)
    assert dt == default_step(compiled, stepper, 0.0, y0, 30.0, aim=False)
    _, last = run_to_end(compiled, method="euler", t_end=30.0, dt=dt, energy_tolerance=None)
    check = check_final_state(compiled, "euler", "dt", dt, 0.0, y0, 30.0, last.y[-1])
    assert not check.accurate and "too inaccurate" in check.message
