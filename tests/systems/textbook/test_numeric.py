"""The textbook's numeric functions never cut a complex value to its real part."""

import warnings

import numpy as np
import pytest
import sympy

from systems.textbook._numeric import vectorize


def test_a_complex_value_is_nan_not_its_real_part():
    x = sympy.Symbol("x", real=True)
    # numpy's power of a complex base: (x + i)**2 = x**2 - 1 + 2 i x, real only at x = 0
    f = vectorize([(x + sympy.I) ** 2, x + 1], [x])
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no ComplexWarning: nothing is cast away
        at_points = f(np.array([0.0, 2.0]))
        one = f(2.0)
    assert at_points[0, 0] == -1.0 and np.isnan(at_points[0, 1])
    assert np.array_equal(at_points[1], [1.0, 3.0])
    assert np.isnan(one[0]) and one[1] == 3.0


def test_an_angle_inside_sines_and_cosines_is_periodic_without_evaluating(monkeypatch):
    """A chain's L needs no lambdify to know its angles are periodic (issue 26 item 6)."""
    import systems.textbook._numeric as numeric

    x, y, v = sympy.symbols("x y v", real=True)
    L = v**2 * sympy.cos(x - y) / 2 + sympy.cos(x) + 2 * sympy.cos(2 * y)
    monkeypatch.setattr(numeric, "vectorize", None)  # any evaluation would fail
    assert numeric.periodic_symbols(L, [x, y], [v]) == {x, y}


@pytest.mark.parametrize(
    ("expr", "proved"),
    [
        ("cos(x)", True),
        ("sin(x - y)*cos(2*x) + y**2", True),
        ("cos(-x + 1)", True),
        ("cos(x/2)", False),  # 4 pi-periodic: left to the numeric test
        ("x*cos(x)", False),
        ("cos(x*y)", False),
        ("cos(pi*x)", False),
    ],
)
def test_trigonometric_only_proves_periodicity_only_where_it_holds(expr, proved):
    from systems.textbook._numeric import _trigonometric_only

    x, y = sympy.symbols("x y", real=True)
    assert _trigonometric_only(sympy.sympify(expr, locals={"x": x, "y": y}), x) is proved


def test_the_numeric_test_still_decides_what_the_structure_cannot():
    from systems.textbook._numeric import periodic_symbols

    x, y = sympy.symbols("x y", real=True)
    assert periodic_symbols(sympy.cos(x / 2) + sympy.cos(y), [x, y], []) == {y}
    assert periodic_symbols(sympy.exp(sympy.cos(x)) * sympy.cos(3 * y), [x, y], []) == {x, y}
