"""``derive SCENE``: Lagrange's and Hamilton's equations, for a person or as JSON."""

from __future__ import annotations

import argparse
import json

import sympy

from explorer.commands.errors import user_errors


def add_parser(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser(
        "derive", help="derive the equations of motion of a scene (catalogue name or .toml)"
    )
    parser.add_argument("scene", help="a catalogue name (see `list`) or a path to a .toml file")
    parser.add_argument("--json", action="store_true", help="print one JSON object")


def run(args: argparse.Namespace) -> int:
    from systems.mechanics import derive
    from systems.scene import load_scene

    with user_errors():
        scene = load_scene(args.scene)
        mechanics = derive(scene)
        if args.json:  # the report searches the equilibria too: only when it is printed
            print(json.dumps(derivation_report(mechanics), indent=2))
        else:
            print(readable(mechanics))
    return 0


def _text(expr) -> str | None:
    return None if expr is None else str(expr)


def derivation_report(mechanics) -> dict:
    """The derivation as JSON-ready data; every expression a string sympify reads back."""
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


def _block(title: str, rows: list[tuple[str, object]], scene) -> list[str]:
    from systems.display import for_display

    lines = ["", title, "-" * len(title)]
    for label, expr in rows:
        shown = for_display(expr, scene)
        art = sympy.pretty(shown, use_unicode=True, wrap_line=False).splitlines() or [""]
        head = f"{label}: " if isinstance(expr, sympy.Eq) else f"{label} = "
        middle = len(art) // 2
        for i, line in enumerate(art):
            lines.append((head if i == middle else " " * len(head)) + line)
    return lines


def readable(mechanics, equilibria: bool = True) -> str:
    """The derivation laid out for a person, with sympy's pretty printer.

    ``equilibria=False`` leaves out the equilibrium search (a second or more), for the
    window, which shows its result apart when it arrives.
    """
    from systems.display import display_names

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
        lines += _equilibria_lines(mechanics, shown)
    return "\n".join(lines)


def equilibria_sentences(mechanics, digits: int = 6) -> tuple[list[str], str]:
    """One sentence per equilibrium (virtual work, small oscillations), and the search's
    note (why there are none, or what was assumed)."""
    from systems.display import display_names
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


def _equilibria_lines(mechanics, shown: dict[str, str]) -> list[str]:
    lines, note = equilibria_sentences(mechanics)
    title = ["", "Equilibria (virtual work: dV/dq = 0)", "------------------------------------"]
    if not lines:
        return title + [f"none: {note}" if note else "none found"]
    return title + [f"- {line}" for line in lines] + ([f"({note})"] if note else [])
