"""Shared numeric helpers: lambdified expressions with parameter values, periodicity, roots.

Not the hot path: ``sympy.lambdify`` with numpy and symengine's common subexpressions
(``matrix_solve.lambdify_cse``) is enough here. Every function returned by ``vectorize``
broadcasts constant entries to the shape of its inputs.
"""

from __future__ import annotations

import math
import weakref
from collections.abc import Callable, Mapping, Sequence

import numpy as np
import sympy

from systems.cpu_limit import TimeLimitExceeded, cpu_limit
from systems.expressions import as_expr
from systems.lambdified import Lambdified, lambdify
from systems.matrix_solve import lambdify_cse
from systems.mechanics import Mechanics

TWO_PI = 2.0 * math.pi

_CACHE: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def cache_for(mechanics: Mechanics) -> dict:
    """A dictionary of derived objects that lives as long as ``mechanics``."""
    try:
        return _CACHE.setdefault(mechanics, {})
    except TypeError:  # not weak-referenceable: no caching
        return {}


class NeedsClosedForm(ValueError):
    """A textbook feature needs a closed form the derivation did not make (see
    ``closed_form_reason``); ``str()`` is one sentence for the user."""


def closed_form_reason(mechanics: Mechanics, feature: str) -> str:
    """Why ``feature`` is not available for a system in matrix form ("" otherwise).

    ``"Routh's reduction needs the Legendre transform in closed form, which a system of 6
    coordinates with a coupled mass matrix leaves to the numerical solver"``.
    """
    if mechanics.matrix_form is None:
        return ""
    return (
        f"{feature} needs the Legendre transform in closed form, which a system of "
        f"{mechanics.n} coordinates with a coupled mass matrix leaves to the numerical solver "
        "(the velocities q̇ = M⁻¹(p − a) are solved at every step)"
    )


def parameter_values(
    mechanics: Mechanics, parameters: Mapping[str, float] | None = None
) -> dict[sympy.Symbol, float]:
    """The scene's parameter values (optionally overridden), keyed by their symbols."""
    values = dict(mechanics.scene.parameter_values)
    if parameters:
        unknown = set(parameters) - set(values)
        if unknown:
            raise ValueError(f"unknown parameter {sorted(unknown)[0]!r}")
        values.update({k: float(v) for k, v in parameters.items()})
    return {mechanics.params[name]: float(value) for name, value in values.items()}


def with_parameters(expr, mechanics: Mechanics, parameters: Mapping[str, float] | None = None):
    """``expr`` with every parameter replaced by its numeric value (sympy Float)."""
    values = {s: sympy.Float(v) for s, v in parameter_values(mechanics, parameters).items()}
    return as_expr(expr).xreplace(values)


def vectorize(
    exprs: Sequence[sympy.Expr], args: Sequence[sympy.Symbol]
) -> Callable[..., np.ndarray]:
    """Lambdify a list of expressions into ``f(*arrays) -> ndarray (len(exprs), *shape)``.

    The arrays are broadcast together; constant expressions are broadcast to their shape.
    ``DiracDelta`` (the second derivative of ``Abs``, which numpy cannot evaluate) is 0:
    its value everywhere but at the kink, where no derivative is defined anyway.
    """
    exprs = [as_expr(e) for e in exprs]
    exprs = [e.replace(sympy.DiracDelta, lambda *_: sympy.S.Zero) for e in exprs]
    raw = lambdify(list(args), exprs, modules="numpy", cse=lambdify_cse)
    return Vectorized(
        raw, len(exprs), lambdify(list(args), exprs, modules="math", cse=lambdify_cse)
    )


