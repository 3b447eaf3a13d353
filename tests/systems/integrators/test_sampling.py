"""States at requested times (``run --samples``, ``--out``, exports): exactly at those times,
as accurate as the run, and never changing the run.

Every compiled family of the registry runs here (``Family.kernel``; scipy's solvers pause
at each time instead): its samples, found inside the compiled loop by the family's
``X_sample`` (a shortened step of the method, DOP853's dense output, the fictitious step
that lands on the time), are compared with an exact solution and with the run's own error
at the steps around each sample; the unsampled trajectory is the same bit for bit; the
bouncing ball keeps both sides of its impacts.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from systems import simulation
from systems.compiled import compile_system
from systems.integrators import STEPPERS
from systems.mechanics import derive
from systems.scene import load_scene, parse_scene
from systems.simulation import Run, Sampler, required_wants, stream
from tests.systems import scenes

W = math.sqrt(1.5)  # scenes.OSCILLATOR: m = 2, k = 3, from x = 1 at rest
GAMMA = 0.1  # scenes.DAMPED_OSCILLATOR: m = k = 1, the force -0.2 x_dot
WD = math.sqrt(1.0 - GAMMA**2)

E = 0.5  # the Kepler orbit's eccentricity, a = k = m = 1, from pericentre
KEPLER = f"""
[system]
coordinates = ["x", "y"]
parameters = {{ k = 1.0 }}
kinetic = "(x_dot**2 + y_dot**2)/2"
potential = "-k/sqrt(x**2 + y**2)"
[initial]
x = {1 - E}
y = 0.0
x_dot = 0.0
y_dot = {math.sqrt((1 + E) / (1 - E))}
"""

PHI0 = math.atan2(-0.8, 0.6)
CIRCLE = """
[system]
coordinates = ["x", "y"]
parameters = { m = 1.0, g = 0.0, l = 1.0 }
kinetic = "m*(x_dot**2 + y_dot**2)/2"
potential = "m*g*y"
[constraints]
holonomic = ["x**2 + y**2 - l**2"]
[initial]
x = 0.6
y = -0.8
x_dot = 0.8
y_dot = 0.6
"""


def _kepler(t: float) -> tuple[float, float]:
    anomaly = t
    for _ in range(50):  # Kepler's equation E - e sin E = t (mean motion 1), by Newton
        anomaly -= (anomaly - E * math.sin(anomaly) - t) / (1 - E * math.cos(anomaly))
    return math.cos(anomaly) - E, math.sqrt(1 - E * E) * math.sin(anomaly)


SYSTEMS = {
    "oscillator": (scenes.OSCILLATOR, lambda t: (math.cos(W * t),)),
    "damped": (
        scenes.DAMPED_OSCILLATOR,
        lambda t: (math.exp(-GAMMA * t) * (math.cos(WD * t) + GAMMA / WD * math.sin(WD * t)),),
    ),
    "kepler": (KEPLER, _kepler),
    "circle": (CIRCLE, lambda t: (math.cos(PHI0 + t), math.sin(PHI0 + t))),
}
T_END = {"oscillator": 10.0, "damped": 10.0, "kepler": 2 * math.pi * 1.5, "circle": 10.0}
# coarse fixed steps, so that the run's error is well above round-off
STEPS = {1: 0.01, 2: 0.05, 4: 0.1, 6: 0.2, 8: 0.4}
TIMES = 97  # sample times, not commensurate with any step


def _cases():
    for name, stepper in sorted(STEPPERS.items()):
        if stepper.family.kernel is None:
            continue  # scipy's solvers: the state of the first step at or after each time
        if stepper.family.constrained:
            yield name, "circle"
        elif stepper.family.name == "logh":
            yield name, "kepler"
        else:
            yield name, "oscillator"
            if stepper.family.name == "gauss_tt":
                yield name, "kepler"
            if stepper.family.name not in ("composition", "logh"):
                yield name, "damped"


_compiled_cache: dict = {}


def _compiled(kind: str, method: str):
    wants = required_wants(method) | {"hamiltonian"}
    key = (kind, wants)
    if key not in _compiled_cache:
        _compiled_cache[key] = compile_system(
            derive(parse_scene(SYSTEMS[kind][0], source=f"<{kind}>")), wants
        )
    return _compiled_cache[key]


def _setting(method: str, kind: str, compiled) -> dict:
    stepper = STEPPERS[method]
    if stepper.setting == "tol":
        return {"tol": 1e-8}
    if stepper.setting == "ds":
        ds = stepper.default_setting(compiled, 0.0, compiled.initial_state(), T_END[kind])
        return {"dt": 8 * ds}  # the fictitious step (Run takes it as dt)
    return {"dt": STEPS[stepper.order]}


def _errors(kind: str, t: np.ndarray, y: np.ndarray) -> np.ndarray:
    exact = np.array([SYSTEMS[kind][1](float(time)) for time in t])
    n = exact.shape[1]
    return np.max(np.abs(y[:, :n] - exact), axis=1)


def _steps(compiled, method, kind, setting):
    """Every step of the unsampled run: (t, y, the last block)."""
    blocks = list(
        stream(compiled, method=method, t_end=T_END[kind], energy_tolerance=None,
               max_points=10**6, **setting)
    )  # fmt: skip
    assert blocks[-1].status == "ok", blocks[-1].message
    t = np.concatenate([[0.0]] + [b.t for b in blocks])
    y = np.concatenate([compiled.initial_state()[None]] + [b.y for b in blocks])
    return t, y, blocks[-1]


def _sampled(compiled, method, kind, setting, times):
    run = Run(compiled, method=method, t_end=T_END[kind], energy_tolerance=None, **setting)
    sampler = Sampler(run, times)
    rows = list(sampler)
    assert sampler.last.status == "ok", sampler.last.message
    return np.array([r[0] for r in rows]), np.array([r[1] for r in rows]), run


@pytest.mark.parametrize(("method", "kind"), list(_cases()))
def test_samples_are_at_the_times_asked_for_and_as_accurate_as_the_run(method, kind, monkeypatch):
    # a few times a call: a call returns after its last time, inside a step that may hold
    # the next call's first times (answered from that step's start, kept by the runner)
    monkeypatch.setattr(simulation, "SAMPLE_CHUNK", 5)
    compiled = _compiled(kind, method)
    setting = _setting(method, kind, compiled)
    t_end = T_END[kind]
    times = np.linspace(0.0, t_end, TIMES)
    t, y, _ = _sampled(compiled, method, kind, setting, times)
    assert np.array_equal(t, times), (t[:4], times[:4])  # exactly, none skipped, none twice
    steps_t, steps_y, _ = _steps(compiled, method, kind, setting)
    step_errors = _errors(kind, steps_t, steps_y)
    sample_errors = _errors(kind, t, y)
    floor = 1e-13
    # DOP853's rows come from its 7th-order interpolant, one order below its steps: their
    # error is of the order of the tolerance, not of the steps around them (at tol 1e-8
    # on the oscillator a row is 10 times the steps around it, 2 times the run's worst)
    tol = setting.get("tol", 0.0) if STEPPERS[method].family.name == "dop853" else 0.0
    worst = 0.0
    for time, error in zip(t[1:], sample_errors[1:], strict=True):
        i = int(np.searchsorted(steps_t, time))  # the steps around the sample
        around = max(np.max(step_errors[max(i - 2, 0) : i + 2]), tol)
        ratio = error / (around + floor)
        worst = max(worst, ratio)
    # as accurate as the steps around each sample (a small factor for where in the step)
    assert worst <= 4.0, (method, kind, worst, np.max(sample_errors), np.max(step_errors))
    if STEPPERS[method].family.constrained:
        violation = compiled.constraints().violation(t, y)
        assert violation <= 1e-10, violation


@pytest.mark.parametrize(("method", "kind"), list(_cases()))
def test_asking_for_samples_never_changes_the_trajectory(method, kind, monkeypatch):
    """The steps with samples are the steps without, bit for bit. The run goes on past
    the last time (to 10 t_end), so no landing on the end time is compared: a
    time-transformed family lands with substeps sized from its recent steps, which
    depend on where its blocks ended."""
    monkeypatch.setattr(simulation, "SAMPLE_CHUNK", 5)
    compiled = _compiled(kind, method)
    setting = _setting(method, kind, compiled)
    t_end = T_END[kind]
    run = Run(compiled, method=method, t_end=10 * t_end, energy_tolerance=None, **setting)
    rows = list(Sampler(run, np.linspace(0.0, t_end, TIMES)))
    assert rows[-1][0] == t_end and not run.finished
    plain = Run(compiled, method=method, t_end=10 * t_end, energy_tolerance=None, **setting)
    done = plain.runner.advance(run.steps, 2)  # as many steps, in one call, no samples
    assert done.steps == run.steps
    assert plain.runner.t == run.runner.t
    assert np.array_equal(plain.runner.y, run.runner.y)
    assert np.array_equal(plain.runner.comp, run.runner.comp)


@pytest.mark.parametrize("chunk", [3, 4096])
def test_a_sample_at_an_impact_is_the_state_after_it_and_none_straddles_one(chunk, monkeypatch):
    monkeypatch.setattr(simulation, "SAMPLE_CHUNK", chunk)
    compiled = compile_system(
        derive(load_scene("bouncing_ball")), required_wants("constrained_dop853")
    )
    t_end = 2.0
    blocks = list(stream(compiled, method="constrained_dop853", t_end=t_end, max_points=10**6))
    assert blocks[-1].status == "ok"
    t = np.concatenate([b.t for b in blocks])
    y = np.concatenate([b.y for b in blocks])
    jumps = np.flatnonzero(t[1:] == t[:-1])  # the state before an impact, then after it
    assert len(jumps) >= 2
    impact = float(t[jumps[0]])
    g, h0, vx = 9.81, 1.0, 0.8
    assert impact == pytest.approx(math.sqrt(2 * h0 / g), rel=1e-9)
    times = np.sort(
        np.concatenate([[impact, impact - 1e-3, impact + 1e-3], np.linspace(0.05, t_end, 41)])
    )
    run = Run(compiled, method="constrained_dop853", t_end=t_end)
    rows = list(Sampler(run, times))
    st = np.array([r[0] for r in rows])
    sy = np.array([r[1] for r in rows])
    assert np.array_equal(st[1:], times)
    at = int(np.flatnonzero(st == impact)[0])
    assert sy[at, 3] > 0.0  # moving up: after the impact
    assert sy[at, 3] == pytest.approx(-0.8 * y[jumps[0], 3], rel=1e-12)
    # before the first impact the fall is exact: y = h0 - g t**2 / 2, x = x0 + vx t
    v0 = math.sqrt(2 * g * h0)
    for time, state in zip(st, sy, strict=True):
        assert state[1] >= -1e-12  # never below the floor: nothing across an impact
        if time < impact:
            assert state[1] == pytest.approx(h0 - g * time**2 / 2, abs=1e-9)
            assert state[3] == pytest.approx(-g * time, abs=1e-9)
        elif time < float(t[jumps[1]]):  # the first flight after it: up at 0.8 v0
            tau = time - impact
            assert state[1] == pytest.approx(0.8 * v0 * tau - g * tau**2 / 2, abs=1e-9)
        assert state[0] == pytest.approx(-2.0 + vx * time, abs=1e-9)
