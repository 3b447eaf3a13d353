"""The Energy tab: the energy theorem checked along a run."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

from systems.textbook.conservation import EnergyBalance, energy_balance
from systems.textbook.jobs._cancel import NEVER, Cancel
from systems.textbook.jobs._run import Run, integrate, parameters_of

if TYPE_CHECKING:
    from systems.compiled import CompiledSystem


@dataclass(frozen=True)
class EnergyResult:
    """Both sides of dH/dt = -dL/dt (partial) + power of the effects, along a run.

    Attributes
    ----------
    balance : EnergyBalance
        Both sides at the run's samples.
    run : Run
    rheonomic : bool
        The classification's ``rheonomic``: the constraints or the transformation
        r(q, t) depend on t (a moving constraint whose agent can do work).
    explicit_time : bool
        L (or H, for a scene given by H) contains t explicitly.
    effects : bool
        Dissipation or forces are switched on.
    hamiltonian_is_energy : bool or None
        H = T + V; None where no energy can be named (L or H alone, with explicit t or
        without a positive kinetic energy), so there is nothing to compare H with.
    """

    balance: EnergyBalance
    run: Run
    rheonomic: bool
    explicit_time: bool
    effects: bool
    hamiltonian_is_energy: bool | None


def energy(compiled: CompiledSystem, duration: float, cancel: Cancel = NEVER) -> EnergyResult:
    """dH/dt and what the energy theorem predicts for it, along a run of ``duration``.

    Raises
    ------
    ValueError
        If the run stops at once, or ``refusal`` gives a reason: a constraint whose force
        does work, which the balance does not include yet.
    Cancelled
    """
    reason = refusal(compiled)
    if reason:
        raise ValueError(reason)
    mechanics = compiled.mechanics
    samples = int(min(20001, max(2001, 100 * duration)))  # dH/dt from samples: keep them dense
    run = integrate(compiled, duration, samples, cancel=cancel)
    if len(run.t) < 5:
        raise ValueError(f"the run stopped at once: {run.message}")
    cancel.check()
    balance = energy_balance(compiled.mechanics, run.t, run.y, parameters=parameters_of(compiled))
    cls = compiled.mechanics.classification
    effects = any(f != 0 for f in compiled.mechanics.generalized_forces)
    expression = mechanics.lagrangian if mechanics.lagrangian is not None else mechanics.hamiltonian
    return EnergyResult(
        balance,
        run,
        bool(cls.rheonomic),
        bool(expression.has(mechanics.t)),
        effects,
        cls.hamiltonian_is_energy,
    )


def refusal(compiled: CompiledSystem) -> str | None:
    """Why the balance dH/dt = -dL/dt (partial) + power of the effects would not hold for
    this system's constraints, or None.

    A constraint does no work when it is scleronomic: a holonomic or unilateral one
    without t, a nonholonomic ``a(q) . qdot = 0`` (no t, no velocity-free part b). A
    moving one does (the multipliers' power, not included yet). Scenes with unilateral
    constraints are refused: the run behind the balance (``integrate``, a smooth DOP853)
    does not stop at impacts.
    """
    from systems.constraints import declared

    mechanics = compiled.mechanics
    scene = mechanics.scene
    given = declared(scene)
    t = mechanics.t
    zero = dict.fromkeys(mechanics.qdot, 0)
    moving = any(f.has(t) for f in (*given.holonomic, *given.nonholonomic, *given.unilateral))
    moving = moving or any(f.xreplace(zero) != 0 for f in given.nonholonomic)
    if moving:
        return (
            "a constraint moves: its force does work (the multipliers' power), which this "
            "balance does not include yet, so dH/dt would not match its prediction"
        )
    if given.unilateral:
        return (
            "the balance along a run with unilateral constraints is not supported yet: its "
            "samples come from a smooth integration that does not stop at the impacts (and "
            "an impact with restitution below 1 takes energy away at an instant, which a "
            "balance of rates cannot show)"
        )
    return None
