"""The Action-angle tab: J(E) and T(E) of a one-degree system up past the separatrix."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import scipy.special
import sympy

from systems.display import pretty_name
from systems.textbook.action_angle import action_angle
from systems.textbook.equilibria import EquilibriumSearch, equilibrium_potential, search_equilibria
from systems.textbook.jobs._cancel import NEVER, Cancel
from systems.textbook.jobs._run import names_of, parameters_of

if TYPE_CHECKING:
    from systems.compiled import CompiledSystem


@dataclass(frozen=True)
class ActionAngleResult:
    """J(E) and T(E) of a one-degree system, with the separatrix and an exact check.

    Attributes
    ----------
    energies, action, period : ndarray
        NaN where there is no bounded motion through ``q0``.
    motion : list[str]
    q0 : float
        The stable equilibrium the motions pass through.
    minimum : float
        U at that equilibrium.
    separatrix : float or None
        The lowest U of an unstable equilibrium above the minimum.
    small_period : float or None
        2 pi / omega of small oscillations.
    exact : ndarray or None
        For U = u0 - c cos(q) with constant mass: the exact libration period
        ``4 sqrt(M/c) K(k^2)``, ``k^2 = (E - U_min) / (2c)`` (NaN above the separatrix).
    exact_formula : str
        That formula in words, for the legend ("" when there is no exact period).
    current : float
        The energy of the initial state.
    current_action, current_period : float or None
        J and T of the initial state's own orbit (None if it is not periodic).
    """

    energies: np.ndarray
    action: np.ndarray
    period: np.ndarray
    motion: list[str]
    q0: float
    minimum: float
    separatrix: float | None
    small_period: float | None
    exact: np.ndarray | None
    exact_formula: str
    current: float
    current_action: float | None = None
    current_period: float | None = None


def action_angle_reason(compiled: CompiledSystem) -> str:
    """Why the action-angle tab does not apply to this system ("" if it does)."""
    mechanics = compiled.mechanics
    if compiled.n != 1:
        return (
            f"action–angle variables are shown for one-degree systems; this one has {compiled.n} "
            "coordinates"
        )
    if mechanics.hamiltonian.has(mechanics.t):
        return "H depends explicitly on t: there are no fixed level sets H = E to integrate over"
    if any(f != 0 for f in mechanics.generalized_forces):
        return "effects (dissipation or forces) are switched on: the motion is not on H = E"
    return ""


def action_angle_table(compiled: CompiledSystem, cancel: Cancel = NEVER) -> ActionAngleResult:
    """What the Action-angle tab shows, in one job: the equilibria (for the well and the
    separatrix), then J and T over the energies (``action_angle_data``).

    Raises
    ------
    ValueError
        If the tab does not apply (``action_angle_reason``) or there is no stable
        equilibrium.
    Cancelled
    """
    reason = action_angle_reason(compiled)
    if reason:
        raise ValueError(reason)
    cancel.check()
    search = search_equilibria(compiled.mechanics, parameters=parameters_of(compiled))
    cancel.check()
    return action_angle_data(compiled, search, cancel=cancel)


def action_angle_data(
    compiled: CompiledSystem,
    equilibria_search: EquilibriumSearch,
    count: int = 160,
    cancel: Cancel = NEVER,
) -> ActionAngleResult:
    """J and T over energies from the bottom of the well to past the separatrix.

    Parameters
    ----------
    compiled : CompiledSystem
        A one-degree system (see ``action_angle_reason``); wants ``hamiltonian``.
    equilibria_search : EquilibriumSearch
        Its equilibria at the same parameter values (the wells and separatrices).
    count : int
        Number of energies.
    cancel : Cancel

    Returns
    -------
    ActionAngleResult

    Raises
    ------
    ValueError
        If the tab does not apply, or there is no stable equilibrium.
    Cancelled
    """

    reason = action_angle_reason(compiled)
    if reason:
        raise ValueError(reason)
    mechanics = compiled.mechanics
    parameters = parameters_of(compiled)
    name = names_of(compiled)[0]
    stable = [e for e in equilibria_search.equilibria if e.stable]
    state = compiled.initial_state()
    current = float(compiled.hamiltonian(0.0, state[None, :])[0])
    if not stable:
        raise ValueError("there is no stable equilibrium, so no librations to measure")
    # the well the current state is in, if it is in one; else the lowest
    well = min(stable, key=lambda e: (abs(e.q[name] - state[0]), e.potential))
    q0, minimum = float(well.q[name]), float(well.potential)
    above = [e.potential for e in equilibria_search.equilibria if not e.stable]
    above = [u for u in above if u > minimum + 1e-12]
    separatrix = min(above) if above else None
    scale = (separatrix - minimum) if separatrix is not None else max(current - minimum, 1.0)
    top = minimum + (2.0 if separatrix is not None else 1.5) * scale
    # below the separatrix: cluster samples towards it (T grows like log there)
    s = np.linspace(0.0, 1.0, count // 2 + 1)[1:]
    below = minimum + scale * (1.0 - (1.0 - s) ** 2 * 0.999 - 1e-4 * (1.0 - s))
    if separatrix is not None:
        after = (
            separatrix + (top - separatrix) * np.linspace(0.0, 1.0, count - count // 2 + 1)[1:] ** 2
        )
        after = np.maximum(after, separatrix + 1e-6 * scale)
        energies = np.concatenate([below, after])
    else:
        energies = minimum + (top - minimum) * np.linspace(0.0, 1.0, count + 1)[1:]
    J, T, motion = np.full(len(energies), np.nan), np.full(len(energies), np.nan), []
    for j, E in enumerate(energies):
        cancel.check()
        try:
            with np.errstate(all="ignore"):
                result = action_angle(mechanics, E, q0=q0, parameters=parameters)
        except (ValueError, ArithmeticError):
            motion.append("")
            continue
        J[j], T[j] = result.action, result.period
        motion.append(result.motion)
    small = None
    if well.frequencies:
        small = 2 * math.pi / float(well.frequencies[0])
    exact, formula = _pendulum_exact(mechanics, parameters, energies, minimum)
    own_action = own_period = None
    for through in (q0, float(state[0])):  # the state itself may sit at a turning point
        try:
            with np.errstate(all="ignore"):
                own = action_angle(mechanics, current, q0=through, parameters=parameters)
        except (ValueError, ArithmeticError):
            continue
        own_action, own_period = float(own.action), float(own.period)
        break
    return ActionAngleResult(
        energies,
        J,
        T,
        motion,
        q0,
        minimum,
        separatrix,
        small,
        exact,
        formula,
        current,
        own_action,
        own_period,
    )


def _pendulum_exact(mechanics, parameters, energies, minimum):
    """The exact libration period when U = u0 - c cos(q + phase) and M is constant."""

    q = mechanics.q[0]
    values = {mechanics.params[k]: v for k, v in parameters.items() if k in mechanics.params}
    U = sympy.expand(equilibrium_potential(mechanics)[0].xreplace(values))
    M = sympy.simplify(mechanics.mass_matrix[0, 0].xreplace(values))
    if M.free_symbols:
        return None, ""
    a = U.coeff(sympy.cos(q))
    rest = sympy.simplify(U - a * sympy.cos(q))
    if rest.has(q) or a.free_symbols or not a.is_number or float(a) >= 0:
        return None, ""
    c, mass = -float(a), float(M)
    k2 = (np.asarray(energies) - minimum) / (2 * c)
    with np.errstate(all="ignore"):
        exact = np.where(
            (k2 > 0) & (k2 < 1),
            4 * math.sqrt(mass / c) * scipy.special.ellipk(np.clip(k2, 0, 1 - 1e-16)),
            np.nan,
        )
    qname = pretty_name(mechanics.scene.coordinates[0])
    formula = f"4·√(M/c)·K(k²), U = −c cos {qname}, k² = (E − U_min)/(2c)"
    return exact, formula
