"""Periodic orbits by shooting and Newton's method, with their Floquet multipliers.

An orbit through y0 is periodic with period T when ``phi_T(y0) = y0`` (phi the flow of
Hamilton's equations). Newton's method corrects (y0, T) with the monodromy matrix M =
d phi_T / d y0, integrated with the orbit (``floquet.monodromy``):

- autonomous systems: unknowns y0 and T, equations ``phi_T(y0) - y0 = 0`` and the phase
  condition ``f(y0_k) . (y0 - y0_k) = 0`` (the correction is across the flow). A
  Hamiltonian orbit lies in a family (one per energy) and symmetries add more, so the
  linear system is singular: for a Hamiltonian flow the energy of the start is held
  (one more row, grad H . dy = H0 - H(y)), and each step is the least-squares
  (minimum-norm) solution with the directions of the symmetries dropped (``RCOND``).
  Two multipliers are 1 whatever the stability (along the orbit, across the energy
  levels) and are set aside by the verdict; symmetries (the figure-eight's translations
  and rotation) add more multipliers at 1, which are counted and reported.
- periodically driven systems: T is the drive's period (or a multiple), only y0 is
  corrected.

Without a period, the first close return of the orbit from the start is the guess
(``guess_period``).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
import scipy.integrate

from systems.expressions import as_expr
from systems.mechanics import Mechanics
from systems.textbook._numeric import fold_angle
from systems.textbook.floquet import (
    UNIT_TOLERANCE,
    VariationalSystem,
    Verdict,
    monodromy,
    periodicity,
    verdict,
)

TOLERANCE = 1e-9
"""Newton stops when |phi_T(y0) - y0| is below this (relative to max(1, |y0|))."""
RCOND = 1e-6
"""Singular values of Newton's matrix below this fraction of the largest are dropped: the
directions along the orbit's family (energy, symmetries), where the matrix is singular up
to the remaining gap; a minimum-norm step along them jumped to another orbit."""
MAX_ITERATIONS = 30
POLISH = 1e-13
"""Newton goes on past ``TOLERANCE`` while it still gains, down to this: the multipliers
at 1 split by about the square root of what is left."""
PATH_POINTS = 400
AT_ONE = 1e-3
"""Multipliers within this of 1 are counted as trivial (1 exactly up to the integration
and the Jordan blocks of the symmetries, which spread them by about sqrt(error))."""


@dataclass(frozen=True)
class PeriodicOrbit:
    """A periodic orbit found by shooting (or the best attempt).

    Attributes
    ----------
    names : tuple of str
        The state's names (q..., p_q...).
    start : ndarray (2n,)
        y0 on the orbit.
    period : float
    converged : bool
        |phi_T(y0) - y0| <= ``TOLERANCE`` max(1, |y0|).
    closure : float
        |phi_T(y0) - y0| at the end.
    iterations : int
    autonomous : bool
    multipliers : tuple of complex
        The eigenvalues of the monodromy matrix, largest modulus first.
    at_one : int
        How many multipliers are 1 within ``AT_ONE`` (2 for an autonomous orbit, more with
        symmetries).
    determinant : float
        det M (1 for a Hamiltonian flow).
    verdict : Verdict
        From the multipliers other than the ``at_one`` at 1 (autonomous), or all of them.
    path : ndarray (k, 2n)
        The orbit over one period at ``PATH_POINTS`` even times (for drawing).
    """

    names: tuple[str, ...]
    start: np.ndarray
    period: float
    converged: bool
    closure: float
    iterations: int
    autonomous: bool
    multipliers: tuple[complex, ...]
    at_one: int
    determinant: float
    verdict: Verdict
    path: np.ndarray | None = None

    @property
    def product(self) -> complex:
        """The product of the multipliers (det M)."""
        return complex(np.prod(np.array(self.multipliers)))

    def as_json(self) -> dict:
        """For ``periodic --json``."""
        return {
            "converged": self.converged,
            "period": self.period,
            "start": dict(zip(self.names, map(float, self.start), strict=True)),
            "closure": self.closure,
            "iterations": self.iterations,
            "autonomous": self.autonomous,
            "multipliers": [[float(m.real), float(m.imag)] for m in self.multipliers],
            "abs_multipliers": [float(abs(m)) for m in self.multipliers],
            "multipliers_at_one": self.at_one,
            "determinant": self.determinant,
            "stability": self.verdict.word,
            "reason": self.verdict.sentence,
        }

    def lines(self, digits: int = 10) -> list[str]:
        """The orbit for a person."""
        state = ", ".join(
            f"{n} = {v:.{digits}g}" for n, v in zip(self.names, self.start, strict=True)
        )
        found = "periodic orbit found" if self.converged else "NOT converged"
        lines = [
            f"{found} after {self.iterations} Newton steps: T = {self.period:.{digits}g}, "
            f"|φ_T(y0) − y0| = {self.closure:.2g}",
            f"start: {state}",
            "Floquet multipliers (eigenvalues of the monodromy matrix):",
        ]
        for m in self.multipliers:
            text = f"{m.real:.{digits}g}"
            if abs(m.imag) > 1e-12:
                text += f" {'+' if m.imag >= 0 else '−'} {abs(m.imag):.{digits}g}i"
            lines.append(f"  {text}   |μ| = {abs(m):.{digits}g}")
        trivial = (
            f"{self.at_one} at 1 (along the orbit, across the energy levels"
            + (", and the symmetries" if self.at_one > 2 else "")
            + ")"
            if self.autonomous
            else f"{self.at_one} at 1"
        )
        lines.append(f"{trivial}; product (det M) = {self.determinant:.12f}")
        lines.append(f"{self.verdict.word}: {self.verdict.sentence}")
        return lines


def _difference(system: VariationalSystem, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    d = np.asarray(a, dtype=float) - np.asarray(b, dtype=float)
    for i in system.angles:
        d[i] = fold_angle(d[i])
    return d


def guess_period(
    system: VariationalSystem, y0: np.ndarray, P: np.ndarray, t_max: float, *, cancel=None
) -> float | None:
    """The time of the first close return of the orbit from ``y0`` within ``t_max``: the
    first local minimum of |y(t) - y0| below a tenth of its largest value so far."""

    def rhs(t, y):
        if cancel is not None:
            cancel.check()
        return np.asarray(system.rhs(t, *y, *P), dtype=float).ravel()

    samples = 20001
    times = np.linspace(0.0, t_max, samples)
    solution = scipy.integrate.solve_ivp(
        rhs, (0.0, t_max), y0, method="DOP853", rtol=1e-10, atol=1e-12, t_eval=times
    )
    y = solution.y.T
    distance = np.array([np.linalg.norm(_difference(system, row, y0)) for row in y])
    t = solution.t
    farthest = 0.0
    for k in range(1, len(distance) - 1):
        farthest = max(farthest, distance[k])
        if (
            farthest > 0
            and distance[k] < 0.1 * farthest
            and distance[k] <= distance[k - 1]
            and distance[k] <= distance[k + 1]
        ):
            return float(t[k])
    return None


def find_periodic_orbit(
    system: VariationalSystem,
    y0: np.ndarray,
    P: np.ndarray,
    period: float,
    *,
    autonomous: bool = True,
    tolerance: float = TOLERANCE,
    max_iterations: int = MAX_ITERATIONS,
    cancel=None,
) -> PeriodicOrbit:
    """Newton's method on (y0, T) (autonomous) or y0 (driven, T fixed) from a guess."""
    y = np.asarray(y0, dtype=float).copy()
    T = float(period)
    m = 2 * system.n
    P = np.asarray(P, dtype=float)

    def flow(t, state):
        return np.asarray(system.rhs(t, *state, *P), dtype=float).ravel()

    energy_row = autonomous and system.symplectic and system.hamiltonian is not None
    if energy_row:  # stay on the start's energy level (the family's parameter)
        level = float(np.asarray(system.hamiltonian(0.0, *y, *P)).ravel()[0])
    result = monodromy(system, y, T, P, cancel=cancel)
    gap = _difference(system, result.final, y)
    iterations = 0
    size = max(1.0, float(np.linalg.norm(y)))
    while float(np.linalg.norm(gap)) > POLISH * size and iterations < max_iterations:
        iterations += 1
        M = result.matrix
        if autonomous:
            f_start = flow(0.0, y)
            f_end = flow(T, result.final)
            rows = m + 2 if energy_row else m + 1
            A = np.zeros((rows, m + 1))
            A[:m, :m] = M - np.eye(m)
            A[:m, m] = f_end
            A[m, :m] = f_start
            b = np.zeros(rows)
            b[:m] = -gap
            if energy_row:  # grad H = (-pdot, qdot)
                A[m + 1, :m] = np.concatenate([-f_start[system.n :], f_start[: system.n]])
                b[m + 1] = level - float(np.asarray(system.hamiltonian(0.0, *y, *P)).ravel()[0])
        else:
            A = M - np.eye(m)
            b = -gap
        step = np.linalg.lstsq(A, b, rcond=RCOND)[0]
        before = float(np.linalg.norm(gap))
        scale = 1.0
        while True:
            trial_y = y + scale * step[:m]
            trial_T = T + scale * step[m] if autonomous else T
            if trial_T <= 0:
                scale /= 2
                continue
            trial = monodromy(system, trial_y, trial_T, P, cancel=cancel)
            trial_gap = _difference(system, trial.final, trial_y)
            if float(np.linalg.norm(trial_gap)) < before or scale < 1e-3:
                break
            scale /= 2
        if float(np.linalg.norm(trial_gap)) >= before:  # no progress: the integration's limit
            iterations -= 1
            break
        y, T, result, gap = trial_y, trial_T, trial, trial_gap
        size = max(1.0, float(np.linalg.norm(y)))
    closure = float(np.linalg.norm(gap))
    mus = result.multipliers
    at_one = int(np.sum(np.abs(mus - 1.0) <= AT_ONE))
    trivial = min(at_one, mus.size) if autonomous else 0
    judged = verdict(mus, system.symplectic, trivial=trivial, tol=UNIT_TOLERANCE)
    names = (*system.names, *(f"p_{name}" for name in system.names))
    path = scipy.integrate.solve_ivp(
        flow,
        (0.0, T),
        y,
        method="DOP853",
        rtol=1e-10,
        atol=1e-12,
        t_eval=np.linspace(0.0, T, PATH_POINTS),
    ).y.T
    return PeriodicOrbit(
        names=names,
        start=y,
        period=T,
        converged=closure <= tolerance * size,
        closure=closure,
        iterations=iterations,
        autonomous=autonomous,
        multipliers=tuple(complex(mu) for mu in mus),
        at_one=at_one,
        determinant=result.determinant,
        verdict=judged,
        path=path,
    )


