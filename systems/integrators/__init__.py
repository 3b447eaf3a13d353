"""Steppers: a registry by name, their compiled loops, and the automatic choice."""

from systems.integrators.choice import choose_method, stiffness_ratio
from systems.integrators.registry import STEPPERS, Stepper, gauss_tableau, get_stepper

__all__ = [
    "STEPPERS",
    "Stepper",
    "choose_method",
    "gauss_tableau",
    "get_stepper",
    "stiffness_ratio",
]
