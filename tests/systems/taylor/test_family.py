"""The compiled taylor family: its steps against the reference integrator's, the exact
Kepler orbit after 100 periods, the order and step as documented, section crossings on
the dense output."""

import math

import mpmath
import numpy as np
import pytest

from systems.compiled import compile_system
from systems.integrators.registry import STEPPERS, make_runner
from systems.mechanics import derive
from systems.scene import load_scene, parse_scene
from systems.simulation import Run, stream
from systems.taylor import reference
from systems.taylor.coefficients import jorba_zou
from systems.taylor.compiled import decomposition_of

EPS = float(np.finfo(float).eps)


def _compiled(name):
    return compile_system(derive(load_scene(name)), ("rhs", "hamiltonian"))


def kepler_start(e: float) -> np.ndarray:
    """Pericentre of the orbit of eccentricity ``e``, a = 1, k = m = 1 (period 2 pi)."""
    return np.array([1 - e, 0.0, 0.0, math.sqrt((1 + e) / (1 - e))])


def kepler_exact(y0: np.ndarray, t: float) -> tuple[np.ndarray, float]:
    """The exact Cartesian Kepler state at ``t`` through ``y0`` as given (its rounded
    values: their energy sets the period), in 40 digits; and the period."""
    with mpmath.workdps(40):
        x, y, vx, vy = (mpmath.mpf(float(v)) for v in y0)
        r0 = mpmath.sqrt(x * x + y * y)
        a = -1 / (2 * ((vx * vx + vy * vy) / 2 - 1 / r0))
        n = mpmath.sqrt(1 / a**3)
        h = x * vy - y * vx
        ex, ey = vy * h - x / r0, -vx * h - y / r0
        e, w = mpmath.sqrt(ex * ex + ey * ey), mpmath.atan2(ey, ex)
        b = a * mpmath.sqrt(1 - e * e)
        c, s = mpmath.cos(w), mpmath.sin(w)
        E0 = mpmath.atan2((-x * s + y * c) / b, (x * c + y * s) / a + e)
        M = E0 - e * mpmath.sin(E0) + n * t
        E = mpmath.findroot(lambda E: E - e * mpmath.sin(E) - M, M)
        X, Y = a * (mpmath.cos(E) - e), b * mpmath.sin(E)
        rate = n / (1 - e * mpmath.cos(E))
        VX, VY = -a * mpmath.sin(E) * rate, b * mpmath.cos(E) * rate
        state = [c * X - s * Y, s * X + c * Y, c * VX - s * VY, s * VX + c * VY]
        return np.array([float(v) for v in state]), float(2 * mpmath.pi / n)


@pytest.mark.parametrize("name", ["kepler_cartesian", "double_pendulum", "henon_heiles"])
def test_the_steps_are_the_reference_integrators(name):
    compiled = _compiled(name)
    d = decomposition_of(compiled.mechanics)
    y0 = compiled.initial_state()
    runner = make_runner(compiled, STEPPERS["taylor"], y0, 0.0, math.inf, None, None)
    assert runner.order == 20
    outcome = runner.advance(30, 100)
    t, y = 0.0, y0
    for i in range(30):
        step = reference.taylor_step(d, t, y, compiled.parameters)
        t, y = step.t, step.y
        # the same order and step rule; sums in another order: round-off apart
        assert math.isclose(outcome.t[i], t, rel_tol=1e-13), (i, outcome.t[i], t)
        assert np.abs(outcome.y[i] - y).max() <= 1e-13 * max(1.0, np.abs(y).max()), i


DOUBLE = EPS / 2
"""A tolerance below machine epsilon: the same order (20) and steps, with the state and
the series' orders 1 and 2 in double-double (``runners.DOUBLE_DOUBLE_BELOW``)."""


