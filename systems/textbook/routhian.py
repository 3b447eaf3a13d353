"""Routhian reduction: cyclic coordinates removed, their momenta held as constants.

For cyclic coordinates q_c (absent from L, with no force on them) the momenta p_c are
conserved. The Routhian ``R(q_r, qdot_r, t; p_c) = L - sum p_c qdot_c`` (qdot_c eliminated
through p_c = dL/dqdot_c) is a Lagrangian for the remaining coordinates q_r alone. Its
velocity-free part gives the effective potential ``V_eff(q_r; p_c) = -R(q_r, qdot_r=0; p_c)``
(planetary motion: ``p_theta^2/(2 m r^2) - k/r``). The reduced Hamiltonian is H itself
read as a function of (q_r, p_r) with p_c a parameter (H does not contain q_c).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
import scipy.integrate
import sympy

from systems.mechanics import Mechanics
from systems.textbook._numeric import (
    NeedsClosedForm,
    bracket_around,
    cache_for,
    closed_form_reason,
    level_crossings,
    vectorize,
    with_parameters,
)


@dataclass(frozen=True, eq=False)
class Reduction:
    """The system reduced by its cyclic coordinates.

    Attributes
    ----------
    mechanics : Mechanics
    cyclic, rest : tuple[str, ...]
        The removed coordinates (c of them) and the remaining ones (r).
    cyclic_momenta : tuple[sympy.Symbol, ...]
        The constants p_c (the scene's momentum symbols ``p_<q>``).
    routhian : sympy.Expr or None
        R(q_r, qdot_r, t; p_c) = L - sum p_c qdot_c; None for a Hamiltonian-only scene.
    effective_potential : sympy.Expr
        V_eff(q_r; p_c) (at t = 0 if R depends on t).
    reduced_hamiltonian : sympy.Expr
        H(q_r, p_r, t; p_c).
    reduced_equations : tuple[sympy.Expr, ...]
        ``(qdot_r..., pdot_r...)``, 2r expressions in (q_r, p_r, t; p_c), with effects.
    cyclic_velocities : tuple[sympy.Expr, ...]
        qdot_c(q_r, p_r, t; p_c), to reconstruct the cyclic coordinates by quadrature.

    The numeric functions of V_eff and H_red are made once per parameter values and kept
    with the reduction, and pickled with it: a reduction made in a worker process comes
    back with the functions it made there, and nothing is lambdified again.
    """

    mechanics: Mechanics
    cyclic: tuple[str, ...]
    rest: tuple[str, ...]
    cyclic_momenta: tuple[sympy.Symbol, ...]
    routhian: sympy.Expr | None
    effective_potential: sympy.Expr
    reduced_hamiltonian: sympy.Expr
    reduced_equations: tuple[sympy.Expr, ...]
    cyclic_velocities: tuple[sympy.Expr, ...]
    _functions: dict = field(default_factory=dict, repr=False)

    @property
    def rest_symbols(self) -> tuple[sympy.Symbol, ...]:
        names = self.mechanics.scene.coordinates
        return tuple(self.mechanics.q[names.index(name)] for name in self.rest)

    @property
    def rest_momenta(self) -> tuple[sympy.Symbol, ...]:
        names = self.mechanics.scene.coordinates
        return tuple(self.mechanics.p[names.index(name)] for name in self.rest)

    def effective_potential_function(
        self, parameters: Mapping[str, float] | None = None
    ) -> Callable[[np.ndarray, Sequence[float]], np.ndarray]:
        """``V_eff(q_rest, p_cyclic) -> (K,)``; q_rest shape (K,) for r = 1 or (K, r)."""
        f = self._numeric("V_eff", [self.effective_potential], [*self.rest_symbols], parameters)

        def V_eff(q_rest, p_cyclic) -> np.ndarray:
            q_rest = _as_rows(q_rest, len(self.rest))
            return f(*q_rest.T, *np.asarray(p_cyclic, dtype=float).ravel())[0]

        return V_eff

    def reduced_hamiltonian_function(
        self, parameters: Mapping[str, float] | None = None
    ) -> Callable[..., np.ndarray]:
        """``H_red(q_rest (K, r), p_rest (K, r), p_cyclic (c,), t=0.0) -> (K,)``."""
        args = [*self.rest_symbols, *self.rest_momenta]
        f = self._numeric("H_red", [self.reduced_hamiltonian], args, parameters, with_t=True)

        def H_red(q_rest, p_rest, p_cyclic, t=0.0) -> np.ndarray:
            r = len(self.rest)
            q_rest, p_rest = _as_rows(q_rest, r), _as_rows(p_rest, r)
            p_c = np.asarray(p_cyclic, dtype=float).ravel()
            return f(*q_rest.T, *p_rest.T, *p_c, t)[0]

        return H_red

    def _numeric(self, name, exprs, args, parameters, with_t=False):
        key = (name, tuple(sorted((parameters or {}).items())))
        cache = self._functions
        if key not in cache:
            exprs = [with_parameters(e, self.mechanics, parameters) for e in exprs]
            extra = [self.mechanics.t] if with_t else []
            cache[key] = vectorize(exprs, [*args, *self.cyclic_momenta, *extra])
        return cache[key]


@dataclass(frozen=True)
class ReducedRun:
    """A run of the reduced dynamics.

    Attributes
    ----------
    t : ndarray, shape (K,)
    q_rest, p_rest : ndarray, shape (K, r)
    q_cyclic : ndarray, shape (K, c)
        The cyclic coordinates reconstructed by quadrature of qdot_c.
    """

    t: np.ndarray
    q_rest: np.ndarray
    p_rest: np.ndarray
    q_cyclic: np.ndarray


def reduce(mechanics: Mechanics, cyclic: Sequence[str] | None = None) -> Reduction:
    """Routhian reduction by the given cyclic coordinates (default: every conserved one).

    Raises
    ------
    ValueError
        If the scene has constraints, a named coordinate is not cyclic or its momentum is
        not conserved (a force acts on it), or there is nothing left to reduce to.
    NeedsClosedForm
        (a ValueError) For a system in matrix form (``Mechanics.matrix_form``): its H and
        Hamilton's equations hold the velocities unsolved, so there is no reduced H.
    """
    from systems.constraints import constrained

    if constrained(mechanics.scene):
        # the reduced system would still carry the constraints (a floor, rolling), which
        # the reduced H and its portrait leave out: a wrong picture
        raise ValueError(
            "the scene has [constraints]: Routh's reduction here works on free coordinates "
            "and would leave them out of the reduced system (not done yet for constrained "
            "systems)"
        )
    names = mechanics.scene.coordinates
    conserved = [name for name in mechanics.cyclic if f"p_{name}" in mechanics.conserved]
    cyclic = tuple(conserved if cyclic is None else cyclic)
    if not cyclic:
        raise ValueError("the system has no cyclic coordinate with a conserved momentum")
    for name in cyclic:
        if name not in conserved:
            raise ValueError(f"{name!r} is not a cyclic coordinate with a conserved momentum")
    rest = tuple(name for name in names if name not in cyclic)
    if not rest:
        raise ValueError("every coordinate is cyclic: nothing is left after reduction")
    reason = closed_form_reason(mechanics, "Routh's reduction")
    if reason:  # H_red and the reduced equations would hold unsolved velocities
        raise NeedsClosedForm(reason)
    ci = [names.index(name) for name in cyclic]
    ri = [names.index(name) for name in rest]
    p_c = tuple(mechanics.p[i] for i in ci)
    H = mechanics.hamiltonian
    equations = mechanics.hamilton_equations
    n = mechanics.n
    reduced_equations = tuple(equations[i] for i in ri) + tuple(equations[n + i] for i in ri)
    cyclic_velocities = tuple(mechanics.velocities[i] for i in ci)
    routhian = None
    if mechanics.lagrangian is not None:
        L = mechanics.lagrangian
        v_c = [mechanics.qdot[i] for i in ci]
        equations_c = [sympy.diff(L, v) - p for v, p in zip(v_c, p_c, strict=True)]
        solved = sympy.solve(equations_c, v_c, dict=True)
        if len(solved) != 1:
            raise ValueError("the cyclic momenta could not be solved for the cyclic velocities")
        substitution = solved[0]
        R = L - sum(p * v for p, v in zip(p_c, v_c, strict=True))
        routhian = _tidy(R.xreplace(substitution))
        zero = {mechanics.qdot[i]: sympy.S.Zero for i in ri}
        V_eff = _tidy(-routhian.xreplace(zero).xreplace({mechanics.t: sympy.S.Zero}))
    else:
        zero = {mechanics.p[i]: sympy.S.Zero for i in ri}
        V_eff = _tidy(H.xreplace(zero).xreplace({mechanics.t: sympy.S.Zero}))
    return Reduction(
        mechanics=mechanics,
        cyclic=cyclic,
        rest=rest,
        cyclic_momenta=p_c,
        routhian=routhian,
        effective_potential=V_eff,
        reduced_hamiltonian=H,
        reduced_equations=reduced_equations,
        cyclic_velocities=cyclic_velocities,
    )


def turning_points(
    reduction: Reduction,
    energy: float,
    p_cyclic: Sequence[float],
    lo: float,
    hi: float,
    *,
    parameters: Mapping[str, float] | None = None,
    samples: int = 4001,
) -> np.ndarray:
    """Every q in [lo, hi] with V_eff(q; p_c) = energy (one remaining coordinate).

    A grid (log-spaced for 0 < lo, hi/lo > 100) locates sign changes; brentq refines them.

    Returns
    -------
    ndarray, shape (m,)
        Ascending.
    """
    _one_rest(reduction)
    V = reduction.effective_potential_function(parameters)
    return level_crossings(lambda q: V(q, p_cyclic), energy, lo, hi, samples)


def motion_interval(
    reduction: Reduction,
    energy: float,
    p_cyclic: Sequence[float],
    q0: float,
    *,
    parameters: Mapping[str, float] | None = None,
) -> tuple[float | None, float | None]:
    """The turning points that enclose the motion through q0 (None for an open side).

    The nearest q below and above ``q0`` where V_eff(q; p_c) rises to ``energy``.
    """
    _one_rest(reduction)
    V = reduction.effective_potential_function(parameters)

    def f(q):
        return V(q, p_cyclic)

    step = 1e-3 * max(1.0, abs(q0))
    limit = 1e6 * max(1.0, abs(q0))
    below = bracket_around(f, energy, q0, -1, first_step=step, limit=limit)
    above = bracket_around(f, energy, q0, +1, first_step=step, limit=limit)
    return below, above


def integrate_reduced(
    reduction: Reduction,
    q_rest0: Sequence[float],
    p_rest0: Sequence[float],
    p_cyclic: Sequence[float],
    t_eval: np.ndarray,
    *,
    q_cyclic0: Sequence[float] | None = None,
    parameters: Mapping[str, float] | None = None,
    rtol: float = 1e-11,
) -> ReducedRun:
    """Integrate the reduced Hamilton's equations (and reconstruct the cyclic angles).

    Parameters
    ----------
    q_rest0, p_rest0 : sequence of r floats
    p_cyclic : sequence of c floats
        The conserved momenta.
    t_eval : ndarray, shape (K,)
        Increasing output times; the run starts at t_eval[0].
    q_cyclic0 : sequence of c floats, optional
        Initial cyclic coordinates (default 0).
    """
    mechanics = reduction.mechanics
    r, c = len(reduction.rest), len(reduction.cyclic)
    key = ("routhian", "rhs", tuple(sorted((parameters or {}).items())))
    cache = cache_for(mechanics)
    if key not in cache:
        exprs = [*reduction.reduced_equations, *reduction.cyclic_velocities]
        exprs = [with_parameters(e, mechanics, parameters) for e in exprs]
        args = [
            mechanics.t,
            *reduction.rest_symbols,
            *reduction.rest_momenta,
            *reduction.cyclic_momenta,
        ]
        cache[key] = vectorize(exprs, args)
    f = cache[key]
    p_c = np.asarray(p_cyclic, dtype=float).ravel()

    def rhs(t, y):
        return f(t, *y[: 2 * r], *p_c)

    t_eval = np.asarray(t_eval, dtype=float)
    q_c0 = np.zeros(c) if q_cyclic0 is None else np.asarray(q_cyclic0, dtype=float)
    y0 = np.concatenate([np.asarray(q_rest0, float), np.asarray(p_rest0, float), q_c0])
    result = scipy.integrate.solve_ivp(
        rhs,
        (t_eval[0], t_eval[-1]),
        y0,
        method="DOP853",
        t_eval=t_eval,
        rtol=rtol,
        atol=rtol * 1e-2,
    )
    if result.status != 0:
        raise RuntimeError(f"the reduced run failed: {result.message}")
    y = result.y.T
    return ReducedRun(t=result.t, q_rest=y[:, :r], p_rest=y[:, r : 2 * r], q_cyclic=y[:, 2 * r :])


def _one_rest(reduction: Reduction) -> None:
    if len(reduction.rest) != 1:
        raise ValueError("turning points need exactly one remaining coordinate")


def _as_rows(values, r: int) -> np.ndarray:
    values = np.asarray(values, dtype=float)
    if r == 1 and values.ndim <= 1:
        return values.reshape(-1, 1)
    return np.atleast_2d(values).reshape(-1, r)


def _tidy(expr: sympy.Expr) -> sympy.Expr:
    candidates = [expr, sympy.cancel(sympy.together(expr)), sympy.expand(expr)]
    return min(candidates, key=lambda e: (e.count_ops(), len(str(e))))
