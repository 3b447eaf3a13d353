"""The kernels' printers: symengine's text and sympy's agree in value on every node the
scene language makes, and what symengine cannot print goes back to sympy."""

from __future__ import annotations

import math

import pytest
import sympy
from hypothesis import given, settings
from hypothesis import strategies as st

from systems import calculus
from systems.codegen import build_module
from systems.kernel_printer import SympyPrinter, Unprintable, engine_text

symengine = pytest.importorskip("symengine")

x, y, z = sympy.symbols("x y z", real=True)
VALUES = {"x": 0.7, "y": -1.3, "z": 2.1}
NAMESPACE = {"math": math, **VALUES}

EXAMPLES = [
    x + y * z,
    -2 * x / y**2,
    sympy.Rational(3, 4) * x - sympy.Rational(-5, 7) / z,
    x ** sympy.Rational(1, 3) * z ** sympy.Rational(-1, 2),
    sympy.sqrt(z) + 1 / sympy.sqrt(x),
    sympy.exp(-x * y) + sympy.log(z),
    sympy.sin(x) ** 4 * sympy.cos(y) ** 3 - sympy.tan(z) ** -2,
    sympy.sinh(x) + sympy.cosh(y) + sympy.tanh(z),
    sympy.asin(x) + sympy.acos(x / 2) + sympy.atan(y),
    sympy.atan2(y, x) - sympy.Abs(y),
    sympy.pi * x + sympy.E**z,
    (x - y) ** 5 + (x + y) ** -3 + y**-1,
    (-y) ** 2 * x**z,
    sympy.Float(1.25) * x - 1e-300 * y,
    sympy.sign(y) * x,
    2 ** (x * z) + (y - 3) ** 2,
]


def _sympy_value(expr) -> float:
    return eval(SympyPrinter().doprint(expr), dict(NAMESPACE))  # noqa: S307 - our printer


def _engine_value(expr) -> float:
    return eval(engine_text(symengine.sympify(expr)), dict(NAMESPACE))  # noqa: S307


@pytest.mark.parametrize("expr", EXAMPLES, ids=str)
def test_both_printers_give_the_same_value(expr):
    expected = _sympy_value(expr)
    assert _engine_value(expr) == pytest.approx(expected, rel=1e-13, abs=1e-300)


ATOMS = st.sampled_from([x, y, z, sympy.Integer(2), sympy.Rational(-3, 5), sympy.pi])


def _combine(children):
    pair = st.tuples(children, children)
    return st.one_of(
        pair.map(lambda ab: ab[0] + ab[1]),
        pair.map(lambda ab: ab[0] * ab[1]),
        pair.map(lambda ab: ab[0] - ab[1]),
        children.map(sympy.sin),
        children.map(sympy.cos),
        st.tuples(children, st.integers(-4, 5)).map(lambda be: be[0] ** be[1]),
    )


@settings(max_examples=150, deadline=None)
@given(st.recursive(ATOMS, _combine, max_leaves=12))
def test_random_expressions_print_alike(expr):
    try:
        expected = _sympy_value(expr)
    except (ZeroDivisionError, OverflowError, ValueError):
        return
    if not math.isfinite(expected):
        return
    got = _engine_value(expr)
    assert got == pytest.approx(expected, rel=1e-9, abs=1e-9)


def test_a_node_outside_the_language_is_unprintable():
    with pytest.raises(Unprintable):
        engine_text(symengine.sympify(sympy.I * x))
    with pytest.raises(Unprintable):
        engine_text(symengine.sympify(sympy.gamma(x)))


def test_replaced_is_xreplace_without_evaluation():
    expr = sympy.sin(x) * y**2 + x * y / z
    mapping = {y: (x + z) / (x - z), z: sympy.cos(x) + 2}
    got = calculus.replaced(expr, mapping)
    want = expr.xreplace(mapping)
    at = {x: 0.3, z: 1.1}  # simultaneous: the z brought in by y's replacement stays
    assert float(got.subs(at)) == pytest.approx(float(want.subs(at)), rel=1e-14)
    assert calculus.replaced(expr, {}) is expr


def test_generated_functions_carry_their_module_file(tmp_path, monkeypatch):
    """The templates' code is compiled once per process, yet every generated module's
    functions name its own file and line: numba's cache and tracebacks go by them."""
    from systems import codegen

    monkeypatch.setenv("PHASE_EXPLORER_CACHE", str(tmp_path))
    monkeypatch.setattr(codegen, "_loaded", {})
    first = build_module("def rhs(t, y, P, out):\n    out[0] = y[0]\n")
    second = build_module("def rhs(t, y, P, out):\n    out[0] = 2.0*y[0]\n")
    drivers = codegen.driver_module()
    for module, names in (
        (first, ["rhs"]),
        (second, ["rhs"]),
        (drivers, ["dop853_step", "compose_run"]),
    ):
        text = open(module.__file__).read().splitlines()
        for name in names:
            code = getattr(module, name).py_func.__code__
            assert code.co_filename == module.__file__
            assert text[code.co_firstlineno - 1].startswith(f"def {name}(")
