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
import json
import math
import re
import sys
import time

import numpy as np

from explorer.commands.errors import UserError, user_errors

SUFFIXES = (".png", ".npz", ".csv")
MAX_POINTS = 4_000_000


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
        "--t-end", type=float, default=None, help="how long each orbit runs (default 500)"
    )
    parser.add_argument(
        "--method",
        default=None,
        help="a fixed-step method (default yoshida4 where it applies, rk4 for a damped or "
        "forced scene, else gauss_legendre4)",
    )
    parser.add_argument(
        "--dt", type=float, default=None, help="the step (default 40 per fastest period)"
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
    parser.add_argument("--json", action="store_true", help="print one JSON object")


def parse_grid(text: str) -> tuple[int, int]:
    """'200x100' -> (200, 100): N along the x axis, M along y."""
    match = re.fullmatch(r"\s*(\d+)\s*[xX×]\s*(\d+)\s*", text)
    if not match:
        raise UserError(f"--grid must be N x M starts such as 200x200, not {text!r}")
    nx, ny = int(match.group(1)), int(match.group(2))
    if nx < 2 or ny < 2 or nx * ny > MAX_POINTS:
        raise UserError(
            f"--grid needs at least 2 starts a side and at most {MAX_POINTS:,} in all, not {text}"
        )
    return nx, ny


def parse_ranges(text: str) -> dict[str, tuple[float, float]]:
    """'y=-0.5:0.7,p_y=-1:1' -> {'y': (-0.5, 0.7), 'p_y': (-1.0, 1.0)}."""
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
        if not bounds[0] < bounds[1]:
            raise UserError(f"--ranges: {name.strip()}'s low end must be below its high end")
        ranges[name.strip()] = bounds
    return ranges


def prepare_map(args: argparse.Namespace, scene_name: str):
    """(scene, compiled, tangent, kernel, grid) from the command's arguments, every
    mistake a ``UserError`` naming what to fix. Shared with the window's tests."""
    from explorer.panels.ranges import axis_range
    from systems.chaos import maps
    from systems.chaos.variational import NotApplicable, load_tangent, refusal
    from systems.compiled import compile_system
    from systems.integrators import STEPPERS
    from systems.mechanics import derive
    from systems.scene import load_scene
    from systems.start_check import check_start

    nx, ny = parse_grid(args.grid)
    ranges = parse_ranges(args.ranges)
    if args.indicator not in maps.INDICATORS:
        raise UserError(f"--indicator is megno or lyapunov, not {args.indicator!r}")
    t_end = maps.DEFAULT_T_END if args.t_end is None else args.t_end
    if not (math.isfinite(t_end) and t_end > 0):
        raise UserError(f"--t-end must be a positive finite time, not {t_end!r}")
    with user_errors():
        scene = load_scene(scene_name)
        mechanics = derive(scene)
    reason = refusal(mechanics)
    if reason:
        raise UserError(f"{scene_name}: a chaos map is not available here: {reason}")
    method = args.method or maps.default_map_method(mechanics)
    wants = (STEPPERS[method].wants if method in STEPPERS else frozenset()) | {"hamiltonian"}
    with user_errors():
        compiled = compile_system(mechanics, wants)
        y0 = check_start(compiled, None)
    try:
        tangent = load_tangent(compiled)
        kernel = maps.map_kernel(tangent, t_end=t_end, method=args.method, dt=args.dt)
    except NotApplicable as exc:
        raise UserError(f"{scene_name}: {exc}") from exc
    names = maps.state_names(mechanics)
    if args.over:
        if args.energy is not None:
            raise UserError(
                "--energy sets the section's energy; a map --over two variables has none"
            )
        over = tuple(part.strip() for part in args.over.split(","))
        if len(over) != 2 or any(name not in names for name in over) or over[0] == over[1]:
            raise UserError(
                f"--over takes two different state variables of {', '.join(names)}, "
                f"not {args.over!r}"
            )
        box = tuple(
            ranges.get(name) or axis_range(scene, name, y0[names.index(name)]) for name in over
        )
        return scene, compiled, tangent, kernel, maps.variable_grid(compiled, over, nx, ny, box, y0)
    section = _section(compiled, scene_name)
    energy = args.energy
    if energy is None:
        energy = float(compiled.hamiltonian(0.0, y0[None, :])[0])
    if not math.isfinite(energy):
        raise UserError(f"--energy must be a finite number, not {energy!r}")
    n = compiled.n
    shown = (names[section.shown], names[n + section.shown])
    unknown = set(ranges) - set(shown)
    if unknown:
        raise UserError(
            f"--ranges: the section's axes are {shown[0]} and {shown[1]}, "
            f"not {', '.join(sorted(unknown))}"
        )
    declared = dict(scene.view.get("ranges", {}) or {})
    box = [
        ranges.get(name) or (tuple(map(float, declared[name])) if name in declared else None)
        for name in shown
    ]
    if None in box:
        try:
            found = maps.section_box(compiled, section, energy)
        except ValueError as exc:
            raise UserError(f"{exc} (--ranges {shown[0]}=a:b,{shown[1]}=c:d)") from exc
        box = [given or guess for given, guess in zip(box, found, strict=True)]
    grid = maps.section_grid(compiled, section, energy, nx, ny, tuple(box))
    if not grid.valid.any():
        raise UserError(
            f"no start of the grid lies on the section at energy {energy:g}: give another "
            "--energy or --ranges"
        )
    return scene, compiled, tangent, kernel, grid


def _section(compiled, scene_name: str):
    from systems.angles import angle_coordinates
    from systems.section import Section

    mechanics = compiled.mechanics
    cls = mechanics.classification
    if compiled.n != 2 or cls.time_dependent or not cls.hamiltonian_conserved:
        raise UserError(
            f"{scene_name}: a map on the Poincaré section needs two degrees of freedom and a "
            "conserved H; span two state variables with --over NAME,NAME instead"
        )
    angles = tuple(angle_coordinates(mechanics))
    return Section.from_scene(mechanics.scene, angles, tuple(mechanics.cyclic))


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
    from systems.chaos import maps
    from systems.files import atomic_path

    suffix = checked_output(args.out, SUFFIXES)
    start = time.perf_counter()
    scene, compiled, tangent, kernel, grid = prepare_map(args, args.scene)
    orbits = int(grid.valid.sum())
    if not args.json:
        print(
            f"{orbits} orbits to t = {kernel.t:g} ({kernel.method}, dt {kernel.dt:.3g}); "
            "Ctrl+C stops",
            file=sys.stderr,
            flush=True,
        )
    result = maps.chaos_map(kernel, grid, cancelled=stopping.requested)
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
        "method": kernel.method, "dt": kernel.dt, "t_end": kernel.t,
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