def start_state(mechanics: Mechanics, values: Mapping[str, float] | None = None) -> np.ndarray:
    """The canonical state (q, p) from the scene's initial values overridden by
    ``values`` (coordinates, ``<q>_dot`` velocities or ``p_<q>`` momenta; momenta
    given for every coordinate win, otherwise p = dL/dqdot of the velocities at t = 0).

    Raises
    ------
    ValueError
        An unknown name.
    """
    scene = mechanics.scene
    given = dict(scene.initial_values)
    allowed = set(scene.coordinates) | set(scene.velocity_names) | set(scene.momentum_names)
    for name in values or {}:
        if name not in allowed:
            raise ValueError(
                f"unknown name {name!r} in the start: use the coordinates, their velocities "
                f"(<q>_dot) or momenta (p_<q>): {', '.join(sorted(allowed))}"
            )
    if values:
        if any(name in scene.velocity_names for name in values):
            for name in scene.momentum_names:
                given.pop(name, None)
        given.update(values)
    q = np.array([float(given.get(name, 0.0)) for name in scene.coordinates])
    if all(name in given for name in scene.momentum_names) or mechanics.momenta is None:
        p = np.array([float(given.get(name, 0.0)) for name in scene.momentum_names])
        return np.concatenate([q, p])
    qdot = [float(given.get(name, 0.0)) for name in scene.velocity_names]
    point = {
        **dict(zip(mechanics.q, q, strict=True)),
        **dict(zip(mechanics.qdot, qdot, strict=True)),
        mechanics.t: 0.0,
        **{mechanics.params[k]: v for k, v in scene.parameter_values.items()},
    }
    # the derivation's momenta (symengine or sympy expressions, never text)
    p = np.array([float(as_expr(m).xreplace(point)) for m in mechanics.momenta])
    return np.concatenate([q, p])


