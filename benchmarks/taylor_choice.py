"""Is the automatic choice's taylor a real speed-up? Integration time of each scene's
choice against the choice without taylor (``measured_choice(..., taylor=False)``), at
their default settings over the scene's run, as ``run`` takes them.

    python benchmarks/taylor_choice.py [SCENE ...]

Each time is the median of ``REPEATS`` runs after a warm one, the two methods
interleaved; a scene's run of a few ms is repeated ``LOOPS`` times within each timing.
Prints the load average before and after: on a shared machine the ratio is what counts.

Where H is not conserved (``STATE_SCENES``: damped, driven, rheonomic) it also prints
what the choice itself cost (its pilots, measured again without the caches: DOP853's
evaluations, taylor's steps, the milliseconds) and checks the accuracy each choice
claims with runs it did not make: the states of both methods' whole runs at the
choice's checkpoints against DOP853 at tolerance ``CHECK_TOL``, trusted up to the last
checkpoint where it agrees with taylor at machine epsilon on steps of a quarter of its
own (``AGREEMENT``); the error there per unit time times the run's length is what the
choice claims to keep within the target.
"""

from __future__ import annotations

import math
import os
import re
import statistics
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import taylor_cost  # noqa: E402  (this folder's calibration: its scenes)

USER_SYSTEMS = os.path.join(os.path.dirname(os.path.abspath(__file__)), "../../shared/user-systems")
STATE_SCENES = (
    "damped_pendulum",
    "driven_damped_pendulum",
    "kapitza_pendulum",
    "mathieu_oscillator",
    "variable_length_pendulum",
    os.path.normpath(os.path.join(USER_SYSTEMS, "shaken_pendulum.toml")),
)
"""The scenes without a conserved H whose classification's DOP853 taylor is priced
against (the catalogue's and the users' that taylor applies to)."""
SCENES = (
    *taylor_cost.SCENES,
    "bead_on_rotating_hoop",
    "stiff_spring_pendulum",
    "figure_eight",
    *STATE_SCENES,
)
"""The scenes the choice changed to taylor (``python main.py methods SCENE``)."""
REPEATS = 7
LOOPS = 10
CHECK_TOL = 1e-15
AGREEMENT = 1e-12
"""The two independent references must agree to this (relative to the state's size)."""


def _seconds(compiled, method: str, t_end: float) -> float:
    from systems.simulation import Run

    start = time.perf_counter()
    for _ in range(LOOPS):
        run = Run(compiled, method=method, t_end=t_end, max_points=2)  # its default setting
        while not run.finished:
            block = run.advance(10.0)
        if block.status != "ok":
            raise RuntimeError(f"{method}: {block.status} {block.message}")
    return (time.perf_counter() - start) / LOOPS


def _choice_cost(compiled, method: str, reason: str, t_end: float) -> str:
    """The choice's pilots, run again outside the caches: counts and milliseconds."""
    from systems.integrators import measured

    counted = {"dop853": 0, "taylor": 0, "runs": 0}
    states_at = measured._states_at

    def counting(compiled, method, *args, **kwargs):
        found = states_at(compiled, method, *args, **kwargs)
        if found is not None:
            counted["runs"] += 1
            counted[method] += found[1] if method == "dop853" else found[2]
        return found

    measured._states_at = counting
    try:
        start = time.perf_counter()
        measured._measure(compiled, method, reason, 0.0, compiled.initial_state(), t_end)
        seconds = time.perf_counter() - start
    finally:
        measured._states_at = states_at
    return (
        f"choice: {counted['runs']} pilots, {counted['dop853']} DOP853 evaluations, "
        f"{counted['taylor']} taylor steps, {seconds * 1e3:.0f} ms"
    )


def _states(compiled, method: str, times: np.ndarray, **setting) -> np.ndarray:
    """The states of a ``method`` run at its default setting (or ``setting``) at
    ``times``, shape (len(times), 2n)."""
    from systems.simulation import Run, Sampler

    run = Run(compiled, method=method, t_end=float(times[-1]), max_points=2, **setting)
    sampler = Sampler(run, times)
    t, y = zip(*sampler.chunks(), strict=True)
    t, y = np.concatenate(t[1:]), np.concatenate(y[1:])
    if sampler.last.status != "ok" or len(t) != len(times):
        raise RuntimeError(f"{method}: {sampler.last.status} {sampler.last.message}")
    return y


