"""Axis labels and legends in the textbook's notation (θ, p<sub>θ</sub>, θ̇)."""

from __future__ import annotations

from systems.display import DOT, pretty_name


def coordinate_label(q: str) -> str:
    """``theta1`` -> ``θ₁``."""
    return pretty_name(q)


def momentum_label(q: str, html: bool = True) -> str:
    """The conjugate momentum of ``q``: ``p<sub>θ</sub>`` (or ``p_θ`` as plain text)."""
    name = pretty_name(q)
    return f"p<sub>{name}</sub>" if html else f"p_{name}"


def velocity_label(q: str) -> str:
    return pretty_name(q, DOT)


def state_label(name: str, html: bool = True) -> str:
    """The label of a scene name: a coordinate, ``<q>_dot`` or ``p_<q>``."""
    if name.startswith("p_"):
        return momentum_label(name[2:], html)
    if name.endswith("_dot"):
        return velocity_label(name[:-4])
    return pretty_name(name)
