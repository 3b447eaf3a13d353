"""``run SCENE``: integrate headless, write the trajectory, report what it cost."""

from __future__ import annotations

import argparse
import csv
import json
import math
import sys
import time
from contextlib import nullcontext
from pathlib import Path

import numpy as np

from explorer.commands.errors import UserError, user_errors
from explorer.commands.stopping import check, deferred, requested, status
from systems.limits import DEFAULT_ENERGY_TOLERANCE, DEFAULT_MAX_STEPS

DEFAULT_SAMPLES = 10_000
"""Rows ``run --out`` writes by default: the states at this many evenly spaced times."""


def add_parser(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser("run", help="integrate a scene headless and report the result")
    parser.add_argument("scene", help="a catalogue name (see `list`) or a path to a .toml file")
    parser.add_argument("--t-end", type=float, default=None, help="end time (default: scene's)")
    parser.add_argument("--method", default=None, help="a stepper name (default: automatic)")
    add_integration_options(parser)
    rows = parser.add_mutually_exclusive_group()
    rows.add_argument(
        "--samples", type=int, default=None,
        help=f"rows written: states at this many evenly spaced times (default {DEFAULT_SAMPLES})",
    )  # fmt: skip
    rows.add_argument("--every", type=float, default=None, help="rows written: one every DT")
    parser.add_argument("--out", default=None, help="write the trajectory to FILE.csv or .npz")
    parser.add_argument("--json", action="store_true", help="print one JSON object")


def add_integration_options(parser: argparse.ArgumentParser) -> None:
    """--dt / --tol, --max-steps and --energy-tolerance, shared by run and export."""
    step = parser.add_mutually_exclusive_group()
    step.add_argument(
        "--dt", type=float, default=None,
        help="step of a fixed-step method (fictitious-time step of a time-transformed one)",
    )  # fmt: skip
    step.add_argument("--tol", type=float, default=None, help="tolerance of an adaptive method")
    parser.add_argument(
        "--max-steps", type=int, default=DEFAULT_MAX_STEPS,
        help=f"step budget: stop with status 'budget' beyond it (default {DEFAULT_MAX_STEPS:.0e})",
    )  # fmt: skip
    parser.add_argument(
        "--energy-tolerance", default=str(DEFAULT_ENERGY_TOLERANCE),
        help="stop when the relative energy error exceeds this (a number, or 'off')",
    )  # fmt: skip


def integration_options(args: argparse.Namespace, method: str, t_end: float) -> dict:
    """``stream`` keywords from the options of ``add_integration_options``, checked against
    the method and a run from 0 to ``t_end`` (``UserError``, exit 2, for a setting it does
    not take or cannot honour)."""
    from systems.usage import integration_settings

    with user_errors():
        return integration_settings(
            method, t_end, dt=args.dt, tol=args.tol, max_steps=args.max_steps,
            energy_tolerance=args.energy_tolerance,
        )  # fmt: skip


def prepare(
    scene_name: str,
    method: str | None,
    extra_wants=("velocities",),
    t_end: float | None = None,
    measure: bool = True,
):
    """Load, derive, choose and compile. Returns (scene, mechanics, method, why, compiled).

    The automatic choice is measured on the compiled system over ``t_end`` (default: the
    scene's ``[view] t_end``; ``systems.integrators.measured``).

    Raises ``UserError`` for an unknown method or one the system does not allow.
    """
    from systems.mechanics import derive
    from systems.scene import load_scene
    from systems.usage import prepare_run

    with user_errors():
        scene = load_scene(scene_name)
        mechanics = derive(scene)
        method, why, compiled = prepare_run(
            mechanics, method, extra_wants=extra_wants, t_end=t_end, measure=measure
        )
    return scene, mechanics, method, why, compiled


def check_method(mechanics, method: str) -> None:
    """``UserError`` when ``method`` does not apply to the system (the registry says why)."""
    from systems.usage import check_method as checked

    with user_errors():
        checked(mechanics, method)


def run(args: argparse.Namespace) -> int:
    from systems.simulation import Run, Sampler, precompile

    endless = args.t_end is not None and math.isinf(args.t_end) and args.t_end > 0
    check_output(args, endless)
    start = time.perf_counter()
    given_end = args.t_end if args.t_end is not None and math.isfinite(args.t_end) else None
    # a step or tolerance given picks the kind of method: the classification's choice
    measure = args.dt is None and args.tol is None
    scene, mechanics, method, why, compiled = prepare(
        args.scene, args.method, t_end=given_end, measure=measure
    )
    t_end = args.t_end if args.t_end is not None else float(scene.view.get("t_end", 10.0))
    if not endless:
        given = "--t-end" if args.t_end is not None else f"the scene's [view] t_end of {t_end}"
        check_t_end(t_end, given, " (or inf, with --out and --every)")
    options = integration_options(args, method, t_end)
    y0 = compiled.initial_state()
    # the system's functions were compiled (or loaded) with it; the method's driver,
    # compiled once per installation, is loaded here
    compile_s = compiled.build_seconds + precompile(compiled, method, y0)
    prepare_s = time.perf_counter() - start

    times = sample_times(args, t_end)
    start = time.perf_counter()
    # the energy at the rows: per block for a stream, else once over all rows below
    diagnostics = ("H",) if endless else ()
    run_ = Run(compiled, method=method, y0=y0, t_end=t_end, diagnostics=diagnostics, **options)
    if args.out:
        print(
            f"integrating to t = {t_end:g}; Ctrl+C stops and writes what is done", file=sys.stderr
        )
    sampler = Sampler(run_, times)
    if endless:
        t, y, qdot, H = stream_trajectory(args.out, scene, compiled, sampler)
    else:
        t, y = collect(sampler)
    # the run is over (finished, or stopped and kept): a signal now waits for its file
    keep = deferred(f"writing {args.out}") if args.out and not endless else nullcontext()
    with keep:
        if not endless:
            with np.errstate(all="ignore"):
                H = compiled.hamiltonian(t, y)
                # the rows' velocities go to --out; the report needs the last only
                qdot = (
                    compiled.velocities(t, y) if args.out else compiled.velocities(t[-1:], y[-1:])
                )
        last, interrupted = sampler.last, sampler.interrupted
        constraints = compiled.constraints()
        violation = None
        if constraints is not None:  # every block's states, and the rows (endless: first, last)
            violation = max(sampler.violation or 0.0, constraints.violation(t, y))
        if last is None:
            last = run_.stop("interrupted", "")
        wall_s = time.perf_counter() - start
        n = compiled.n
        conserved = mechanics.classification.hamiltonian_conserved
        max_rel = None
        if conserved:
            scale = abs(H[0]) if abs(H[0]) > 1e-8 else 1.0
            max_rel = max(float(np.max(np.abs(H - H[0])) / scale), sampler.worst / scale)
        if args.out and not endless:
            try:
                multipliers = None if constraints is None else constraints.multipliers(t, y)
                write_trajectory(args.out, scene, t, y, qdot, H, n, multipliers)
            except OSError as exc:
                raise UserError(f"could not write {args.out}: {exc.strerror or exc}") from None
    status_, message = ("interrupted" if interrupted else last.status), last.message
    accuracy = None
    if not (endless or interrupted or conserved) and last.status == "ok":
        # nothing in the run watched its answer: a finer second run does
        from systems.run_check import check_final_state

        found = check_final_state(
            compiled, method, last.setting, last.setting_value, 0.0, y0, float(last.t[-1]),
            last.y[-1], max_steps=args.max_steps,
        )  # fmt: skip
        accuracy = found.as_dict()
        if not found.accurate:
            status_, message = "inaccurate", found.message
    double = bool(getattr(run_.runner, "double", False))
    report = {
        "method": method,
        "why": why,
        # taylor below machine epsilon: the state and orders 1 and 2 in double-double
        "arithmetic": "double-double" if double else "double",
        "steps": int(last.steps),
        "rhs_evaluations": int(last.rhs_evaluations),
        "setting": {last.setting: last.setting_value} if last.setting else {},
        "wall_s": wall_s,
        "prepare_s": prepare_s,
        "compile_s": compile_s,
        "t_end": float(t[-1]),
        "final": {
            "q": dict(zip(scene.coordinates, map(float, y[-1, :n]), strict=True)),
            "qdot": dict(zip(scene.coordinates, map(float, qdot[-1]), strict=True)),
            "p": dict(zip(scene.coordinates, map(float, y[-1, n:]), strict=True)),
        },
        "max_rel_energy_error": max_rel,
        "max_constraint_violation": violation,
        "accuracy": accuracy,
        "status": status_,
        "message": (
            f"interrupted at t = {t[-1]:.6g}; the {sampler.count} rows up to there were written"
            + ("" if args.out else " (none: no --out)")
            if interrupted
            else message
        ),
    }
    if args.json:
        print(json.dumps(report, indent=2))
    else:
        print(readable(scene, report))
    if report["status"] == "ok":
        return 0
    done = "inaccurate" if report["status"] == "inaccurate" else f"stopped: {report['status']}"
    print(f"{done}: {report['message']}", file=sys.stderr)
    return status() if interrupted else 1


def check_t_end(t_end: float, given: str = "--t-end", alternative: str = "") -> None:
    """``UserError`` unless ``t_end`` is a finite time of at least ``MIN_T_END``.

    ``given`` names where the time came from; ``alternative`` is added to the message
    (" (or inf, with --out and --every)").
    """
    from systems.usage import check_t_end as checked

    with user_errors():
        checked(t_end, given, alternative)


def check_output(args: argparse.Namespace, endless: bool) -> None:
    """``UserError`` for an ``--out`` that cannot be written, before any work is done."""
    if args.out is not None and Path(args.out).suffix.lower() not in (".csv", ".npz"):
        raise UserError(f"--out must end in .csv or .npz, not {args.out!r}")
    if endless:
        if args.out is None or Path(args.out).suffix.lower() != ".csv" or args.every is None:
            raise UserError(
                "an endless run (--t-end inf) streams its rows to disk: give --out FILE.csv "
                "and --every DT; it ends with Ctrl+C, the step budget or a problem"
            )
    if args.out is not None:
        from systems.files import write_problem

        problem = write_problem(args.out)
        if problem:
            raise UserError(f"--out: {problem}")


def collect(sampler) -> tuple[np.ndarray, np.ndarray]:
    """All samples of ``sampler`` as arrays t (k,), y (k, 2n); Ctrl+C (or SIGTERM, SIGHUP:
    ``explorer.commands.stopping``) keeps those so far."""
    ts, ys = [], []
    try:
        for t, y in sampler.chunks():  # thousands of rows a chunk
            ts.append(t)
            ys.append(y)
            check()
    except KeyboardInterrupt:
        sampler.interrupted = True
    except Exception:
        if not requested():
            raise
        sampler.interrupted = True  # the signal's exception was lost (``stopping``)
    sampler.count = sum(len(t) for t in ts)
    if not ts:
        return np.empty(0), np.empty((0, len(sampler.run.y0)))
    return np.concatenate(ts), np.concatenate(ys)


def stream_trajectory(path: str, scene, compiled, sampler):
    """Write the samples of an endless run to the CSV ``path`` as they come.

    The rows go to a temporary file beside ``path``, renamed onto it when the run ends
    (Ctrl+C, the step budget or a problem), so ``path`` never holds half a row. Returns
    the first and last samples as (t (2,), y (2, 2n), qdot (2, n), H (2,)).
    """
    from systems.constraints import multiplier_names
    from systems.files import atomic_path

    n = compiled.n
    header = ["t", *scene.coordinates, *scene.velocity_names, *scene.momentum_names, "H"]
    header += multiplier_names(scene)
    constraints = compiled.constraints()
    kept: list[tuple[float, np.ndarray, np.ndarray, float]] = []
    sampler.count = 0
    try:
        with (
            atomic_path(path) as temporary,
            open(temporary, "w", newline="", encoding="utf-8") as handle,
        ):
            writer = csv.writer(handle)
            writer.writerow(header)
            try:
                for t, y in sampler:
                    with np.errstate(all="ignore"):
                        H = float(compiled.hamiltonian(t, y[None])[0])
                        qdot = compiled.velocities(t, y[None])[0]
                    row = [t, *y[:n], *qdot, *y[n:], H]
                    if constraints is not None:
                        row += list(constraints.multipliers(t, y[None])[0])
                    writer.writerow([repr(float(v)) for v in row])
                    sampler.count += 1
                    kept = [*kept[:1], (t, y, qdot, H)]
                    check()
            except KeyboardInterrupt:
                sampler.interrupted = True
            except Exception:
                if not requested():
                    raise
                sampler.interrupted = True  # the signal's exception was lost (``stopping``)
    except OSError as exc:
        raise UserError(f"could not write {path}: {exc.strerror or exc}") from None
    t, y, qdot, H = (np.array(column) for column in zip(*kept, strict=True))
    return t, y, qdot, H


def sample_times(args: argparse.Namespace, t_end: float):
    """The simulation times whose states are written: ``--samples`` evenly spaced (default
    10 000) or one every ``--every`` (endlessly, for an endless run). Chosen by simulation
    time, never by wall time, so the same command writes the same file on any machine."""
    from systems.usage import sample_times as times

    with user_errors():
        return times(t_end, samples=args.samples, every=args.every, default=DEFAULT_SAMPLES)


def write_trajectory(path: str, scene, t, y, qdot, H, n: int, multipliers=None) -> None:
    """CSV columns t, each q, each q_dot, each p_q, H, and for a scene with constraints
    their multipliers lambda_1 .. lambda_k (``multipliers``, shape (rows, k)); or the same
    arrays in an .npz (the multipliers as ``lambda``).

    Written whole or not at all (``systems.files.atomic_path``).
    """
    from systems.constraints import multiplier_names
    from systems.files import atomic_path, write_rows

    header = ["t", *scene.coordinates, *scene.velocity_names, *scene.momentum_names, "H"]
    columns = [t, y[:, :n], qdot, y[:, n:], H]
    extra = {}
    if multipliers is not None:
        header += multiplier_names(scene)
        columns.append(multipliers)
        extra["lambda"] = multipliers
    with atomic_path(path) as temporary:
        if Path(path).suffix.lower() == ".npz":
            np.savez(
                temporary, t=t, q=y[:, :n], qdot=qdot, p=y[:, n:], H=H, columns=np.array(header),
                **extra,
            )  # fmt: skip
            return
        with open(temporary, "w", newline="", encoding="utf-8") as handle:
            csv.writer(handle).writerow(header)
            write_rows(handle, np.column_stack(columns))


def readable(scene, report: dict) -> str:
    lines = [
        f"{scene.title}: integrated to t = {report['t_end']:g} with {report['method']}",
        f"  why: {report['why']}",
        f"  {report['steps']} steps, {report['rhs_evaluations']} evaluations, "
        f"{report['wall_s']:.3g} s after {report['prepare_s']:.3g} s of preparation (numba "
        f"compiled or loaded its kernels in {report['compile_s']:.3g} s of these)",
    ]
    if report["arithmetic"] == "double-double":
        lines.append(
            "  arithmetic: the state and the series' orders 1 and 2 in double-double (a "
            "tolerance below machine epsilon)"
        )
    if report["max_rel_energy_error"] is not None:
        lines.append(f"  max relative energy error: {report['max_rel_energy_error']:.3g}")
    if report["max_constraint_violation"] is not None:
        lines.append(f"  max constraint violation: {report['max_constraint_violation']:.3g}")
    accuracy = report["accuracy"]
    if accuracy is not None and accuracy["final_state_error"] is not None:
        lines.append(
            f"  checked against {accuracy['checked_against']}: final state off by about "
            f"{accuracy['final_state_error']:.2g}"
        )
    final = ", ".join(f"{k} = {v:.10g}" for k, v in report["final"]["q"].items())
    lines.append(f"  final: {final}")
    lines.append(
        f"  status: {report['status']}" + (f" ({report['message']})" * bool(report["message"]))
    )
    return "\n".join(lines)
