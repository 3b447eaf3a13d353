"""Whitelist parser: expression text from a user or a scene file -> sympy expression.

Text is never handed to ``eval``, ``sympify`` or ``parse_expr``. It is parsed by Python's
``ast`` (which only builds a tree and runs nothing), every node is checked against a short
whitelist, and the sympy expression is built node by node. Sizes are bounded so no input
can hang the program: text length, nesting depth, literal size, and the size of powers
with numeric exponents.
"""

from __future__ import annotations

import ast
import difflib
import io
import keyword
import math
import numbers
import re
import tokenize
from collections.abc import Callable, Mapping

import sympy

MAX_TEXT = 20_000
MAX_DEPTH = 60
MAX_LITERAL_DIGITS = 60
MAX_INTEGER_EXPONENT = 100
MAX_RESULT_DIGITS = 300

FUNCTIONS: dict[str, Callable[..., sympy.Expr]] = {
    "sin": sympy.sin,
    "cos": sympy.cos,
    "tan": sympy.tan,
    "exp": sympy.exp,
    "log": sympy.log,
    "sqrt": sympy.sqrt,
    "sinh": sympy.sinh,
    "cosh": sympy.cosh,
    "tanh": sympy.tanh,
    "asin": sympy.asin,
    "acos": sympy.acos,
    "atan": sympy.atan,
    "atan2": sympy.atan2,
    "Abs": sympy.Abs,
    "abs": sympy.Abs,
}
ARITY = {name: 1 for name in FUNCTIONS} | {"atan2": 2}
MAX_CONSTANT = 1e100
FLOAT_FUNCTIONS: dict[str, Callable[..., float]] = {
    "sin": math.sin,
    "cos": math.cos,
    "tan": math.tan,
    "exp": math.exp,
    "log": math.log,
    "sqrt": math.sqrt,
    "sinh": math.sinh,
    "cosh": math.cosh,
    "tanh": math.tanh,
    "asin": math.asin,
    "acos": math.acos,
    "atan": math.atan,
    "atan2": math.atan2,
    "Abs": abs,
    "abs": abs,
}
CONSTANTS: dict[str, sympy.Expr] = {"pi": sympy.pi}
RESERVED = frozenset(FUNCTIONS) | frozenset(CONSTANTS) | {"t"}


class ExpressionError(ValueError):
    """An expression the parser refuses, with where and why.

    Attributes
    ----------
    field : str or None
        Where the text came from, e.g. ``"system.kinetic"``.
    text : str
        The text as the user typed it.
    position : int or None
        1-based column of the offending character.
    reason : str
        What is wrong, in words that say what to fix.
    """

    def __init__(
        self, reason: str, *, text: str, field: str | None = None, position: int | None = None
    ):
        self.reason = reason
        self.text = text
        self.field = field
        self.position = position
        super().__init__(str(self))

    def __str__(self) -> str:
        where = f"{self.field}: " if self.field else ""
        at = f" (at position {self.position})" if self.position else ""
        return f"{where}{self.reason}{at}"

    def __reduce__(self):
        return (_rebuild_error, (self.reason, self.text, self.field, self.position))

    def with_field(self, field: str) -> ExpressionError:
        """A copy of this error attributed to ``field``."""
        return ExpressionError(self.reason, text=self.text, field=field, position=self.position)


def _rebuild_error(reason, text, field, position) -> ExpressionError:
    return ExpressionError(reason, text=text, field=field, position=position)


def check_name(name: object, *, field: str | None = None) -> str:
    """Validate a coordinate or parameter name and return it.

    Raises
    ------
    ExpressionError
        If the name is not a plain identifier, is a Python keyword, a function or
        constant name, ``t``, or starts with an underscore.
    """
    text = str(name)
    if not isinstance(name, str) or not name.isidentifier() or not name.isascii():
        reason = f"{text!r} is not a valid name: use letters, digits and underscores"
    elif keyword.iskeyword(name):
        reason = f"{name!r} is a reserved word; choose another name"
    elif name.startswith("_"):
        reason = f"{name!r} may not start with an underscore"
    elif name in RESERVED:
        reason = f"{name!r} is a built-in name (function, constant or time); choose another"
    else:
        return name
    raise ExpressionError(reason, text=text, field=field)


