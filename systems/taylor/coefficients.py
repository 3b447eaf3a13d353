"""Taylor-coefficient recurrences of the elementary operations, and a reference evaluator.

Coefficients are *normalized* derivatives: ``[u]_k = u^(k)(t0) / k!``, so that
``u(t0 + h) = sum_k [u]_k h^k``. For each op of ``systems.taylor.decompose.OPS``,
``RECURRENCES[op](k, args, deps, own)`` gives ``[u]_k`` for k >= 1 from the
coefficients of the arguments up to order k, of the hidden dependencies up to k - 1 and
of the node itself up to k - 1 (order 0 is the function's value, ``VALUES``). The
formulas (Jorba & Zou 2005, section 3; Moore's rules), with ``a' = sum_j j a_j h^(j-1)``:

- ``a b``: ``sum_{j=0}^{k} a_j b_{k-j}``; ``a / b``: ``(a_k - sum_{j=1}^{k} b_j q_{k-j}) / b_0``
- ``a^e`` (e constant): ``p_k = sum_{j=0}^{k-1} (e (k-j) - j) a_{k-j} p_j / (k a_0)``
- ``sqrt a``: ``(a_k - sum_{j=1}^{k-1} s_j s_{k-j}) / (2 s_0)``
- ``exp a``: ``sum_{j=1}^{k} j a_j e_{k-j} / k``; ``log a``:
  ``(a_k - sum_{j=1}^{k-1} j l_j a_{k-j} / k) / a_0``
- ``sin a``/``cos a``: ``s_k = sum j a_j c_{k-j} / k``, ``c_k = -sum j a_j s_{k-j} / k``
  (``sinh``/``cosh`` without the minus)
- ``tan a`` (d = tan^2): ``a_k + sum_{j=1}^{k} j a_j d_{k-j} / k``; ``tanh``: minus
- ``w r' = g'`` forms, ``w`` a dependency: ``asin`` (w = sqrt(1 - a^2), g = a),
  ``acos`` (same w, g = -a), ``atan`` (w = 1 + a^2, g = a), ``atan2(y, x)``
  (w = x^2 + y^2, ``w r' = x y' - y x'``):
  ``r_k = ([g' w-free part]_{k-1} - sum_{j=1}^{k-1} w_j (k-j) r_{k-j}) / (k w_0)``
- ``|a|``: ``sign(a_0) a_k``; ``sign a``: 0 (both analytic only where a_0 != 0).

``taylor_coefficients`` is the reference evaluator in numpy: plain loops over orders
and nodes, any number of states at once. It is what the compiled family (a later
session) is tested against; it is not fast and is not used by any integrator.
"""

from __future__ import annotations

import math

import numpy as np

from systems.taylor.decompose import Arg, Decomposition


def _conv(a: np.ndarray, b: np.ndarray, k: int, start: int = 0, stop: int | None = None):
    """``sum_{j=start}^{stop} a_j b_{k-j}`` (stop = k by default), over the batch."""
    stop = k if stop is None else stop
    if stop < start:
        return np.zeros(a.shape[1:])
    j = np.arange(start, stop + 1)
    return np.einsum("j...,j...->...", a[j], b[k - j])


def _weighted(a: np.ndarray, b: np.ndarray, k: int) -> np.ndarray:
    """``sum_{j=1}^{k} j a_j b_{k-j}``: the coefficient of h^(k-1) in a' b."""
    j = np.arange(1, k + 1)
    return np.einsum("j,j...,j...->...", j.astype(float), a[j], b[k - j])


def _ratio_form(k: int, g_prime_k: np.ndarray, w: np.ndarray, r: np.ndarray) -> np.ndarray:
    """r_k of ``w r' = g'`` given ``[g']_{k-1}`` (k g_k for g' itself)."""
    correction = np.zeros_like(g_prime_k)
    if k > 1:
        j = np.arange(1, k)
        correction = np.einsum("j,j...,j...->...", (k - j).astype(float), w[j], r[k - j])
    return (g_prime_k - correction) / (k * w[0])


def _mul(k, A, D, own):
    return _conv(A[0], A[1], k)


def _div(k, A, D, own):
    a, b = A
    return (a[k] - _conv(b, own, k, 1)) / b[0]


def _pow(k, A, D, own):
    a, e = A[0], A[1][0]
    j = np.arange(0, k)
    factors = e[None, :] * (k - j)[:, None] - j[:, None]  # (k, B)
    total = np.einsum("jb,jb,jb->b", factors, a[k - j], own[j])
    return total / (k * a[0])


