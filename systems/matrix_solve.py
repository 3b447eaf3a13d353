"""Velocities of a system in matrix form: solve M(q, t) qdot = p - a(q, t) numerically.

``solve_augmented`` is plain Python that numba compiles unchanged: ``systems.compiled``
copies its source into a scene's kernel module, where the printed system functions fill
the augmented matrix and call it. ``state_function`` is the numpy counterpart for the
symbolic layer's numerical checks (stiffness, the start check).
"""

from __future__ import annotations

import inspect
import math
from collections.abc import Callable, Sequence

import numpy as np
import sympy

from systems import calculus
from systems.expressions import as_expr


def solve_augmented(W, n):
    """Solve ``M x = b`` in place for the augmented array ``W = [M | b | diag(M)]``.

    Parameters
    ----------
    W : ndarray, shape (n, n + 2)
        Columns ``0..n-1`` hold M (both triangles), column ``n`` holds b and column
        ``n + 1`` a copy of M's diagonal. On return column ``n`` holds x.
    n : int

    Cholesky first (M is symmetric positive definite for a kinetic energy), factoring into
    the lower triangle. A pivot that is not positive means M is not positive definite
    there: the lower triangle and diagonal are restored from the upper triangle and the
    copy, and Gaussian elimination with partial pivoting solves instead. A singular M
    gives inf or nan, which the integrator's driver rejects like any non-finite step.
    """
    positive = True
    for j in range(n):
        s = W[j, j]
        for k in range(j):
            s -= W[j, k] * W[j, k]
        if not s > 0.0:
            positive = False
            break
        d = math.sqrt(s)
        W[j, j] = d
        for i in range(j + 1, n):
            s = W[j, i]  # M[i, j], read from the untouched upper triangle
            for k in range(j):
                s -= W[i, k] * W[j, k]
            W[i, j] = s / d
    if positive:
        for i in range(n):  # L y = b
            s = W[i, n]
            for k in range(i):
                s -= W[i, k] * W[k, n]
            W[i, n] = s / W[i, i]
        for i in range(n - 1, -1, -1):  # L^T x = y
            s = W[i, n]
            for k in range(i + 1, n):
                s -= W[k, i] * W[k, n]
            W[i, n] = s / W[i, i]
        return
    for i in range(n):
        W[i, i] = W[i, n + 1]
        for j in range(i):
            W[i, j] = W[j, i]
    for j in range(n):
        pivot = j
        for i in range(j + 1, n):
            if abs(W[i, j]) > abs(W[pivot, j]):
                pivot = i
        if pivot != j:
            for k in range(j, n + 1):
                W[j, k], W[pivot, k] = W[pivot, k], W[j, k]
        for i in range(j + 1, n):
            f = W[i, j] / W[j, j]
            for k in range(j, n + 1):
                W[i, k] -= f * W[j, k]
    for i in range(n - 1, -1, -1):
        s = W[i, n]
        for k in range(i + 1, n):
            s -= W[i, k] * W[k, n]
        W[i, n] = s / W[i, i]


def kernel_source() -> str:
    """The source of ``solve_augmented`` as it goes into a kernel module."""
    return inspect.getsource(solve_augmented)


def lambdify_cse(exprs):
    """``sympy.cse`` for ``sympy.lambdify(..., cse=lambdify_cse)``, by symengine where it
    can (``systems.calculus.cse``): sympy's took seconds on a chain's Hamilton's equations.

    symengine names its temporaries ``x<k>`` avoiding every name in the expressions and
    gives back plain symbols; ``lambdify`` prints symbols by name, so they need not be
    turned back into the scene's (an ``xreplace`` cost more than the elimination).
    """
    exprs = [as_expr(e) for e in (exprs if isinstance(exprs, (list, tuple)) else [exprs])]
    return calculus.cse(exprs)


