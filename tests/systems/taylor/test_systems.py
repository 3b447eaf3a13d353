"""Whole systems: the Taylor coefficients of the solution through a state, against the
exact series (the harmonic oscillator) and against forward differences of Euler's
iterates at a step of 2**-100 in arithmetic of 100 bits an order (mpmath, evaluating the equations
sympy derived: nothing of the Taylor code), for catalogue scenes and a system with every
function of the parser (abs aside: its recurrence is checked in test_elementary).

The reference once differentiated the right-hand side symbolically order after order
(y^(k) = D^(k-1) f): 9 s of CPU for these orders, its own round-off 1e-13 at Kepler's
ninth, where this one costs milliseconds and agrees with the exact series to 1e-27."""

import math

import mpmath
import numpy as np
import pytest
import sympy as sp

from systems.mechanics import derive
from systems.scene import load_scene, parse_scene
from systems.taylor.coefficients import evaluate, taylor_coefficients
from systems.taylor.compiled import decomposition_of
from systems.taylor.decompose import NotDecomposable, decompose, decompose_mechanics

EVERY_HAMILTONIAN = " + ".join(
    [
        "p_x**2/2 + p_y**2/2*(2 + tanh(x)) + a*sin(x)*cos(y) + exp(x/4)*log(3 + y)",
        "sqrt(5 + x**2) + atan(x*y) + asin(y/3) + acos(x/4) + atan2(y, 3 + x)",
        "b*sinh(x/2)*cosh(y/3) + tan(y/2) + (2 + x)**1.5 + (4 + y)**(-2.5) + x**3*y**2",
        "(2 + cos(t))*x + p_x*(asin(y/3) + acos(x/4) + atan(x*y) + atan2(y, 3 + x))",
    ]
)
EVERY_FUNCTION = f"""
title = "every function"
[system]
coordinates = ["x", "y"]
parameters = {{ a = 0.7, b = 1.3 }}
hamiltonian = "{EVERY_HAMILTONIAN}"
[initial]
x = 0.3
y = -0.2
p_x = 0.4
p_y = 0.1
"""


def _mechanics(name):
    if name == "every_function":
        return derive(parse_scene(EVERY_FUNCTION))
    return derive(load_scene(name))


def _euler_series(mechanics, t0, y0, P, order, bits=100):
    """[y]_k, (order + 1, m): the k-th forward difference of Euler's iterates at step
    h = 2**-bits over h**k k!, which is [y]_k + O(h), in arithmetic wide enough
    (bits * (order + 2)) that dividing by h**k leaves the O(h) as the only error."""
    symbols = [
        mechanics.t,
        *mechanics.q,
        *mechanics.p,
        *(mechanics.params[n] for n, _ in mechanics.scene.parameters),
    ]
    f = sp.lambdify(symbols, list(mechanics.hamilton_equations), modules="mpmath")
    with mpmath.workprec(bits * (order + 2)):
        h = mpmath.ldexp(1, -bits)
        t = mpmath.mpf(float(t0))
        y = [mpmath.mpf(float(v)) for v in y0]
        parameters = [mpmath.mpf(float(v)) for v in P]
        iterates = [y]
        for _ in range(order):
            y = [v + h * dv for v, dv in zip(y, f(t, *y, *parameters), strict=True)]
            t += h
            iterates.append(y)
        rows = []
        for k in range(order + 1):
            weights = [(-1) ** (k - i) * math.comb(k, i) for i in range(k + 1)]
            difference = [
                mpmath.fsum(w * state[j] for w, state in zip(weights, iterates, strict=False))
                for j in range(len(y))
            ]
            rows.append([float(d / (h**k * math.factorial(k))) for d in difference])
    return np.array(rows)