def _sqrt(k, A, D, own):
    return (A[0][k] - _conv(own, own, k, 1, k - 1)) / (2.0 * own[0])


def _exp(k, A, D, own):
    return _weighted(A[0], own, k) / k


def _log(k, A, D, own):
    a = A[0]
    j = np.arange(1, k)
    correction = np.einsum("j,j...,j...->...", j.astype(float), own[j], a[k - j]) if k > 1 else 0.0
    return (a[k] - correction / k) / a[0]


RECURRENCES = {
    "time": lambda k, A, D, own: np.zeros_like(own[0]) + (1.0 if k == 1 else 0.0),
    "neg": lambda k, A, D, own: -A[0][k],
    "add": lambda k, A, D, own: A[0][k] + A[1][k],
    "sub": lambda k, A, D, own: A[0][k] - A[1][k],
    "mul": _mul,
    "square": lambda k, A, D, own: _conv(A[0], A[0], k),
    "div": _div,
    "pow": _pow,
    "sqrt": _sqrt,
    "exp": _exp,
    "log": _log,
    "sin": lambda k, A, D, own: _weighted(A[0], D[0], k) / k,
    "cos": lambda k, A, D, own: -_weighted(A[0], D[0], k) / k,
    "sinh": lambda k, A, D, own: _weighted(A[0], D[0], k) / k,
    "cosh": lambda k, A, D, own: _weighted(A[0], D[0], k) / k,
    "tan": lambda k, A, D, own: A[0][k] + _weighted(A[0], D[0], k) / k,
    "tanh": lambda k, A, D, own: A[0][k] - _weighted(A[0], D[0], k) / k,
    "asin": lambda k, A, D, own: _ratio_form(k, k * A[0][k], D[0], own),
    "acos": lambda k, A, D, own: _ratio_form(k, -k * A[0][k], D[0], own),
    "atan": lambda k, A, D, own: _ratio_form(k, k * A[0][k], D[0], own),
    "atan2": lambda k, A, D, own: _ratio_form(
        k, _weighted(A[0], A[1], k) - _weighted(A[1], A[0], k), D[0], own
    ),
    "abs": lambda k, A, D, own: np.sign(A[0][0]) * A[0][k],
    "sign": lambda k, A, D, own: np.zeros_like(own[0]),
}
"""op -> ``f(k, args, deps, own)``: the k-th coefficient (k >= 1), shape (B,), from the
arguments' coefficients ``args`` (each (order + 1, B)), the dependencies' ``deps`` and the
node's own ``own`` (read up to k - 1)."""

VALUES = {
    "neg": np.negative,
    "add": np.add,
    "sub": np.subtract,
    "mul": np.multiply,
    "square": np.square,
    "div": np.divide,
    "pow": np.power,
    "sqrt": np.sqrt,
    "exp": np.exp,
    "log": np.log,
    "sin": np.sin,
    "cos": np.cos,
    "sinh": np.sinh,
    "cosh": np.cosh,
    "tan": np.tan,
    "tanh": np.tanh,
    "asin": np.arcsin,
    "acos": np.arccos,
    "atan": np.arctan,
    "atan2": np.arctan2,
    "abs": np.abs,
    "sign": np.sign,
}
"""op -> its value at order 0 (numpy)."""


def _states(y0, P, count):
    y0 = np.asarray(y0, dtype=float)
    single = y0.ndim == 1
    Y = np.atleast_2d(y0)  # (B, m)
    P = np.asarray(P, dtype=float)
    P = np.broadcast_to(P, (Y.shape[0], count)) if P.ndim == 1 else P
    return single, Y, P


def _run(d: Decomposition, t0, U: np.ndarray, P: np.ndarray, order: int, ode: bool) -> None:
    """Fill the nodes' coefficients in ``U`` (variables + nodes, order + 1, B): with
    ``ode`` the variables' from the outputs (``[y]_{k+1} = [f]_k / (k + 1)``), else the
    variables' are given."""
    m = d.m
    B = U.shape[2]
    constants: dict[tuple, np.ndarray] = {}

    def series(arg: Arg) -> np.ndarray:
        if arg.kind == "u":
            return U[arg.value]
        key = (arg.kind, arg.value)
        found = constants.get(key)
        if found is None:
            found = np.zeros((order + 1, B))
            found[0] = arg.value if arg.kind == "num" else P[:, arg.value]
            constants[key] = found
        return found

    for k in range(order + 1):
        for i, node in enumerate(d.nodes, start=m):
            if node.op == "time":
                U[i, k] = t0 if k == 0 else (1.0 if k == 1 else 0.0)
                continue
            A = [series(a) for a in node.args]
            with np.errstate(all="ignore"):
                if k == 0:
                    U[i, 0] = VALUES[node.op](*(a[0] for a in A))
                elif not node.constant:
                    U[i, k] = RECURRENCES[node.op](k, A, [U[j] for j in node.deps], U[i])
        if ode and k < order:
            for j, out in enumerate(d.outputs):
                U[j, k + 1] = series(out)[k] / (k + 1)
    return [series(out) for out in d.outputs]


