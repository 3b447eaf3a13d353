"""Orbit diagrams of driven systems (``systems.chaos.bifurcation``): the driven damped
pendulum's period doubling where the literature puts it, the stroboscopic samples at
whole periods of the drive, and what is refused.

The catalogue's driven damped pendulum is theta'' + 0.5 theta' + sin(theta) =
A cos(2 t / 3) (m = g = l = 1, b = 0.5): Baker & Gollub's (Chaotic Dynamics: An
Introduction) pendulum with quality factor q = 1 / 0.5 = 2, drive frequency 2/3 and
drive amplitude g = A, which is also J. R. Taylor's (Classical Mechanics, 2005,
chapter 12) with omega_0 = 1.5 omega and beta = omega_0 / 4 in units of 1 / omega_0,
and drive strength gamma = A. Taylor's thresholds of the cascade from phi(0) = -pi/2,
phi'(0) = 0: period 2 from gamma_1 = 1.0663, 4 from 1.0793, 8 from 1.0821; Baker &
Gollub: period two near g = 1.07, chaotic near 1.5.
"""

import math

import numpy as np
import pytest

from systems.chaos import bifurcation as bf
from systems.compiled import compile_system
from systems.mechanics import derive
from systems.scene import load_scene
from systems.simulation import Run, Sampler

START = np.array([-math.pi / 2, 0.0])


@pytest.fixture(scope="module")
def pendulum():
    return compile_system(derive(load_scene("driven_damped_pendulum")), ("rhs", "hamiltonian"))


def test_the_drive_sets_the_stroboscopic_period(pendulum):
    assert bf.drive_period(pendulum) == pytest.approx(3 * math.pi, rel=1e-14)
    assert bf.drive_period(pendulum, {"w": 0.5}) == pytest.approx(4 * math.pi, rel=1e-14)
    hh = compile_system(derive(load_scene("henon_heiles")), ("rhs", "hamiltonian"))
    assert bf.drive_period(hh) is None


def test_the_first_period_doubling_is_taylors_gamma_1(pendulum):
    kernel = bf.strobe_kernel(pendulum, "A", transient=20000.0, samples=16)
    values = np.round(np.arange(1.060, 1.0751, 0.0005), 4)
    diagram = bf.orbit_diagram(kernel, values, y0=START)
    assert (diagram.status == 0).all()
    found = bf.periods(diagram, 1e-6, angles=(0,))
    first = values[np.argmax(found == 2)]
    assert (found[values < first] == 1).all() and (found[values >= first] == 2).all(), found
    assert 1.0655 < first <= 1.0675
    # past a flip the two branches part like sqrt(A - gamma_1): the line through the
    # squared gaps meets 0 at the threshold
    p = diagram.variable("p_theta")
    gap2 = (p[:, -1] - p[:, -2]) ** 2
    near = (values >= first) & (values <= first + 0.003)
    slope, intercept = np.polyfit(values[near], gap2[near], 1)
    assert abs(-intercept / slope - 1.0663) < 5e-4


def test_the_cascade_goes_on_to_chaos(pendulum):
    kernel = bf.strobe_kernel(pendulum, "A", transient=20000.0, samples=32)
    diagram = bf.orbit_diagram(kernel, np.array([1.078, 1.0805, 1.0824, 1.5]), y0=START)
    assert list(bf.periods(diagram, 1e-6, angles=(0,))) == [2, 4, 8, 0]


def test_the_samples_are_the_states_at_whole_periods(pendulum):
    # A = 1.06: periodic (at 1.2 the motion is chaotic and amplifies any difference)
    T = 3 * math.pi
    kernel = bf.strobe_kernel(
        pendulum, "A", transient=5 * T, samples=4, method="rk4", per_period=400
    )
    assert kernel.transient_periods == 5
    diagram = bf.orbit_diagram(kernel, np.array([1.06]), y0=START)
    times = T * np.arange(6, 10)
    sampler = Sampler(Run(pendulum.with_parameters({"A": 1.06}), method="dop853", tol=1e-12,
                          y0=START, t_end=9 * T), times)  # fmt: skip
    exact = np.array([y for t, y in sampler][1:])
    assert np.abs(diagram.samples[0] - exact).max() < 1e-6