def periodic_orbit(
    mechanics: Mechanics,
    start: Mapping[str, float] | None = None,
    *,
    period: float | None = None,
    parameters: Mapping[str, float] | None = None,
    t_max: float | None = None,
    cancel=None,
) -> PeriodicOrbit:
    """The periodic orbit near ``start`` (the scene's initial state by default).

    For an autonomous system, ``period`` is the guess (default: ``guess_period`` within
    ``t_max``, by default the scene's ``[view] t_end`` or 100); for a periodically driven
    one, the period is the drive's times ``round(period / T_drive)`` (default 1).

    Raises
    ------
    ValueError
        Why no orbit can be sought (matrix form, constraints, no close return,
        a non-periodic drive), for a person.
    """
    system = VariationalSystem.build(mechanics)
    P = system.parameter_vector(parameters)
    y0 = start_state(mechanics, start)
    if mechanics.classification.time_dependent:
        info = periodicity(mechanics, parameters)
        if not info.periodic:
            raise ValueError(f"the equations depend on t and are {info.reason}")
        drive = float(info.period)
        multiple = 1 if period is None else max(1, round(float(period) / drive))
        return find_periodic_orbit(system, y0, P, multiple * drive, autonomous=False, cancel=cancel)
    if period is None:
        horizon = t_max or float(mechanics.scene.view.get("t_end", 100.0) or 100.0)
        period = guess_period(system, y0, P, horizon, cancel=cancel)
        if period is None:
            raise ValueError(
                f"the orbit from this start does not come back near it within t = "
                f"{horizon:g}: give a period guess (--period) or a longer --t-max"
            )
    if not math.isfinite(period) or period <= 0:
        raise ValueError("the period must be a positive number")
    return find_periodic_orbit(system, y0, P, float(period), autonomous=True, cancel=cancel)
