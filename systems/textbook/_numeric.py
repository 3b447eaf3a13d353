"""Shared numeric helpers: lambdified expressions with parameter values, periodicity, roots.

Not the hot path: ``sympy.lambdify`` with numpy and symengine's common subexpressions
(``matrix_solve.lambdify_cse``) is enough here. Every function returned by ``vectorize``
broadcasts constant entries to the shape of its inputs.
"""

from __future__ import annotations

import math
import multiprocessing
import time
import weakref
from collections.abc import Callable, Mapping, Sequence

import numpy as np
import sympy

from systems.deadline import checkpoint
from systems.expressions import as_expr
from systems.matrix_solve import lambdify_cse
from systems.mechanics import Mechanics

TWO_PI = 2.0 * math.pi
POLL_SECONDS = 0.05
"""How often ``run_bounded`` looks, while it waits for its child, whether the thread was
asked to stop (``systems.deadline.checkpoint``)."""

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
    """
    exprs = [as_expr(e) for e in exprs]
    raw = sympy.lambdify(list(args), exprs, modules="numpy", cse=lambdify_cse)

    def function(*arrays) -> np.ndarray:
        arrays = [np.asarray(a, dtype=float) for a in arrays]
        shape = np.broadcast_shapes(*(a.shape for a in arrays)) if arrays else ()
        if not shape:  # one point (a root finder's call): no broadcasting loop
            with np.errstate(all="ignore"):
                return np.array(raw(*arrays), dtype=float)
        with np.errstate(all="ignore"):
            values = raw(*arrays)
        out = np.empty((len(exprs), *shape))
        for i, value in enumerate(values):
            out[i] = np.broadcast_to(np.asarray(value, dtype=float), shape)
        return out

    return function


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

    For a chain of twenty links, lambdifying L twice per coordinate took seconds.
    """
    present = [s for s in candidates if expr.has(s)]
    if not present:
        return set()
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
        return set()
    scale = max(1.0, float(np.max(np.abs(base))))
    return {
        symbol
        for symbol, moved in zip(present, values[1:], strict=True)
        if np.all(np.isfinite(moved)) and float(np.max(np.abs(base - moved))) <= 1e-9 * scale
    }


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
    """Run ``function(*args)`` in a forked child process; None if it fails or overruns.

    sympy's solvers may run for a very long time on some inputs; a child process can be
    stopped, a thread cannot. Where ``fork`` is unavailable, returns None (the caller
    falls back to a numeric method). A thread asked to stop (``systems.deadline.cancel``)
    raises ``Abandoned`` within ``POLL_SECONDS``, its child killed.
    """
    checkpoint()
    try:
        context = multiprocessing.get_context("fork")
    except ValueError:
        return None
    receiver, sender = context.Pipe(duplex=False)
    process = context.Process(target=_child, args=(sender, function, args), daemon=True)
    try:
        process.start()
    except OSError:
        return None
    sender.close()
    result = None
    end = time.monotonic() + timeout
    try:
        while not receiver.poll(min(POLL_SECONDS, max(0.0, end - time.monotonic()))):
            checkpoint()  # nobody waits for the answer any more: the child is killed below
            if time.monotonic() >= end:
                break
        else:
            status, value = receiver.recv()
            result = value if status == "ok" else None
    except (EOFError, OSError):
        result = None
    finally:
        receiver.close()
        if process.is_alive():
            process.kill()
        process.join(1.0)
    return result


def _child(sender, function, args) -> None:
    try:
        value = function(*args)
        sender.send(("ok", value))
    except BaseException as exc:  # noqa: BLE001 - reported to the parent as a failure
        try:
            sender.send(("error", repr(exc)))
        except Exception:  # noqa: BLE001
            pass
    finally:
        sender.close()