def _kepler_error_after_100_periods(compiled, e: float, tol: float | None = None) -> float:
    y0 = kepler_start(e)
    _, period = kepler_exact(y0, 0.0)
    setting = {} if tol is None else {"tol": tol}
    blocks = list(
        stream(
            compiled, method="taylor", y0=y0, t_end=100 * period, energy_tolerance=None,
            **setting,
        )
    )  # fmt: skip
    last = blocks[-1]
    assert last.status == "ok" and last.t[-1] == 100 * period
    exact, _ = kepler_exact(y0, 100 * period)
    return float(np.abs(last.y[-1] - exact).max() / np.abs(exact).max())


@pytest.mark.parametrize(("e", "bound"), [(0.5, 1e-11), (0.9, 1e-9)])
def test_kepler_after_100_periods_is_the_exact_orbit(e, bound):
    error = _kepler_error_after_100_periods(_compiled("kepler_cartesian"), e)
    # measured: 3.7e-12 at e = 0.5 (3775 steps), 1.1e-10 at e = 0.9 (7319 steps); heyoka
    # 7.13 at its default tolerance, the same steps: 8.7e-13 and 1.2e-9. Round-off, not
    # truncation: orders 21 and 23 take the same steps and move the error at random, and
    # so does any change in the order of operations (1.2e-12 and 1.8e-10 with one Horner
    # chain per variable). The state and the time carry their rounding from step to step
    # (Kahan; a compensated clock); what is left is the coefficient function's own
    # rounding in orders 1 and 2 (docs/internals.md), so 1e-12 is no safe bound here
    assert error <= bound, error


@pytest.mark.parametrize(("e", "bound"), [(0.5, 1e-12), (0.9, 2e-12)])
def test_kepler_after_100_periods_in_double_double_is_the_exact_orbit_to_1e_12(e, bound):
    error = _kepler_error_after_100_periods(_compiled("kepler_cartesian"), e, DOUBLE)
    # measured: 5.5e-14 at e = 0.5 (3775 steps), 1.9e-13 at e = 0.9 (7319 steps), the
    # state a double-double from step to step and the series' orders 1 and 2 computed
    # (systems.taylor.double) and summed in double-double: the coefficient function's
    # own rounding in those orders was what was left at machine epsilon (above)
    assert error <= bound, error


def test_a_tolerance_out_of_range_says_what_taylor_takes():
    assert STEPPERS["taylor"].setting_error(tol=DOUBLE) is None
    assert STEPPERS["taylor"].setting_error(tol=1e-16) is None
    reason = STEPPERS["taylor"].setting_error(tol=1e-18)
    assert "between 1e-16 and 1" in reason and "double-double" in reason, reason
    assert "double-double" not in STEPPERS["dop853"].setting_error(tol=1e-18)


def test_kepler_over_eccentricities_in_double_double():
    # as below, in double-double: measured 6.3e-13 at most, median 2.3e-13 (16 values:
    # 4.4e-13 and 1.5e-13; 32 values: 5.7e-13 and 1.6e-13)
    compiled = _compiled("kepler_cartesian")
    errors = [
        _kepler_error_after_100_periods(compiled, e, DOUBLE) for e in np.linspace(0.45, 0.6, 8)
    ]
    assert max(errors) <= 1.5e-12, errors
    assert float(np.median(errors)) <= 6e-13, errors


def test_the_double_double_function_is_built_only_when_asked():
    """At the default tolerance (and at eps, or without the compensated state) a run
    neither writes nor compiles ``taylor_double``: the drivers get ``no_double`` (one
    function for every scene, never called); below eps the scene's is built once and
    kept with the coefficient function."""
    from systems.taylor import double

    compiled = _compiled("kepler_cartesian")  # a system of its own: nothing built yet
    kernels = compiled.taylor()
    y0 = kepler_start(0.5)
    for tol, compensated in ((None, True), (EPS, True), (DOUBLE, False)):
        runner = make_runner(compiled, STEPPERS["taylor"], y0, 0.0, 1.0, tol, None, compensated)
        assert not runner.double and runner.fns[1] is double.no_double()
        assert runner.advance(10**6, 10).code.name == "END"
        assert kernels._double is None, (tol, compensated)
    runner = make_runner(compiled, STEPPERS["taylor"], y0, 0.0, 1.0, DOUBLE, None)
    assert runner.double and kernels._double is not None
    assert runner.fns[1] is kernels._double.function
    assert runner.advance(10**6, 10).code.name == "END"
    built = kernels._double
    make_runner(compiled, STEPPERS["taylor"], y0, 0.0, 1.0, 1e-16, None)
    assert kernels._double is built  # once per scene