class Vectorized:
    """What ``vectorize`` returns: ``f(*arrays) -> ndarray (count, *shape)``, picklable
    (its function crosses as source text: ``systems.lambdified``).

    Parameters
    ----------
    raw : Lambdified
        The lambdified list of ``count`` expressions.
    count : int
    scalar : Lambdified, optional
        The same with Python's ``math`` module, for one point: a root finder calls with
        scalars hundreds of thousands of times, and numpy's functions on 0-d arrays cost
        about ten times more (25 against ~4 us a call for the three-body figure-eight's
        gradient, whose search called it 280 000 times). Where it raises (a domain error,
        a division by zero, a function ``math`` lacks) the call goes through numpy, which
        gives NaN, inf or the function.
    """

    __slots__ = ("count", "raw", "scalar")

    def __init__(self, raw: Lambdified, count: int, scalar: Lambdified | None = None):
        self.raw = raw
        self.count = count
        self.scalar = scalar

    def __call__(self, *arrays) -> np.ndarray:
        if self.scalar is not None and all(isinstance(a, float) for a in arrays):
            try:
                return np.array(self.scalar(*map(float, arrays)), dtype=float)
            except (ArithmeticError, ValueError, TypeError, NameError):
                pass  # numpy's answer: NaN, inf, or a function math lacks
        arrays = [np.asarray(a, dtype=float) for a in arrays]
        shape = np.broadcast_shapes(*(a.shape for a in arrays)) if arrays else ()
        if not shape:  # one point (a root finder's call): no broadcasting loop
            with np.errstate(all="ignore"):
                return _real(self.raw(*arrays))
        with np.errstate(all="ignore"):
            values = self.raw(*arrays)
        out = np.empty((self.count, *shape))
        for i, value in enumerate(values):
            # assignment broadcasts and casts; only a complex value needs _real (a
            # Hessian of 32 coordinates has 1024 entries, most of them constant, per call)
            out[i] = _real(value) if np.iscomplexobj(value) else value
        return out

    def __reduce__(self):
        return (Vectorized, (self.raw, self.count, self.scalar))


def _real(value) -> np.ndarray:
    """``value`` as floats; a complex value (an expression with I, a power of a negative
    number) is NaN wherever its imaginary part is not round-off, never silently cut to
    its real part."""
    value = np.asarray(value)
    if not np.iscomplexobj(value):
        return value.astype(float)
    with np.errstate(all="ignore"):
        real = np.where(
            np.abs(value.imag) <= 1e-12 * (1.0 + np.abs(value.real)), value.real, np.nan
        )
    return real.astype(float)


def is_periodic(expr: sympy.Expr, symbol: sympy.Symbol, others: Sequence[sympy.Symbol]) -> bool:
    """True if ``expr`` is unchanged by ``symbol -> symbol + 2 pi`` at random real points."""
    if not expr.has(symbol):
        return False
    shifted = expr.xreplace({symbol: symbol + 2 * sympy.pi})
    free = sorted((expr.free_symbols | set(others)) - {symbol}, key=str)
    f = vectorize([expr, shifted], [symbol, *free])
    rng = np.random.default_rng(7)
    points = rng.uniform(-2.0, 2.0, size=(1 + len(free), 8))
    points[1:] = np.where(np.abs(points[1:]) < 0.2, 0.7, points[1:])
    base, moved = f(*points)
    if not (np.all(np.isfinite(base)) and np.all(np.isfinite(moved))):
        return False
    scale = max(1.0, float(np.max(np.abs(base))))
    return bool(np.max(np.abs(base - moved)) <= 1e-9 * scale)


def periodic_symbols(
    expr: sympy.Expr, candidates: Sequence[sympy.Symbol], others: Sequence[sympy.Symbol]
) -> set[sympy.Symbol]:
    """The ``candidates`` in which ``expr`` is 2 pi-periodic: ``is_periodic`` for each,
    with one lambdify and one evaluation (the shift is applied to the inputs).

    For a chain of twenty links, lambdifying L twice per coordinate took seconds. A
    candidate that enters only through sines and cosines of ``k q + ...`` (k a nonzero
    integer, ``_trigonometric_only``) is periodic by construction, without evaluating
    anything: a six-link chain's L needs no lambdify at all.
    """
    present = [s for s in candidates if expr.has(s)]
    proved = {s for s in present if _trigonometric_only(expr, s)}
    present = [s for s in present if s not in proved]
    if not present:
        return proved
    free = sorted(expr.free_symbols | set(others) | set(present), key=str)
    f = vectorize([expr], free)
    rng = np.random.default_rng(7)
    points = rng.uniform(-2.0, 2.0, size=(len(free), 8))
    points = np.where(np.abs(points) < 0.2, 0.7, points)
    blocks = [points]
    for symbol in present:
        moved = points.copy()
        moved[free.index(symbol)] += TWO_PI
        blocks.append(moved)
    values = f(*np.concatenate(blocks, axis=1))[0].reshape(len(blocks), points.shape[1])
    base = values[0]
    if not np.all(np.isfinite(base)):
        return proved
    scale = max(1.0, float(np.max(np.abs(base))))
    return proved | {
        symbol
        for symbol, moved in zip(present, values[1:], strict=True)
        if np.all(np.isfinite(moved)) and float(np.max(np.abs(base - moved))) <= 1e-9 * scale
    }


_TRIGONOMETRIC = (sympy.sin, sympy.cos, sympy.tan, sympy.cot, sympy.sec, sympy.csc)


