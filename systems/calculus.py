"""Differentiation at C speed: symengine computes, sympy holds the results.

sympy's ``diff`` was three quarters of a pendulum chain's derivation (3.5 s of 6.5 s for
eight links); symengine differentiates the same Lagrangian in milliseconds. Expressions go
to symengine once, every derivative is taken there, and the results come back as sympy
expressions in the scene's own symbols (symengine keeps no assumptions, so its plain
symbols are replaced by the scene's real ones). Whatever symengine cannot represent or
differentiate in closed form (a ``Derivative`` left in a result) falls back to sympy.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence

import numpy as np
import sympy

from systems.expressions import FUNCTIONS, as_expr

try:
    import symengine
except ImportError:  # pragma: no cover - a dependency; sympy alone is only slower
    symengine = None


class Unsupported(Exception):
    """symengine could not take these derivatives; use sympy."""


def to_symengine(value):
    """``value`` (sympy, symengine or a number) as a symengine object; never parses text
    (``symengine.sympify`` would parse a string)."""
    if isinstance(value, symengine.Basic):
        return value
    return symengine.sympify(as_expr(value))


if symengine is not None:

    class SceneSymbol(symengine.Symbol):
        """A symengine symbol that turns back into the scene's own sympy symbol (with its
        assumptions): converting back and then replacing every symbol cost as much as
        the derivatives saved."""

        def __init__(self, name, original):
            self.original = original
            super().__init__(name, store_pickle=True)  # subclasses must, see Symbol

        def _sympy_(self):
            return self.original

        def __reduce__(self):
            return (SceneSymbol, (str(self), self.original))


# symengine's type names -> sympy constructors; sqrt and exp arrive as Pow
_SYMPY_NODES = {"Add": sympy.Add, "Mul": sympy.Mul, "Pow": sympy.Pow} | FUNCTIONS


def _converted(value, memo: dict) -> sympy.Expr:
    """``sympy.sympify(value)``, remembering every subexpression converted: a chain's
    equations repeat the same products of sines and cosines hundreds of times, and
    sympify converted each occurrence anew (two thirds of a twenty-link derivation)."""
    found = memo.get(value)
    if found is not None:
        return found
    node = _SYMPY_NODES.get(type(value).__name__)
    if node is None or isinstance(value, SceneSymbol):
        result = as_expr(value)
    else:
        result = node(*(_converted(a, memo) for a in value.args))
    memo[value] = result
    return result


class Calculus:
    """Derivatives of expressions in a fixed set of symbols.

    Parameters
    ----------
    symbols : iterable of sympy.Symbol
        Every symbol the expressions may contain (coordinates, velocities, momenta, t,
        parameters), with the assumptions the results must carry.
    """

    def __init__(self, symbols: Iterable[sympy.Symbol]):
        self.symbols = tuple(symbols)
        self._memo: dict = {}
        if symengine is not None:
            self._own = {s: SceneSymbol(s.name, s) for s in self.symbols}
            self._plain = {symengine.Symbol(s.name): self._own[s] for s in self.symbols}

    def to_engine(self, expr: sympy.Expr):
        """``expr`` as a symengine expression in symbols that convert back to the scene's."""
        if symengine is None:
            raise Unsupported("symengine is not installed")
        try:
            return to_symengine(expr).subs(self._plain)
        except (RuntimeError, TypeError, ValueError, NotImplementedError) as exc:
            raise Unsupported(str(exc)) from None

    def variable(self, symbol: sympy.Symbol):
        return self._own[symbol]

    def to_sympy(self, value) -> sympy.Expr:
        """A symengine result as sympy, in the scene's symbols."""
        expr = _converted(value, self._memo)
        if expr.has(sympy.Derivative, sympy.Subs):
            raise Unsupported("a derivative symengine left unevaluated")
        return expr

    def gradient(self, expr: sympy.Expr, variables: Sequence[sympy.Symbol]) -> list[sympy.Expr]:
        """[d expr / d v for v in variables], by symengine (sympy if it cannot)."""
        try:
            engine = self.to_engine(expr)
            return [self.to_sympy(engine.diff(self.variable(v))) for v in variables]
        except Unsupported:
            return [sympy.diff(expr, v) for v in variables]

    def lagrangian_parts(
        self,
        L: sympy.Expr,
        q: Sequence[sympy.Symbol],
        qd: Sequence[sympy.Symbol],
        t: sympy.Symbol,
    ) -> tuple[list, list[list], list, list]:
        """Momenta, velocity Hessian and the rest of Lagrange's equations of ``L``.

        Returns
        -------
        momenta : list of n expressions dL/dqdot_i
        hessian : n lists of n expressions d2L/dqdot_i dqdot_j (M for a quadratic L)
        gradient : list of n expressions dL/dq_i
        rest : list of n expressions sum_j dp_i/dq_j qdot_j + dp_i/dt (the total time
            derivative of p_i but for its accelerations)

        Raises
        ------
        Unsupported
            When symengine cannot do it; the caller differentiates with sympy instead.
        """
        n = len(q)
        engine = self.to_engine(L)
        qs = [self.variable(s) for s in q]
        vs = [self.variable(s) for s in qd]
        ts = self.variable(t)
        momenta = [engine.diff(v) for v in vs]
        hessian: list[list] = [[None] * n for _ in range(n)]
        for i in range(n):
            for j in range(i, n):
                hessian[i][j] = hessian[j][i] = momenta[i].diff(vs[j])
        gradient = [engine.diff(x) for x in qs]
        rest = []
        for i in range(n):
            total = momenta[i].diff(ts)
            for j in range(n):
                total += momenta[i].diff(qs[j]) * vs[j]
            rest.append(total)
        back = self.to_sympy
        converted_hessian: list[list] = [[None] * n for _ in range(n)]
        for i in range(n):
            for j in range(i, n):
                converted_hessian[i][j] = converted_hessian[j][i] = back(hessian[i][j])
        return (
            [back(m) for m in momenta],
            converted_hessian,
            [back(g) for g in gradient],
            [back(r) for r in rest],
        )


