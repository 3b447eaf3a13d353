"""A plain numpy Taylor integrator: the *reference* for the compiled family, not a method.

Nothing registers it (``systems.integrators.registry`` knows nothing of it) and nothing
should run it for speed: every step is Python loops over orders and nodes
(``coefficients.taylor_coefficients``). It pins down what the compiled family must do,
step by step, so that family can be tested against it:

- **order** from the tolerance (Jorba & Zou 2005, section 3.2; heyoka's choice):
  ``p = ceil(-ln(tol) / 2 + 1)``, 20 at machine epsilon (``coefficients.jorba_zou``);
- **step** from the last two coefficients: with the absolute and relative tolerances
  equal, the norms relative to ``max(1, |y|_inf)``,
  ``rho = min((1 / |[y]_{p-1}|)^(1/(p-1)), (1 / |[y]_p|)^(1/p))`` estimates the radius of
  convergence, and ``h = rho / e^2 * exp(-0.7 / (p - 1))`` (Jorba & Zou's
  ``rho / e^2`` with heyoka's safety factor), which makes the truncation error about
  the tolerance;
- the series summed by Horner's rule (the compiled family adds compensated summation).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from systems.taylor.coefficients import horner, jorba_zou, taylor_coefficients
from systems.taylor.decompose import Decomposition

EPSILON = float(np.finfo(float).eps)


def step_size(coefficients: np.ndarray, order: int) -> float:
    """Jorba and Zou's step from the last two of ``coefficients`` (order + 1, m)."""
    scale = max(1.0, float(np.abs(coefficients[0]).max()))
    radii = []
    for k in (order - 1, order):
        norm = float(np.abs(coefficients[k]).max()) / scale
        radii.append(math.inf if norm == 0.0 else norm ** (-1.0 / k))
    rho = min(radii)
    return rho / math.e**2 * math.exp(-0.7 / (order - 1))


@dataclass(frozen=True)
class Step:
    """One Taylor step: ``t``, ``y`` (m,) after it, its length ``h``, its ``order`` and the
    ``coefficients`` (order + 1, m) at its start (the dense output: ``horner(c, s)``)."""

    t: float
    y: np.ndarray
    h: float
    order: int
    coefficients: np.ndarray


def taylor_step(
    decomposition: Decomposition,
    t: float,
    y: np.ndarray,
    P: np.ndarray,
    tolerance: float = EPSILON,
    t_end: float = math.inf,
) -> Step:
    """One step from ``(t, y)`` (y (m,)), of Jorba and Zou's order and length, cut at
    ``t_end``."""
    order = max(2, jorba_zou(tolerance))
    c = taylor_coefficients(decomposition, t, y, P, order)
    h = step_size(c, order)
    if not math.isfinite(h):  # a polynomial solution: every coefficient zero
        h = t_end - t if math.isfinite(t_end) else 1.0
    h = min(h, t_end - t)
    return Step(t + h, horner(c, h), h, order, c)


def integrate(
    decomposition: Decomposition,
    t0: float,
    y0: np.ndarray,
    P: np.ndarray,
    t_end: float,
    tolerance: float = EPSILON,
    max_steps: int = 1_000_000,
) -> tuple[np.ndarray, np.ndarray]:
    """Taylor steps from ``t0`` to ``t_end``: the times (S + 1,) and states (S + 1, m).

    Raises
    ------
    RuntimeError
        After ``max_steps`` steps or at a state that is not finite.
    """
    times, states = [float(t0)], [np.asarray(y0, dtype=float)]
    t, y = float(t0), states[0]
    while t < t_end:
        if len(times) > max_steps:
            raise RuntimeError(f"more than {max_steps} Taylor steps before t = {t_end}")
        step = taylor_step(decomposition, t, y, P, tolerance, t_end)
        if not np.all(np.isfinite(step.y)) or step.h <= 0.0:
            raise RuntimeError(f"the Taylor step from t = {t} failed (h = {step.h})")
        t, y = (t_end if step.t >= t_end else step.t), step.y
        times.append(t)
        states.append(y)
    return np.array(times), np.array(states)