def state_function(
    mechanics, exprs: Sequence[sympy.Expr], parameters: dict
) -> Callable[[float, np.ndarray], np.ndarray]:
    """``exprs`` of (q, p, t) as a numpy function ``f(t, y)`` of one state y = (q, p).

    For a system in matrix form (``Mechanics.matrix_form``) the velocities in ``exprs``
    are first solved from ``M(q, t) qdot = p - a(q, t)``.

    Parameters
    ----------
    mechanics : systems.mechanics.Mechanics
    exprs : sequence of sympy expressions
    parameters : dict
        Parameter symbol -> value, substituted before lambdifying.

    Returns
    -------
    callable
        ``f(t, y)`` with y shape (2n,), returning an array of shape (len(exprs),).
    """
    n = mechanics.n
    q, qd, p, t = mechanics.q, mechanics.qdot, mechanics.p, mechanics.t
    # the parameters are arguments with fixed values: substituting them first walked
    # every expression (a large system's equations) once more
    names, fixed = list(parameters), np.array(list(parameters.values()), dtype=float)
    f = calculus.fast_function([t, *q, *qd, *p, *names], [as_expr(e) for e in exprs])
    form = mechanics.matrix_form
    if form is None:
        zero = np.zeros(n)
        return lambda time, y: f(np.concatenate(([time], y[:n], zero, y[n:], fixed)))
    blocks = [as_expr(e) for e in (*form.mass_matrix, *form.shift)]
    g = calculus.fast_function([t, *q, *names], blocks)

    def evaluate(time: float, y: np.ndarray) -> np.ndarray:
        values = g(np.concatenate(([time], y[:n], fixed)))
        M = values[: n * n].reshape(n, n)
        a = values[n * n :]
        velocities = np.linalg.solve(M, y[n:] - a)
        return f(np.concatenate(([time], y[:n], velocities, y[n:], fixed)))

    return evaluate


def batch_velocities(
    mechanics, parameters: dict
) -> Callable[[np.ndarray, np.ndarray, np.ndarray], np.ndarray]:
    """The velocities of many states of a system in matrix form, solved numerically.

    Parameters
    ----------
    mechanics : systems.mechanics.Mechanics
        With ``matrix_form`` set.
    parameters : dict
        Parameter symbol -> value, substituted before lambdifying.

    Returns
    -------
    callable
        ``f(t, Q, P) -> Qdot``: ``t`` scalar or shape (K,), ``Q`` and ``P`` shape (K, n),
        ``Qdot`` shape (K, n), solving ``M(q, t) qdot = p - a(q, t)`` state by state with
        one stacked ``numpy.linalg.solve``. A state whose M is singular or not finite
        gets nan velocities.
    """
    form = mechanics.matrix_form
    if form is None:
        raise ValueError("batch_velocities: the system is not in matrix form")
    n = mechanics.n
    upper = [(i, j) for i in range(n) for j in range(i, n)]
    entries = [as_expr(form.mass_matrix[i, j]).xreplace(parameters) for i, j in upper]
    entries += [as_expr(e).xreplace(parameters) for e in form.shift]
    g = sympy.lambdify((mechanics.t, *mechanics.q), entries, modules="numpy", cse=lambdify_cse)
    rows = np.array([i for i, _ in upper])
    cols = np.array([j for _, j in upper])

    def velocities(t, Q: np.ndarray, P: np.ndarray) -> np.ndarray:
        Q = np.atleast_2d(np.asarray(Q, dtype=float))
        P = np.atleast_2d(np.asarray(P, dtype=float))
        K = len(Q)
        t = np.broadcast_to(np.asarray(t, dtype=float), (K,))
        with np.errstate(all="ignore"):
            values = g(t, *Q.T)
            columns = np.empty((len(entries), K))
            for k, value in enumerate(values):
                columns[k] = np.broadcast_to(np.asarray(value, dtype=float), (K,))
        M = np.empty((K, n, n))
        M[:, rows, cols] = columns[: len(upper)].T
        M[:, cols, rows] = columns[: len(upper)].T
        rhs = P - columns[len(upper) :].T
        out = np.full((K, n), np.nan)
        good = np.all(np.isfinite(M), axis=(1, 2)) & np.all(np.isfinite(rhs), axis=1)
        if np.any(good):
            try:
                out[good] = np.linalg.solve(M[good], rhs[good][..., None])[..., 0]
            except np.linalg.LinAlgError:  # some M singular: one by one
                for k in np.flatnonzero(good):
                    try:
                        out[k] = np.linalg.solve(M[k], rhs[k])
                    except np.linalg.LinAlgError:
                        pass
        return out

    return velocities
