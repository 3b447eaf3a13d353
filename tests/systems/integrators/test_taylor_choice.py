"""taylor in the automatic choice (issue 28 item 2): priced by counted work (its steps
times ``taylor_equivalents``, a model of one step in right-hand-side evaluations), never
timed, against the measured choice without it, at the same energy target."""

from __future__ import annotations

import numpy as np
import pytest

from systems.compiled import compile_system
from systems.integrators import choose_method
from systems.integrators import measured as measured_module
from systems.integrators.measured import measured_choice, taylor_equivalents
from systems.integrators.stepsize import ENERGY_TARGET
from systems.mechanics import derive
from systems.scene import load_scene
from systems.simulation import run_to_end
from systems.taylor.compiled import decomposition_of
from systems.taylor.decompose import decompose_mechanics
from tests.systems.integrators.test_measured_choice import _compiled  # (the same systems)


def _choices(compiled, t_end: float):
    """(with taylor, without taylor): each (method, why)."""
    method, reason = choose_method(compiled.mechanics)
    y0 = compiled.initial_state()
    return (
        measured_choice(compiled, method, reason, 0.0, y0, t_end),
        measured_choice(compiled, method, reason, 0.0, y0, t_end, taylor=False),
    )


def _priced_run(compiled, method: str, t_end: float, order: int = 20) -> tuple[float, float]:
    """(relative energy error, priced cost) of a whole run at the method's defaults: a
    taylor step counts ``taylor_equivalents`` evaluations."""
    blocks, last = run_to_end(compiled, method=method, t_end=t_end, diagnostics=("H",))
    assert last.status == "ok", last.message
    H0 = compiled.hamiltonian(0.0, compiled.initial_state()[None])[0]
    H = np.concatenate([b.diagnostics["H"] for b in blocks if len(b.t)])
    error = float(np.max(np.abs(H - H0)) / max(abs(H0), 1e-8))
    cost = float(last.rhs_evaluations)
    if method == "taylor":
        cost = last.steps * taylor_equivalents(decomposition_of(compiled.mechanics), order)
    return error, cost


@pytest.mark.parametrize(("name", "t_end"), [("henon_heiles", 200.0), ("kepler_cartesian", 40.0)])
def test_taylor_is_chosen_where_its_priced_work_is_least_and_the_run_keeps_the_target(name, t_end):
    compiled = _compiled(name)
    (chosen, why), (other, _) = _choices(compiled, t_end)
    assert chosen == "taylor", why
    assert why.startswith(f"measured on this system over t = {t_end:g}: Taylor series of order 20")
    assert "machine epsilon" in why and f"where {other} needs" in why
    error, cost = _priced_run(compiled, "taylor", t_end)
    assert error <= ENERGY_TARGET
    _, theirs = _priced_run(compiled, other, t_end)
    assert cost < theirs  # the whole runs, priced as the pilots were


def test_a_constrained_scene_never_gets_taylor():
    mechanics = derive(load_scene("atwood_machine"))
    compiled = compile_system(mechanics, ("rhs", "hamiltonian"))
    method, reason = choose_method(mechanics)
    assert method == "constrained_dop853"
    assert measured_choice(compiled, method, reason, 0.0, compiled.initial_state(), 20.0) == (
        method,
        reason,
    )


def test_over_a_run_long_enough_for_taylor_s_drift_the_symplectic_method_is_kept():
    """Taylor's energy error grows with the run (1.1e7 steps of the pendulum to t = 1e6
    kept 7.3e-12); a splitting's stays bounded: by t = 1e7 taylor's would pass the
    target's margin and the pendulum keeps yoshida8 (DOP853's drift is larger still)."""
    compiled = _compiled("simple_pendulum")
    (chosen, why), _ = _choices(compiled, 1e7)
    assert chosen == "yoshida8", why
    assert "taylor would let the energy error reach" in why