def parse_expression(
    text: str, symbols: Mapping[str, sympy.Basic], *, field: str | None = None
) -> sympy.Expr:
    """Parse ``text`` into a sympy expression using only whitelisted constructs.

    Parameters
    ----------
    text
        The expression, e.g. ``"m*l**2*theta_dot**2/2"``. ``^`` is read as a power.
    symbols
        Every name the expression may use, mapped to its sympy object.
    field
        Where the text came from, for error messages.

    Returns
    -------
    sympy.Expr

    Raises
    ------
    ExpressionError
        With the reason and the 1-based position of the offending part.
    """
    if not isinstance(text, str):
        if isinstance(text, bool) or not isinstance(text, int | float):
            raise ExpressionError("expected an expression in quotes", text=str(text), field=field)
        text = repr(text)
    source = text.replace("^", "**")
    if not source.strip():
        raise ExpressionError("the expression is empty", text=text, field=field)
    if len(source) > MAX_TEXT:
        raise ExpressionError(
            f"the expression is too long ({len(source)} characters; limit {MAX_TEXT})",
            text=text,
            field=field,
        )
    if "\n" in source.strip() or ";" in source:
        raise ExpressionError("write one expression on one line", text=text, field=field)
    depth = _bracket_depth(source)
    if depth > MAX_DEPTH:
        raise ExpressionError(
            f"the expression is nested too deeply ({depth} levels; limit {MAX_DEPTH})",
            text=text,
            field=field,
        )
    try:
        tree = ast.parse(source.strip(), mode="eval")
    except SyntaxError as exc:
        hint = _writing_hint(source, symbols)
        if hint is not None:
            reason, at = hint
            position = _original_position(text, at)
        else:
            reason = f"syntax error: {_syntax_reason(exc)}"
            position = _original_position(text, exc.offset) if exc.offset else len(text)
        raise ExpressionError(reason, text=text, field=field, position=position) from None
    except (RecursionError, MemoryError):
        raise ExpressionError(
            f"the expression is nested too deeply (limit {MAX_DEPTH})", text=text, field=field
        ) from None
    except ValueError:
        raise ExpressionError("the expression cannot be read", text=text, field=field) from None
    offset = len(source) - len(source.lstrip())
    builder = _Builder(text, symbols, field, offset)
    builder.value(tree.body, 0)
    try:
        return builder.build(tree.body, 0)
    except ExpressionError:
        raise
    except Exception as exc:  # sympy's own evaluation failed: report it, never crash
        raise ExpressionError(
            f"the expression cannot be evaluated ({type(exc).__name__})", text=text, field=field
        ) from None


def _original_position(text: str, position: int) -> int:
    """Map a 1-based column of the text with ``^`` written as ``**`` back to ``text``."""
    seen = 0
    for index, char in enumerate(text):
        seen += 2 if char == "^" else 1
        if seen >= position:
            return index + 1
    return len(text)


def _short(expr: object, limit: int = 24) -> str:
    text = str(expr)
    return text if len(text) <= limit else text[: limit - 3] + "..."


def _bracket_depth(source: str) -> int:
    depth = deepest = 0
    for char in source:
        if char in "([{":
            depth += 1
            deepest = max(deepest, depth)
        elif char in ")]}":
            depth -= 1
    return deepest


_ENDS_OPERAND = {tokenize.NUMBER, tokenize.NAME}
_OPERATORS = {"+", "-", "*", "/", "**"}


