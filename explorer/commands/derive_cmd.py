"""``derive SCENE``: Lagrange's and Hamilton's equations, for a person, as JSON or LaTeX.

The text and the data come from ``systems.report``, which the window uses too; the LaTeX
and the typeset equations from ``systems.typeset``, which the window's Derivation tab
shows. ``--out`` writes a handout: a PDF (A4) or an SVG, the equations typeset as
vectors (``explorer.equations.write_derivation``, drawn offscreen), a LaTeX document or
the text.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from explorer.commands.errors import UserError, user_errors

OUT_SUFFIXES = (".pdf", ".svg", ".tex", ".txt")


def add_parser(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser(
        "derive", help="derive the equations of motion of a scene (catalogue name or .toml)"
    )
    parser.add_argument("scene", help="a catalogue name (see `list`) or a path to a .toml file")
    shown = parser.add_mutually_exclusive_group()
    shown.add_argument("--json", action="store_true", help="print one JSON object")
    shown.add_argument(
        "--latex",
        action="store_true",
        help="print the derivation as a LaTeX document (amsmath; LuaLaTeX or XeLaTeX)",
    )
    parser.add_argument(
        "--out",
        metavar="FILE",
        help="write the derivation to FILE instead: .pdf or .svg (typeset, for handouts), "
        ".tex (LaTeX) or .txt (text)",
    )


def run(args: argparse.Namespace) -> int:
    from systems.mechanics import derive
    from systems.report import derivation_json, readable
    from systems.scene import load_scene

    out = _check_out(args)
    with user_errors():
        scene = load_scene(args.scene)
        mechanics = derive(scene)
        if out is not None:
            return _write(mechanics, out, args.out)
        if args.json:  # the report searches the equilibria too: only when it is printed
            print(json.dumps(derivation_json(mechanics), indent=2))
        elif args.latex:
            from systems.typeset import typeset_derivation

            typeset = typeset_derivation(mechanics, equilibria=True, outlines=False)
            print(typeset.latex_document(), end="")
        else:
            print(readable(mechanics))
    return 0


def _check_out(args: argparse.Namespace) -> Path | None:
    """``--out`` as a path, refused before any work if it cannot be written."""
    if args.out is None:
        return None
    if args.json or args.latex:
        raise UserError("--out writes the derivation to a file: leave out --json and --latex")
    out = Path(args.out)
    if out.suffix.lower() not in OUT_SUFFIXES:
        raise UserError(f"{args.out}: --out must end in .pdf, .svg, .tex or .txt")
    from systems.files import write_problem

    problem = write_problem(out)
    if problem:
        raise UserError(f"--out: {problem}")
    return out


def _write(mechanics, out: Path, name: str) -> int:
    from explorer.commands.export_cmd import write_errors

    suffix = out.suffix.lower()
    with write_errors(name):
        if suffix == ".txt":
            from systems.files import atomic_path
            from systems.report import readable

            text = readable(mechanics)
            with atomic_path(out) as temporary:
                Path(temporary).write_text(text + "\n", encoding="utf-8")
        else:
            from systems.typeset import typeset_derivation

            typeset = typeset_derivation(mechanics, equilibria=True, outlines=suffix != ".tex")
            if suffix == ".tex":
                from systems.files import atomic_path

                with atomic_path(out) as temporary:
                    Path(temporary).write_text(typeset.latex_document(), encoding="utf-8")
            else:
                from explorer.headless import ensure_qt_platform

                ensure_qt_platform()
                from explorer.app import application
                from explorer.equations import write_derivation

                application()
                write_derivation(typeset, out)
    print(f"wrote {out}")
    return 0
