"""Derivations and equilibria as text for people, and as JSON-ready data.

Qt-free, so the CLI (``derive``) and the window (its Derivation text and equilibrium
lines, the Textbook tabs' captions) say the same thing without the window importing CLI
code. Display names (θ₁, θ̇₁, p_θ₁) come from ``systems.display``; the JSON keeps the
scene's own names.
"""

from __future__ import annotations

import re
from typing import TYPE_CHECKING

import sympy

from systems.display import display_names, for_display

if TYPE_CHECKING:
    from systems.mechanics import Mechanics
    from systems.scene import Scene


def one_line(expression: sympy.Basic) -> str:
    """A sympy expression as one line of text: ``p_θ²/(2·m·r²) − k/r``.

    Parameters
    ----------
    expression : sympy.Basic
        Usually already renamed for display by ``systems.display.for_display``.

    Returns
    -------
    str
        ``sympy.sstr`` with squares, cubes and fourth powers as superscripts, π, ``·`` for
        products and ``−`` for minus.
    """
    text = sympy.sstr(expression)
    for power, glyph in (("**2", "²"), ("**3", "³"), ("**4", "⁴")):
        text = text.replace(power, glyph)
    text = re.sub(r"\bpi\b", "π", text)
    return text.replace("**", "^").replace("*", "·").replace("-", "−")


def readable(mechanics: Mechanics, equilibria: bool = True) -> str:
    """The derivation laid out for a person, with sympy's pretty printer.

    Parameters
    ----------
    mechanics : Mechanics
        A derived scene.
    equilibria : bool
        Whether to end with the equilibria (virtual work). ``False`` leaves out their
        search (a second or more), for the window, which shows its result apart when it
        arrives.

    Returns
    -------
    str
        Title, coordinates and parameters, L, Lagrange's equations, accelerations, momenta,
        H, Hamilton's equations, classification, conserved quantities and (optionally)
        equilibria, one block each.
    """
    scene = mechanics.scene
    shown = display_names(scene)
    params = ", ".join(f"{shown[k]} = {v:g}" for k, v in scene.parameters) or "none"
    lines = [scene.title, "=" * len(scene.title)]
    if scene.description:
        lines.append(scene.description)
    coordinates = ", ".join(shown[q] for q in scene.coordinates)
    lines.append(f"coordinates: {coordinates}; parameters: {params}")
    if scene.enabled_effects():
        lines.append(f"effects on: {', '.join(scene.enabled_effects())}")
    if mechanics.lagrangian is not None:
        lines += _block("Lagrangian", [("L", mechanics.lagrangian)], scene)
        equations = [(f"({i + 1})", eq) for i, eq in enumerate(mechanics.lagrange_equations())]
        lines += _block("Lagrange's equations", equations, scene)
        try:
            accelerations = zip(scene.coordinates, mechanics.accelerations(), strict=True)
            rows = [(shown[f"{q}_ddot"], a) for q, a in accelerations]
            lines += _block("Accelerations", rows, scene)
        except ValueError:
            pass
    if mechanics.momenta is not None:
        rows = [(shown[p], m) for p, m in zip(scene.momentum_names, mechanics.momenta, strict=True)]
        lines += _block("Generalized momenta p = dL/dq̇", rows, scene)
    lines += _block("Hamiltonian", [("H", mechanics.hamiltonian)], scene)
    names = list(scene.coordinates) + list(scene.momentum_names)
    rows = [
        (f"d{shown[name]}/dt", expr)
        for name, expr in zip(names, mechanics.hamilton_equations, strict=True)
    ]
    lines += _block("Hamilton's equations", rows, scene)
    lines += ["", "Classification", "--------------"]
    lines += [f"- {sentence}" for sentence in mechanics.classification.describe()]
    cyclic = ", ".join(shown[q] for q in mechanics.cyclic) or "none"
    lines.append(f"- cyclic coordinates: {cyclic}")
    if mechanics.conserved:
        rows = [(shown.get(name, name), expr) for name, expr in mechanics.conserved.items()]
        lines += _block("Conserved quantities", rows, scene)
    if equilibria:
        lines += _equilibria_lines(mechanics)
    return "\n".join(lines)


