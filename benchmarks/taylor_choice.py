"""Is the automatic choice's taylor a real speed-up? Integration time of each scene's
choice against the choice without taylor (``measured_choice(..., taylor=False)``), at
their default settings over the scene's run, as ``run`` takes them.

    python benchmarks/taylor_choice.py [SCENE ...]

Each time is the median of ``REPEATS`` runs after a warm one, the two methods
interleaved; a scene's run of a few ms is repeated ``LOOPS`` times within each timing.
Prints the load average before and after: on a shared machine the ratio is what counts.
"""

from __future__ import annotations

import os
import statistics
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import taylor_cost  # noqa: E402  (this folder's calibration: its scenes)

SCENES = (
    *taylor_cost.SCENES,
    "bead_on_rotating_hoop",
    "stiff_spring_pendulum",
    "figure_eight",
)
"""The scenes the choice changed to taylor (``python main.py methods SCENE``)."""
REPEATS = 7
LOOPS = 10


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


def main(names: list[str]) -> None:
    from explorer.commands.run_cmd import prepare
    from systems.integrators import choose_method
    from systems.integrators.measured import measured_choice
    from systems.simulation import Run

    print(f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")
    print(f"{'scene':22s} {'without taylor':>16s} {'ms':>8s} {'choice':>8s} {'ms':>8s} {'x':>6s}")
    for name in names:
        scene, mechanics, chosen, _, compiled = prepare(name, None, extra_wants=())
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
        print(
            f"{name:22s} {before:>16s} {a:8.2f} {chosen:>8s} {b:8.2f} {a / b:6.2f}  "
            f"(its setting {setting:.3g})",
            flush=True,
        )
    print(f"load average {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main(sys.argv[1:] or list(SCENES))