def _writing_hint(source: str, symbols: Mapping[str, sympy.Basic]) -> tuple[str, int] | None:
    """What to fix in text Python cannot read, in a student's words, with its 1-based
    column in ``source``: a velocity written ``x'``, a missing ``*`` (``2 x``, ``3x``,
    ``m/2 (a + b)``), a function without brackets (``sin x``), an expression ending in
    an operator. None where no such slip is found (Python's own reason is given)."""
    prime = re.search(r"([A-Za-z_]\w*)\s*'", source)
    if prime is not None:
        name = prime.group(1)
        return f"a velocity is written {name}_dot, not {name}'", prime.end()
    try:
        tokens = [
            t
            for t in tokenize.generate_tokens(io.StringIO(source).readline)
            if t.type not in (tokenize.NEWLINE, tokenize.NL, tokenize.ENDMARKER, tokenize.INDENT)
        ]
    except (tokenize.TokenError, SyntaxError, IndentationError):
        return None
    for before, after in zip(tokens, tokens[1:], strict=False):
        column = after.start[1] + 1
        if before.type == tokenize.NAME and before.string in FUNCTIONS:
            if after.type in _ENDS_OPERAND:
                return (
                    f"write {before.string}({after.string}): a function's argument goes in "
                    "brackets",
                    column,
                )
            continue
        ends = before.type in _ENDS_OPERAND or before.string == ")"
        starts = after.type in _ENDS_OPERAND or after.string == "("
        if ends and starts and not keyword.iskeyword(after.string):
            if before.string == ")" or after.string == "(":
                return f"missing * before {after.string}", column
            return (
                f"missing * between {before.string} and {after.string}: write "
                f"{before.string}*{after.string}",
                column,
            )
    if tokens and tokens[-1].string in _OPERATORS:
        last = tokens[-1]
        return f"the expression ends with {last.string}: something is missing after it", (
            last.start[1] + 1
        )
    return None


def _syntax_reason(exc: SyntaxError) -> str:
    message = exc.msg or "invalid syntax"
    if "digits" in message and "limit" in message:
        return f"a number is too long (limit {MAX_LITERAL_DIGITS} digits)"
    return message[0].lower() + message[1:] if message else "invalid syntax"


_BINARY = {
    ast.Add: lambda a, b: a + b,
    ast.Sub: lambda a, b: a - b,
    ast.Mult: lambda a, b: a * b,
    ast.Div: lambda a, b: a / b,
}
_ADDITIVE = (ast.Add, ast.Sub)
_MULTIPLICATIVE = (ast.Mult, ast.Div)
_INVERSE = {
    None: lambda a: a,
    ast.Add: lambda a: a,
    ast.Sub: lambda a: -a,
    ast.Mult: lambda a: a,
    ast.Div: lambda a: sympy.Pow(a, -1),
}


def _chain(node: ast.BinOp) -> list[tuple[type | None, ast.AST, ast.AST]]:
    """The operands of a chain such as ``a + b - c + d`` or ``a*b/c``, left to right.

    Python's ``ast`` nests ``a + b + c`` to the left, so a flat sum of 300 terms is a tree
    300 deep; taken as one chain (of + and -, or of * and /), its depth is 1, and a long
    sum written out by hand is not mistaken for deep nesting. Returns (operator before the
    operand, None for the first; operand; the node to point at in a message).
    """
    family = _ADDITIVE if isinstance(node.op, _ADDITIVE) else _MULTIPLICATIVE
    items = []
    while isinstance(node, ast.BinOp) and isinstance(node.op, family):
        items.append((type(node.op), node.right, node))
        node = node.left
    items.append((None, node, node))
    items.reverse()
    return items


