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
        If the run stops at once, or a constraint moves (its force does work, which the
        balance does not include yet).
    Cancelled
    """
    mechanics = compiled.mechanics
    constraints = getattr(mechanics.scene, "holonomic_constraints", ())
    if constraints and any(
        mechanics.scene.expression(f"constraints.holonomic[{i}]").has(mechanics.t)
        for i in range(len(constraints))
    ):
        raise ValueError(
            "a constraint moves: its force does work (the multipliers' power), which this "
            "balance does not include yet, so dH/dt would not match its prediction"
        )
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
