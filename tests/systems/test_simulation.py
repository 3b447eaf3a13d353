"""The stream contract: blocks, budgets, diagnostics, events, failures, ensembles."""

import math

import numpy as np
import pytest

from systems.compiled import compile_system
from systems.integrators import STEPPERS, choose_method
from systems.mechanics import derive
from systems.scene import load_scene
from systems.simulation import PROBLEMS, ensemble, required_wants, stream
from tests.systems.scenes import DAMPED_OSCILLATOR, DRIVEN_DAMPED, PLANETARY, scene

ALL = ("rhs", "hamiltonian", "velocities", "separable", "drawing")


@pytest.fixture(scope="module")
def oscillator():
    return compile_system(derive(load_scene("harmonic_oscillator")), ALL)


@pytest.fixture(scope="module")
def pendulum():
    return compile_system(derive(load_scene("simple_pendulum")), ALL)


def exact_oscillator(t, y0):
    # m = k = 1 in the catalogue scene
    return np.column_stack(
        [y0[0] * np.cos(t) + y0[1] * np.sin(t), -y0[0] * np.sin(t) + y0[1] * np.cos(t)]
    )


@pytest.mark.parametrize(
    "method", ["leapfrog", "yoshida6", "gauss_legendre4", "dop853", "radau", "logh_yoshida4"]
)
def test_every_family_reaches_t_end_exactly_with_accurate_states(oscillator, pendulum, method):
    system = oscillator
    if method == "logh_yoshida4":  # needs V < 0: a pendulum hanging below its pivot
        system = pendulum
    blocks = list(stream(system, method=method, t_end=7.3, diagnostics=("H",)))
    assert all(b.status == "running" for b in blocks[:-1])
    last = blocks[-1]
    assert last.status == "ok" and last.message == ""
    assert last.t[-1] == 7.3
    t = np.concatenate([b.t for b in blocks])
    assert np.all(np.diff(t) > 0)
    y = np.concatenate([b.y for b in blocks])
    H = np.concatenate([b.diagnostics["H"] for b in blocks])
    assert last.steps > 0 and last.rhs_evaluations >= last.steps
    if system is oscillator:
        error = np.abs(y - exact_oscillator(t, system.initial_state())).max()
        assert error < (1e-3 if method != "radau" else 1e-4)
    assert np.ptp(H) / abs(H[0]) < 1e-3


def test_blocks_respect_the_point_limit_and_compute_only_what_is_asked(oscillator):
    blocks = list(
        stream(
            oscillator, method="leapfrog", t_end=200.0, dt=1e-4, max_points=50, block_seconds=0.01
        )
    )
    assert len(blocks) > 1
    for b in blocks:
        assert 1 <= len(b.t) <= 50
        assert b.diagnostics == {}
        assert b.y.shape == (len(b.t), 2)
    # points are evenly spaced in steps inside a block
    gaps = np.diff(blocks[1].t[:-1])
    np.testing.assert_allclose(gaps, gaps[0], rtol=1e-9)


def test_diagnostics_have_the_documented_shapes(pendulum):
    b = next(iter(stream(pendulum, t_end=1.0, diagnostics=("H", "qdot", "points"))))
    k = len(b.t)
    assert b.diagnostics["H"].shape == (k,)
    assert b.diagnostics["qdot"].shape == (k, 1)
    assert b.diagnostics["points"].shape == (k, 1, 2)
    np.testing.assert_allclose(b.diagnostics["points"][:, 0, 0], np.sin(b.y[:, 0]), atol=1e-12)


def test_missing_compiled_functions_are_named():
    compiled = compile_system(derive(load_scene("simple_pendulum")), ("rhs",))
    with pytest.raises(ValueError, match="separable"):
        next(iter(stream(compiled, method="leapfrog", t_end=1.0)))
    assert required_wants("yoshida4", ("H",)) == {"rhs", "separable", "hamiltonian"}


def test_poincare_crossings_are_interpolated_to_high_accuracy(oscillator):
    # x = 0 upward crossings of x = cos t happen at t = 3 pi / 2 + 2 pi k
    blocks = list(stream(oscillator, method="yoshida6", dt=0.05, t_end=40.0, section=(0, 0.0, 1)))
    t = np.concatenate([b.events_t for b in blocks])
    y = np.concatenate([b.events_y for b in blocks])
    expected = 1.5 * np.pi + 2 * np.pi * np.arange(len(t))
    assert len(t) == 6
    np.testing.assert_allclose(t, expected, atol=1e-6)
    np.testing.assert_allclose(y[:, 0], 0.0, atol=1e-12)
    np.testing.assert_allclose(y[:, 1], 1.0, atol=1e-6)


def test_dop853_crossings_use_its_dense_output(oscillator):
    # a few long steps: cubic Hermite would be off by far more than the tolerance
    blocks = list(stream(oscillator, method="dop853", tol=1e-12, t_end=40.0, section=(0, 0.0, 1)))
    t = np.concatenate([b.events_t for b in blocks])
    assert blocks[-1].steps < 300  # steps of about 0.18: 1/35 of a period
    np.testing.assert_allclose(t, 1.5 * np.pi + 2 * np.pi * np.arange(6), atol=1e-10)
    y = np.concatenate([b.events_y for b in blocks])
    np.testing.assert_allclose(y[:, 1], 1.0, atol=1e-10)