def _trigonometric_only(expr: sympy.Expr, symbol: sympy.Symbol) -> bool:
    """True if every occurrence of ``symbol`` in ``expr`` is in the argument ``k symbol +
    rest`` of a trigonometric function, k a nonzero integer and rest free of it: then
    ``expr`` is 2 pi-periodic in ``symbol`` exactly."""
    if expr == symbol:
        return False
    if not expr.has(symbol):
        return True
    if isinstance(expr, _TRIGONOMETRIC):
        _, dependent = expr.args[0].as_independent(symbol, as_Add=True)
        k, rest = dependent.as_coeff_Mul()
        return bool(rest == symbol and k.is_Integer and k != 0)
    return all(_trigonometric_only(a, symbol) for a in expr.args)


def fold_angle(x: float | np.ndarray) -> float | np.ndarray:
    """Angles folded into (-pi, pi]."""
    folded = -np.mod(-np.asarray(x, dtype=float) + math.pi, TWO_PI) + math.pi
    return float(folded) if np.ndim(folded) == 0 else folded


def level_crossings(
    f: Callable[[np.ndarray], np.ndarray], level: float, lo: float, hi: float, samples: int = 2001
) -> np.ndarray:
    """Every x in [lo, hi] where ``f(x) = level`` (sign changes on a grid, then brentq).

    A log-spaced grid is used when ``0 < lo`` and ``hi / lo > 100``. Returns shape (m,).
    """

    if 0 < lo and hi / lo > 100:
        x = np.geomspace(lo, hi, samples)
    else:
        x = np.linspace(lo, hi, samples)
    with np.errstate(all="ignore"):
        g = f(x) - level
    roots = []
    for i in range(samples - 1):
        a, b = g[i], g[i + 1]
        if not (np.isfinite(a) and np.isfinite(b)):
            continue
        if a == 0.0:
            roots.append(x[i])
        elif a * b < 0:
            roots.append(_brent(lambda s: float(f(np.array([s]))[0]) - level, x[i], x[i + 1]))
    if np.isfinite(g[-1]) and g[-1] == 0.0:
        roots.append(x[-1])
    return np.array(roots, dtype=float)


def bracket_around(
    f: Callable[[np.ndarray], np.ndarray],
    level: float,
    x0: float,
    direction: int,
    *,
    first_step: float,
    limit: float,
    growth: float = 1.05,
) -> float | None:
    """The first x beyond ``x0`` (to the right for direction +1) where ``f(x) = level``.

    Steps outward geometrically from ``first_step`` until ``limit`` away from ``x0``;
    returns None if ``f`` stays below ``level`` (an unbounded or open side).
    """
    if growth == 1.0:
        steps = first_step * np.arange(1, math.ceil(limit / first_step) + 1)
    else:  # s_k+1 = growth s_k + first_step, a geometric series
        k = np.arange(
            1, 1 + math.ceil(math.log1p(limit * (growth - 1) / first_step) / math.log(growth)) + 1
        )
        steps = first_step * (growth**k - 1) / (growth - 1)
    steps = np.minimum(steps, limit)
    x = x0 + direction * np.concatenate([[0.0], steps])
    with np.errstate(all="ignore"):
        g = f(x) - level
    stop = np.flatnonzero(~np.isfinite(g[1:]) | (g[1:] >= 0.0))
    if stop.size == 0:
        return None
    i = int(stop[0]) + 1
    if not np.isfinite(g[i]):
        return None
    if g[i] == 0.0:
        return float(x[i])
    return _brent(lambda s: float(f(np.array([s]))[0]) - level, x[i - 1], x[i])


def _brent(function, a: float, b: float) -> float:
    from scipy.optimize import brentq

    lo, hi = min(a, b), max(a, b)
    return float(brentq(function, lo, hi, xtol=1e-15 * max(1.0, abs(lo), abs(hi)), rtol=1e-15))


# -- running sympy with a time limit ----------------------------------------------------------


def run_bounded(function: Callable, args: tuple, timeout: float):
    """``function(*args)`` stopped after ``timeout`` seconds of CPU time; None if it fails
    or overruns (the caller falls back to a numeric method).

    sympy's solvers may run for a very long time on some inputs. The limit is
    ``systems.cpu_limit``'s, so this runs in a process's main thread: the command line's,
    or the worker process the window sends an equilibrium search to.
    """
    try:
        with cpu_limit(timeout, "sympy.solve"):
            try:
                return function(*args)
            except Exception:  # noqa: BLE001 - sympy gave up: numeric methods instead
                return None
    except TimeLimitExceeded:
        return None
