"""Expressions for people: textbook names (theta1 -> θ₁, theta1_dot -> θ̇₁, p_theta1 -> p_θ₁)
and tidied forms (``tidied``).

Only for showing expressions to people (CLI text, GUI labels); machine-readable output
keeps the scene's own names.
"""

from __future__ import annotations

import functools
import math
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


@functools.lru_cache(maxsize=4096)
def tidied(expr: sympy.Expr) -> sympy.Expr:
    """``expr`` tidied for reading: fractions cancelled, common factors pulled out.

    Only for display (``systems.report``, the window's derivation): the derivation keeps
    its expressions as derived. Remembered, since a layout asks for the same ones again.

    No ``trigsimp``: across the catalogue it changed one expression out of ~100 (for the
    worse) and cost half of the time this took for a double pendulum. Nothing is done to
    an expression whose expansion would be large: ``cancel`` expands numerator and
    denominator, and a 40-term sum to the 20th power has 10**14 terms.
    """
    expr = as_expr(expr)
    if _nodes_exceed(expr, 4000) or expr.count_ops() > 400:
        return expr
    if expanded_terms(expr) > EXPANSION_LIMIT:
        return expr
    tidy = sympy.cancel(sympy.together(expr))
    candidates = [expr, tidy, sympy.factor_terms(tidy)]
    return min(candidates, key=lambda e: (e.count_ops(), len(str(e))))


def _nodes_exceed(expr: sympy.Expr, limit: int) -> bool:
    """True if ``expr`` has more than ``limit`` nodes; stops counting there (count_ops
    of a large expression costs more than the rest of its derivation)."""
    for count, _ in enumerate(sympy.preorder_traversal(expr)):
        if count >= limit:
            return True
    return False


EXPANSION_LIMIT = 2000
"""Most terms an expression may expand to before the derivation stops expanding it."""


def expanded_terms(expr: sympy.Expr, cap: int = 10**12) -> int:
    """An upper bound on the number of terms of ``expand(expr)``, counted without expanding.

    A sum adds its terms' counts, a product multiplies them, an integer power n of a sum
    of k terms has at most C(k + n - 1, n); anything else counts as one term.
    """
    if expr.is_Add:
        return min(cap, sum(expanded_terms(a, cap) for a in expr.args))
    if expr.is_Mul:
        total = 1
        for a in expr.args:
            total = min(cap, total * expanded_terms(a, cap))
        return total
    if expr.is_Pow and expr.exp.is_Integer and expr.exp > 1:
        k = expanded_terms(expr.base, cap)
        n = int(expr.exp)
        if k == 1:
            return 1
        if n > 10**4 or k > 10**4:
            return cap
        return min(cap, math.comb(k + n - 1, n))
    return 1