def test_the_harmonic_oscillator_has_the_cosine_and_sine_series():
    mechanics = _mechanics("harmonic_oscillator")
    d = decomposition_of(mechanics)
    omega = math.sqrt(1.7 / 0.8)
    c = taylor_coefficients(d, 0.0, [1.0, 0.0], [0.8, 1.7], 20)  # m = 0.8, k = 1.7
    k = np.arange(21)
    factorials = np.array([math.factorial(j) for j in k], dtype=float)
    cosine = np.where(k % 2 == 0, (-1.0) ** (k // 2) * omega**k / factorials, 0.0)
    sine = np.where(k % 2 == 1, (-1.0) ** (k // 2) * omega**k / factorials, 0.0)
    np.testing.assert_allclose(c[:, 0], cosine, rtol=1e-14, atol=0)
    np.testing.assert_allclose(c[:, 1], -0.8 * omega * sine, rtol=1e-14, atol=0)


@pytest.mark.parametrize(
    ("name", "order"),
    [
        ("kepler_cartesian", 12),
        ("planetary_motion", 14),
        ("double_pendulum", 12),
        ("every_function", 10),
    ],
)
def test_the_coefficients_are_those_of_eulers_differences_in_high_precision(name, order):
    mechanics = _mechanics(name)
    d = decomposition_of(mechanics)
    P = np.array([v for _, v in mechanics.scene.parameters]) * 1.1
    rng = np.random.default_rng(3)
    y0 = np.array([v for _, v in mechanics.scene.initial], dtype=float)
    y0 = y0 + rng.uniform(-0.1, 0.1, y0.shape)
    got = taylor_coefficients(d, 0.4, y0, P, order)
    exact = _euler_series(mechanics, 0.4, y0, P, order)
    for k in range(order + 1):
        scale = np.abs(exact[k]).max()
        assert np.abs(got[k] - exact[k]).max() <= 1e-13 * scale, (k, got[k] - exact[k])


@pytest.mark.parametrize("name", ["kepler_cartesian", "planetary_motion", "double_pendulum"])
def test_order_20_steps_reproduce_a_tight_dop853_run(name):
    from scipy.integrate import solve_ivp

    from systems.compiled import compile_system
    from systems.taylor.coefficients import horner

    mechanics = _mechanics(name)
    compiled = compile_system(mechanics, ("rhs",))
    d = decomposition_of(mechanics)
    P = compiled.parameters
    y = compiled.initial_state()
    t, h = 0.0, 0.01  # the double pendulum's series converges within about 0.4 at its start
    for _ in range(50):
        y = horner(taylor_coefficients(d, t, y, P, 20), h)
        t += h
    reference = solve_ivp(
        compiled.rhs, (0.0, t), compiled.initial_state(), method="DOP853", rtol=2.3e-14, atol=1e-16
    ).y[:, -1]
    assert np.abs(y - reference).max() <= 1e-13 * np.abs(reference).max()


def test_the_decomposition_evaluates_to_the_equations_and_shares_subexpressions():
    mechanics = _mechanics("every_function")
    d = decomposition_of(mechanics)
    rhs = sp.lambdify(
        [
            mechanics.t,
            *mechanics.q,
            *mechanics.p,
            *(mechanics.params[n] for n, _ in mechanics.scene.parameters),
        ],
        list(mechanics.hamilton_equations),
    )
    rng = np.random.default_rng(5)
    Y = rng.uniform(-0.5, 0.5, (50, 4))
    got = evaluate(d, 0.3, Y, [0.7, 1.3])
    exact = np.array([rhs(0.3, *y, 0.7, 1.3) for y in Y], dtype=float)
    np.testing.assert_allclose(got, exact, rtol=1e-13, atol=1e-14)
    keys = [(node.op, node.args) for node in d.nodes]
    assert len(keys) == len(set(keys))  # every node once
    counts = d.counts()
    for op in ("sin", "cos", "sinh", "cosh", "tan", "tanh", "asin", "acos", "atan", "atan2"):
        assert counts.get(op, 0) >= 1, op


def test_refusals_name_the_reason():
    x, y = sp.symbols("x y")
    with pytest.raises(NotDecomposable, match="gamma"):
        decompose([sp.gamma(x), y], [x, y])
    with pytest.raises(NotDecomposable, match="unknown symbol z"):
        decompose([sp.Symbol("z"), y], [x, y])
    chain = derive(load_scene("pendulum_chain"))
    if chain.matrix_form is not None:
        with pytest.raises(NotDecomposable, match="matrix form"):
            decompose_mechanics(chain)