_FLOAT_BINARY = {
    ast.Add: lambda a, b: a + b,
    ast.Sub: lambda a, b: a - b,
    ast.Mult: lambda a, b: a * b,
    ast.Div: lambda a, b: a / b,
    ast.Pow: lambda a, b: a**b,
}
_OPERATOR_NAMES = {
    ast.FloorDiv: "//",
    ast.Mod: "%",
    ast.MatMult: "@",
    ast.LShift: "<<",
    ast.RShift: ">>",
    ast.BitOr: "|",
    ast.BitAnd: "&",
    ast.BitXor: "^",
}
_FORBIDDEN = {
    ast.Attribute: "attribute access ('.') is not allowed",
    ast.Subscript: "indexing with [] is not allowed",
    ast.Lambda: "lambda is not allowed",
    ast.Compare: "comparisons are not allowed in an expression",
    ast.BoolOp: "'and'/'or' are not allowed",
    ast.IfExp: "'if ... else' is not allowed",
    ast.List: "lists are not allowed",
    ast.Tuple: "tuples are not allowed: use one expression",
    ast.Dict: "dictionaries are not allowed",
    ast.Set: "sets are not allowed",
    ast.ListComp: "comprehensions are not allowed",
    ast.SetComp: "comprehensions are not allowed",
    ast.DictComp: "comprehensions are not allowed",
    ast.GeneratorExp: "generators are not allowed",
    ast.JoinedStr: "strings are not allowed",
    ast.NamedExpr: "':=' is not allowed",
    ast.Starred: "'*' unpacking is not allowed",
    ast.Await: "'await' is not allowed",
    ast.Yield: "'yield' is not allowed",
}


