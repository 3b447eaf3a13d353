"""Integration methods: a registry of families and methods, their runners and the choice."""

from systems.integrators.choice import choose_method, stiffness_ratio
from systems.integrators.registry import FAMILIES, STEPPERS, Family, Stepper, get_stepper
from systems.integrators.tableaux import gauss_tableau

__all__ = [
    "FAMILIES",
    "STEPPERS",
    "Family",
    "Stepper",
    "choose_method",
    "gauss_tableau",
    "get_stepper",
    "stiffness_ratio",
]