def _accuracy(compiled, methods: tuple[str, str], t_end: float, why: str) -> str:
    """Each method's state error per unit time, times ``t_end``, against the taylor
    reference (trusted where DOP853 at ``CHECK_TOL`` agrees with it), and what the
    choice claimed (the numbers of ``why``)."""
    from systems.integrators.measured import RATE_CHECKPOINTS, STATE_CHECKPOINTS

    eps = float(np.finfo(float).eps)
    times = t_end * 2.0 ** -np.arange(STATE_CHECKPOINTS - 1, -1, -1, dtype=float)
    independent = _states(compiled, "dop853", times, tol=CHECK_TOL)
    h = t_end / _steps(compiled, "taylor", t_end, tol=eps) / 4
    reference = _states(compiled, "taylor", times, tol=eps, max_step=h)
    scale = np.maximum(1.0, np.max(np.abs(reference), axis=1))
    gap = np.max(np.abs(independent - reference), axis=1) / scale
    trusted = int(np.argmin(np.append(gap <= AGREEMENT, False)))
    if trusted == 0:
        return f"references part by {gap[0]:.1e} at t = {times[0]:.3g}: unchecked"
    found = []
    for method in methods:
        error = np.max(np.abs(_states(compiled, method, times) - reference), axis=1) / scale
        last = slice(max(0, trusted - RATE_CHECKPOINTS), trusted)  # as the choice measures
        rate = float(np.max(error[last] / times[last]))
        found.append(f"{method} {rate * t_end:.1e} ({error[trusted - 1]:.1e} at the end)")
    claims = re.findall(r"(?:keep it to|for) (\S+?)(?:\s|$)", why)
    return (
        f"checked to t = {times[trusted - 1]:.3g} (references within {gap[:trusted].max():.1e}): "
        + ", ".join(found)
        + f"; claimed {' and '.join(claims) or why[-60:]}"
    )


def _steps(compiled, method: str, t_end: float, **setting) -> int:
    from systems.simulation import run_to_end

    _, last = run_to_end(compiled, method=method, t_end=t_end, max_points=2, **setting)
    return max(last.steps, 1)


def main(names: list[str]) -> None:
    from explorer.commands.run_cmd import prepare
    from systems.integrators import choose_method
    from systems.integrators.measured import measured_choice
    from systems.simulation import Run

    print(f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")
    print(f"{'scene':24s} {'without taylor':>16s} {'ms':>8s} {'choice':>8s} {'ms':>8s} {'x':>6s}")
    for name in names:
        scene, mechanics, chosen, why, compiled = prepare(name, None, extra_wants=())
        t_end = float(scene.view.get("t_end", 10.0))
        method, reason = choose_method(mechanics)
        y0 = compiled.initial_state()
        before, _ = measured_choice(compiled, method, reason, 0.0, y0, t_end, taylor=False)
        times = {before: [], chosen: []}
        for repeat in range(REPEATS + 1):
            for m in times:
                seconds = _seconds(compiled, m, t_end)
                if repeat:
                    times[m].append(seconds)
        a, b = (statistics.median(times[m]) * 1e3 for m in (before, chosen))
        setting = Run(compiled, method=chosen, t_end=t_end).setting_value
        label = os.path.basename(name)
        print(
            f"{label:24s} {before:>16s} {a:8.2f} {chosen:>8s} {b:8.2f} {a / b:6.2f}  "
            f"(its setting {setting:.3g})",
            flush=True,
        )
        c = mechanics.classification
        if not (c.conservative and c.hamiltonian_conserved) and not math.isinf(t_end):
            print(f"{'':24s} {_choice_cost(compiled, method, reason, t_end)}", flush=True)
            print(f"{'':24s} {_accuracy(compiled, (before, chosen), t_end, why)}", flush=True)
    print(f"load average {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main(sys.argv[1:] or list(SCENES))
