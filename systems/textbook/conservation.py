"""The energy theorem along a run: dH/dt = -dL/dt (partial) + the power of the effects.

Along a solution of Lagrange's equations with generalized forces Q,
``dH/dt = -partial L / partial t + sum qdot_i Q_i``. For a rheonomic scene H changes
exactly as fast as L depends on t; for a scleronomic one H is conserved even where
T + V is not (a bead on a spinning hoop). ``energy_balance`` returns both sides for a
computed trajectory: the left side by differentiating the sampled H(t), the right side
from the formula at every sample.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
import scipy.interpolate
import sympy

from systems import matrix_solve
from systems.mechanics import Mechanics
from systems.textbook._numeric import cache_for, parameter_values, vectorize, with_parameters


@dataclass(frozen=True)
class EnergyBalance:
    """Both sides of the energy theorem along a sampled trajectory.

    Attributes
    ----------
    t : ndarray, shape (K,)
    hamiltonian : ndarray, shape (K,)
        H(q, p, t) at each sample.
    rate : ndarray, shape (K,)
        dH/dt from the sampled H(t) (the derivative of its not-a-knot cubic spline):
        the left side.
    partial : ndarray, shape (K,)
        -partial L / partial t = partial H / partial t at each sample.
    power : ndarray, shape (K,)
        sum qdot_i Q_i of the enabled effects (zero without effects).
    energy : ndarray, shape (K,), or None
        T + V where the scene defines both, to compare with H.
    """

    t: np.ndarray
    hamiltonian: np.ndarray
    rate: np.ndarray
    partial: np.ndarray
    power: np.ndarray
    energy: np.ndarray | None

    @property
    def predicted(self) -> np.ndarray:
        """The right side: ``partial + power``, shape (K,)."""
        return self.partial + self.power


def energy_balance(
    mechanics: Mechanics,
    t: np.ndarray,
    y: np.ndarray,
    *,
    parameters: Mapping[str, float] | None = None,
) -> EnergyBalance:
    """dH/dt along a trajectory and -dL/dt (partial) + effects' power at the same samples.

    Parameters
    ----------
    t : ndarray, shape (K,)
        Increasing sample times (K >= 3); dense samples make ``rate`` accurate (its error
        falls like the cube of the spacing).
    y : ndarray, shape (K, 2n)
        Canonical states (q, p), as ``systems.simulation`` streams them.
    """
    t = np.asarray(t, dtype=float)
    n = mechanics.n
    y = np.asarray(y, dtype=float).reshape(len(t), 2 * n)
    f = _functions(mechanics, parameters)
    columns = [t, *y.T]
    H, partial, power, energy = f(*columns)
    if len(t) >= 4:
        rate = scipy.interpolate.CubicSpline(t, H).derivative()(t)
    else:
        rate = np.gradient(H, t, edge_order=2)
    has_energy = mechanics.kinetic is not None and mechanics.potential is not None
    return EnergyBalance(
        t=t,
        hamiltonian=H,
        rate=rate,
        partial=partial,
        power=power,
        energy=energy if has_energy else None,
    )


def _functions(mechanics: Mechanics, parameters):
    """``f(t, q_1.., p_1..) -> (H, partial, power, energy)``, each shape (K,), cached.

    For a system in matrix form H, its partial t-derivative, the power and T + V are
    formed in (q, qdot, p, t) and the velocities of every sample are solved numerically
    from ``M(q, t) qdot = p - a(q, t)`` (``matrix_solve.batch_velocities``). The partial
    derivative is then -dL/dt at the solved velocities, which holds the time dependence of
    M(t) and a(t) as well as that of L0: H's expression with qdot left unsolved does not.
    """
    key = ("conservation", tuple(sorted((parameters or {}).items())))
    cache = cache_for(mechanics)
    if key in cache:
        return cache[key]
    form = mechanics.matrix_form
    to_velocities = dict(zip(mechanics.qdot, mechanics.velocities, strict=True))
    if mechanics.lagrangian is not None:
        partial = -sympy.diff(mechanics.lagrangian, mechanics.t).xreplace(to_velocities)
    elif form is not None:  # never: matrix form comes from a Lagrangian
        raise ValueError("a system in matrix form without a Lagrangian")
    else:
        partial = sympy.diff(mechanics.hamiltonian, mechanics.t)
    power = sum(
        (
            v * Q.xreplace(to_velocities)
            for v, Q in zip(mechanics.velocities, mechanics.generalized_forces, strict=True)
        ),
        sympy.S.Zero,
    )
    if mechanics.kinetic is not None and mechanics.potential is not None:
        energy = (mechanics.kinetic + mechanics.potential).xreplace(to_velocities)
    else:
        energy = sympy.S.Zero
    exprs = [mechanics.hamiltonian, partial, power, energy]
    exprs = [with_parameters(e, mechanics, parameters) for e in exprs]
    if form is None:
        f = vectorize(exprs, [mechanics.t, *mechanics.q, *mechanics.p])
    else:
        f = _solved(mechanics, exprs, parameters)
    cache[key] = f
    return f


def _solved(mechanics: Mechanics, exprs, parameters):
    """``vectorize`` over (t, q, p) of expressions in (t, q, qdot, p), for a system in
    matrix form: qdot is solved at every sample."""
    n = mechanics.n
    raw = vectorize(exprs, [mechanics.t, *mechanics.q, *mechanics.qdot, *mechanics.p])
    solve = matrix_solve.batch_velocities(mechanics, parameter_values(mechanics, parameters))

    def function(t, *columns) -> np.ndarray:
        t = np.asarray(t, dtype=float)
        Q = np.stack([np.asarray(c, dtype=float) for c in columns[:n]], axis=-1)
        P = np.stack([np.asarray(c, dtype=float) for c in columns[n:]], axis=-1)
        shape = np.broadcast_shapes(t.shape, Q.shape[:-1], P.shape[:-1])
        Q = np.broadcast_to(Q, (*shape, n)).reshape(-1, n)
        P = np.broadcast_to(P, (*shape, n)).reshape(-1, n)
        ts = np.broadcast_to(t, shape).reshape(-1)
        V = solve(ts, Q, P)
        out = raw(ts, *Q.T, *V.T, *P.T)
        return out.reshape(len(exprs), *shape)

    return function