def test_kepler_over_eccentricities_keeps_its_round_off_below_heyokas():
    # 100 periods at eight eccentricities over 0.45 .. 0.6: the round-off's phase drift
    # lands anywhere from 1e-14 to 1e-11 by the eccentricity (measured: 6.1e-12 at most,
    # median 2.5e-12); heyoka 7.13 on the same equations and steps: 1e-14 to 3.1e-11,
    # median 8.9e-12 (16 eccentricities); ours without the compensated state
    # (compensated=False): 6e-15 to 4.1e-11, median 1.1e-11
    compiled = _compiled("kepler_cartesian")
    errors = [_kepler_error_after_100_periods(compiled, e) for e in np.linspace(0.45, 0.6, 8)]
    assert max(errors) <= 2e-11, errors
    assert float(np.median(errors)) <= 6e-12, errors


def test_the_energy_round_off_grows_like_sqrt_t():
    # Brouwer's law: with the state's rounding carried from step to step (Kahan) and
    # the time compensated, the energy error is a random walk. The RMS relative error
    # over the second half of [0, k periods], 16 nearby orbits of e = 0.5, against k
    compiled = _compiled("kepler_cartesian")
    ks = np.array([30, 100, 300, 1000])

    def rms(compensated: bool, tol: float | None = None) -> np.ndarray:
        total = np.zeros(len(ks))
        for r in range(16):
            y0 = kepler_start(0.5) * [1, 1, 1, 1 + 0.002 * r]
            _, period = kepler_exact(y0, 0.0)
            runner = make_runner(
                compiled, STEPPERS["taylor"], y0, 0.0, ks[-1] * period, tol, None, compensated
            )  # fmt: skip
            outcome = runner.advance(10**6, 10**6)
            assert outcome.code.name == "END"
            H = compiled.hamiltonian(outcome.t, outcome.y)
            H0 = compiled.hamiltonian(0.0, y0[None])[0]
            err = (H - H0) / H0
            t = outcome.t
            total += [np.mean(err[(t > k * period / 2) & (t <= k * period)] ** 2) for k in ks]
        return np.sqrt(total / 16)

    compensated = rms(True)
    # the state and orders 1 and 2 in double-double: the walk stays below the rounding
    # of H evaluated at the double y up to 1000 periods (measured: 3.3e-16 at 30, 4.4e-16
    # at 1000 periods, 8 orbits; a drift of slope 1 shows beyond: 1.2e-15 at 3000, 4.3e-15
    # at 10 000, the truncation's)
    double = rms(True, DOUBLE)
    assert double[-1] <= 1e-15 and 2 * double[-1] < compensated[-1], (double, compensated)
    slope = np.polyfit(np.log(ks), np.log(compensated), 1)[0]
    # measured: slope 0.47 (0.41-0.60 over the order of operations and the number of
    # orbits), the uncompensated state's energy error 4.4 times larger at 1000 periods;
    # a drift would have slope 1
    assert 0.3 <= slope <= 0.7, (slope, compensated)
    assert rms(False)[-1] > 2 * compensated[-1], compensated