def test_a_looser_tolerance_is_taken_where_priced_well_below_and_reaches_the_run():
    """The figure-eight's coefficient function is the looped form at every order (too
    many products to unroll), so a lower order is cheaper a step while the step count
    hardly changes: taylor at 1e-10 (order 13), whose run keeps the target, beats the
    splitting; the run at taylor's default setting takes that tolerance, and only that
    run (another compiled system gets machine epsilon)."""
    from systems.integrators import get_stepper
    from systems.integrators.measured import chosen_tolerance

    compiled = _compiled("figure_eight")
    t_end = float(compiled.mechanics.scene.view["t_end"])
    (chosen, why), (other, _) = _choices(compiled, t_end)
    assert (chosen, other) == ("taylor", "logh_yoshida6"), why
    assert "Taylor series of order 13 (tolerance 1.0e-10)" in why
    y0 = compiled.initial_state()
    assert chosen_tolerance(compiled, 0.0, y0, t_end) == 1e-10
    taylor = get_stepper("taylor")
    assert taylor.default_setting(compiled, 0.0, y0, t_end) == 1e-10
    assert taylor.default_setting(compiled, 0.0, y0, 2 * t_end) == np.finfo(float).eps
    error, cost = _priced_run(compiled, "taylor", t_end, order=13)
    assert error <= ENERGY_TARGET
    _, theirs = _priced_run(compiled, other, t_end)
    assert cost < theirs
    fresh = _compiled("figure_eight")
    assert taylor.default_setting(fresh, 0.0, y0, t_end) == np.finfo(float).eps


def test_the_window_s_endless_run_keeps_dop853_without_a_pilot():
    """Over unbounded time taylor's energy error grows like DOP853's: an endless run
    (the window's) keeps the classification's DOP853 as it was."""
    compiled = _compiled("planetary_motion")
    method, reason = choose_method(compiled.mechanics)
    assert method == "dop853"
    y0 = compiled.initial_state()
    assert measured_choice(compiled, method, reason, 0.0, y0, float("inf")) == (method, reason)


def test_the_price_of_a_step_grows_like_the_square_of_the_order_with_products():
    """Kepler's series are products (p^2 terms an order); the oscillator's are scalings
    (p): doubling the order costs Kepler more; both cost more than one evaluation. Order
    20 has the unrolled coefficient function, cheaper a term than the looped form of the
    other orders (at order 10 the oscillator's looped step is priced above its unrolled
    order 20)."""
    kepler = decompose_mechanics(derive(load_scene("kepler_cartesian")))
    oscillator = decompose_mechanics(derive(load_scene("harmonic_oscillator")))
    for d in (kepler, oscillator):
        assert taylor_equivalents(d, 15) < taylor_equivalents(d, 30) < taylor_equivalents(d, 60)
        assert taylor_equivalents(d, 20) < taylor_equivalents(d, 21)  # unrolled, looped
        assert taylor_equivalents(d, 20) > 1.0
    growth = taylor_equivalents(kepler, 60) / taylor_equivalents(kepler, 30)
    assert growth > 3.0
    assert taylor_equivalents(oscillator, 60) / taylor_equivalents(oscillator, 30) < 2.0
    assert measured_module._taylor_features(kepler)["convolutions"] > 0
    assert measured_module._taylor_features(oscillator)["convolutions"] == 0


def test_methods_names_the_taylor_choice_and_why(capsys):
    from explorer.cli import main

    assert main(["methods", "henon_heiles"]) == 0
    out = capsys.readouterr().out
    assert "* taylor" in out
    assert "* automatic choice: taylor: measured on this system over t = 200" in out


def test_run_takes_the_chosen_tolerance_and_an_asked_taylor_machine_epsilon(capsys):
    """Through the command line: the automatic choice's looser tolerance reaches its run;
    ``--method taylor`` is the family's default, machine epsilon."""
    import json

    from explorer.cli import main

    assert main(["run", "figure_eight", "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["method"] == "taylor" and report["setting"] == {"tol": 1e-10}
    assert report["status"] == "ok" and report["max_rel_energy_error"] <= ENERGY_TARGET
    assert main(["run", "figure_eight", "--method", "taylor", "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["setting"] == {"tol": np.finfo(float).eps}