def test_what_is_refused_says_why(pendulum):
    with pytest.raises(ValueError, match="no parameter 'Q'.*m, g, l, b, A, w"):
        bf.strobe_kernel(pendulum, "Q")
    hh = compile_system(derive(load_scene("henon_heiles")), ("rhs", "hamiltonian", "separable"))
    with pytest.raises(ValueError, match="does not depend on t"):
        bf.strobe_kernel(hh, "Q")
    with pytest.raises(ValueError, match="fixed-step method"):
        bf.strobe_kernel(pendulum, "A", method="dop853")
    with pytest.raises(ValueError, match="leapfrog|dissipat|forc"):
        bf.strobe_kernel(pendulum, "A", method="yoshida4")


def test_a_frequency_of_zero_leaves_the_row_out(pendulum):
    kernel = bf.strobe_kernel(pendulum, "w", transient=0.0, samples=2)
    diagram = bf.orbit_diagram(kernel, np.array([0.0, 2 / 3]), y0=START)
    assert diagram.status[0] == -1 and np.isnan(diagram.samples[0]).all()
    assert diagram.status[1] == 0 and np.isfinite(diagram.samples[1]).all()


def test_a_run_with_a_strobe_gives_the_states_once_per_period(pendulum):
    T = bf.drive_period(pendulum)
    run = Run(pendulum, method="dop853", tol=1e-12, t_end=100 * T, strobe=T)
    times, states = [], []
    while not run.finished:
        block = run.advance(0.05)
        times += list(block.events_t)
        states += list(block.events_y)
    assert len(times) == 100
    assert np.allclose(times, T * np.arange(1, 101), rtol=0, atol=1e-12)
    exact = Sampler(Run(pendulum, method="dop853", tol=1e-12, t_end=100 * T), T * np.arange(1, 101))
    expected = np.array([y for _, y in exact][1:])
    assert np.abs(np.array(states) - expected).max() < 1e-9
    with pytest.raises(ValueError, match="strobe must be a positive period"):
        Run(pendulum, strobe=T, section=(0, 0.0, 1))


def _strobe_run(compiled, value: float, periods: int, tol=None) -> np.ndarray:
    """The states at the first ``periods`` periods of the drive of a single taylor run
    (``Run(strobe=T)``) at A = ``value`` from START: (periods, 2)."""
    at = compiled.with_parameters({"A": value})
    run = Run(at, method="taylor", tol=tol, y0=START, strobe=bf.drive_period(at))
    states: list = []
    while len(states) < periods:
        states += list(run.advance(0.05).events_y)
    return np.array(states[:periods])


@pytest.mark.parametrize("tol", [None, 1e-16])
def test_a_taylor_diagram_is_each_values_single_run_bitwise(pendulum, tol):
    """``method="taylor"``: the orbits in SIMD batches, each lane its own A (11 values:
    a full batch and a part one on any CPU) and its own times; every row is the single
    taylor run's strobe at its value, bitwise (the same steps, the same series), also in
    double-double (``tol`` below machine epsilon: each lane's ``taylor_double`` at its
    own parameters). Were the parameters lane 0's, the rows would all be row 0's."""
    values = np.array([1.06, 1.07, 1.08, 1.1, 1.2, 1.3, 1.4, 1.5, 1.05, 1.065, 1.075])
    kernel = bf.strobe_kernel(pendulum, "A", transient=0.0, samples=3, method="taylor", tol=tol)
    assert kernel.tol == (tol or np.finfo(float).eps) and bool(kernel.coef[5]) == (tol is not None)
    diagram = bf.orbit_diagram(kernel, values, y0=START)
    assert (diagram.status == 0).all() and diagram.tol == kernel.tol
    assert (diagram.steps > 50).all()  # several steps a period, counted per row
    assert "tolerance" in diagram.checked and "energy" in diagram.checked
    for row, value in enumerate(values):
        assert np.array_equal(diagram.samples[row], _strobe_run(pendulum, value, 3, tol)), value
    assert len({diagram.samples[row, -1, 1] for row in range(len(values))}) == len(values)


