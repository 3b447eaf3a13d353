"""Coefficients of the methods: composition weights, Gauss-Legendre and explicit tableaux."""

from __future__ import annotations

import functools
from functools import cache
from types import ModuleType

import numpy as np


def _symmetric(outer_to_inner: tuple[float, ...]) -> tuple[float, ...]:
    """Weights ``(w_m, ..., w_1)`` -> the palindrome with ``w_0 = 1 - 2 sum`` in the middle."""
    w0 = 1.0 - 2.0 * sum(outer_to_inner)
    return (*outer_to_inner, w0, *reversed(outer_to_inner))


_CBRT2 = 2.0 ** (1.0 / 3.0)
LEAPFROG = (1.0,)
TRIPLE_JUMP = _symmetric((1.0 / (2.0 - _CBRT2),))
# Yoshida (1990), Phys. Lett. A 150, 262: order 6 solution A and order 8 solution D,
# listed as (w_m, ..., w_1).
YOSHIDA6 = _symmetric((0.784513610477560, 0.235573213359357, -1.17767998417887))
YOSHIDA8 = _symmetric(
    (
        0.914844246229740,
        0.253693336566229,
        -1.44485223686048,
        -0.158240635368243,
        1.93813913762276,
        -1.96061023297549,
        0.102799849391985,
    )
)


def kick_drift(weights: tuple[float, ...]) -> tuple[np.ndarray, np.ndarray]:
    """Merged stage coefficients of the composed kick-drift-kick leapfrog.

    Returns
    -------
    kick : ndarray, shape (s + 1,)
    drift : ndarray, shape (s,)
    """
    w = np.array(weights, dtype=float)
    kick = np.empty(len(w) + 1)
    kick[0] = w[0] / 2
    kick[1:-1] = (w[:-1] + w[1:]) / 2
    kick[-1] = w[-1] / 2
    return kick, w.copy()


@cache
def gauss_tableau(stages: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Gauss-Legendre collocation tableau and its stage extrapolation matrix.

    Returns
    -------
    A : ndarray, shape (s, s)
    b, c : ndarray, shape (s,)
    E : ndarray, shape (s, s)
        ``Z_next = E @ Z``: the collocation polynomial of a step (through 0 at node 0 and
        the increments ``Z`` at the nodes ``c``), continued to ``1 + c`` and taken
        relative to its value at 1. This is the starting guess of the next step.
    """
    x, _ = np.polynomial.legendre.leggauss(stages)
    c = (x + 1.0) / 2.0
    nodes = np.concatenate([[0.0], c])
    s = stages
    A = np.empty((s, s))
    b = np.empty(s)
    E = np.empty((s, s))
    P = np.polynomial.Polynomial
    for j in range(s):
        # Lagrange basis on the nodes c (for A, b) and on (0, c) (for the extrapolation)
        others = np.delete(c, j)
        ell = (P.fromroots(others) if len(others) else P([1.0])) / np.prod(c[j] - others)
        integral = ell.integ()
        b[j] = integral(1.0) - integral(0.0)
        A[:, j] = integral(c) - integral(0.0)
        others0 = np.delete(nodes, j + 1)
        L = P.fromroots(others0) / np.prod(c[j] - others0)
        E[:, j] = L(1.0 + c) - L(1.0)
    return A, b, c, E


EXPLICIT_TABLEAUX = {
    "euler": (np.zeros((1, 1)), np.array([1.0]), np.array([0.0])),
    "rk4": (
        np.array(
            [[0.0, 0.0, 0.0, 0.0], [0.5, 0.0, 0.0, 0.0], [0.0, 0.5, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0]]
        ),
        np.array([1.0, 2.0, 2.0, 1.0]) / 6.0,
        np.array([0.0, 0.5, 0.5, 1.0]),
    ),
}
"""Explicit Runge-Kutta tableaux ``(A, b, c)`` by name."""


@cache
def symplectic_weights(stages: int) -> np.ndarray:
    """``MU`` (s, s) with a_ij = MU_ij b_j for the Gauss-Legendre tableau of ``stages``.

    MU_ii = 1/2 and MU_ji = 1 - MU_ij, which floating point computes exactly (Sterbenz:
    every MU_ij of s <= 3 lies in [1/2, 2]), so b_i a_ij + b_j a_ji = b_i b_j holds for the
    rounded coefficients too: the method as computed conserves quadratic invariants.
    """
    A, b, _, _ = gauss_tableau(stages)
    MU = np.empty((stages, stages))
    for i in range(stages):
        MU[i, i] = 0.5
        for j in range(i):
            MU[i, j] = A[i, j] / b[j]
            MU[j, i] = 1.0 - MU[i, j]
            if (MU[i, j] - 1.0) + MU[j, i] != 0.0:
                raise ArithmeticError(f"MU[{i}, {j}] is outside [1/2, 2] for {stages} stages")
    return MU


@functools.cache
def dop853_coefficients() -> ModuleType:
    """scipy's ``dop853_coefficients`` module, read without importing ``scipy.integrate``
    (whose package initialisation took 0.26 s of a first dop853 run; the module itself
    needs only numpy)."""
    import importlib.util
    from pathlib import Path

    scipy = importlib.util.find_spec("scipy")
    path = Path(scipy.origin).parent / "integrate" / "_ivp" / "dop853_coefficients.py"
    spec = importlib.util.spec_from_file_location("_phase_explorer_dop853", path)
    if spec is None or not path.exists():
        from scipy.integrate._ivp import dop853_coefficients

        return dop853_coefficients
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module