def taylor_coefficients(
    decomposition: Decomposition,
    t0: float | np.ndarray,
    y0: np.ndarray,
    P: np.ndarray,
    order: int,
    *,
    nodes: bool = False,
) -> np.ndarray:
    """The Taylor coefficients of the solution of ``dy/dt = f(y, t)`` through ``y0``.

    ``[y]_0 = y0``, ``[y]_{k+1} = [f]_k / (k + 1)``, the nodes' coefficients of order k
    computed in the decomposition's order from the state's up to k.

    Parameters
    ----------
    decomposition : Decomposition
    t0 : float or array (B,)
    y0 : array (m,) or (B, m)
    P : array (k,) or (B, k)
        The parameters, in ``decomposition.parameters``' order.
    order : int
        The highest order N >= 0.
    nodes : bool
        Return every node's coefficients too.

    Returns
    -------
    array (N + 1, m), or (B, N + 1, m) for B states; with ``nodes``, (N + 1, m + nodes)
    resp. (B, N + 1, m + nodes), state variables first. Row k is ``[y]_k``.
    """
    d = decomposition
    single, Y, P = _states(y0, P, len(d.parameters))
    B, m = Y.shape
    if m != d.m:
        raise ValueError(f"a state of {m} variables for a decomposition of {d.m}")
    U = np.zeros((m + len(d.nodes), order + 1, B))
    U[:m, 0] = Y.T
    t0 = np.broadcast_to(np.asarray(t0, dtype=float), (B,))
    _run(d, t0, U, P, order, ode=True)
    width = len(U) if nodes else m
    result = U[:width].transpose(2, 1, 0)  # (B, N + 1, width)
    return result[0] if single else result


def output_series(
    decomposition: Decomposition, t0: float | np.ndarray, variables: np.ndarray, P: np.ndarray
) -> np.ndarray:
    """The Taylor coefficients of ``f(u(h), t0 + h)`` for given series of the variables.

    Parameters
    ----------
    decomposition : Decomposition
    t0 : float or array (B,)
    variables : array (N + 1, m) or (B, N + 1, m)
        ``[u_i]_k`` of each state variable.
    P : array (k,) or (B, k)

    Returns
    -------
    array (N + 1, m) or (B, N + 1, m): ``[f_i]_k``.
    """
    d = decomposition
    V = np.asarray(variables, dtype=float)
    single = V.ndim == 2
    V = V[None] if single else V
    B, N1, m = V.shape
    _, _, P = _states(np.zeros((B, m)), P, len(d.parameters))
    U = np.zeros((m + len(d.nodes), N1, B))
    U[:m] = V.transpose(2, 1, 0)
    t0 = np.broadcast_to(np.asarray(t0, dtype=float), (B,))
    outputs = np.array(_run(d, t0, U, P, N1 - 1, ode=False))  # (m, N + 1, B)
    result = outputs.transpose(2, 1, 0)
    return result[0] if single else result


def evaluate(decomposition: Decomposition, t: float, y: np.ndarray, P: np.ndarray) -> np.ndarray:
    """``f(y, t)`` through the decomposition: (m,) for y (m,), (B, m) for y (B, m)."""
    d = decomposition
    coefficients = taylor_coefficients(d, t, y, P, 1)  # [y]_1 = f
    return coefficients[..., 1, :]


def horner(coefficients: np.ndarray, h: float | np.ndarray) -> np.ndarray:
    """``sum_k c_k h^k`` for ``coefficients`` (..., N + 1, m): returns (..., m)."""
    c = np.asarray(coefficients)
    h = np.asarray(h, dtype=float)[..., None] if np.ndim(h) else float(h)
    total = c[..., -1, :].copy()
    for k in range(c.shape[-2] - 2, -1, -1):
        total = total * h + c[..., k, :]
    return total


def jorba_zou(tolerance: float) -> int:
    """The order ``ceil(-ln(tolerance) / 2 + 1)`` Jorba and Zou (2005) derive for a
    tolerance (heyoka's choice): 20 at machine epsilon."""
    return math.ceil(-math.log(tolerance) / 2 + 1)
