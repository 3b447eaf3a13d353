"""Textbook names for display: theta1 -> θ₁, theta1_dot -> θ̇₁, p_theta1 -> p_θ₁.

Only for showing expressions to people (CLI text, GUI labels); machine-readable output
keeps the scene's own names.
"""

from __future__ import annotations

import re

import sympy

from systems.expressions import as_expr

GREEK = {
    "alpha": "α", "beta": "β", "gamma": "γ", "delta": "δ", "epsilon": "ε", "zeta": "ζ",
    "eta": "η", "theta": "θ", "iota": "ι", "kappa": "κ", "lam": "λ", "mu": "μ", "nu": "ν",
    "xi": "ξ", "omicron": "ο", "rho": "ρ", "sigma": "σ", "tau": "τ", "upsilon": "υ",
    "phi": "φ", "chi": "χ", "psi": "ψ", "omega": "ω", "Gamma": "Γ", "Delta": "Δ",
    "Theta": "Θ", "Lambda": "Λ", "Xi": "Ξ", "Pi": "Π", "Sigma": "Σ", "Phi": "Φ",
    "Psi": "Ψ", "Omega": "Ω",
}  # fmt: skip
SUBSCRIPTS = str.maketrans("0123456789", "₀₁₂₃₄₅₆₇₈₉")
DOT, DDOT = "\u0307", "\u0308"


def _split(name: str) -> tuple[str, str]:
    match = re.fullmatch(r"(.*?)_?(\d*)", name)
    assert match is not None
    return match.group(1), match.group(2)


def pretty_name(name: str, accent: str = "") -> str:
    """The display form of a coordinate or parameter name, with an optional dot accent."""
    stem, digits = _split(name)
    stem = GREEK.get(stem, stem)
    if not stem:
        stem, digits = digits, ""
    return stem + accent + digits.translate(SUBSCRIPTS)


def display_names(scene) -> dict[str, str]:
    """Scene name -> display name for coordinates, velocities, momenta and parameters."""
    names = {}
    for q in scene.coordinates:
        names[q] = pretty_name(q)
        names[f"{q}_dot"] = pretty_name(q, DOT)
        names[f"{q}_ddot"] = pretty_name(q, DDOT)
        names[f"p_{q}"] = "p_" + pretty_name(q)
    for name, _ in scene.parameters:
        names[name] = pretty_name(name)
    return names


def for_display(expr: sympy.Expr, scene) -> sympy.Expr:
    """``expr`` with its symbols renamed for people; pretty-print the result."""
    names = display_names(scene)
    mapping = {
        s: sympy.Symbol(names[s.name], real=True)
        for s in as_expr(expr).free_symbols
        if s.name in names
    }
    return as_expr(expr).xreplace(mapping)
