"""Each elementary operation's Taylor coefficients against sympy's series, to 1e-14.

An operand is a random polynomial u(h) with float coefficients (exact rationals for
sympy); the decomposition of f(u) is run on its coefficients (``output_series``) and
compared with the series of f(u(h)) that sympy expands exactly, to order 20.
"""

import mpmath
import numpy as np
import pytest
import sympy as sp

from systems.taylor.coefficients import output_series
from systems.taylor.decompose import decompose

ORDER = 20
x, y, a = sp.symbols("x y a", real=True)

DIGITS = 50
mpmath.mp.dps = DIGITS


class Series:
    """A truncated power series in h with mpmath coefficients (ORDER + 1 of them)."""

    def __init__(self, c):
        self.c = [mpmath.mpf(v) for v in c]

    def __add__(self, other):
        return Series([u + v for u, v in zip(self.c, other.c, strict=True)])

    def __sub__(self, other):
        return Series([u - v for u, v in zip(self.c, other.c, strict=True)])

    def __mul__(self, other):
        if not isinstance(other, Series):
            return Series([u * other for u in self.c])
        return Series(
            [sum(self.c[j] * other.c[k - j] for j in range(k + 1)) for k in range(ORDER + 1)]
        )

    def __truediv__(self, other):
        q = []
        for k in range(ORDER + 1):
            q.append((self.c[k] - sum(other.c[j] * q[k - j] for j in range(1, k + 1))) / other.c[0])
        return Series(q)

    def apply(self, function, derivative=None):
        """function(self): the function's Taylor coefficients at the constant term from
        sympy (``series``; its derivative's series integrated where ``derivative`` is
        given, repeated differentiation for tan and tanh, whose series sympy expands
        slowly at a point), composed with the rest, exact to DIGITS."""
        z = sp.Symbol("z")
        x0 = sp.Float(mpmath.nstr(self.c[0], DIGITS), DIGITS)
        if derivative is not None:
            expansion = sp.series(derivative(x0 + z), z, 0, ORDER).removeO()
            g = [function(x0)] + [expansion.coeff(z, j - 1) / j for j in range(1, ORDER + 1)]
        elif function in (sp.tan, sp.tanh):
            g, e = [], function(z)
            for j in range(ORDER + 1):
                g.append(e.evalf(DIGITS, subs={z: x0}) / sp.factorial(j))
                e = sp.expand(sp.diff(e, z))
        else:
            expansion = sp.series(function(x0 + z), z, 0, ORDER + 1).removeO()
            g = [expansion.coeff(z, j) for j in range(ORDER + 1)]
        g = [mpmath.mpf(str(sp.N(v, DIGITS))) for v in g]
        tail = Series([0, *self.c[1:]])
        total = Series([g[0]] + [0] * ORDER)
        power = Series([1] + [0] * ORDER)
        for j in range(1, ORDER + 1):
            power = power * tail
            total = total + power * g[j]
        return total


def _asin_derivative(u):
    return 1 / sp.sqrt(1 - u**2)


def _acos_derivative(u):
    return -1 / sp.sqrt(1 - u**2)


def _seven_thirds(u):
    return u**SEVEN_THIRDS


def _inverse_sqrt(u):
    return 1 / sp.sqrt(u)


SEVEN_THIRDS = sp.Rational(7, 3)
A = sp.Float(1.75)


def _atan(X):
    return X.apply(sp.atan, lambda u: 1 / (1 + u**2))