class _Builder:
    def __init__(self, text: str, symbols: Mapping[str, sympy.Basic], field: str | None, offset):
        self.text = text
        self.source = text.replace("^", "**").strip()  # what ``ast`` read
        self.symbols = symbols
        self.field = field
        self.offset = offset

    def fail(self, reason: str, node: ast.AST | None = None) -> ExpressionError:
        position = None
        if node is not None and hasattr(node, "col_offset"):
            position = _original_position(self.text, node.col_offset + 1 + self.offset)
        return ExpressionError(reason, text=self.text, field=self.field, position=position)

    def value(self, node: ast.AST, depth: int) -> float | None:
        """The float value of a constant subtree (None if it uses a symbol), bounded.

        Computed with plain floats before sympy sees the expression, so that constants
        which overflow, are complex or undefined are refused instead of handed to sympy's
        unbounded exact evaluation (``exp(exp(exp(100)))`` would never return).
        """
        if depth > MAX_DEPTH:
            raise self.fail(f"the expression is nested too deeply (limit {MAX_DEPTH})", node)
        try:
            result = self._value(node, depth)
        except ExpressionError:
            raise
        except OverflowError:
            raise self.fail("a number in the expression is too large", node) from None
        except ZeroDivisionError:
            raise self.fail("division by zero", node) from None
        except ValueError:
            reason = "a constant in the expression is undefined for real numbers"
            raise self.fail(reason, node) from None
        if result is None:
            return None
        if isinstance(result, complex):
            raise self.fail("a constant in the expression is not a real number", node)
        if not math.isfinite(result) or abs(result) > MAX_CONSTANT:
            raise self.fail(
                f"a number in the expression is too large (limit {MAX_CONSTANT:g})", node
            )
        return float(result)

    def _value(self, node: ast.AST, depth: int):
        match node:
            case ast.Constant(value=value) if isinstance(value, int | float) and not isinstance(
                value, bool
            ):
                if isinstance(value, int) and value.bit_length() > MAX_LITERAL_DIGITS * 3.33:
                    raise self.fail(
                        f"the number is too long (limit {MAX_LITERAL_DIGITS} digits)", node
                    )
                return float(value)
            case ast.Name(id=name) if name in CONSTANTS and name not in self.symbols:
                return math.pi
            case ast.UnaryOp(op=ast.USub() | ast.UAdd() as op, operand=operand):
                inner = self.value(operand, depth + 1)
                return None if inner is None else (-inner if isinstance(op, ast.USub) else inner)
            case ast.BinOp(op=ast.Add() | ast.Sub() | ast.Mult() | ast.Div()):
                total = None
                values = [(op, self.value(operand, depth + 1)) for op, operand, _ in _chain(node)]
                if any(v is None for _, v in values):
                    return None
                for op, v in values:
                    total = v if op is None else _FLOAT_BINARY[op](total, v)
                return total
            case ast.BinOp(op=ast.Pow() as op):
                a = self.value(node.left, depth + 1)
                b = self.value(node.right, depth + 1)
                if a is None or b is None:
                    return None
                return _FLOAT_BINARY[type(op)](a, b)
            case ast.Call(func=ast.Name(id=name), args=args) if name in FLOAT_FUNCTIONS:
                values = [self.value(arg, depth + 1) for arg in args]
                if any(v is None for v in values) or len(values) != ARITY[name]:
                    return None
                return FLOAT_FUNCTIONS[name](*values)
        for child in ast.iter_child_nodes(node):
            self.value(child, depth + 1)
        return None

    def build(self, node: ast.AST, depth: int) -> sympy.Expr:
        if depth > MAX_DEPTH:
            raise self.fail(f"the expression is nested too deeply (limit {MAX_DEPTH})", node)
        match node:
            case ast.Constant(value=value):
                return self.constant(value, node)
            case ast.Name(id=name):
                return self.name(name, node)
            case ast.UnaryOp(op=ast.USub(), operand=operand):
                return -self.build(operand, depth + 1)
            case ast.UnaryOp(op=ast.UAdd(), operand=operand):
                return self.build(operand, depth + 1)
            case ast.UnaryOp():
                raise self.fail("only + and - may stand before a term", node)
            case ast.BinOp(op=ast.Pow(), left=left, right=right):
                return self.power(self.build(left, depth + 1), self.build(right, depth + 1), node)
            case ast.BinOp(op=op) if type(op) in _BINARY:
                parts = []
                for kind, operand, at in _chain(node):
                    part = self.build(operand, depth + 1)
                    if kind is ast.Div and part == 0:
                        raise self.fail("division by zero", at)
                    parts.append(_INVERSE[kind](part))
                result = sympy.Add(*parts) if type(op) in _ADDITIVE else sympy.Mul(*parts)
                self.check_size(result, node)
                return result
            case ast.BinOp(op=op):
                symbol = _OPERATOR_NAMES.get(type(op), "this operator")
                raise self.fail(f"the operator {symbol} is not allowed; use + - * / **", node)
            case ast.Call():
                return self.call(node, depth)
        for kind, reason in _FORBIDDEN.items():
            if isinstance(node, kind):
                raise self.fail(reason, node)
        raise self.fail(f"{type(node).__name__} is not allowed in an expression", node)

    def constant(self, value: object, node: ast.AST) -> sympy.Expr:
        if isinstance(value, bool) or not isinstance(value, int | float):
            if isinstance(value, complex):
                raise self.fail("complex numbers are not allowed", node)
            if isinstance(value, str | bytes):
                raise self.fail("strings are not allowed in an expression", node)
            raise self.fail(f"{value!r} is not a number", node)
        if isinstance(value, int):
            if value.bit_length() > MAX_LITERAL_DIGITS * 3.33:
                raise self.fail(f"the number is too long (limit {MAX_LITERAL_DIGITS} digits)", node)
            return sympy.Integer(value)
        if not math.isfinite(value):
            raise self.fail("the number is too large", node)
        return sympy.Float(value)

    def name(self, name: str, node: ast.AST) -> sympy.Expr:
        if name.startswith("__") or name.endswith("__"):
            raise self.fail(f"the name {name!r} is not allowed", node)
        if name in self.symbols:
            return self.symbols[name]
        if name in CONSTANTS:
            return CONSTANTS[name]
        if name in FUNCTIONS:
            raise self.fail(f"{name} is a function: write {name}(...)", node)
        known = ", ".join(sorted(self.symbols)) or "none"
        close = difflib.get_close_matches(name, list(self.symbols), n=1, cutoff=0.75)
        guess = f"; did you mean {close[0]}?" if close else ""
        raise self.fail(f"unknown name {name!r}{guess} (known names: {known})", node)

    def call(self, node: ast.Call, depth: int) -> sympy.Expr:
        if isinstance(node.func, ast.Constant | ast.BinOp | ast.UnaryOp | ast.Call):
            before = ast.get_source_segment(self.source, node.func) or "the number"
            if isinstance(node.func, ast.BinOp | ast.UnaryOp):
                before = f"({before})"
            raise self.fail(f"missing * between {before} and (: write {before}*(...)", node)
        if not isinstance(node.func, ast.Name):
            raise self.fail("only the listed functions may be called, by name", node)
        name = node.func.id
        if name in self.symbols:
            raise self.fail(f"{name} is not a function: write {name}*(...) for a product", node)
        if name not in FUNCTIONS:
            allowed = ", ".join(sorted(set(FUNCTIONS) - {"abs"}))
            raise self.fail(f"unknown function {name!r} (allowed: {allowed})", node)
        if node.keywords:
            raise self.fail(f"{name}() takes no keyword arguments", node)
        if len(node.args) != ARITY[name]:
            count = ARITY[name]
            raise self.fail(f"{name}() takes {count} argument{'s' if count > 1 else ''}", node)
        args = [self.build(arg, depth + 1) for arg in node.args]
        result = FUNCTIONS[name](*args)
        self.check_size(result, node)
        return result

    def power(self, base: sympy.Expr, exponent: sympy.Expr, node: ast.AST) -> sympy.Expr:
        if exponent.is_Number:
            if abs(float(exponent)) > MAX_INTEGER_EXPONENT:
                raise self.fail(
                    f"the exponent {_short(exponent)} is too large (limit {MAX_INTEGER_EXPONENT})",
                    node,
                )
            if base.is_Rational and base != 0:
                # the exact value's size: digits of numerator and denominator, times the
                # exponent (log10|base| alone is negative for |base| < 1 and let
                # (10**-60)**100 through to sympy, which then never returned)
                digits = abs(float(exponent)) * _exact_digits(base)
                if digits > MAX_RESULT_DIGITS:
                    raise self.fail("the power is too large to compute exactly", node)
        elif exponent.is_number:
            magnitude = self.value(node.right, 0)
            if magnitude is not None and abs(magnitude) > MAX_INTEGER_EXPONENT:
                raise self.fail("the exponent is too large", node)
        if base == 0 and exponent.is_Number and exponent < 0:
            raise self.fail("division by zero (0 to a negative power)", node)
        result = sympy.Pow(base, exponent)
        self.check_size(result, node)
        return result

    def check_size(self, result: sympy.Expr, node: ast.AST) -> None:
        for power in result.atoms(sympy.Pow):
            if power.exp.is_Integer and abs(power.exp) > MAX_INTEGER_EXPONENT:
                raise self.fail(
                    f"the combined exponent {_short(power.exp)} is too large "
                    f"(limit {MAX_INTEGER_EXPONENT})",
                    node,
                )
        if result.is_Rational and _exact_digits(result) > MAX_RESULT_DIGITS:
            raise self.fail("the number is too large to compute exactly", node)
        if result is sympy.zoo or result is sympy.nan or result.has(sympy.zoo, sympy.nan):
            raise self.fail("the expression is undefined (division by zero)", node)


def _exact_digits(number: sympy.Rational) -> float:
    """Decimal digits of a rational's numerator and denominator together."""
    bits = abs(int(number.p)).bit_length() + abs(int(number.q)).bit_length()
    return bits * math.log10(2.0)


def as_expr(value: sympy.Basic | int | float) -> sympy.Basic:
    """A sympy object for a sympy object (or matrix), a symengine object or a plain number.

    Never parses text: ``sympy.sympify`` would ``eval`` a string, so every conversion of
    a derived value goes through here (user text goes through ``parse_expression``).
    """
    if isinstance(value, sympy.Basic | sympy.MatrixBase):
        return value
    if isinstance(value, str | bytes | bool):
        raise TypeError(f"expected a sympy expression or a number, got {type(value).__name__}")
    if isinstance(value, numbers.Integral):
        return sympy.Integer(int(value))
    if isinstance(value, numbers.Real):
        return sympy.Float(float(value))
    convert = getattr(type(value), "_sympy_", None)  # symengine's objects
    if convert is None:
        raise TypeError(f"expected a sympy expression or a number, got {type(value).__name__}")
    return convert(value)
