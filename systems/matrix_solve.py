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
    values = [as_expr(e).xreplace(parameters) for e in exprs]
    f = sympy.lambdify((t, q, qd, p), values, modules="math", cse=True)
    form = mechanics.matrix_form
    if form is None:
        return lambda time, y: np.array(f(time, y[:n], np.zeros(n), y[n:]), dtype=float)
    blocks = [form.mass_matrix.xreplace(parameters), form.shift.xreplace(parameters)]
    g = sympy.lambdify((t, q), blocks, modules="math", cse=True)

    def evaluate(time: float, y: np.ndarray) -> np.ndarray:
        M, a = g(time, y[:n])
        M = np.array(M, dtype=float).reshape(n, n)
        a = np.array(a, dtype=float).reshape(n)
        velocities = np.linalg.solve(M, y[n:] - a)
        return np.array(f(time, y[:n], velocities, y[n:]), dtype=float)

    return evaluate
