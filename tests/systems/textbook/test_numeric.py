"""The textbook's numeric functions never cut a complex value to its real part."""

import warnings

import numpy as np
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
