"""``export SCENE --panel P --out FILE``: a panel's figure rendered headless (PNG or SVG),
or the scene's trajectory as CSV.

Figures are drawn at ``--width`` x ``--height`` pixels (either alone keeps the default
figure's shape; default 1000 x 720 laid out, less the panel's margins); a larger figure
is the same layout scaled up (``explorer.export.figure_layout``). An SVG's curves are
simplified to its resolution. A CSV holds the states at ``--every DT`` of simulated time
(as ``run --every``) or at ``--points N`` evenly spaced times (``run``'s default spacing
otherwise).

``--poincare --orbits N`` draws a section portrait instead of the scene's one orbit: N
starts on the section at the start's energy (or ``--energy``), spread over the allowed
interval of the line p = 0, each orbit's crossings in its own colour
(``systems.section_orbits``: taylor in SIMD batches over all cores; a scene taylor
refuses runs one orbit at a time with its own method). The energy error is printed, and
a warning names the orbits that cannot be trusted (exit status 1, the figure written).

Ctrl+C (or SIGTERM) stops an export at any stage: nothing is written (an existing
``--out`` is left as it was) and the status is 130 (143).
"""

from __future__ import annotations

import argparse
import math
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from explorer.commands.errors import UserError, user_errors
from explorer.orbit_colours import orbit_colour

PANELS = ("configuration", "phase", "conserved", "workprecision")
SUFFIXES = (".png", ".svg", ".csv")
PORTRAIT_CROSSINGS = 2000
PORTRAIT_T_END = 2000.0
"""A section portrait's orbits run this long by default (``[view] t_end`` is one orbit's
drawing, far too short for a section): a few hundred crossings each."""
MAX_ORBITS = 10_000


