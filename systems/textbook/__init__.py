"""The textbook made explorable: virtual work, Hamilton's principle, conservation theorems.

Headless (numpy, scipy, sympy; never Qt). User documentation: ``docs/textbook.md``.

- ``equilibria``: ``find_equilibria``, ``search_equilibria``, ``equilibria_json``.
- ``action``: ``action``, ``action_curve``, ``second_variation``, ``solve_two_point``,
  ``shoot_two_point``.
- ``conservation``: ``energy_balance`` (dH/dt = -dL/dt partial + effects' power).
- ``routhian``: ``reduce``, ``turning_points``, ``motion_interval``, ``integrate_reduced``.
- ``action_angle``: ``action_angle``, ``action_angle_table``.

Each name is imported from its module when it is first used (PEP 562), so importing one
of them does not import the others' dependencies (``action`` brings ``scipy.integrate``,
half a second that ``derive`` does not need).
"""

from __future__ import annotations

import importlib

_MODULES = {
    "action": (
        "ActionCurve",
        "BoundaryPath",
        "SecondVariation",
        "action",
        "action_curve",
        "lagrangian_function",
        "second_variation",
        "shoot_two_point",
        "sine_variation",
        "solve_two_point",
    ),
    "action_angle": ("ActionAngle", "action_angle", "action_angle_table"),
    "conservation": ("EnergyBalance", "energy_balance"),
    "equilibria": (
        "Equilibrium",
        "EquilibriumSearch",
        "equilibria_json",
        "equilibrium_potential",
        "find_equilibria",
        "search_equilibria",
    ),
    "routhian": (
        "ReducedRun",
        "Reduction",
        "integrate_reduced",
        "motion_interval",
        "reduce",
        "turning_points",
    ),
}
_HOME = {name: module for module, names in _MODULES.items() for name in names}

__all__ = sorted(_HOME)


def __getattr__(name: str):
    """A public name, from its module (imported now if it was not)."""
    if name not in _HOME:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(f"{__name__}.{_HOME[name]}"), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted([*globals(), *_HOME])