def cse(
    exprs: Sequence[sympy.Expr], rename: dict | None = None
) -> tuple[list[tuple[sympy.Symbol, sympy.Expr]], list]:
    """Common-subexpression elimination of ``exprs``, by symengine where it can.

    Returns (temporaries, reduced) as ``sympy.cse`` does, in sympy expressions with plain
    symbols (for printing: the temporaries are named ``x0, x1, ...``, so the expressions
    must not use such names themselves). For a twenty-link chain's kernels symengine takes
    0.02 s where sympy took 2 s. ``rename`` (symbol -> symbol) is applied first, on the
    way to symengine.
    """
    rename = rename or {}
    try:
        temporaries, reduced = engine_cse(exprs, rename)
        back: dict = {}
        return (
            [(sympy.Symbol(name), _converted(e, back)) for name, e in temporaries],
            [_converted(e, back) for e in reduced],
        )
    except Unsupported:
        pass
    renamed = [as_expr(e).xreplace(rename) for e in exprs]
    return sympy.cse(renamed, symbols=sympy.numbered_symbols("x"))


def engine_cse(exprs: Sequence[sympy.Expr], rename: dict) -> tuple[list[tuple[str, object]], list]:
    """``cse`` left in symengine: (temporaries as (name, symengine expression), reduced
    symengine expressions), for printing without the way back to sympy
    (``systems.kernel_printer.engine_text``).

    Raises
    ------
    Unsupported
        Without symengine, or for an expression it cannot take.
    """
    if symengine is None:
        raise Unsupported("symengine is not installed")
    try:
        memo: dict = {}
        engine = [_to_engine(as_expr(e), rename, memo) for e in exprs]
        temporaries, reduced = symengine.cse(engine)
    except (RuntimeError, TypeError, ValueError, NotImplementedError, AttributeError) as exc:
        raise Unsupported(str(exc)) from None
    return [(str(s), e) for s, e in temporaries], list(reduced)


def replaced(expr: sympy.Basic, mapping: dict) -> sympy.Basic:
    """``expr.xreplace(mapping)`` without re-evaluating the nodes above a replacement.

    xreplace rebuilds each changed node through its constructor, which combines powers
    and asks sympy's assumptions about every new base: putting a double pendulum's
    velocities v(q, p) = adj(M) (p - a)/det M into dL/dq spent 10 ms asking whether
    det M is zero. The result is the same expression, merely not canonicalized; the
    kernels' printer, CSE and ``systems.display`` take it as it is.
    """
    memo: dict = {}

    def walk(node):
        if node in mapping:
            return mapping[node]
        if not node.args:
            return node
        found = memo.get(node)
        if found is None:
            args = tuple(walk(a) for a in node.args)
            changed = any(a is not b for a, b in zip(args, node.args, strict=True))
            found = node.func(*args, evaluate=False) if changed else node
            memo[node] = found
        return found

    return walk(as_expr(expr))


