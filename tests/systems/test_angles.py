"""Angle coordinates: declared or detected, wrapped with breaks, and sections modulo 2 pi."""

from __future__ import annotations

import math
import time

import numpy as np
import pytest

from systems.angles import (
    angle_coordinates,
    branch,
    break_at_wraps,
    declared_angles,
    detect_angles,
    wrap,
)
from systems.compiled import compile_system
from systems.integrators.events import periodic_brackets
from systems.mechanics import derive
from systems.scene import load_scene, parse_scene
from systems.simulation import Run

TWO_PI = 2 * math.pi


def _scene(coordinates, kinetic, potential, extra="", drawing=""):
    names = ", ".join(f'"{q}"' for q in coordinates)
    return parse_scene(
        f"""
title = "t"
[system]
coordinates = [{names}]
parameters = {{ k = 1.0, l = 1.0 }}
kinetic = "{kinetic}"
potential = "{potential}"
{extra}
{drawing}
"""
    )


@pytest.mark.parametrize(
    "name, expected",
    [
        ("double_pendulum", ("theta1", "theta2")),
        ("simple_pendulum", ("theta",)),
        ("driven_damped_pendulum", ("theta",)),  # the force A cos(w t) is periodic in theta
        ("planetary_motion", ("theta",)),  # cyclic: an angle through its drawing
        ("spherical_pendulum", ("theta", "phi")),
        ("henon_heiles", ()),
        ("kepler_cartesian", ()),
        ("harmonic_oscillator", ()),
        ("coupled_oscillators", ()),
    ],
)
def test_catalogue_angles_are_detected(name, expected):
    assert detect_angles(load_scene(name)) == expected


def test_a_coordinate_periodic_in_some_terms_only_is_not_an_angle():
    torsion = _scene(["theta"], "theta_dot**2/2", "-cos(theta) + k*theta**2/2")
    assert detect_angles(torsion) == ()
    pushed = _scene(
        ["theta"], "theta_dot**2/2", "-cos(theta)", '[effects]\nforces = { theta = "-k*theta" }'
    )
    assert detect_angles(pushed) == ()
    # half-angles are not 2 pi-periodic
    assert detect_angles(_scene(["theta"], "theta_dot**2/2", "-cos(theta/2)")) == ()
    # sin and cos of integer multiples and of differences are
    rotors = _scene(["a", "b"], "a_dot**2/2 + b_dot**2/2", "-cos(2*a - b) - k*sin(3*b)**2")
    assert detect_angles(rotors) == ("a", "b")


def test_a_coordinate_that_appears_nowhere_or_only_linearly_is_no_angle():
    free = _scene(["x"], "x_dot**2/2", "0")
    assert detect_angles(free) == ()
    rolling = _scene(
        ["theta"], "theta_dot**2/2", "0", drawing='[drawing]\npoints = { c = ["l*theta", "0"] }'
    )
    assert detect_angles(rolling) == ()
    turning = _scene(
        ["theta"],
        "theta_dot**2/2",
        "0",
        drawing='[drawing]\npoints = { c = ["l*cos(theta)", "l*sin(theta)"] }',
    )
    assert detect_angles(turning) == ("theta",)


def test_declared_angles_win_over_detection():
    scene = _scene(["x", "theta"], "x_dot**2/2 + theta_dot**2/2", "-cos(theta) + x**2/2")
    assert declared_angles(scene) is None
    assert detect_angles(scene) == ("theta",)
    declared = _scene(
        ["x", "theta"],
        "x_dot**2/2 + theta_dot**2/2",
        "-cos(theta) + x**2/2",
        extra='[view]\nangles = ["x"]',
    )
    assert angle_coordinates(derive(declared)) == ("x",)
    none = _scene(
        ["x", "theta"],
        "x_dot**2/2 + theta_dot**2/2",
        "-cos(theta) + x**2/2",
        extra="[view]\nangles = []",
    )
    assert angle_coordinates(derive(none)) == ()


def test_detection_is_bounded_for_many_coordinates():
    n = 64
    names = [f"x{i}" for i in range(n)]
    chain = _scene(
        names,
        " + ".join(f"{q}_dot**2/2" for q in names),
        " + ".join(f"k*({a} - {b})**2/2" for a, b in zip(names, names[1:], strict=False)),
    )
    start = time.process_time()
    assert detect_angles(chain) == ()
    rotors = _scene(
        names,
        " + ".join(f"{q}_dot**2/2" for q in names),
        " - ".join(f"cos({a} - {b})" for a, b in zip(names, names[1:], strict=False)),
    )
    assert detect_angles(rotors) == tuple(names)
    assert time.process_time() - start < 5.0


def test_wrap_and_branch():
    x = np.array([math.pi, -math.pi, 0.0, 3 * math.pi, -3 * math.pi + 1e-9, 7.0])
    w = wrap(x)
    assert np.all((w > -math.pi) & (w <= math.pi))
    assert w[0] == pytest.approx(math.pi) and w[1] == pytest.approx(math.pi)
    assert np.allclose(w + TWO_PI * branch(x), x)
    assert wrap(7.0) == pytest.approx(7.0 - TWO_PI)


def _longest_unbroken_jump(x: np.ndarray) -> float:
    steps = np.abs(np.diff(x))
    return float(np.nanmax(steps)) if np.isfinite(steps).any() else 0.0