def test_energy_error_past_the_threshold_stops_the_run(pendulum):
    blocks = list(stream(pendulum, method="leapfrog", dt=0.3, t_end=50.0, energy_tolerance=1e-3))
    last = blocks[-1]
    assert last.status == "energy_error"
    assert "energy error" in last.message
    assert np.all(np.isfinite(np.concatenate([b.y for b in blocks])))


def test_a_blow_up_stops_with_a_status_instead_of_nans():
    # a leapfrog step far beyond the stability limit of a stiff oscillator grows without
    # bound; without the energy watch the state would overflow to inf and NaN
    compiled = compile_system(derive(load_scene("harmonic_oscillator")), ALL)
    stiff = compiled.with_parameters({"k": 1e4})
    blocks = list(stream(stiff, method="leapfrog", dt=0.5, t_end=1e4, energy_tolerance=math.inf))
    last = blocks[-1]
    assert last.status in PROBLEMS and last.status != "energy_error"
    assert last.message
    for b in blocks:
        assert np.all(np.isfinite(b.y))


def test_time_dependent_and_dissipative_scenes_run_adaptively():
    compiled = compile_system(derive(scene(DRIVEN_DAMPED)), ("rhs", "hamiltonian"))
    method, why = choose_method(compiled.mechanics)
    assert method == "dop853" and "driven" in why
    last = list(stream(compiled, t_end=30.0, tol=1e-9))[-1]
    assert last.status == "ok"
    loose = list(stream(compiled, t_end=30.0, tol=1e-6))[-1]
    assert loose.steps < last.steps
    np.testing.assert_allclose(loose.y[-1], last.y[-1], atol=1e-4)


def test_ensemble_matches_single_runs_and_uses_one_call():
    compiled = compile_system(derive(scene(PLANETARY)), ("rhs", "hamiltonian"))
    Y0 = np.array([[1.0, 0.0, 0.0, 1.2 + 0.05 * i] for i in range(8)])
    t, Y, status = ensemble(compiled, Y0, method="gauss_legendre4", t_end=5.0, dt=0.01, samples=10)
    assert Y.shape == (8, 10, 4) and t.shape == (10,) and np.all(status == 0)
    assert t[-1] == pytest.approx(5.0)
    for i in (0, 7):
        last = list(stream(compiled, method="gauss_legendre4", y0=Y0[i], t_end=5.0, dt=0.01))[-1]
        np.testing.assert_allclose(Y[i, -1], last.y[-1], rtol=1e-10, atol=1e-12)


def test_separable_ensemble(pendulum):
    Y0 = np.column_stack([np.linspace(0.1, 3.0, 16), np.zeros(16)])
    t, Y, status = ensemble(pendulum, Y0, method="yoshida4", t_end=10.0, dt=0.01, samples=5)
    assert np.all(status == 0)
    H = pendulum.hamiltonian(0.0, Y[:, -1])
    np.testing.assert_allclose(H, pendulum.hamiltonian(0.0, Y0), atol=1e-5)
    last = list(stream(pendulum, method="yoshida4", y0=Y0[9], t_end=10.0, dt=0.01))[-1]
    np.testing.assert_allclose(Y[9, -1], last.y[-1], rtol=1e-10, atol=1e-12)


def test_automatic_choices_on_the_catalogue():
    expected = {
        "harmonic_oscillator": "yoshida8",
        "planetary_motion": "dop853",
        "kepler_cartesian": "logh_yoshida6",
        "double_pendulum": "gauss_legendre6",
        "driven_damped_pendulum": "dop853",
        "damped_pendulum": "dop853",
    }
    for name, method in expected.items():
        chosen, why = choose_method(derive(load_scene(name)))
        assert chosen == method, (name, why)
        assert why and "\n" not in why
    assert set(expected.values()) <= set(STEPPERS)


@pytest.mark.parametrize("method", ["gauss_legendre4_tt", "gauss_legendre6_tt"])
def test_time_transformed_gauss_legendre_order_and_landing(oscillator, method):
    # in fictitious time the order is the method's; the run lands exactly on t_end
    y0 = oscillator.initial_state()
    steps = (0.2, 0.1, 0.05) if method.startswith("gauss_legendre4") else (0.4, 0.2, 0.1)
    errors = []
    for ds in steps:
        last = list(stream(oscillator, method=method, dt=ds, t_end=10.0))[-1]
        assert last.status == "ok" and last.t[-1] == 10.0
        errors.append(np.abs(last.y[-1] - exact_oscillator(np.array([10.0]), y0)[0]).max())
    order = np.polyfit(np.log(steps), np.log(errors), 1)[0]
    assert order == pytest.approx(STEPPERS[method].order, abs=0.4)


