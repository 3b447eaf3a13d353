"""The textbook made explorable: virtual work, Hamilton's principle, conservation theorems.

Headless (numpy, scipy, sympy; never Qt). User documentation: ``docs/textbook.md``.

- ``equilibria``: ``find_equilibria``, ``search_equilibria``, ``equilibria_json``.
- ``action``: ``action``, ``action_curve``, ``second_variation``, ``solve_two_point``,
  ``shoot_two_point``.
- ``conservation``: ``energy_balance`` (dH/dt = -dL/dt partial + effects' power).
- ``routhian``: ``reduce``, ``turning_points``, ``motion_interval``, ``integrate_reduced``.
- ``action_angle``: ``action_angle``, ``action_angle_table``.
"""

from systems.textbook.action import (
    ActionCurve,
    BoundaryPath,
    SecondVariation,
    action,
    action_curve,
    lagrangian_function,
    second_variation,
    shoot_two_point,
    sine_variation,
    solve_two_point,
)
from systems.textbook.action_angle import ActionAngle, action_angle, action_angle_table
from systems.textbook.conservation import EnergyBalance, energy_balance
from systems.textbook.equilibria import (
    Equilibrium,
    EquilibriumSearch,
    equilibria_json,
    equilibrium_potential,
    find_equilibria,
    search_equilibria,
)
from systems.textbook.routhian import (
    ReducedRun,
    Reduction,
    integrate_reduced,
    motion_interval,
    reduce,
    turning_points,
)

__all__ = [
    "ActionAngle",
    "ActionCurve",
    "BoundaryPath",
    "EnergyBalance",
    "Equilibrium",
    "EquilibriumSearch",
    "ReducedRun",
    "Reduction",
    "SecondVariation",
    "action",
    "action_angle",
    "action_angle_table",
    "action_curve",
    "energy_balance",
    "equilibria_json",
    "equilibrium_potential",
    "find_equilibria",
    "integrate_reduced",
    "lagrangian_function",
    "motion_interval",
    "reduce",
    "search_equilibria",
    "second_variation",
    "shoot_two_point",
    "sine_variation",
    "solve_two_point",
    "turning_points",
]
