"""``bifurcation SCENE --parameter NAME --range A:B:N --out FILE``: the orbit diagram of a
periodically driven system over one parameter (``systems.chaos.bifurcation``).

For each of N values from A to B, the orbit from the scene's start (or ``--start``)
runs the transient, then K periods of the drive; its state at the end of each is kept
(the stroboscopic section) and plotted against the parameter. Exit status 1 when some
orbits stopped early.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time

import numpy as np

from explorer.commands.chaosmap_cmd import add_dask_option
from explorer.commands.errors import UserError, user_errors
from systems.usage import MAX_DIAGRAM_VALUES as MAX_VALUES

SUFFIXES = (".png", ".npz")


def add_parser(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser(
        "bifurcation",
        help="the orbit (bifurcation) diagram of a driven system over one parameter",
        description="An orbit diagram: for each value of a parameter, the orbit's state "
        "once per period of the drive (the stroboscopic section) after a transient, "
        "all values in one parallel compiled loop. The driven damped pendulum's "
        "period-doubling route to chaos: --parameter A --range 1.0:1.1:400.",
    )
    parser.add_argument("scene", help="a catalogue name (see `list`) or a path to a .toml file")
    parser.add_argument("--parameter", required=True, help="the parameter to scan, e.g. A")
    parser.add_argument("--range", required=True, dest="span", help="A:B:N, N values from A to B")
    parser.add_argument(
        "--transient", type=float, default=None,
        help="time left out before sampling, rounded up to whole periods (default 300 periods)",
    )  # fmt: skip
    parser.add_argument(
        "--samples", type=int, default=64, help="periods sampled per value (default 64)"
    )
    parser.add_argument(
        "--method",
        default=None,
        help="taylor (adaptive Taylor series in SIMD batches; the default where it applies) "
        "or a fixed-step method such as rk4 (the default elsewhere)",
    )
    parser.add_argument(
        "--tol", type=float, default=None,
        help="taylor's tolerance (default machine epsilon)",
    )  # fmt: skip
    parser.add_argument(
        "--steps-per-period", type=int, default=None,
        help="a fixed-step method's steps per period of the drive (default 200)",
    )  # fmt: skip
    parser.add_argument(
        "--start", default="",
        help="the start of every orbit, e.g. theta=-1.5708,theta_dot=0 (default: the scene's)",
    )  # fmt: skip
    parser.add_argument(
        "--variable", default=None,
        help="the state variable plotted (default: the first coordinate's momentum for an "
        "angle, else the first coordinate)",
    )  # fmt: skip
    parser.add_argument("--out", required=True, help="FILE.png or FILE.npz")
    add_dask_option(parser, "values")
    parser.add_argument("--json", action="store_true", help="print one JSON object")


def parse_span(text: str) -> np.ndarray:
    """'1.0:1.1:400' -> 400 values from 1.0 to 1.1."""
    parts = text.split(":")
    try:
        lo, hi, count = float(parts[0]), float(parts[1]), int(parts[2])
        if len(parts) != 3:
            raise ValueError
    except (ValueError, IndexError):
        raise UserError(
            f"--range takes A:B:N (N values from A to B), e.g. 1.0:1.1:400, not {text!r}"
        ) from None
    if not (math.isfinite(lo) and math.isfinite(hi)) or not 1 <= count <= MAX_VALUES:
        raise UserError(
            f"--range needs finite ends and from 1 to {MAX_VALUES} values, not {text!r}"
        )
    if count > 1 and lo == hi:
        raise UserError(f"--range: {count} values need two different ends")
    return np.linspace(lo, hi, count)


def run(args: argparse.Namespace) -> int:
    from explorer.commands import stopping
    from explorer.commands.chaosmap_cmd import check_dask, checked_output, dask_client
    from explorer.commands.periodic_cmd import _start as parse_start
    from explorer.commands.progress import terminal_progress
    from systems.chaos import bifurcation as bf
    from systems.chaos.maps import state_names
    from systems.files import atomic_path
    from systems.mechanics import derive
    from systems.scene import load_scene
    from systems.usage import diagram_setup

    suffix = checked_output(args.out, SUFFIXES)
    values = parse_span(args.span)
    start_values = parse_start(args.start)
    check_dask(args.dask)
    start = time.perf_counter()
    with user_errors():
        scene = load_scene(args.scene)
        mechanics = derive(scene)
        compiled, kernel, y0, variable, angles = diagram_setup(
            mechanics, args.scene, parameter=args.parameter, transient=args.transient,
            samples=args.samples, method=args.method, steps_per_period=args.steps_per_period,
            start=start_values, variable=args.variable, tol=args.tol,
        )  # fmt: skip
    names = state_names(mechanics)
    if not args.json:
        how = (
            f"tolerance {kernel.tol:.3g}"
            if kernel.tol is not None
            else f"{kernel.per_period} steps a period"
        )
        print(
            f"{len(values)} orbits, {kernel.transient_periods} + {kernel.samples} periods "
            f"each ({kernel.method}, {how})"
            + (f" on the Dask cluster {args.dask}" if args.dask else "")
            + "; Ctrl+C stops",
            file=sys.stderr,
            flush=True,
        )
    with (
        dask_client(args.dask) as client,
        terminal_progress("values", json_output=args.json) as progress,
    ):
        diagram = bf.orbit_diagram(
            kernel, values, y0=y0, cancelled=stopping.requested, progress=progress,
            client=client,
        )  # fmt: skip
    if not diagram.complete:
        raise KeyboardInterrupt
    index = names.index(variable)
    wrap = index in angles
    if suffix == ".npz":
        with atomic_path(args.out) as temporary, open(temporary, "wb") as handle:
            np.savez_compressed(
                handle, values=values, samples=diagram.samples, periods_T=diagram.periods_T,
                status=diagram.status, names=np.array(names), parameter=args.parameter,
                transient_periods=kernel.transient_periods, y0=y0,
            )  # fmt: skip
    else:
        from explorer.commands.chaos_plot import render_points

        column = diagram.variable(variable, wrap=wrap)
        x = np.repeat(values, column.shape[1])
        y = column.ravel()
        keep = np.isfinite(y)
        render_points(
            x[keep], y[keep], labels=(args.parameter, variable), path=args.out,
            title=f"{scene.title}: {variable} once per period of the drive, over {args.parameter}",
        )  # fmt: skip
    found = bf.periods(diagram, angles=tuple(angles))
    stopped = int((diagram.status > 0).sum())
    report = {
        "scene": scene.name or args.scene,
        "parameter": args.parameter,
        "range": [float(values[0]), float(values[-1]), len(values)],
        "variable": variable,
        "method": kernel.method,
        "steps_per_period": None if kernel.tol is not None else kernel.per_period,
        "tol": kernel.tol,
        "steps": [int(n) for n in diagram.steps],
        "checked": diagram.checked,
        "transient_periods": kernel.transient_periods,
        "samples": kernel.samples,
        "drive_period": bf.drive_period(compiled),
        "periods": [int(p) for p in found],
        "stopped": stopped,
        "wall_s": time.perf_counter() - start,
        "out": args.out,
    }
    if args.json:
        print(json.dumps(report, indent=2))
    else:
        counts = {p: int((found == p).sum()) for p in sorted(set(found.tolist()))}
        text = ", ".join(
            f"{c} of period {p}" if p else f"{c} without a period" for p, c in counts.items()
        )
        print(
            f"{scene.title}: orbit diagram over {args.parameter} in [{values[0]:g}, {values[-1]:g}]"
        )
        print(f"{text} (up to {kernel.samples // 2} periods of the drive); {diagram.wall_s:.1f} s")
        print(f"checked: {diagram.checked}")
        if stopped:
            print(f"{stopped} orbits stopped early (left out)")
        print(f"wrote {args.out}")
    return 1 if stopped else 0
