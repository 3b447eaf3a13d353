"""Python source for the kernels' expressions, from sympy or straight from symengine.

Both printers write what numba compiles well: ``math.*`` calls, integer powers from 2 to
4 as products, square roots as ``math.sqrt``, every number as a float literal (integer
arithmetic in a kernel would be exact and slow, or overflow).

``engine_text`` prints a symengine expression without converting it back to sympy:
after symengine's common-subexpression elimination, the conversion back and sympy's
printer were two thirds of a double pendulum's kernel printing. It prints only the
nodes that the scene language can produce and their derivatives; anything else raises
``Unprintable``, and the caller prints through sympy (``SympyPrinter``) instead.
"""

from __future__ import annotations

import sympy
from sympy.printing.pycode import PythonCodePrinter

try:
    import symengine
except ImportError:  # pragma: no cover - a dependency; sympy alone is only slower
    symengine = None


class SympyPrinter(PythonCodePrinter):
    """Prints ``math.*`` calls numba understands; integer powers as multiplication."""

    def __init__(self) -> None:
        super().__init__({"fully_qualified_modules": True, "standard": "python3", "order": "none"})

    def _print_Pow(self, expr, rational=False):
        base, exponent = expr.as_base_exp()
        if exponent.is_Integer and 2 <= abs(int(exponent)) <= 4:
            factor = "*".join([self.parenthesize(base, 100)] * abs(int(exponent)))
            return f"({factor})" if exponent > 0 else f"(1.0/({factor}))"
        if exponent == sympy.Rational(1, 2):
            return f"math.sqrt({self._print(base)})"
        if exponent == -sympy.Rational(1, 2):
            return f"(1.0/math.sqrt({self._print(base)}))"
        return super()._print_Pow(expr, rational=rational)

    def _print_Rational(self, expr):
        return f"({float(expr.p)}/{float(expr.q)})"

    def _print_Integer(self, expr):
        return f"{float(expr.p)}"


class Unprintable(Exception):
    """``engine_text`` met a node it does not print; print through sympy."""


_CALLS = {
    "sin": "math.sin",
    "cos": "math.cos",
    "tan": "math.tan",
    "log": "math.log",
    "sinh": "math.sinh",
    "cosh": "math.cosh",
    "tanh": "math.tanh",
    "asin": "math.asin",
    "acos": "math.acos",
    "atan": "math.atan",
    "atan2": "math.atan2",
    "Abs": "abs",
}
"""symengine's function types -> what the kernels call (exp and sqrt arrive as Pow)."""


def engine_text(expr) -> str:
    """Python source for the symengine expression ``expr`` (symbols printed by name).

    Raises
    ------
    Unprintable
        For a node outside the scene language (complex numbers, infinities, unknown
        functions), or an expression nested too deeply to walk.
    """
    try:
        return _text(expr)
    except RecursionError:
        raise Unprintable("nested too deeply") from None


def _number(expr) -> str | None:
    """A float literal for a real number node, None for anything else."""
    if isinstance(expr, symengine.Integer):
        return repr(float(int(expr)))
    if isinstance(expr, symengine.Rational):
        p, q = expr.get_num_den()
        return f"({float(int(p))!r}/{float(int(q))!r})"
    if isinstance(expr, symengine.RealDouble):
        return repr(float(expr))
    return None


def _text(expr) -> str:
    number = _number(expr)
    if number is not None:
        return number
    if isinstance(expr, symengine.Symbol):
        return str(expr)
    kind = type(expr).__name__
    if kind == "Add":
        return " + ".join(_text(a) for a in expr.args)
    if kind == "Mul":
        return "*".join(_factor(a) for a in expr.args)
    if kind == "Pow":
        return _power(*expr.args)
    if kind == "Pi":
        return "math.pi"
    if kind == "Exp1":
        return "math.e"
    if kind == "sign":
        inner = _text(expr.args[0])
        return f"(0.0 if ({inner}) == 0.0 else math.copysign(1.0, {inner}))"
    call = _CALLS.get(kind)
    if call is None:
        raise Unprintable(f"no kernel form for {kind}")
    return f"{call}({', '.join(_text(a) for a in expr.args)})"


def _factor(expr) -> str:
    """A factor of a product: sums and negative numbers in parentheses."""
    text = _text(expr)
    if type(expr).__name__ == "Add" or text.startswith("-"):
        return f"({text})"
    return text


def _base(expr) -> str:
    """The base of a power: anything but a symbol or a non-negative number in
    parentheses."""
    text = _text(expr)
    if isinstance(expr, symengine.Symbol) or (
        _number(expr) is not None and not text.startswith("-")
    ):
        return text
    return f"({text})"


def _power(base, exponent) -> str:
    if type(base).__name__ == "Exp1":
        return f"math.exp({_text(exponent)})"
    if isinstance(exponent, symengine.Integer):
        k = int(exponent)
        if 2 <= abs(k) <= 4:
            product = "*".join([_base(base)] * abs(k))
            return f"({product})" if k > 0 else f"(1.0/({product}))"
        if k == -1:
            return f"(1.0/{_base(base)})"
    if isinstance(exponent, symengine.Rational) and not isinstance(exponent, symengine.Integer):
        p, q = (int(v) for v in exponent.get_num_den())
        if (p, q) == (1, 2):
            return f"math.sqrt({_text(base)})"
        if (p, q) == (-1, 2):
            return f"(1.0/math.sqrt({_text(base)}))"
    return f"{_base(base)}**{_base(exponent)}"
