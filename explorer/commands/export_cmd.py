"""``export SCENE --panel P --out FILE``: a panel's figure rendered headless (PNG or SVG)."""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

from explorer.commands.errors import UserError, user_errors

PANELS = ("configuration", "phase", "conserved", "workprecision")


def add_parser(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser(
        "export", help="render a panel of a scene to PNG or SVG without a display"
    )
    parser.add_argument("scene", help="a catalogue name (see `list`) or a path to a .toml file")
    parser.add_argument(
        "--panel", choices=PANELS, default="phase", help="which panel (default: phase)"
    )
    parser.add_argument(
        "--t-end",
        type=float,
        default=None,
        help="integrate to this time (default: the scene's [view] t_end)",
    )
    parser.add_argument(
        "--poincare",
        action="store_true",
        help="phase panel: the Poincaré section (two-degree autonomous systems)",
    )
    parser.add_argument("--out", required=True, help="the figure to write: FILE.png or FILE.svg")


def run(args: argparse.Namespace) -> int:
    from explorer.headless import ensure_qt_platform

    out = Path(args.out)
    if out.suffix.lower() not in (".png", ".svg"):
        raise UserError(f"{args.out}: --out must end in .png or .svg")
    from systems.files import write_problem

    problem = write_problem(out)
    if problem:
        raise UserError(f"--out: {problem}")
    if args.t_end is not None and not (math.isfinite(args.t_end) and args.t_end > 0):
        raise UserError(f"--t-end must be a positive finite time, not {args.t_end:g}")
    ensure_qt_platform()
    from systems.scene import load_scene

    with user_errors():
        scene = load_scene(args.scene)
        if args.panel == "workprecision":
            return _workprecision(scene, args, out)
        from explorer.headless import render_panel

        try:
            written, main = render_panel(
                scene, args.panel, out, t_end=args.t_end, poincare=args.poincare
            )
        except ValueError as exc:
            raise UserError(str(exc)) from exc
    if main is not None and main.status not in ("ok", "running"):
        print(f"warning: the integration stopped early: {main.message}", file=sys.stderr)
    print(f"wrote {written}")
    return 0


def _workprecision(scene, args, out: Path) -> int:
    from explorer.export import render_workprecision
    from explorer.panels.workprecision_view import run_workprecision

    result = run_workprecision(scene, t_end=args.t_end)
    written = render_workprecision(result, out)
    print(f"wrote {written}")
    return 0
