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


LATEX_GREEK = {name: "\\lambda" if name == "lam" else "\\" + name for name in GREEK}
"""The LaTeX of each Greek stem (``lam`` is λ: ``lambda`` is a Python keyword)."""


def latex_name(name: str, accent: str = "") -> str:
    """The LaTeX of a coordinate or parameter name, with ``accent`` (``dot``, ``ddot``):
    ``theta1`` -> ``\\theta_{1}``, ``x_dot`` of ``x`` -> ``\\dot{x}``, ``k_B`` -> ``k_{B}``,
    ``mass`` -> ``\\mathrm{mass}`` (upright, as a word)."""
    stem, digits = _split(name)
    if not stem:
        stem, digits = digits, ""
    base, *under = stem.split("_")
    if base in LATEX_GREEK:
        base = LATEX_GREEK[base]
    elif not base.isdigit() and (len(base) > 1 or not base.isalpha()):
        base = "\\mathrm{" + base.replace("_", "\\_") + "}"
    if accent:
        base = f"\\{accent}{{{base}}}"
    subscript = ",".join(filter(None, [*(latex_name(u) for u in under if u), digits]))
    return f"{base}_{{{subscript}}}" if subscript else base


def latex_names(scene) -> dict[str, str]:
    """Scene name -> LaTeX for coordinates, velocities, accelerations, momenta and
    parameters (``display_names`` in LaTeX)."""
    names = {}
    for q in scene.coordinates:
        names[q] = latex_name(q)
        names[f"{q}_dot"] = latex_name(q, "dot")
        names[f"{q}_ddot"] = latex_name(q, "ddot")
        names[f"p_{q}"] = f"p_{{{latex_name(q)}}}"
    for name, _ in scene.parameters:
        names[name] = latex_name(name)
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
    candidates = [expr, tidy]
    if tidy.count_ops() <= 3 * max(expr.count_ops(), 1):
        # a cancel that tripled the size is not won back by common factors: across the
        # catalogue's and users' reports (733 expressions) factor_terms never did, and
        # it took 1.7 of their 5.4 s (the three-body forces: 25 ops, 1806 cancelled)
        candidates.append(sympy.factor_terms(tidy))
    ops = [e.count_ops() for e in candidates]
    tied = [e for e, count in zip(candidates, ops, strict=True) if count == min(ops)]
    if len(tied) == 1:
        return tied[0]
    return min(tied, key=lambda e: len(str(e)))  # printed only to break a tie


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


def combine_trig(expr: sympy.Expr) -> sympy.Expr:
    """Products of sines and cosines combined where a sum allows it, cheaply:
    ``c sin a sin b + c cos a cos b -> c cos(a - b)``, ``c cos a cos b - c sin a sin b ->
    c cos(a + b)``, ``c sin a cos b ∓ c cos a sin b -> c sin(a ∓ b)``,
    ``c sin² a + c cos² a -> c``.

    The terms of a pendulum chain's mass matrix; ``sympy.trigsimp`` finds the same at a
    hundred times the cost (27 s for a twenty-link chain's 210 entries).
    """
    expr = as_expr(expr)
    if expr.is_Atom:
        return expr
    args = [combine_trig(a) for a in expr.args]
    if any(new is not old for new, old in zip(args, expr.args, strict=True)):
        expr = expr.func(*args)
    if expr.is_Add:
        return _combine_sum(expr)
    return expr


def _trig_term(term: sympy.Expr):
    """``(kind, args, coefficient)`` of ``c·f(a)·g(b)`` or ``c·f(a)²`` with f, g in sin,
    cos; None for any other term. kinds: ``ss``, ``cc``, ``sc`` (sin a cos b), ``s2``,
    ``c2``."""
    trig, rest = [], []
    for factor in sympy.Mul.make_args(term):
        base, power = factor.as_base_exp()
        if isinstance(base, (sympy.sin, sympy.cos)) and power in (1, 2):
            trig += [base] * int(power)
        else:
            rest.append(factor)
    if len(trig) != 2:
        return None
    c = sympy.Mul(*rest)
    (f, g) = trig
    if f == g:
        return ("s2" if isinstance(f, sympy.sin) else "c2", (f.args[0],), c)
    if isinstance(f, sympy.sin) and isinstance(g, sympy.sin):
        return ("ss", tuple(sorted((f.args[0], g.args[0]), key=sympy.default_sort_key)), c)
    if isinstance(f, sympy.cos) and isinstance(g, sympy.cos):
        return ("cc", tuple(sorted((f.args[0], g.args[0]), key=sympy.default_sort_key)), c)
    if isinstance(f, sympy.cos):
        f, g = g, f
    return ("sc", (f.args[0], g.args[0]), c)


def _combine_sum(expr: sympy.Add) -> sympy.Expr:
    terms = list(expr.args)
    parsed = [_trig_term(term) for term in terms]
    index: dict = {}
    for k, entry in enumerate(parsed):
        if entry is not None:
            index.setdefault((entry[0], entry[1]), []).append(k)
    used: set[int] = set()
    combined = []

    def partner(kind, args, coefficient) -> int | None:
        for k in index.get((kind, args), []):
            if k not in used and parsed[k][2] == coefficient:
                return k
        return None

    for k, entry in enumerate(parsed):
        if entry is None or k in used:
            continue
        kind, args, c = entry
        found = None
        if kind == "ss":
            found = (partner("cc", args, c), c * sympy.cos(args[0] - args[1]))
            if found[0] is None:
                found = (partner("cc", args, -c), -c * sympy.cos(args[0] + args[1]))
        elif kind == "cc":
            found = (partner("ss", args, c), c * sympy.cos(args[0] - args[1]))
            if found[0] is None:
                found = (partner("ss", args, -c), c * sympy.cos(args[0] + args[1]))
        elif kind == "sc":
            swapped = (args[1], args[0])
            found = (partner("sc", swapped, -c), c * sympy.sin(args[0] - args[1]))
            if found[0] is None:
                found = (partner("sc", swapped, c), c * sympy.sin(args[0] + args[1]))
        elif kind in ("s2", "c2"):
            found = (partner("c2" if kind == "s2" else "s2", args, c), c)
        if found is None or found[0] is None:
            continue
        used.update((k, found[0]))
        combined.append(found[1])
    if not used:
        return expr
    return sympy.Add(*[term for k, term in enumerate(terms) if k not in used], *combined)