CASES = {  # name: (expression, the same on Series, x_0 range, y_0 range); a = 1.75
    "add": (x + y, lambda X, Y: X + Y, (-1, 1), (-1, 1)),
    "sub": (x - 3 * y, lambda X, Y: X - Y * 3, (-1, 1), (-1, 1)),
    "mul": (x * y, lambda X, Y: X * Y, (-1, 1), (-1, 1)),
    "div": (x / y, lambda X, Y: X / Y, (-1, 1), (1, 2)),
    "constant over": (a / y, lambda X, Y: Series([1.75] + [0] * ORDER) / Y, (-1, 1), (1, 2)),
    "square": (x**2, lambda X, Y: X * X, (-1, 1), (-1, 1)),
    "integer power": (x**5 * y**-3, lambda X, Y: X * X * X * X * X / (Y * Y * Y), (-1, 1), (1, 2)),
    "real power": (x**SEVEN_THIRDS, lambda X, Y: X.apply(_seven_thirds), (0.5, 2), (0, 1)),
    "parameter power": (x**a, lambda X, Y: X.apply(lambda u: u**A), (0.5, 2), (0, 1)),
    "sqrt": (sp.sqrt(x), lambda X, Y: X.apply(sp.sqrt), (0.5, 2), (0, 1)),
    "inverse sqrt": (1 / sp.sqrt(x), lambda X, Y: X.apply(_inverse_sqrt), (0.5, 2), (0, 1)),
    "exp": (sp.exp(x), lambda X, Y: X.apply(sp.exp), (-1, 1), (0, 1)),
    "log": (sp.log(x), lambda X, Y: X.apply(sp.log), (0.5, 2), (0, 1)),
    "sin": (sp.sin(x), lambda X, Y: X.apply(sp.sin), (-2, 2), (0, 1)),
    "cos": (sp.cos(x), lambda X, Y: X.apply(sp.cos), (-2, 2), (0, 1)),
    "tan": (sp.tan(x), lambda X, Y: X.apply(sp.tan), (-1, 1), (0, 1)),
    "sinh": (sp.sinh(x), lambda X, Y: X.apply(sp.sinh), (-1, 1), (0, 1)),
    "cosh": (sp.cosh(x), lambda X, Y: X.apply(sp.cosh), (-1, 1), (0, 1)),
    "tanh": (sp.tanh(x), lambda X, Y: X.apply(sp.tanh), (-1, 1), (0, 1)),
    "asin": (sp.asin(x), lambda X, Y: X.apply(sp.asin, _asin_derivative), (-0.6, 0.6), (0, 1)),
    "acos": (sp.acos(x), lambda X, Y: X.apply(sp.acos, _acos_derivative), (-0.6, 0.6), (0, 1)),
    "atan": (sp.atan(x), lambda X, Y: _atan(X), (-2, 2), (0, 1)),
    "atan2": (sp.atan2(y, x), lambda X, Y: _atan(Y / X), (0.5, 2), (-1, 1)),
    "atan2 left": (sp.atan2(y, x), lambda X, Y: _atan(Y / X), (-2, -0.5), (-1, 1)),
    "abs": (sp.Abs(x), lambda X, Y: X * -1, (-2, -0.5), (0, 1)),
    "varying power": (y**x, lambda X, Y: (X * Y.apply(sp.log)).apply(sp.exp), (-1, 1), (0.5, 2)),
}  # fmt: skip


def _operand(rng, low, high):
    """Coefficients (ORDER + 1,) of a random operand, decaying like those of an analytic
    function with radius 2."""
    c = rng.uniform(-1, 1, ORDER + 1) / 2.0 ** np.arange(ORDER + 1)
    c[0] = rng.uniform(low, high)
    return c


@pytest.mark.parametrize("name", sorted(CASES))
def test_each_elementary_function_matches_sympys_series(name):
    expr, on_series, x_range, y_range = CASES[name]
    rng = np.random.default_rng(sorted(CASES).index(name))
    for _ in range(2):
        X, Y = _operand(rng, *x_range), _operand(rng, *y_range)
        d = decompose([expr, sp.Integer(0)], [x, y], [a])
        got = output_series(d, 0.0, np.stack([X, Y], axis=1), [1.75])[:, 0]
        exact = np.array([float(c) for c in on_series(Series(X), Series(Y)).c])
        if name == "atan2 left":  # atan(y / x) + pi: the same series beyond order 0
            exact[0] = float(mpmath.atan2(Y[0], X[0]))
        scale = np.abs(exact).max()
        assert np.abs(got - exact).max() <= 1e-14 * scale, (name, got - exact)