def test_time_transformed_gauss_legendre_on_an_eccentric_polar_orbit():
    compiled = compile_system(derive(load_scene("planetary_motion")), ("rhs", "hamiltonian"))
    e = 0.9
    y0 = np.array([1 + e, 0.0, 0.0, math.sqrt(1 - e * e)])  # apocentre, a = k = m = 1
    blocks = list(
        stream(compiled, method="gauss_legendre4_tt", y0=y0, t_end=40 * np.pi, diagnostics=("H",))
    )
    assert blocks[-1].status == "ok"
    H = np.concatenate([b.diagnostics["H"] for b in blocks])
    # not symplectic: the energy error swells during each pericentre passage, but it
    # returns (symmetric method, reversible system) instead of accumulating
    assert np.abs(H / H[0] - 1).max() < 1e-4
    assert abs(H[-1] / H[0] - 1) < 1e-8
    # steps shrink at pericentre: far fewer than a fixed step small enough there
    assert blocks[-1].steps < 3000
    np.testing.assert_allclose(blocks[-1].y[-1, [0, 2, 3]], y0[[0, 2, 3]], atol=1e-3)


@pytest.mark.parametrize(
    "method", ["yoshida4", "gauss_legendre4", "logh_leapfrog", "gauss_legendre4_tt", "dop853"]
)
def test_endless_runs_stream_until_the_caller_stops(pendulum, method):
    generator = stream(pendulum, method=method, block_seconds=0.005)
    blocks = [next(generator) for _ in range(6)]
    generator.close()
    assert all(b.status == "running" and len(b.t) for b in blocks)
    t = np.concatenate([b.t for b in blocks])
    assert np.all(np.diff(t) > 0) and t[-1] > 0.1


# -- a damped run whose energy rises is wrong, and says so ------------------------------------


def _damped(text: str = DAMPED_OSCILLATOR, **parameters):
    from systems.scene import parse_scene

    mechanics = derive(parse_scene(text, source="damped.toml"))
    compiled = compile_system(mechanics, ("rhs", "hamiltonian"))
    return compiled.with_parameters(parameters) if parameters else compiled


def test_damping_is_proved_to_take_energy_away():
    assert _damped().mechanics.classification.dissipative == ("c",)
    assert derive(load_scene("damped_pendulum")).classification.dissipative is not None
    for name in ("simple_pendulum", "driven_damped_pendulum", "bouncing_ball"):
        assert derive(load_scene(name)).classification.dissipative is None, name
    # a force that can push as well as brake proves nothing
    pushing = DAMPED_OSCILLATOR.replace('"-c*x_dot"', '"-c*x_dot + x"')
    assert _damped(pushing).mechanics.classification.dissipative is None


@pytest.mark.parametrize(
    "method, dt, make",
    [
        ("rk4", 3.0, lambda: _damped()),  # beyond RK4's stability bound: x grows to 1e6
        ("rk4", 2.5, lambda: compile_system(derive(load_scene("damped_pendulum")))),
        ("euler", 0.5, lambda: _damped()),
    ],
)
def test_a_run_whose_damped_energy_rises_is_not_ok(method, dt, make):
    blocks = list(stream(make(), method=method, dt=dt, t_end=100.0))
    last = blocks[-1]
    assert last.status == "energy_error", last.message
    assert "damping can only take energy away" in last.message


@pytest.mark.parametrize("method", ["rk4", "dop853", "implicit_midpoint"])
def test_an_accurate_damped_run_is_ok(method):
    compiled = compile_system(derive(load_scene("damped_pendulum")))
    dt = {"rk4": 0.01, "implicit_midpoint": 0.01}.get(method)
    options = {"dt": dt} if dt else {}
    last = list(stream(compiled, method=method, t_end=30.0, **options))[-1]
    assert last.status == "ok", last.message


def test_negative_damping_is_not_watched():
    """A slider that makes the 'damping' push invalidates the proof: no false alarm."""
    compiled = _damped(c=-0.2)
    last = list(stream(compiled, method="dop853", t_end=20.0))[-1]
    assert last.status == "ok", last.message


def test_a_fixed_step_beyond_the_methods_stability_is_not_ok():
    """The driven damped pendulum neither conserves nor provably loses energy: the
    linearised motion tells that rk4 at dt = 3 multiplies a damped oscillation by 1.17 a
    step, so the run ends 'unstable' with the largest stable step, not ok."""
    compiled = compile_system(derive(load_scene("driven_damped_pendulum")))
    last = list(stream(compiled, method="rk4", dt=3.0, t_end=100.0))[-1]
    assert last.status == "unstable", last.message
    assert "take dt below 2.9" in last.message
    last = list(stream(compiled, method="rk4", dt=2.0, t_end=100.0))[-1]
    assert last.status == "ok", last.message


@pytest.mark.parametrize(
    "order, eigenvalue, bound",
    [(4, 1j, 2 * math.sqrt(2)), (1, -1.0, 2.0), (1, 1j, 0.0), (4, -1.0, 2.785293563)],
)
def test_the_largest_stable_step_of_the_runge_kutta_polynomials(order, eigenvalue, bound):
    from systems.simulation import _stable_step

    assert _stable_step(order, eigenvalue) == pytest.approx(bound, abs=1e-6)
