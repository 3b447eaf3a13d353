"""The Principle tab: Hamilton's principle along the run, and the two-point problem."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from systems.textbook.action import (
    BoundaryPath,
    action_curve,
    second_variation,
    shoot_two_point,
    sine_variation,
    solve_two_point,
)
from systems.textbook.jobs._cancel import NEVER, Cancel
from systems.textbook.jobs._run import Run, integrate, parameters_of

if TYPE_CHECKING:
    from systems.compiled import CompiledSystem


@dataclass(frozen=True)
class PrincipleResult:
    """S(eps) along the sine variation ``k`` of coordinate ``index`` over [0, duration].

    Attributes
    ----------
    run : Run
        The true path.
    eps, action : ndarray
        The sampled amplitudes and S(eps).
    slope, curvature : float
        dS/deps and d2S/deps2 at eps = 0.
    nature : str
        From ``second_variation``: ``"minimum"``, ``"saddle"``, ``"maximum"``, ``"degenerate"``.
    eigenvalues : ndarray
        The second variation's eigenvalues (ascending).
    eta : ndarray, shape (K, n)
        The variation (for drawing a varied path).
    lagrangian_only : bool
        True when effects (dissipation, forces) are on: they are not part of L, so the
        computed path is not a stationary path of this action.
    """

    run: Run
    index: int
    k: int
    eps: np.ndarray
    action: np.ndarray
    slope: float
    curvature: float
    nature: str
    eigenvalues: np.ndarray
    eta: np.ndarray
    lagrangian_only: bool


def principle(
    compiled: CompiledSystem,
    duration: float,
    k: int,
    index: int,
    amplitude: float,
    start: float = 0.0,
    cancel: Cancel = NEVER,
) -> PrincipleResult:
    """S(eps) and the second variation on the stretch [start, start + duration] of the run.

    Parameters
    ----------
    compiled : CompiledSystem
    duration : float
        Length of the stretch.
    k : int
        Mode number of the variation ``sin(k pi (t - start) / duration)``.
    index : int
        The coordinate varied.
    amplitude : float
        S is sampled for eps in [-amplitude, amplitude].
    start : float
        Where the stretch begins along the run from the initial state.
    cancel : Cancel

    Returns
    -------
    PrincipleResult

    Raises
    ------
    ValueError
        If the scene has no Lagrangian or the run does not complete.
    Cancelled
    """

    mechanics = compiled.mechanics
    if mechanics.lagrangian is None:
        raise ValueError("the scene gives only a Hamiltonian: the action needs a Lagrangian")
    _refuse_constraints(mechanics)
    y0 = None
    if start > 0:
        before = integrate(compiled, start, 2, cancel=cancel)
        if not before.complete:
            raise ValueError(f"the run to t = {start:g} did not complete: {before.message}")
        y0 = before.y[-1]
    run = integrate(compiled, duration, 801, y0=y0, t0=start, cancel=cancel)
    if not run.complete or len(run.t) < 5:
        raise ValueError(
            f"the run over [{start:g}, {start + duration:g}] did not complete: {run.message}"
        )
    cancel.check()
    parameters = parameters_of(compiled)
    q = run.y[:, : compiled.n]
    eps = np.linspace(-amplitude, amplitude, 41)
    curve = action_curve(
        mechanics,
        run.t,
        q,
        run.qdot,
        eps,
        k=k,
        direction=index,
        parameters=parameters,
        step=amplitude * 1e-3,
    )
    cancel.check()
    second = second_variation(mechanics, run.t, q, run.qdot, parameters=parameters)
    eta, _ = sine_variation(run.t, k, index, n=compiled.n)
    return PrincipleResult(
        run=run,
        index=index,
        k=k,
        eps=curve.eps,
        action=curve.action,
        slope=float(curve.slope),
        curvature=float(curve.curvature),
        nature=second.nature,
        eigenvalues=second.eigenvalues,
        eta=eta,
        lagrangian_only=any(f != 0 for f in mechanics.generalized_forces),
    )


@dataclass(frozen=True)
class TwoPointResult:
    """The path from A to B in time T, by the stationary discrete action and by shooting."""

    action_path: BoundaryPath
    shooting_path: BoundaryPath | None
    shooting_error: str


def two_point(
    compiled: CompiledSystem,
    qa: Sequence[float],
    qb: Sequence[float],
    duration: float,
    t0: float = 0.0,
    cancel: Cancel = NEVER,
) -> TwoPointResult:
    """From configuration ``qa`` at t0 to ``qb`` at t0 + duration, both ways.

    A failed shooting is reported in ``shooting_error``, not raised.
    """
    _refuse_constraints(compiled.mechanics)
    parameters = parameters_of(compiled)
    path = solve_two_point(compiled.mechanics, qa, qb, duration, t0=t0, parameters=parameters)
    cancel.check()
    try:
        shot = shoot_two_point(
            compiled.mechanics,
            qa,
            qb,
            duration,
            t0=t0,
            parameters=parameters,
            velocity_guess=path.qdot[0],
        )
        error = ""
    except (ValueError, RuntimeError, np.linalg.LinAlgError) as exc:
        shot, error = None, str(exc)
    return TwoPointResult(path, shot, error)


def _refuse_constraints(mechanics) -> None:
    """A ValueError for a scene with constraints: the action of its free coordinates is
    stationary only among paths that keep the constraints, and these jobs vary the path
    freely (the Cartesian pendulum's S(eps) then has a slope of -7.5: a principle that
    seems to fail, a wrong answer)."""
    from systems.constraints import constrained

    if constrained(mechanics.scene):
        raise ValueError(
            "the scene has constraints: the action is stationary only among paths that "
            "keep them, and this tab varies the path freely (not done yet for constrained "
            "systems)"
        )