def test_the_order_follows_the_tolerance_and_the_step_the_motion():
    compiled = _compiled("kepler_cartesian")
    e = 0.9
    y0 = kepler_start(e)
    counts = {}
    for tol in (EPS, 1e-10, 1e-6):
        runner = make_runner(compiled, STEPPERS["taylor"], y0, 0.0, 2 * math.pi, tol, None)
        assert runner.order == max(2, jorba_zou(tol))  # 20, 13, 8
        outcome = runner.advance(10**5, 10**5)
        assert outcome.code.name == "END"
        counts[tol] = outcome.steps
        h = np.diff(np.concatenate([[0.0], outcome.t]))[:-1]  # the last lands on t_end
        starts = np.concatenate([y0[None], outcome.y[:-2]])
        r = np.hypot(starts[:, 0], starts[:, 1])
        # the radius of convergence follows the distance to the complex singularity of
        # the motion, ~ r^(3/2): the steps from pericentre and apocentre (r 0.1 and 1.9)
        near, far = h[r < 0.15].min(), h[r > 1.8].max()
        ratio = near / far
        expected = (0.1 / 1.9) ** 1.5
        assert expected / 3 < ratio < expected * 3, (tol, ratio, expected)
    # Jorba and Zou: the tolerance sets the order, the step hardly changes with it
    assert max(counts.values()) <= 1.5 * min(counts.values()), counts
    # the truncation error of a step is about the tolerance (relative to max(1, |y|)):
    # a step against the series of twice the order over the same h
    d = decomposition_of(compiled.mechanics)
    for tol in (1e-6, 1e-10, EPS):
        step = reference.taylor_step(d, 0.0, y0, compiled.parameters, tol)
        runner = make_runner(compiled, STEPPERS["taylor"], y0, 0.0, math.inf, tol, None)
        outcome = runner.advance(1, 2)
        assert math.isclose(outcome.t[0], step.h, rel_tol=1e-12)
        from systems.taylor.coefficients import horner, taylor_coefficients

        finer = horner(taylor_coefficients(d, 0.0, y0, compiled.parameters, 40), step.h)
        error = np.abs(outcome.y[0] - finer).max() / max(1.0, np.abs(y0).max())
        assert error <= max(10 * tol, 4 * EPS), (tol, error)
        assert error >= tol / 1e3 or tol == EPS, (tol, error)  # not far shorter than needed


OSCILLATOR = """
[system]
coordinates = ["x"]
parameters = { m = 1.0, k = 2.0 }
kinetic = "m*x_dot**2/2"
potential = "k*x**2/2"
[initial]
x = 1.0
x_dot = 0.0
"""


def test_section_crossings_are_located_on_the_series_to_round_off():
    # the oscillator x = cos(w t) crosses x = 0.3 downward at (acos(0.3) + 2 pi j) / w
    compiled = compile_system(derive(parse_scene(OSCILLATOR)), ("rhs", "hamiltonian"))
    w = math.sqrt(2.0)
    run = Run(compiled, method="taylor", t_end=40.0, section=(0, 0.3, -1))
    events = []
    while not run.finished:
        block = run.advance(1.0)
        events.extend(block.events_t)
    expected = (math.acos(0.3) + 2 * math.pi * np.arange(len(events))) / w
    assert len(events) == math.floor(40.0 * w / (2 * math.pi) + 1 - math.acos(0.3) / (2 * math.pi))
    assert np.abs(np.array(events) - expected).max() <= 1e-13
    # Kepler, e = 0.9: the crossings of y = 0 upward are the pericentre passages, at
    # whole periods of the orbit through the rounded start, in steps of 0.01 to 1
    compiled = _compiled("kepler_cartesian")
    y0 = kepler_start(0.9)
    _, period = kepler_exact(y0, 0.0)
    run = Run(compiled, method="taylor", y0=y0, t_end=3.5 * period, section=(1, 0.0, 1))
    found_t, found_y = [], []
    while not run.finished:
        block = run.advance(1.0)
        found_t.extend(block.events_t)
        found_y.extend(block.events_y)
    assert len(found_t) == 3
    for j, (t, y) in enumerate(zip(found_t, found_y, strict=True), start=1):
        assert abs(t - j * period) <= 1e-13, (j, t - j * period)
        exact, _ = kepler_exact(y0, j * period)
        assert np.abs(y - exact).max() <= 1e-12 * np.abs(exact).max()


