"""The current system's parameters, and a run of it on a uniform grid."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import scipy.integrate

from systems.textbook.jobs._cancel import NEVER, Cancel

if TYPE_CHECKING:
    from systems.compiled import CompiledSystem


def parameters_of(compiled: CompiledSystem) -> dict[str, float]:
    """The compiled system's parameter values by name (sliders included)."""
    return {
        name: float(value)
        for name, value in zip(compiled.parameter_names, compiled.parameters, strict=True)
    }


def names_of(compiled: CompiledSystem) -> tuple[str, ...]:
    """The compiled system's coordinate names, in the scene's order."""
    return tuple(compiled.mechanics.scene.coordinates)


@dataclass(frozen=True)
class Run:
    """The current system integrated from its initial state on a uniform grid.

    Attributes
    ----------
    t : ndarray, shape (K,)
    y : ndarray, shape (K, 2n)
        Canonical states.
    qdot : ndarray, shape (K, n)
    complete : bool
        False if the integration stopped early (``t`` then ends where it stopped).
    message : str
    """

    t: np.ndarray
    y: np.ndarray
    qdot: np.ndarray
    complete: bool
    message: str


def integrate(
    compiled: CompiledSystem,
    duration: float,
    samples: int = 801,
    *,
    y0: np.ndarray | None = None,
    t0: float = 0.0,
    cancel: Cancel = NEVER,
    rtol: float = 1e-10,
) -> Run:
    """Integrate Hamilton's equations (``compiled.rhs``) with DOP853.

    From ``y0`` (default: the scene's initial state) at ``t0`` over [t0, t0 + duration],
    sampled at ``samples`` uniform times.

    Parameters
    ----------
    compiled : CompiledSystem
        Wants ``rhs`` and ``velocities``.
    duration : float
    samples : int
        Number of uniform sample times, both ends included.
    y0 : ndarray, shape (2n,), optional
    t0 : float
    cancel : Cancel
        Checked at every evaluation of the right-hand side.
    rtol : float
        DOP853's relative tolerance (the absolute one is a hundredth of it).

    Returns
    -------
    Run

    Raises
    ------
    Cancelled
    """
    start = compiled.initial_state() if y0 is None else np.asarray(y0, dtype=float)

    def rhs(t, y):
        cancel.check()
        return compiled.rhs(t, y)

    t1 = float(t0) + float(duration)
    t_eval = np.linspace(float(t0), t1, int(samples))
    with np.errstate(all="ignore"):
        result = scipy.integrate.solve_ivp(
            rhs,
            (float(t0), t1),
            start,
            method="DOP853",
            t_eval=t_eval,
            rtol=rtol,
            atol=rtol * 1e-2,
        )
    y = np.asarray(result.y.T, dtype=float)
    t = np.asarray(result.t, dtype=float)
    complete = result.status == 0 and len(t) == len(t_eval)
    qdot = compiled.velocities(t, y) if len(t) else np.empty((0, compiled.n))
    return Run(t, y, qdot, complete, str(result.message))
