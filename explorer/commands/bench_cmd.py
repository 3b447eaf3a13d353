"""``bench SCENE``: the work-precision diagram (error against wall time, per method)."""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

from explorer.commands.errors import UserError


def add_parser(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser(
        "bench", help="work-precision diagram: error against wall time for several methods"
    )
    parser.add_argument("scene", help="a catalogue name (see `list`) or a path to a .toml file")
    parser.add_argument("--t-end", type=float, default=None, help="end time (default: scene's)")
    parser.add_argument(
        "--methods", default=None, help="comma-separated stepper names (default: those that fit)"
    )
    parser.add_argument(
        "--levels", type=int, default=6, help="points per curve (default 6, at most 12)"
    )
    parser.add_argument("--out", default=None, help="draw the diagram to FILE.png or FILE.svg")
    parser.add_argument("--csv", default=None, help="write the measurements to FILE.csv")


def _progress(done: int, total: int, text: str) -> None:
    width = 24
    filled = int(width * done / max(total, 1))
    line = f"\r[{'#' * filled}{'.' * (width - filled)}] {done}/{total} {text}"
    print(f"{line:<80}", end="" if done < total else "\n", file=sys.stderr, flush=True)


def render(result, path: str) -> Path:
    """The GUI's renderer when it is there, else the minimal one of this package."""
    try:
        from explorer.export import render_workprecision

        return render_workprecision(result, path)
    except ImportError:
        from explorer.commands.bench_plot import render as fallback

        return fallback(result, path)


def check_outputs(args: argparse.Namespace) -> None:
    """``UserError`` for a ``--out`` or ``--csv`` that cannot be written, before the sweep
    (a missing folder, a folder in the file's place)."""
    from systems.files import write_problem

    if args.out is not None and Path(args.out).suffix.lower() not in (".png", ".svg"):
        raise UserError(f"--out must end in .png or .svg, not {args.out!r}")
    for option, path in (("--out", args.out), ("--csv", args.csv)):
        if path is not None:
            problem = write_problem(path)
            if problem:
                raise UserError(f"{option}: {problem}")


def run(args: argparse.Namespace) -> int:
    from explorer.commands.run_cmd import check_method, check_t_end, prepare
    from systems.integrators import STEPPERS
    from systems.workprecision import MAX_LEVELS, default_methods, sweep, sweep_problem

    check_outputs(args)
    if not 2 <= args.levels <= MAX_LEVELS:
        raise UserError(f"--levels must be 2 to {MAX_LEVELS}, not {args.levels}")
    if args.t_end is not None:
        check_t_end(args.t_end)
    scene, mechanics, _, _, compiled = prepare(args.scene, None, extra_wants=(), measure=False)
    if args.methods:
        methods = [m.strip() for m in args.methods.split(",") if m.strip()]
        for method in methods:
            if method not in STEPPERS:
                raise UserError(f"unknown method {method!r}; choose from {', '.join(STEPPERS)}")
            check_method(mechanics, method)
    else:
        methods = default_methods(mechanics)
    wants = set().union(*(STEPPERS[m].wants for m in methods))
    if not wants <= compiled.wanted:
        from systems.compiled import compile_system

        compiled = compile_system(mechanics, compiled.wanted | wants)
    t_end = args.t_end if args.t_end is not None else float(scene.view.get("t_end", 10.0))
    problem = sweep_problem(compiled, methods, t_end=t_end, levels=args.levels)
    if problem:
        raise UserError(f"{problem}: lower --t-end or --levels")
    result = sweep(compiled, methods, t_end=t_end, levels=args.levels, progress=_progress)
    print(f"{result.title}: t_end = {result.t_end:.6g}; reference: {result.reference}")
    print(f"{'method':<18} {'setting':>12} {'wall s':>9} {'steps':>9} {'error':>9} {'energy':>9}")
    for p in result.points:
        energy = "-" if p.energy_error is None else f"{p.energy_error:9.2e}"
        error = f"{p.final_error:9.2e}" if math.isfinite(p.final_error) else "      inf"
        status = "" if p.status == "ok" else f"  ({p.status})"
        print(
            f"{p.method:<18} {p.setting + '=' + format(p.value, '.3g'):>12} {p.wall_s:9.2e} "
            f"{p.steps:9d} {error} {energy:>9}{status}"
        )
    sys.stdout.flush()  # the table is kept even if a file below cannot be written
    failed = []
    for path, write in ((args.csv, result.write_csv), (args.out, lambda p: render(result, p))):
        if not path:
            continue
        try:
            write(path)
        except OSError as exc:
            failed.append(f"could not write {path}: {exc.strerror or exc}")
        else:
            print(f"wrote {path}")
    if failed:
        raise UserError("; ".join(failed))
    return 0
