"""What the Textbook tabs show, computed on the current system (headless: no Qt).

Each job takes a ``CompiledSystem`` (its ``.mechanics`` and its parameter values, sliders
included) and returns a small frozen value that a tab draws as it is. The window runs
the jobs in a task pool (``explorer.textbook.tasks``); long loops check a ``Cancel`` token
so a superseded or shut-down job stops early, raising ``Cancelled``.

- ``equilibria`` -> ``EquilibriaResult``: ``search_equilibria`` at the current parameters.
- ``principle`` -> ``PrincipleResult``: S(eps) and the second variation along the run;
  ``two_point`` -> ``TwoPointResult``: the path from A to B by the discrete action and by
  shooting.
- ``reduction_setup`` -> ``ReductionSetup`` (the symbolic Routhian reduction) and
  ``reduction_curves`` -> ``ReductionCurves`` (V_eff, turning points and the reduced
  portrait for one value of the conserved momenta); ``level_curve`` draws a level set of
  an H quadratic in p.
- ``action_angle_reason`` and ``action_angle_data`` -> ``ActionAngleResult``: J(E), T(E).
- ``energy`` -> ``EnergyResult``: the energy theorem along a run.
- ``integrate`` -> ``Run``: the system from its initial state on a uniform grid (DOP853).
"""

from systems.textbook.jobs._action_angle import (
    ActionAngleResult,
    action_angle_data,
    action_angle_reason,
)
from systems.textbook.jobs._cancel import NEVER, Cancel, Cancelled
from systems.textbook.jobs._energy import EnergyResult, energy
from systems.textbook.jobs._equilibria import EquilibriaResult, equilibria
from systems.textbook.jobs._principle import PrincipleResult, TwoPointResult, principle, two_point
from systems.textbook.jobs._reduction import (
    ReductionCurves,
    ReductionSetup,
    level_curve,
    reduction_curves,
    reduction_setup,
)
from systems.textbook.jobs._run import Run, integrate, names_of, parameters_of

__all__ = [
    "NEVER",
    "ActionAngleResult",
    "Cancel",
    "Cancelled",
    "EnergyResult",
    "EquilibriaResult",
    "PrincipleResult",
    "ReductionCurves",
    "ReductionSetup",
    "Run",
    "TwoPointResult",
    "action_angle_data",
    "action_angle_reason",
    "energy",
    "equilibria",
    "integrate",
    "level_curve",
    "names_of",
    "parameters_of",
    "principle",
    "reduction_curves",
    "reduction_setup",
    "two_point",
]
