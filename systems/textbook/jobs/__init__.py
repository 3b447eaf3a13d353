"""What the Textbook tabs show, computed on the current system (headless: no Qt).

Each job takes a ``CompiledSystem`` (its ``.mechanics`` and its parameter values, sliders
included) and returns a small frozen value that a tab draws as it is. The window runs
each job in a worker process (``explorer.textbook.tasks`` through ``systems.processes``)
and stops a superseded one by ending its process, so every job, its arguments and its
value pickle: a job is a function of this package (never of a module that imports Qt),
and its value is plain data, numeric functions included (``systems.lambdified``). Called
in a process of its own, a job's long loops check a ``Cancel`` token (``NEVER`` by
default) and stop early, raising ``Cancelled``.

- ``equilibria`` -> ``EquilibriaResult``: ``search_equilibria`` at the current parameters.
- ``principle`` -> ``PrincipleResult``: S(eps) and the second variation along the run;
  ``two_point`` -> ``TwoPointResult``: the path from A to B by the discrete action and by
  shooting.
- ``reduction_setup`` -> ``ReductionSetup`` (the symbolic Routhian reduction) and
  ``reduction_curves`` -> ``ReductionCurves`` (V_eff, turning points and the reduced
  portrait for one value of the conserved momenta; fast, numeric); ``reduction_with_curves``
  does both, the tab's job; ``level_curve`` draws a level set of an H quadratic in p.
- ``action_angle_reason`` and ``action_angle_data`` -> ``ActionAngleResult``: J(E), T(E);
  ``action_angle_table`` finds the equilibria first, the tab's job.
- ``energy`` -> ``EnergyResult``: the energy theorem along a run.
- ``integrate`` -> ``Run``: the system from its initial state on a uniform grid (DOP853).
- ``floquet`` -> ``FloquetResult``: the constant solutions of a periodically driven system
  and their Floquet multipliers; ``chart_block`` -> ``ChartBlock``: rows of a stability
  chart over two parameters; ``periodic_orbit_from`` -> ``PeriodicOrbit``: shooting and
  Newton from a start (``systems.textbook.floquet``, ``periodic_orbits``).
"""

from systems.textbook.jobs._action_angle import (
    ActionAngleResult,
    action_angle_data,
    action_angle_reason,
    action_angle_table,
)
from systems.textbook.jobs._cancel import NEVER, Cancel, Cancelled
from systems.textbook.jobs._energy import EnergyResult, energy
from systems.textbook.jobs._equilibria import EquilibriaResult, equilibria
from systems.textbook.jobs._floquet import (
    ChartBlock,
    FloquetResult,
    chart_block,
    floquet,
    periodic_orbit_from,
)
from systems.textbook.jobs._principle import PrincipleResult, TwoPointResult, principle, two_point
from systems.textbook.jobs._reduction import (
    Quadratic,
    ReductionCurves,
    ReductionSetup,
    level_curve,
    reduction_curves,
    reduction_setup,
    reduction_with_curves,
)
from systems.textbook.jobs._run import Run, integrate, names_of, parameters_of

__all__ = [
    "NEVER",
    "ActionAngleResult",
    "Cancel",
    "Cancelled",
    "ChartBlock",
    "EnergyResult",
    "EquilibriaResult",
    "FloquetResult",
    "PrincipleResult",
    "Quadratic",
    "ReductionCurves",
    "ReductionSetup",
    "Run",
    "TwoPointResult",
    "action_angle_data",
    "action_angle_reason",
    "action_angle_table",
    "chart_block",
    "energy",
    "equilibria",
    "floquet",
    "integrate",
    "level_curve",
    "names_of",
    "parameters_of",
    "periodic_orbit_from",
    "principle",
    "reduction_curves",
    "reduction_setup",
    "reduction_with_curves",
    "two_point",
]