def _to_engine(expr: sympy.Basic, rename: dict, memo: dict):
    """``symengine.sympify(expr.xreplace(rename))``, converting each distinct
    subexpression once: the closed forms of a small system repeat the same determinant
    and products many times, and both ``xreplace`` and ``symengine.sympify`` walk every
    occurrence (most of a triple pendulum's kernel printing)."""
    found = memo.get(expr)
    if found is not None:
        return found
    if expr.is_Symbol:
        result = symengine.Symbol(rename.get(expr, expr).name)
    elif expr.is_Add or expr.is_Mul:
        args = [_to_engine(a, rename, memo) for a in expr.args]
        result = symengine.Add(*args) if expr.is_Add else symengine.Mul(*args)
    elif expr.is_Pow:
        base, exponent = (_to_engine(a, rename, memo) for a in expr.args)
        result = base**exponent
    elif expr.is_Function and type(expr).__name__ in _SYMPY_NODES:
        function = getattr(symengine, type(expr).__name__)
        result = function(*(_to_engine(a, rename, memo) for a in expr.args))
    else:  # numbers, constants and anything rarer: symengine's own conversion
        result = to_symengine(expr.xreplace(rename) if rename else expr)
    memo[expr] = result
    return result


def fast_function(
    arguments: Sequence[sympy.Symbol], exprs: Sequence[sympy.Expr]
) -> Callable[[np.ndarray], np.ndarray]:
    """``exprs`` as a numeric function of the ``arguments``' values.

    symengine's ``Lambdify`` where it can (made in milliseconds: ``sympy.lambdify`` printed
    and compiled Python source for most of a second for a ten-link chain's equations),
    ``sympy.lambdify`` otherwise.

    Returns
    -------
    callable
        ``f(values)``, ``values`` shape (len(arguments),), returning shape (len(exprs),).
    """
    count = len(exprs)
    if symengine is not None:
        try:
            memo: dict = {}
            engine_arguments = [_to_engine(a, {}, memo) for a in arguments]
            engine_exprs = [_to_engine(as_expr(e), {}, memo) for e in exprs]
            function = symengine.Lambdify(
                engine_arguments, engine_exprs, real=True, cse=True, backend="lambda"
            )

            def evaluate(values: np.ndarray) -> np.ndarray:
                result = function(np.asarray(values, dtype=float))
                return np.asarray(result, dtype=float).reshape(count)

            return evaluate
        except (RuntimeError, TypeError, ValueError, NotImplementedError, AttributeError):
            pass
    plain = sympy.lambdify([list(arguments)], list(exprs), modules="math", cse=True)
    return lambda values: np.array(plain(list(values)), dtype=float).reshape(count)


def numeric_evaluator(expr: sympy.Expr):
    """``f(values) -> complex``: ``expr`` at the symbol values of a dict.

    symengine in double precision where it can (a zero test of a large expression took
    0.1 s in sympy's 20-digit ``evalf``), sympy otherwise. Raises TypeError, ValueError,
    ZeroDivisionError or RuntimeError where the value is not a finite number.
    """
    expr = as_expr(expr)
    if symengine is not None:
        try:
            engine = _to_engine(expr, {}, {})
        except (RuntimeError, TypeError, ValueError, NotImplementedError, AttributeError):
            engine = None
        if engine is not None:

            def evaluate(values: dict) -> complex:
                plain = {symengine.Symbol(s.name): v for s, v in values.items()}
                value = complex(engine.subs(plain))
                if value != value or abs(value) == float("inf"):
                    raise ZeroDivisionError("not a finite number")
                return value

            return evaluate

    def evaluate_sympy(values: dict) -> complex:
        return complex(expr.xreplace({s: sympy.Float(v) for s, v in values.items()}).evalf(20))

    return evaluate_sympy


def numeric_matrix(matrix: sympy.Matrix, values: dict) -> list[list[complex]]:
    """The entries of ``matrix`` at the symbol values of a dict, as complex numbers.

    symengine substitutes all entries at once (sympy's ``xreplace(...).evalf()`` of a
    twenty-link chain's mass matrix took a second). Raises TypeError or ValueError where
    an entry is not a number.
    """
    rows, cols = matrix.shape
    if symengine is not None:
        try:
            engine = symengine.Matrix(matrix.tolist())
        except (RuntimeError, TypeError, ValueError, NotImplementedError):
            engine = None
        if engine is not None:
            plain = {symengine.Symbol(s.name): float(v) for s, v in values.items()}
            numeric = engine.subs(plain)
            return [[complex(numeric[i, j]) for j in range(cols)] for i in range(rows)]
    numeric = matrix.xreplace(values).evalf()
    return [[complex(numeric[i, j]) for j in range(cols)] for i in range(rows)]
