"""Property tests (hypothesis): random expression trees written with the parser's
functions (``systems.expressions.FUNCTIONS``), parsed by the whitelist parser, decompose
into nodes whose values are the expression's at random points, and whose first-order
coefficients along a random direction are its directional derivative (sympy's diff)."""

import numpy as np
import sympy as sp
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from systems.expressions import FUNCTIONS, parse_expression
from systems.taylor.coefficients import output_series
from systems.taylor.decompose import decompose

NAMES = ("x", "y", "a", "t")
SYMBOLS = {name: sp.Symbol(name, real=True) for name in NAMES}
X, Y, A, T = (SYMBOLS[name] for name in NAMES)
# each function with its argument kept inside its domain (and away from overflow)
WRAPPED = {
    "sin": "sin({})",
    "cos": "cos({})",
    "tan": "tan(tanh({}))",
    "exp": "exp(tanh({}))",
    "log": "log(1 + ({})**2)",
    "sqrt": "sqrt(1 + ({})**2)",
    "sinh": "sinh(tanh({}))",
    "cosh": "cosh(tanh({}))",
    "tanh": "tanh({})",
    "asin": "asin(tanh({})/2)",
    "acos": "acos(tanh({})/2)",
    "atan": "atan({})",
    "Abs": "Abs(2 + tanh({}))",
    "abs": "abs(2 + tanh({}))",
}
BINARY = {
    "+": "({}) + ({})",
    "-": "({}) - ({})",
    "*": "({})*({})",
    "/": "({})/(2 + ({})**2)",
    "atan2": "atan2({}, 2 + ({})**2)",
    "power": "(1 + ({})**2)**(1.5 + tanh({})**2)",
    "cube": "({})**3 + ({})",
}
assert set(WRAPPED) | {"atan2"} == set(FUNCTIONS)

leaves = st.sampled_from(["x", "y", "a", "t", "0.5", "3", "pi", "a*x", "y/a"])
trees = st.recursive(
    leaves,
    lambda inner: st.one_of(
        st.tuples(st.sampled_from(sorted(WRAPPED)), inner).map(
            lambda p: WRAPPED[p[0]].format(p[1])
        ),
        st.tuples(st.sampled_from(sorted(BINARY)), inner, inner).map(
            lambda p: BINARY[p[0]].format(p[1], p[2])
        ),
    ),
    max_leaves=12,
)


@settings(
    deadline=None,
    derandomize=True,
    max_examples=60,
    database=None,
    suppress_health_check=[HealthCheck.too_slow],
)
@given(text=trees, other=trees)
def test_random_trees_decompose_to_their_values_and_derivatives(text, other):
    exprs = [parse_expression(text, SYMBOLS), parse_expression(other, SYMBOLS)]
    d = decompose(exprs, [X, Y], [A], T)
    rng = np.random.default_rng(len(text) + 7 * len(other))
    points = rng.uniform(-1.5, 1.5, (8, 4))  # t, x, y, a
    directions = rng.uniform(-1, 1, (8, 3))  # dt/dh = 1 always; dx, dy, and 0 for a
    values = sp.lambdify([T, X, Y, A], exprs)
    slopes = sp.lambdify(
        [T, X, Y, A, *sp.symbols("dx dy")],
        [
            sp.diff(e, T) + sp.diff(e, X) * sp.Symbol("dx") + sp.diff(e, Y) * sp.Symbol("dy")
            for e in exprs
        ],
    )
    for (t, x, y, a), (dx, dy, _) in zip(points, directions, strict=True):
        series = np.array([[x, y], [dx, dy]])
        got = output_series(d, t, series, [a])
        exact = np.array(values(t, x, y, a), dtype=float)
        slope = np.array(slopes(t, x, y, a, dx, dy), dtype=float)
        np.testing.assert_allclose(got[0], exact, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(got[1], slope, rtol=1e-10, atol=1e-10)