def test_the_strobe_loop_takes_the_sweep_functions_own_width(pendulum, monkeypatch):
    """The scalar code is remembered per scene and may come from another decomposition
    of the same equations (the scene derived another way: more nodes, another width);
    the loop's ``out`` has the sweep function's own columns, or it reads garbage."""
    taylor = pendulum.taylor()
    width = taylor.width
    monkeypatch.setattr(taylor, "width", width + 3)
    kernel = bf.strobe_kernel(pendulum, "A", transient=0.0, samples=2, method="taylor")
    monkeypatch.undo()
    assert kernel.coef[0] == width
    diagram = bf.orbit_diagram(kernel, np.array([1.06, 1.2]), y0=START)
    assert (diagram.status == 0).all()
    assert np.array_equal(diagram.samples[0], _strobe_run(pendulum, 1.06, 2))


def test_taylor_and_rk4_agree_where_rk4_is_accurate(pendulum):
    """Period 1 (A = 1.06) and period 2 (1.076): the taylor diagram's samples are the
    rk4 diagram's (400 steps a period) to its accuracy, with the same periods."""
    T = bf.drive_period(pendulum)
    values = np.array([1.06, 1.076])
    options = {"transient": 300 * T, "samples": 8}
    rk4 = bf.orbit_diagram(
        bf.strobe_kernel(pendulum, "A", method="rk4", per_period=400, **options), values, y0=START
    )
    taylor = bf.orbit_diagram(
        bf.strobe_kernel(pendulum, "A", method="taylor", **options), values, y0=START
    )
    assert rk4.method == "rk4" and taylor.method == "taylor" and rk4.tol is None
    assert np.abs(taylor.samples - rk4.samples).max() < 1e-6
    assert (
        list(bf.periods(taylor, 1e-6, angles=(0,)))
        == list(bf.periods(rk4, 1e-6, angles=(0,)))
        == [1, 2]
    )


def test_a_taylor_diagram_stops_between_chunks_when_cancelled(pendulum):
    kernel = bf.strobe_kernel(pendulum, "A", transient=0.0, samples=2, method="taylor")
    asked = []

    def cancelled() -> bool:
        asked.append(1)
        return len(asked) > 1  # after the first chunk

    diagram = bf.orbit_diagram(
        kernel, np.linspace(1.0, 1.2, 6), y0=START, chunk=2, cancelled=cancelled
    )
    assert not diagram.complete
    assert (diagram.status[:2] == 0).all() and (diagram.status[2:] == -1).all()
    assert np.isfinite(diagram.samples[:2]).all() and np.isnan(diagram.samples[2:]).all()


def test_a_tolerance_is_taylors_only(pendulum):
    with pytest.raises(ValueError, match="rk4 takes a number of steps.*not a tolerance"):
        bf.strobe_kernel(pendulum, "A", method="rk4", tol=1e-10)
    with pytest.raises(ValueError, match="tol"):
        bf.strobe_kernel(pendulum, "A", method="taylor", tol=2.0)
    with pytest.raises(ValueError, match="taylor takes a tolerance, not a number of steps"):
        bf.strobe_kernel(pendulum, "A", method="taylor", per_period=400)
    assert bf.strobe_kernel(pendulum, "A").method == "taylor"  # the default where it applies


def test_a_turning_angle_is_compared_modulo_two_pi_at_its_own_scale():
    k = np.arange(16)
    theta = 1e4 + 2 * np.pi * k + 0.01 * (k % 2)  # turning, and alternating by 0.01
    p = 1.0 + 0.0 * k
    samples = np.stack([theta, p], axis=-1)[None]
    diagram = bf.OrbitDiagram(
        parameter="A", values=np.array([1.0]), samples=samples, periods_T=np.array([1.0]),
        status=np.array([0]), names=("theta", "p_theta"), method="rk4", per_period=200,
        transient_periods=0, t0=0.0, wall_s=0.0, complete=True,
    )  # fmt: skip
    assert list(bf.periods(diagram, 1e-4, angles=(0,))) == [2]
    assert list(bf.periods(diagram, 1e-1, angles=(0,))) == [1]