def test_a_scene_in_matrix_form_or_with_constraints_is_refused_with_the_reason():
    stepper = STEPPERS["taylor"]
    chain = derive(load_scene("pendulum_chain"))
    reason = stepper.applies_to(chain)
    assert reason is not None and "taylor" in reason and "matrix form" in reason
    reason = stepper.applies_to(derive(load_scene("cartesian_pendulum")))
    assert reason is not None and "taylor" in reason and "constraints" in reason
    assert stepper.applies_to(derive(load_scene("double_pendulum"))) is None


def test_equations_with_a_kink_are_refused():
    # sign(x) (dp/dt in V = |x|) has the series of the side it starts on: the motion is a
    # parabola whose series ends at order 2, so one step would have crossed x = 0 to the
    # end (the energy guard caught it; with damping nothing would have)
    text = '[system]\ncoordinates = ["x"]\nhamiltonian = "p_x**2/2 + abs(x)"\n'
    text += "[initial]\nx = 0.5\np_x = 0.0\n"
    reason = STEPPERS["taylor"].applies_to(derive(parse_scene(text)))
    assert reason is not None and "taylor" in reason and "sign of the state" in reason
    # a constant's kink is no kink: |a| of a parameter is a number
    text = '[system]\ncoordinates = ["x"]\nparameters = { a = -2.0 }\n'
    text += 'hamiltonian = "p_x**2/2 + abs(a)*x**2/2"\n[initial]\nx = 0.5\np_x = 0.0\n'
    assert STEPPERS["taylor"].applies_to(derive(parse_scene(text))) is None


@pytest.mark.parametrize("tol", [None, DOUBLE])
@pytest.mark.parametrize("batched", [True, False])
def test_an_ensemble_is_the_single_runs_rows_and_stops_a_row_alone(batched, tol):
    """``simulation.ensemble`` with taylor: one parallel loop, each row its own steps
    (``batched``: the coefficients of a batch of rows from one call of the SIMD batch
    function, 11 rows: a full batch and a part one on any CPU); its samples are the
    single run's dense output at the same times (the same steps, the same series:
    bitwise), a Kepler orbit of e = 0.9 among near-circular ones is followed with its
    own short steps, and a row whose state turns non-finite stops alone with its
    status."""
    from systems.integrators.codes import Status
    from systems.simulation import ensemble

    compiled = _compiled("kepler_cartesian")
    Y0 = np.array([kepler_start(e) for e in (0.1, 0.5, 0.9, *np.linspace(0.0, 0.3, 8))])
    t, Y, status = ensemble(
        compiled, Y0, method="taylor", t_end=3.0, samples=7, batched=batched, tol=tol
    )  # fmt: skip
    assert t.shape == (7,) and t[-1] == 3.0 and Y.shape == (11, 7, 4)
    assert not status.any()
    for row, y0 in enumerate(Y0):
        runner = make_runner(compiled, STEPPERS["taylor"], y0, 0.0, 3.0, tol, None)
        assert runner.double == (tol is not None)
        outcome = runner.advance(10**9, 2, samples=t)
        assert outcome.sampled == 7
        assert np.array_equal(outcome.y[:7], Y[row]), row
    for row, y0 in enumerate(Y0):  # and the exact orbit, to round-off over 3 time units
        exact = np.array([kepler_exact(y0, s)[0] for s in t])
        assert np.abs(Y[row] - exact).max() <= 1e-13 * np.abs(exact).max(), row
    # the origin: 1/r is infinite, the row's first step non-finite; the others go on
    bad = np.vstack([Y0[:1], np.zeros((1, 4)), Y0[2:]])
    _, Y, status = ensemble(
        compiled, bad, method="taylor", t_end=3.0, samples=2, batched=batched, tol=tol
    )  # fmt: skip
    assert status[1] == int(Status.NON_FINITE) and not status[[0, *range(2, 11)]].any()
    assert np.isnan(Y[1]).all() and np.isfinite(Y[[0, *range(2, 11)]]).all()
