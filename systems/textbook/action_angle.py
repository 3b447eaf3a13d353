"""Action-angle quantities of one-degree autonomous systems: J(E) and T(E) = dJ/dE.

For ``H = W(q) (p - a(q))^2 / 2 + U(q)`` (any H quadratic in p; W = d2H/dp2 > 0) the
level set H = E has ``p = a +- sqrt(2 (E - U) / W)`` and ``qdot = +- sqrt(2 W (E - U))``.

- Libration (E - U > 0 between turning points q- < q+): ``J = 2 integral sqrt(2(E-U)/W) dq``
  and ``T = 2 integral dq / sqrt(2 W (E - U))``. The substitution
  ``q = c + w sin(phi)`` (c, w the centre and half-width of [q-, q+]) removes the square
  root endpoint singularity: with ``g = (E - U) / ((q+ - q)(q - q-))``,
  ``T = 2 integral_{-pi/2}^{pi/2} dphi / sqrt(2 W g)`` and
  ``J = 2 w^2 integral cos^2(phi) sqrt(2 g / W) dphi``, smooth integrands summed by
  Gauss-Legendre rules of doubling order until they agree.
- Rotation (a 2 pi-periodic H with E above U everywhere): p over one full turn,
  ``J = integral_{-pi}^{pi} (sqrt(2(E-U)/W) + s a) dq`` for motion in the direction s, and
  ``T = integral dq / sqrt(2 W (E - U))``; the integrands are periodic, so the trapezoid
  rule converges geometrically.

J here is the closed integral of p dq itself (some books divide it by 2 pi); the angular
frequency is ``2 pi / T``. T is computed as its own integral, not by differentiating J.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
import scipy.special
import sympy

from systems.mechanics import Mechanics
from systems.textbook._numeric import (
    TWO_PI,
    bracket_around,
    cache_for,
    is_periodic,
    vectorize,
    with_parameters,
)

MAX_NODES = 1 << 12


@dataclass(frozen=True)
class ActionAngle:
    """Action and period of the motion with a given energy.

    Attributes
    ----------
    energy : float
    motion : str
        ``"libration"`` (back and forth between turning points) or ``"rotation"``
        (a full turn of a periodic coordinate).
    action : float
        J = closed integral of p dq.
    period : float
        T = dJ/dE.
    frequency : float
        The angular frequency 2 pi / T.
    turning_points : tuple[float, float] or None
        (q-, q+) for a libration.
    converged : bool
        False if the quadrature did not settle (very close to a separatrix).
    """

    energy: float
    motion: str
    action: float
    period: float
    frequency: float
    turning_points: tuple[float, float] | None
    converged: bool


def action_angle(
    mechanics: Mechanics,
    energy: float,
    *,
    q0: float = 0.0,
    direction: int = 1,
    parameters: Mapping[str, float] | None = None,
    rtol: float = 1e-11,
) -> ActionAngle:
    """J(E) and T(E) for the motion of energy ``energy`` through the point ``q0``.

    Parameters
    ----------
    mechanics : Mechanics
        One coordinate, H independent of t, no enabled effects, H quadratic in p.
    energy : float
    q0 : float
        A point the motion passes through (inside the well for a libration), with
        U(q0) < energy.
    direction : +1 or -1
        The sense of a rotation (ignored for a libration).

    Raises
    ------
    ValueError
        For a system that does not qualify, or an energy with no motion through q0, or
        an unbounded motion (no turning point on one side, not periodic).
    """
    parts = _parts(mechanics, parameters)
    U, W, a, periodic = parts["U"], parts["W"], parts["a"], parts["periodic"]
    energy = float(energy)
    if not U(np.array([q0]))[0] < energy:
        raise ValueError(f"no motion through q = {q0}: U(q0) is not below the energy {energy}")
    if periodic:
        step, limit, growth = TWO_PI / 2048, TWO_PI, 1.0
    else:
        step, limit, growth = 1e-3 * max(1.0, abs(q0)), 1e6 * max(1.0, abs(q0)), 1.05
    below = bracket_around(U, energy, q0, -1, first_step=step, limit=limit, growth=growth)
    above = bracket_around(U, energy, q0, +1, first_step=step, limit=limit, growth=growth)
    if below is not None and above is not None:
        return _libration(U, W, energy, below, above, rtol)
    if periodic:
        return _rotation(U, W, a, energy, q0, int(np.sign(direction) or 1), rtol)
    raise ValueError(f"the motion of energy {energy} through q = {q0} is unbounded")


def action_angle_table(
    mechanics: Mechanics,
    energies: Sequence[float] | np.ndarray,
    *,
    q0: float = 0.0,
    direction: int = 1,
    parameters: Mapping[str, float] | None = None,
) -> tuple[np.ndarray, np.ndarray, list[str]]:
    """J(E) and T(E) over many energies, for a plot against E.

    Returns
    -------
    J, T : ndarray, shape (E,)
        NaN where there is no bounded motion through q0.
    motion : list[str]
        ``"libration"``, ``"rotation"`` or ``""`` per energy.
    """
    energies = np.asarray(energies, dtype=float)
    J, T, motion = np.full(energies.shape, np.nan), np.full(energies.shape, np.nan), []
    for i, E in enumerate(energies):
        try:
            result = action_angle(mechanics, E, q0=q0, direction=direction, parameters=parameters)
        except ValueError:
            motion.append("")
            continue
        J[i], T[i] = result.action, result.period
        motion.append(result.motion)
    return J, T, motion


# -- the integrals ----------------------------------------------------------------------------


def _libration(U, W, E, lo, hi, rtol) -> ActionAngle:
    c, w = (hi + lo) / 2, (hi - lo) / 2

    def integrals(nodes):
        phi, weights = _gauss(nodes)
        s = np.sin(phi)
        q = c + w * s
        with np.errstate(all="ignore"):
            g = (E - U(q)) / (w * w * (1 - s) * (1 + s))
            Wq = W(q)
            period = 2 * np.sum(weights / np.sqrt(2 * Wq * g))
            action = 2 * w * w * np.sum(weights * np.cos(phi) ** 2 * np.sqrt(2 * g / Wq))
        return action, period

    (action, period), converged = _converge(integrals, rtol)
    return ActionAngle(E, "libration", action, period, TWO_PI / period, (lo, hi), converged)


def _rotation(U, W, a, E, q0, direction, rtol) -> ActionAngle:
    def integrals(nodes):
        q = q0 - math.pi + TWO_PI * np.arange(nodes) / nodes
        h = TWO_PI / nodes
        with np.errstate(all="ignore"):
            kinetic = 2 * (E - U(q))
            Wq = W(q)
            period = h * np.sum(1 / np.sqrt(kinetic * Wq))
            action = h * np.sum(np.sqrt(kinetic / Wq) + direction * a(q))
        return action, period

    (action, period), converged = _converge(integrals, rtol)
    return ActionAngle(E, "rotation", action, period, TWO_PI / period, None, converged)


def _converge(integrals, rtol):
    """Double the nodes until two estimates agree to ``rtol``.

    Rounding in E - U(q) next to the turning points (U is a difference of large numbers
    in a shallow well) grows with the number of nodes, so doubling also stops once the
    change grows again: the estimate with the smallest change is returned, and it counts
    as converged if that change is below ``1000 * rtol``.
    """
    nodes = 16
    previous = integrals(nodes)
    best, best_change = previous, math.inf
    while nodes < MAX_NODES:
        nodes *= 2
        current = integrals(nodes)
        if not all(np.isfinite(x) for x in current):
            break
        change = max(
            abs(x - y) / abs(x) if x != 0 else abs(x - y)
            for x, y in zip(current, previous, strict=True)
        )
        if change < best_change:
            best, best_change = current, change
        elif change > 10 * best_change:
            break
        if change <= rtol:
            break
        previous = current
    return best, bool(best_change <= 1e3 * rtol)


@lru_cache(maxsize=16)
def _gauss(nodes: int) -> tuple[np.ndarray, np.ndarray]:
    """Gauss-Legendre nodes and weights on [-pi/2, pi/2]."""
    x, weights = scipy.special.roots_legendre(nodes)
    return x * (math.pi / 2), weights * (math.pi / 2)


def _parts(mechanics: Mechanics, parameters) -> dict:
    """U(q), W(q), a(q) as vectorized functions, and whether H is 2 pi-periodic."""
    if mechanics.n != 1:
        raise ValueError("action-angle variables are computed for one-degree systems only")
    if mechanics.hamiltonian.has(mechanics.t):
        raise ValueError("action-angle variables need an autonomous system (H without t)")
    if any(f != 0 for f in mechanics.generalized_forces):
        raise ValueError("action-angle variables need a conservative system (no effects)")
    key = ("action_angle", tuple(sorted((parameters or {}).items())))
    cache = cache_for(mechanics)
    if key in cache:
        return cache[key]
    (q,), (p,) = mechanics.q, mechanics.p
    H = with_parameters(mechanics.hamiltonian, mechanics, parameters)
    try:
        degree = sympy.Poly(sympy.expand(H), p).degree()
    except sympy.PolynomialError:
        degree = None
    W = sympy.diff(H, p, 2)
    if degree != 2 or W.has(p):
        raise ValueError("action-angle quadratures need H quadratic in the momentum")
    a = -sympy.diff(H, p).xreplace({p: 0}) / W
    U = H.xreplace({p: a})
    f_U, f_W, f_a = (vectorize([e], [q]) for e in (U, W, a))
    parts = {
        "U": lambda x: f_U(x)[0],
        "W": lambda x: f_W(x)[0],
        "a": lambda x: f_a(x)[0],
        "periodic": is_periodic(H, q, [p]),
    }
    cache[key] = parts
    return parts
