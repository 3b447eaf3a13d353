"""``lyapunov SCENE``: the Lyapunov spectrum and the fast indicators of the scene's orbit.

The variational equations are written from the symbolic Jacobian of Hamilton's
equations (effects included) and integrated with the orbit by the compiled drivers
(``systems.chaos``): DOP853 at tolerance 1e-12 by default; a fixed-step method carries
the tangent map of its own scheme (a Yoshida composition its drifts and kicks,
Gauss-Legendre its collocation). Exit status 1 when the integration stopped before the
end time; Ctrl+C (SIGTERM, SIGHUP) prints the estimates so far (status ``interrupted``)
and exits with 128 + the signal.
"""

from __future__ import annotations

import argparse
import json
import sys
import time

from explorer.commands.errors import UserError, user_errors

DEFAULT_T_END = 1e4


def add_parser(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser(
        "lyapunov",
        help="the Lyapunov spectrum, MEGNO and SALI/GALI of the scene's orbit",
        description="The Lyapunov spectrum by Benettin's method (QR re-orthonormalisation), "
        "the maximal exponent, MEGNO (mean <Y>: 2 quasi-periodic, 0 periodic in an "
        "isochronous system, growing like max*t/2 when chaotic), SALI and GALI, from the "
        "variational equations compiled with the system. Methods: dop853 (default, "
        "tolerance 1e-12), euler, rk4, the Gauss-Legendre methods and, for a separable "
        "H = T(p) + V(q, t), leapfrog and the Yoshida compositions, each integrating the "
        "tangent map of its own scheme. Not: the time-transformed methods (logh_*, *_tt), "
        "scipy's stiff solvers and scenes with [constraints].",
    )
    parser.add_argument("scene", help="a catalogue name (see `list`) or a path to a .toml file")
    parser.add_argument(
        "--t-end", type=float, default=DEFAULT_T_END,
        help=f"how long to integrate (default {DEFAULT_T_END:g}); exponents converge like 1/t",
    )  # fmt: skip
    parser.add_argument("--method", default=None, help="a method (default dop853)")
    step = parser.add_mutually_exclusive_group()
    step.add_argument("--dt", type=float, default=None, help="step of a fixed-step method")
    step.add_argument("--tol", type=float, default=None, help="tolerance of dop853")
    parser.add_argument(
        "--start", default="",
        help="the start, e.g. x=0,y=0.1,p_x=0.45,p_y=0 (coordinates, <q>_dot velocities or "
        "p_<q> momenta; default: the scene's initial state)",
    )  # fmt: skip
    parser.add_argument(
        "--exponents", type=int, default=None,
        help="how many exponents, largest first (default all 2n)",
    )  # fmt: skip
    parser.add_argument("--json", action="store_true", help="print one JSON object")


def run(args: argparse.Namespace) -> int:
    from explorer.commands import stopping
    from explorer.commands.periodic_cmd import _start as parse_start
    from systems.chaos.lyapunov import DEFAULT_METHOD, LyapunovRun, Spectrum
    from systems.chaos.variational import NotApplicable, load_tangent
    from systems.compiled import compile_system
    from systems.integrators import STEPPERS
    from systems.mechanics import derive
    from systems.scene import load_scene
    from systems.usage import check_lyapunov, check_lyapunov_options, start_state

    values = parse_start(args.start)
    t_end = args.t_end
    method = args.method or DEFAULT_METHOD
    start = time.perf_counter()
    with user_errors():
        check_lyapunov_options(method, t_end)
        scene = load_scene(args.scene)
        mechanics = derive(scene)
        check_lyapunov(mechanics, method, args.scene)
    wants = STEPPERS[method].wants | {"hamiltonian"}
    with user_errors():
        compiled = compile_system(mechanics, wants)
        y0 = start_state(compiled, values)
    try:
        tangent = load_tangent(compiled)
        compile_s = compiled.build_seconds + tangent.build_seconds
        chaos = LyapunovRun(
            tangent, method=method, y0=y0, t_end=t_end, dt=args.dt, tol=args.tol,
            exponents=args.exponents,
        )  # fmt: skip
    except NotApplicable as exc:
        raise UserError(str(exc)) from exc
    interrupted = False
    try:
        said = False
        while not chaos.done:
            chaos.advance(seconds=0.2)
            stopping.check()
            if not said and not chaos.done:  # estimates exist: a stop now reports them
                said = True
                print(
                    f"integrating to t = {t_end:g}; Ctrl+C stops and prints the estimates so far",
                    file=sys.stderr,
                    flush=True,
                )
    except KeyboardInterrupt:
        interrupted = True
    except Exception:
        if not stopping.requested():
            raise
        interrupted = True  # the signal's exception was lost on the way (``stopping``)
    if chaos.t == chaos.t0:  # stopped before an interval: nothing to report
        raise KeyboardInterrupt
    result = Spectrum(
        estimate=chaos.estimate, history=chaos.history.arrays(), method=method,
        setting=chaos.setting, setting_value=chaos.setting_value, t0=chaos.t0, t_end=t_end,
        compile_s=compile_s, wall_s=time.perf_counter() - start,
        energy_error=chaos.energy_error(),
    )  # fmt: skip
    report = result.as_json()
    report = {"scene": scene.name or args.scene, **report}
    if interrupted:  # the estimates up to where the signal came
        report["status"] = "interrupted"
        report["message"] = f"stopped by {stopping.cause()} at t = {chaos.t:.6g}"
    if args.json:
        print(json.dumps(report, indent=2))
    else:
        print("\n".join(_lines(scene, report)))
    if interrupted:
        return stopping.status()
    return 0 if report["status"] == "ok" else 1


def _lines(scene, report: dict) -> list[str]:
    setting = "tol" if "tol" in report else "dt"
    exponents = ", ".join(f"{x:.6g}" for x in report["exponents"])
    megno = report["megno"]
    lines = [
        f"{scene.title}: Lyapunov spectrum and fast indicators",
        f"method: {report['method']} ({setting} {report[setting]:g}), {report['steps']} "
        f"steps, {report['intervals']} QR re-orthonormalisations, {report['wall_s']:.2f} s",
        f"exponents: {exponents}  (largest first; sum {report['sum']:.3g})",
        f"max: {report['max']:.6g}",
        f"megno: {megno:.6g}, {report['verdict']} (mean <Y>: 2 quasi-periodic, 0 periodic "
        f"and isochronous, max*t/2 = {report['max'] * report['t_end'] / 2:.3g} if chaotic)",
        f"sali: {report['sali']:.3g}  gali_{report['gali_order']}: {report['gali']:.3g}",
        f"t_end: {report['t_end']:g}",
    ]
    if report["energy_error"] is not None:
        lines.append(f"relative energy error of the orbit: {report['energy_error']:.2g}")
    if report["status"] != "ok":
        lines.append(f"stopped ({report['status']}): {report['message']}")
    return lines