def add_parser(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser(
        "export",
        help="render a panel of a scene to PNG or SVG without a display, or write it as CSV",
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
        help="phase panel: the Poincaré section (two-degree autonomous systems), or the "
        "stroboscopic section of a periodically driven one (t = T, 2T, ...)",
    )
    parser.add_argument(
        "--orbits",
        type=int,
        default=None,
        help="with --poincare: a section portrait of this many orbits from starts spread "
        "over the section (taylor, in SIMD batches on all cores)",
    )
    parser.add_argument(
        "--energy",
        type=float,
        default=None,
        help="with --orbits: the section's energy (default: the scene's start's)",
    )
    parser.add_argument(
        "--crossings",
        type=int,
        default=None,
        help=f"with --orbits: crossings kept per orbit at most (default {PORTRAIT_CROSSINGS})",
    )
    parser.add_argument("--width", type=int, default=None, help="figure width in pixels (PNG, SVG)")
    parser.add_argument(
        "--height", type=int, default=None, help="figure height in pixels (PNG, SVG)"
    )
    rows = parser.add_mutually_exclusive_group()
    rows.add_argument(
        "--every",
        type=float,
        default=None,
        help="CSV: one row every DT of simulated time (as run --every)",
    )
    rows.add_argument(
        "--points",
        type=int,
        default=None,
        help="CSV: this many rows, evenly spaced in simulated time",
    )
    parser.add_argument(
        "--out", required=True, help="the file to write: FILE.png, FILE.svg or FILE.csv"
    )


def image_size(args: argparse.Namespace, base: tuple[int, int]) -> tuple[int, int] | None:
    """The figure's pixel size from ``--width``/``--height`` (one alone keeps the shape of
    ``base``), or None for the default. ``UserError`` for a size out of range."""
    from explorer.export import MAX_PIXELS

    width, height = args.width, args.height
    for name, value in (("--width", width), ("--height", height)):
        if value is not None and not 1 <= value <= MAX_PIXELS:
            raise UserError(f"{name} must be between 1 and {MAX_PIXELS} pixels, not {value}")
    if width is None and height is None:
        return None
    if width is None:
        width = max(1, round(height * base[0] / base[1]))
    if height is None:
        height = max(1, round(width * base[1] / base[0]))
    return (width, height)


def csv_times(args: argparse.Namespace, t_end: float):
    """The simulated times of a CSV's rows, chosen as ``run`` chooses them: one every
    ``--every`` from 0 and ``t_end``, or ``--points`` evenly spaced from 0 to ``t_end``
    (``run --samples N`` gives N + 1 rows), or ``run``'s default."""
    from explorer.commands.run_cmd import sample_times

    samples = None if args.points is None else args.points - 1
    return sample_times(argparse.Namespace(every=args.every, samples=samples), t_end)


def check_args(args: argparse.Namespace, out: Path) -> None:
    """``UserError`` for options that do not go together, before any work is done."""
    suffix = out.suffix.lower()
    if suffix not in SUFFIXES:
        raise UserError(f"{args.out}: --out must end in .png or .svg (a figure) or .csv (a table)")
    table = suffix == ".csv"
    if table and (args.width is not None or args.height is not None):
        raise UserError("--width and --height size a figure (.png, .svg), not a CSV table")
    if not table and (args.every is not None or args.points is not None):
        raise UserError("--every and --points choose the rows of a CSV table, not a figure")
    if table and args.panel == "workprecision":
        raise UserError("the work-precision panel is a figure: --out must be .png or .svg")
    if args.every is not None and not (math.isfinite(args.every) and args.every > 0):
        raise UserError(f"--every must be a positive time, not {args.every:g}")
    if args.points is not None and not 2 <= args.points <= 10**7:
        raise UserError(f"--points must be between 2 and 10000000, not {args.points}")
    portrait_options = (args.energy, args.crossings)
    if args.orbits is None and any(v is not None for v in portrait_options):
        raise UserError("--energy and --crossings go with --orbits (a section portrait)")
    if args.orbits is not None:
        if not args.poincare or args.panel != "phase" or table:
            raise UserError("--orbits draws a section portrait: give --poincare and a .png or .svg")
        if not 1 <= args.orbits <= MAX_ORBITS:
            raise UserError(f"--orbits must be between 1 and {MAX_ORBITS}, not {args.orbits}")
        if args.crossings is not None and not 1 <= args.crossings <= 10**6:
            raise UserError(f"--crossings must be between 1 and 1000000, not {args.crossings}")
        if args.energy is not None and not math.isfinite(args.energy):
            raise UserError(f"--energy must be a finite number, not {args.energy}")
    if args.t_end is not None:
        from explorer.commands.run_cmd import check_t_end

        check_t_end(args.t_end)


def run(args: argparse.Namespace) -> int:
    try:
        return _export(args)
    except KeyboardInterrupt:
        from explorer.commands.stopping import cause, status

        print(f"stopped ({cause()}): {args.out} was not written", file=sys.stderr)
        return status()


def _export(args: argparse.Namespace) -> int:
    from explorer.headless import FIGURE_SIZE, ensure_qt_platform

    out = Path(args.out)
    check_args(args, out)
    size = image_size(args, FIGURE_SIZE)
    from systems.files import write_problem

    problem = write_problem(out)
    if problem:
        raise UserError(f"--out: {problem}")
    ensure_qt_platform()
    from systems.scene import load_scene

    with user_errors(), write_errors(args.out):
        scene = load_scene(args.scene)
        if args.panel == "workprecision":
            return _workprecision(scene, args, out, size)
        if args.orbits is not None:
            return _portrait(scene, args, out, size)
        try:
            if out.suffix.lower() == ".csv":
                from explorer.headless import write_csv

                t_end = float(args.t_end or scene.view.get("t_end", 20.0))
                written, main = write_csv(scene, out, t_end, csv_times(args, t_end))
            else:
                from explorer.headless import render_panel

                written, main = render_panel(
                    scene,
                    args.panel,
                    out,
                    t_end=args.t_end,
                    poincare=args.poincare,
                    image_size=size,
                )
        except ValueError as exc:
            raise UserError(str(exc)) from exc
    if main is not None and main.status not in ("ok", "running"):
        print(f"warning: the integration stopped early: {main.message}", file=sys.stderr)
    print(f"wrote {written}")
    return 0


@contextmanager
def write_errors(out: str) -> Iterator[None]:
    """``UserError`` (exit 2) for an ``OSError`` in the block: ``out`` could not be
    written (a full disk, a device that refuses, a folder removed meanwhile)."""
    try:
        yield
    except OSError as exc:
        raise UserError(f"could not write {out}: {exc.strerror or exc}") from None


def _workprecision(scene, args, out: Path, size: tuple[int, int] | None) -> int:
    from explorer.export import render_workprecision
    from explorer.panels.workprecision_view import run_workprecision

    try:
        result = run_workprecision(scene, t_end=args.t_end)
    except ValueError as exc:
        raise UserError(f"{exc}: lower --t-end") from None
    written = render_workprecision(result, out, image_size=size)
    print(f"wrote {written}")
    return 0


def _portrait(scene, args, out: Path, size: tuple[int, int] | None) -> int:
    """``--poincare --orbits N``: the section portrait drawn in the phase panel."""
    import numpy as np

    from explorer.app import application
    from explorer.builder import build
    from explorer.export import export_widget, signals_held
    from explorer.headless import FIGURE_SIZE, make_panel
    from explorer.trajectories import TrajectoryStore
    from systems.section_orbits import default_starts, section_portrait
    from systems.simulation import Block

    app = application()
    built = build(scene)
    compiled = built.compiled
    view = make_panel("phase")
    try:
        view.resize(*FIGURE_SIZE)
        y0 = compiled.initial_state()
        view.set_system(compiled, y0)
        view.set_mode("poincare")
        if view.mode != "poincare" or view.section is None:
            raise UserError(
                "--orbits draws a Poincaré section: it needs an autonomous conservative "
                "system of two degrees of freedom"
            )
        section = view.section
        with np.errstate(all="ignore"):
            start_energy = float(compiled.hamiltonian(0.0, y0[None, :])[0])
        energy = start_energy if args.energy is None else float(args.energy)
        t_end = PORTRAIT_T_END if args.t_end is None else float(args.t_end)
        try:
            starts = default_starts(compiled, section, energy, args.orbits)
            portrait = section_portrait(
                compiled, section, energy, starts, t_end=t_end,
                crossings=args.crossings or PORTRAIT_CROSSINGS, fallback=True,
            )  # fmt: skip
        except ValueError as exc:
            raise UserError(str(exc)) from exc
        view.set_system(compiled, portrait.starts[0])  # the section's energy: its region
        store = TrajectoryStore(n_points=len(compiled.point_names), capacity=64)
        for r, start in enumerate(portrait.starts):
            trajectory = store.add(start)
            trajectory.colour = orbit_colour(r, len(portrait.starts))
            block = Block(
                t=np.array([0.0]), y=start[None, :], diagnostics={}, status="ok",
                message=portrait.messages[r], steps=int(portrait.steps[r]), rhs_evaluations=0,
                method=portrait.method, events_t=portrait.t[r], events_y=portrait.y[r],
            )  # fmt: skip
            store.append(trajectory.key, block)
        with signals_held():
            view.show()
            app.processEvents()
            view.refresh(store)
            app.processEvents()
        written = export_widget(view.export_target(), out, size)
    finally:
        with signals_held():
            view.close()
            view.deleteLater()
            app.processEvents()
    print(portrait.summary())
    for message in [m for m in portrait.messages if m][:5]:
        print(f"warning: {message}", file=sys.stderr)
    print(f"wrote {written}")
    return 0 if portrait.trusted.all() else 1