def test_wrapped_curves_break_at_the_edges():
    t = np.linspace(0.0, 40.0, 400)
    q = 1.3 * t + 0.4 * np.sin(3 * t)  # turns about eight times
    p = np.cos(t)
    x, y = break_at_wraps([q, p], [True, False])
    assert np.nanmax(np.abs(x)) <= math.pi + 1e-12
    assert _longest_unbroken_jump(x) < math.pi  # no chord across the plot
    breaks = np.flatnonzero(np.isnan(x))
    turns = int(branch(q[-1]) - branch(q[0]))
    assert len(breaks) == turns
    for i in breaks:  # the line runs to one edge and resumes at the other, same p
        assert abs(x[i - 1]) == pytest.approx(math.pi) and x[i + 1] == pytest.approx(-x[i - 1])
        assert y[i - 1] == pytest.approx(y[i + 1])
    # the original points are all there, in order
    finite = ~np.isnan(x)
    inner = np.isin(np.arange(len(x)), np.concatenate([breaks - 1, breaks + 1]))
    assert np.allclose(x[finite & ~inner], wrap(q))
    # two angles (a torus) and a jump of several turns in one step
    q2 = -0.7 * t
    a, b = break_at_wraps([q, q2], [True, True])
    assert _longest_unbroken_jump(a) < math.pi and _longest_unbroken_jump(b) < math.pi
    far = np.array([0.0, 0.5, 0.5 + 3 * TWO_PI, 1.0 + 3 * TWO_PI])
    fx, _ = break_at_wraps([far, np.zeros(4)], [True, False])
    assert np.isnan(fx).sum() == 1 and _longest_unbroken_jump(fx) < math.pi


def test_periodic_brackets_find_every_level_in_both_directions():
    t = np.linspace(0.0, 10.0, 1001)
    q = 2.0 * t - 0.3  # upward through 0, 2 pi, 4 pi, ...
    y = np.column_stack([q, np.ones_like(q)])
    bt, by, levels = periodic_brackets(t, y, 0, 0.0, +1)
    expected = np.arange(0, math.floor(q[-1] / TWO_PI) + 1) * TWO_PI
    assert np.allclose(levels, expected)
    assert np.all(by[:, 0, 0] < levels) and np.all(by[:, 1, 0] >= levels)
    assert np.all(bt[:, 1] - bt[:, 0] == pytest.approx(0.01))
    assert len(periodic_brackets(t, y, 0, 0.0, -1)[0]) == 0
    down = np.column_stack([-q, np.ones_like(q)])
    _, _, down_levels = periodic_brackets(t, down, 0, 1.0, -1)
    # from 0.3 down to -19.7: the levels 1 - 2 pi, 1 - 4 pi, 1 - 6 pi (1 itself is above)
    assert np.allclose(down_levels, 1.0 - TWO_PI * np.arange(1, 4))
    assert len(down_levels) == len(periodic_brackets(t, down, 0, 1.0, 0)[0])
    # a step that turns twice crosses two levels
    jump = np.array([[0.1, 0.0], [0.2 + 2 * TWO_PI, 0.0]])
    assert len(periodic_brackets(np.array([0.0, 1.0]), jump, 0, 0.0, +1)[0]) == 2


@pytest.fixture(scope="module")
def double_pendulum():
    return compile_system(derive(load_scene("double_pendulum")), ("rhs", "hamiltonian"))


def _events(run: Run, seconds: float) -> tuple[np.ndarray, np.ndarray]:
    ts, ys = [], []
    while not run.finished:
        block = run.advance(seconds)
        ts.append(block.events_t)
        ys.append(block.events_y)
    return np.concatenate(ts), np.concatenate(ys)


def test_double_pendulum_section_on_an_angle_collects_crossings_modulo_2pi(double_pendulum):
    compiled = double_pendulum
    # energetic enough that the first link tumbles: theta1 runs off by many turns whatever
    # rounding does to the chaotic details (the scene's own start wanders only sometimes)
    start = np.array([0.0, 0.0, 20.0, 10.0])
    run = Run(compiled, y0=start, t_end=200.0, section=(0, 0.0, 1), energy_tolerance=None)
    assert run.section_period == pytest.approx(TWO_PI)
    t, y = _events(run, 0.05)
    assert abs(run.good[1][0]) > 20 * math.pi
    assert len(t) >= 40  # two points by t = 5000 before crossings were taken modulo 2 pi
    assert np.all(np.diff(t) > 0)
    assert np.allclose(wrap(y[:, 0]), 0.0, atol=1e-9)
    rates = np.array([compiled.rhs(ti, yi)[0] for ti, yi in zip(t, y, strict=True)])
    assert np.all(rates > 0)  # upward crossings only
    H = compiled.hamiltonian(t, y)
    assert H == pytest.approx(H[0], rel=1e-6)
    # where blocks end changes nothing: the same crossings from differently sized blocks
    again = Run(compiled, y0=start, t_end=200.0, section=(0, 0.0, 1), energy_tolerance=None)
    t2, _ = _events(again, 0.4)
    assert len(t2) == len(t) and np.allclose(t2, t, rtol=0, atol=1e-9)


def test_a_section_on_a_length_is_left_to_the_compiled_loop():
    compiled = compile_system(
        derive(load_scene("henon_heiles")), ("rhs", "hamiltonian", "separable")
    )
    run = Run(compiled, t_end=50.0, section=(0, 0.0, 1))
    assert run.section_period is None
    t, y = _events(run, 0.05)
    assert len(t) > 3 and np.allclose(y[:, 0], 0.0, atol=1e-9)