def equilibria_sentences(mechanics: Mechanics, digits: int = 6) -> tuple[list[str], str]:
    """One sentence per equilibrium (virtual work, small oscillations), and the search's note.

    Parameters
    ----------
    mechanics : Mechanics
        A derived scene; its equilibria are searched at the scene's parameter values.
    digits : int
        Significant digits of coordinates and frequencies.

    Returns
    -------
    sentences : list[str]
        ``"θ = 0: stable, ω = 3.13"`` or ``"θ = 3.14: unstable (maximum)"``, one per
        equilibrium.
    note : str
        Why there are none, or what the search assumed; empty if nothing to say.
    """
    from systems.textbook import search_equilibria

    search = search_equilibria(mechanics)
    shown = display_names(mechanics.scene)
    lines = []
    for eq in search.equilibria:
        where = ", ".join(f"{shown.get(k, k)} = {v:.{digits}g}" for k, v in eq.q.items())
        if eq.stable and not eq.frequencies:
            lines.append(
                f"{where}: stable, with no small-oscillation frequency (the inertia there is "
                "zero or infinite, so the motion is not harmonic)"
            )
        elif eq.stable:
            omegas = ", ".join(f"{w:.{digits}g}" for w in eq.frequencies)
            lines.append(f"{where}: stable, \u03c9 = {omegas}")
        else:
            lines.append(f"{where}: unstable ({eq.kind})")
    return lines, search.reason or ""


def derivation_json(mechanics: Mechanics) -> dict:
    """The derivation as JSON-ready data.

    Parameters
    ----------
    mechanics : Mechanics
        A derived scene; its equilibria are searched too.

    Returns
    -------
    dict
        ``title``, ``coordinates``, ``parameters``, ``lagrangian``, ``accelerations``
        (None when M cannot be solved symbolically), ``momenta``, ``hamiltonian``,
        ``hamilton_equations``, ``cyclic``, ``conserved``, ``classification`` and
        ``equilibria``, with the scene's own names; every expression is a string that
        ``sympy.sympify`` reads back.
    """
    from systems.mechanics import DerivationError
    from systems.textbook import equilibria_json

    scene = mechanics.scene
    try:
        accelerations = dict(
            zip(scene.coordinates, map(_text, mechanics.accelerations()), strict=True)
        )
    except DerivationError:
        accelerations = None
    names = list(scene.coordinates) + list(scene.momentum_names)
    return {
        "title": scene.title,
        "coordinates": list(scene.coordinates),
        "parameters": scene.parameter_values,
        "lagrangian": _text(mechanics.lagrangian),
        "accelerations": accelerations,
        "momenta": None
        if mechanics.momenta is None
        else dict(zip(scene.coordinates, map(_text, mechanics.momenta), strict=True)),
        "hamiltonian": _text(mechanics.hamiltonian),
        "hamilton_equations": dict(
            zip(names, map(_text, mechanics.hamilton_equations), strict=True)
        ),
        "cyclic": list(mechanics.cyclic),
        "conserved": {name: _text(expr) for name, expr in mechanics.conserved.items()},
        "classification": mechanics.classification.as_dict(),
        "equilibria": equilibria_json(mechanics),
    }


def _text(expr: sympy.Basic | None) -> str | None:
    return None if expr is None else str(expr)


def _block(title: str, rows: list[tuple[str, object]], scene: Scene) -> list[str]:
    lines = ["", title, "-" * len(title)]
    for label, expr in rows:
        shown = for_display(expr, scene)
        art = sympy.pretty(shown, use_unicode=True, wrap_line=False).splitlines() or [""]
        head = f"{label}: " if isinstance(expr, sympy.Eq) else f"{label} = "
        middle = len(art) // 2
        for i, line in enumerate(art):
            lines.append((head if i == middle else " " * len(head)) + line)
    return lines


def _equilibria_lines(mechanics: Mechanics) -> list[str]:
    lines, note = equilibria_sentences(mechanics)
    title = ["", "Equilibria (virtual work: dV/dq = 0)", "------------------------------------"]
    if not lines:
        return title + [f"none: {note}" if note else "none found"]
    return title + [f"- {line}" for line in lines] + ([f"({note})"] if note else [])
