"""``chaosmap SCENE --grid NxM --out FILE``: MEGNO or the maximal exponent over a grid of
starts (``systems.chaos.maps``).

By default the grid lies on the scene's Poincaré section (two degrees of freedom, H
conserved) at the start's energy or ``--energy``, the missing momentum solved as a click
on the section solves it; ``--over NAME,NAME`` spans two state variables instead, the
rest of the state from the scene's start. Exit status 1 when some orbits stopped early
(they are left out of the fraction and shown grey).
"""

from __future__ import annotations

import argparse
import contextlib
import json
import math
import re
import sys
import time
from collections.abc import Iterator

import numpy as np

from explorer.commands.errors import UserError, user_errors

SUFFIXES = (".png", ".npz", ".csv")


def add_parser(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser(
        "chaosmap",
        help="MEGNO or the maximal Lyapunov exponent over a grid of starts",
        description="A chaos map: every start of an N x M grid on the Poincaré section (at "
        "the section's energy, the missing momentum solved) or over two state variables "
        "(--over), integrated with one tangent vector in one parallel compiled loop, "
        "coloured by MEGNO's mean <Y> (2 regular, growing like max*t/2 when chaotic) or "
        "the maximal exponent.",
    )
    parser.add_argument("scene", help="a catalogue name (see `list`) or a path to a .toml file")
    parser.add_argument(
        "--grid", default="100x100", help="N x M starts, e.g. 200x200 (default 100x100)"
    )
    parser.add_argument(
        "--energy", type=float, default=None, help="the section's energy (default: the start's)"
    )
    parser.add_argument("--indicator", default="megno", help="megno (default) or lyapunov")
    parser.add_argument(
        "--t-end",
        type=float,
        default=None,
        help="how long each orbit runs (default 500; 100 for an implicit method, "
        "gauss_legendre4: each of its steps costs tens of an explicit one's)",
    )
    parser.add_argument(
        "--method",
        default=None,
        help="a fixed-step method (default yoshida4 where it applies, rk4 for a damped or "
        "forced scene, else gauss_legendre4), or taylor: adaptive Taylor series at machine "
        "precision with the variational equations and MEGNO's integral in its series, the "
        "orbits in SIMD batches",
    )
    parser.add_argument(
        "--dt", type=float, default=None, help="the step (default 40 per fastest period)"
    )
    parser.add_argument(
        "--tol",
        type=float,
        default=None,
        help="--method taylor: the tolerance (default machine epsilon; a map's verdicts "
        "hold at 1e-10 in fewer, cheaper steps)",
    )
    parser.add_argument(
        "--over", default=None,
        help="two state variables to span instead of the section, e.g. theta1,theta2",
    )  # fmt: skip
    parser.add_argument(
        "--ranges", default="",
        help="the axes' ranges, e.g. y=-0.5:0.7,p_y=-0.5:0.5 (default: [view] ranges, or "
        "the section's allowed region)",
    )  # fmt: skip
    parser.add_argument("--out", required=True, help="FILE.png, FILE.npz or FILE.csv")
    add_dask_option(parser, "starts")
    parser.add_argument("--json", action="store_true", help="print one JSON object")


def add_dask_option(parser: argparse.ArgumentParser, rows: str) -> None:
    """``--dask auto|tcp://HOST:PORT`` (shared with ``bifurcation``)."""
    parser.add_argument(
        "--dask", default=None, metavar="auto|tcp://HOST:PORT",
        help=f"compute chunks of the {rows} on a Dask cluster: auto starts one of this "
        "machine's cores, tcp://HOST:PORT uses a running scheduler (`dask scheduler`, "
        "`dask worker tcp://HOST:PORT`); the same numbers as without. Needs the dask "
        'extra: pip install -e ".[dask]"',
    )  # fmt: skip


@contextlib.contextmanager
def dask_client(address: str | None) -> Iterator[object]:
    """The ``distributed.Client`` of ``--dask`` (``systems.chaos.distributed.connect``),
    or None without it; a scheduler that does not answer is a ``UserError``."""
    if address is None:
        yield None
        return
    from systems.chaos.distributed import connect

    with contextlib.ExitStack() as stack:
        with user_errors():
            client = stack.enter_context(connect(address))
        yield client


def check_dask(address: str | None) -> None:
    """``--dask``'s value and the extra, checked before the work (``UserError``)."""
    if address is not None:
        from systems.chaos.distributed import check_address, require_dask

        with user_errors():
            check_address(address)
            require_dask()


def parse_grid(text: str) -> tuple[int, int]:
    """'200x100' -> (200, 100): N along the x axis, M along y (sizes checked by
    ``systems.usage.check_map_options``)."""
    match = re.fullmatch(r"\s*(\d+)\s*[xX×]\s*(\d+)\s*", text)
    if not match:
        raise UserError(f"--grid must be N x M starts such as 200x200, not {text!r}")
    return int(match.group(1)), int(match.group(2))


def parse_ranges(text: str) -> dict[str, tuple[float, float]]:
    """'y=-0.5:0.7,p_y=-1:1' -> {'y': (-0.5, 0.7), 'p_y': (-1.0, 1.0)}."""
    from systems.usage import check_ranges

    ranges = {}
    for item in filter(None, (part.strip() for part in text.split(","))):
        name, equals, span = item.partition("=")
        lo, colon, hi = span.partition(":")
        try:
            bounds = (float(lo), float(hi))
        except ValueError:
            bounds = None
        if not (equals and colon and bounds and all(map(math.isfinite, bounds))):
            raise UserError(f"--ranges takes name=low:high items, e.g. y=-0.5:0.7, not {item!r}")
        ranges[name.strip()] = bounds
    with user_errors():
        return check_ranges(ranges)


def prepare_map(args: argparse.Namespace, scene_name: str):
    """(scene, compiled, tangent, kernel, grid) from the command's arguments, every
    mistake a ``UserError`` naming what to fix (``systems.usage``'s checks, which the
    Python API shares). Shared with the window's tests."""
    from systems.mechanics import derive
    from systems.scene import load_scene
    from systems.usage import check_map_options, map_setup

    nx, ny = parse_grid(args.grid)
    ranges = parse_ranges(args.ranges)
    with user_errors():
        t_end = check_map_options(nx, ny, args.indicator, args.t_end, grid_text=args.grid)
        scene = load_scene(scene_name)
        mechanics = derive(scene)
        over = None if not args.over else tuple(part.strip() for part in args.over.split(","))
        compiled, tangent, kernel, grid = map_setup(
            mechanics, scene_name, nx=nx, ny=ny, t_end=t_end, method=args.method, dt=args.dt,
            over=over, ranges=ranges, energy=args.energy,
        )  # fmt: skip
    tol = getattr(args, "tol", None)
    if tol is not None:
        if kernel.method != "taylor":
            raise UserError(f"--tol goes with --method taylor; {kernel.method} takes --dt")
        from systems.chaos import maps
        from systems.chaos.variational import NotApplicable

        try:
            kernel = maps.map_kernel(tangent, t_end=kernel.t_end, method="taylor", tol=tol)
        except NotApplicable as exc:
            raise UserError(f"--tol: {exc}") from exc
    return scene, compiled, tangent, kernel, grid


def checked_output(out: str, suffixes: tuple[str, ...]) -> str:
    """The suffix of ``out`` (one of ``suffixes``), checked writable before the work."""
    from systems.files import write_problem

    suffix = "." + out.rpartition(".")[2].lower() if "." in out else ""
    if suffix not in suffixes:
        *first, last = suffixes
        raise UserError(f"--out must end in {', '.join(first)} or {last}, not {out!r}")
    problem = write_problem(out)
    if problem:
        raise UserError(problem)
    return suffix


def run(args: argparse.Namespace) -> int:
    from explorer.commands import stopping
    from explorer.commands.progress import terminal_progress
    from systems.chaos import maps
    from systems.files import atomic_path

    suffix = checked_output(args.out, SUFFIXES)
    check_dask(args.dask)
    start = time.perf_counter()
    scene, compiled, tangent, kernel, grid = prepare_map(args, args.scene)
    orbits = int(grid.valid.sum())
    if not args.json:
        where = f" on the Dask cluster {args.dask}" if args.dask else ""
        print(
            f"{orbits} orbits to t = {kernel.t:g} ({kernel.method}, {step_text(kernel)})"
            f"{where}; Ctrl+C stops",
            file=sys.stderr,
            flush=True,
        )
    with (
        dask_client(args.dask) as client,
        terminal_progress("orbits", json_output=args.json) as progress,
    ):
        result = maps.chaos_map(
            kernel, grid, cancelled=stopping.requested, progress=progress, client=client
        )
    if not result.complete:
        raise KeyboardInterrupt
    indicator = args.indicator
    _write(result, indicator, scene, args.out, suffix, atomic_path)
    stopped = int((result.status > 0).sum())
    report = {
        "scene": scene.name or args.scene,
        "indicator": indicator,
        "chaotic_fraction": result.chaotic_fraction(indicator),
        "threshold": result.threshold(indicator),
        "megno_chaotic_fraction": result.chaotic_fraction("megno"),
        "lyapunov_chaotic_fraction": result.chaotic_fraction("lyapunov"),
        "grid": {
            "x": grid.names[0], "y": grid.names[1], "nx": len(grid.xs), "ny": len(grid.ys),
            "x_range": [float(grid.xs[0]), float(grid.xs[-1])],
            "y_range": [float(grid.ys[0]), float(grid.ys[-1])],
            "energy": grid.energy,
            "section": None if grid.section is None else {
                "coordinate": maps.state_names(compiled.mechanics)[grid.section[0]],
                "value": grid.section[1],
            },
            "orbits": orbits,
        },
        "method": kernel.method, "dt": None if kernel.taylor else kernel.dt,
        "tol": kernel.tol if kernel.taylor else None, "t_end": kernel.t,
        "stopped": stopped,
        "wall_s": time.perf_counter() - start,
        "map_s": result.wall_s,
        "out": args.out,
    }  # fmt: skip
    if args.json:
        print(json.dumps(report, indent=2))
    else:
        fraction = report["chaotic_fraction"]
        print(
            f"{scene.title}: {indicator} map of {len(grid.xs)}x{len(grid.ys)} over "
            f"({grid.names[0]}, {grid.names[1]})"
            + (f" on the section at E = {grid.energy:.6g}" if grid.energy is not None else "")
        )
        print(
            f"chaotic fraction {fraction:.4f} ({indicator} > {report['threshold']:.4g}) of "
            f"{orbits - stopped} orbits to t = {kernel.t:g}; {result.wall_s:.1f} s"
        )
        if stopped:
            print(f"{stopped} orbits stopped early (shown grey, left out)")
        print(f"wrote {args.out}")
    return 1 if stopped else 0


def step_text(kernel) -> str:
    """'dt 0.143', or 'tol 2.2e-16' for taylor's adaptive steps."""
    if kernel.taylor is not None:
        return f"adaptive, tol {kernel.tol:.2g}"
    return f"dt {kernel.dt:.3g}"


def _write(result, indicator: str, scene, out: str, suffix: str, atomic_path) -> None:
    grid = result.grid
    if suffix == ".npz":
        with atomic_path(out) as temporary, open(temporary, "wb") as handle:
            np.savez_compressed(
                handle, x=grid.xs, y=grid.ys, megno=result.megno, lyapunov=result.lyapunov,
                megno_now=result.megno_now, status=result.status, starts=grid.starts,
                names=np.array(grid.names), t_end=result.t_end, dt=result.dt,
                energy=np.nan if grid.energy is None else grid.energy,
            )  # fmt: skip
    elif suffix == ".csv":
        X, Y = np.meshgrid(grid.xs, grid.ys)
        table = np.column_stack([
            X.ravel(), Y.ravel(), result.megno.ravel(), result.lyapunov.ravel(),
            result.megno_now.ravel(), result.status.ravel(),
        ])  # fmt: skip
        header = f"{grid.names[0]},{grid.names[1]},megno,lyapunov,megno_now,status"
        with atomic_path(out) as temporary:
            np.savetxt(temporary, table, delimiter=",", header=header, comments="", fmt="%.10g")
    else:
        from explorer.commands.chaos_plot import render_map

        values = result.values(indicator)
        threshold = result.threshold(indicator)
        if indicator == "megno":
            levels = (0.0, 2 * threshold)
        else:
            finite = values[np.isfinite(values)]
            levels = (0.0, float(np.quantile(finite, 0.99)) if finite.size else 1.0)
        where = f" on {grid.names[0]}, {grid.names[1]}"
        if grid.energy is not None:
            where = f", section at E = {grid.energy:.4g}"
        label = "MEGNO <Y>" if indicator == "megno" else "maximal exponent"
        title = f"{scene.title}: {label} to t = {result.t_end:g}{where}"
        render_map(
            values, grid.xs, grid.ys, title=title, labels=grid.names, colour_label=label,
            levels=levels, path=out,
        )  # fmt: skip
