"""Calibrate the automatic choice's price of a Taylor step in right-hand-side evaluations.

``systems.integrators.measured`` counts work, never time: a DOP853 run costs its
right-hand-side evaluations, a Taylor run its steps times ``measured.taylor_equivalents``
(a model from the decomposition's node counts and the order). This script times both on
catalogue scenes (integration only, each the best of ``REPEATS`` runs after a warm one)
and prints, per scene, the measured equivalents (seconds per Taylor step over seconds per
DOP853 evaluation) next to the model's, and the ratio of the two.

    python benchmarks/taylor_cost.py [SCENE ...]

The numbers in docs/internals.md ("The automatic choice and taylor") come from this.
"""

from __future__ import annotations

import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

SCENES = (
    "harmonic_oscillator",
    "simple_pendulum",
    "henon_heiles",
    "kepler_cartesian",
    "planetary_motion",
    "coupled_oscillators",
    "spherical_pendulum",
    "double_pendulum",
    "pendulum_ring",
    "fpu_chain",
)
REPEATS = 5
EVALUATIONS = 300_000
"""DOP853 evaluations of each timed run, about (the scene's run lengthened to them)."""


def _timed(
    compiled, method: str, t_end: float, repeats: int = REPEATS, **setting
) -> tuple[float, int, int]:
    """(best seconds, steps, evaluations) of a run of ``method`` to ``t_end``."""
    from systems.simulation import Run

    best, steps, evaluations = float("inf"), 0, 0
    for repeat in range(repeats + 1):
        run = Run(
            compiled, method=method, t_end=t_end, max_points=2, energy_tolerance=None,
            **setting,
        )  # fmt: skip
        start = time.perf_counter()
        while not run.finished:
            block = run.advance(10.0)
        seconds = time.perf_counter() - start
        if repeat or not repeats:
            best = min(best, seconds)
        steps, evaluations = block.steps, block.rhs_evaluations
    return best, steps, evaluations


def main(names: list[str]) -> None:
    from systems.compiled import compile_system
    from systems.integrators import measured
    from systems.mechanics import derive
    from systems.scene import load_scene
    from systems.simulation import required_wants
    from systems.taylor.decompose import decompose_mechanics

    print(f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")
    print(
        f"{'scene':22s} {'m':>3s} {'nodes':>5s} {'dop853 ns/ev':>12s} {'taylor ns/st':>12s} "
        f"{'measured':>8s} {'model':>7s} {'model/meas':>10s}"
    )
    for name in names:
        mechanics = derive(load_scene(name))
        wants = required_wants("taylor") | required_wants("dop853") | {"hamiltonian"}
        compiled = compile_system(mechanics, wants)
        t_end = float(mechanics.scene.view.get("t_end", 10.0))
        # long enough that the run's own overhead (a block, the energy at its ends) is
        # small against the steps: about EVALUATIONS DOP853 evaluations
        _, _, evals = _timed(compiled, "dop853", t_end, repeats=0, tol=1e-12)
        t_end *= max(1.0, EVALUATIONS / evals)
        d_seconds, _, d_evals = _timed(compiled, "dop853", t_end, tol=1e-12)
        t_seconds, t_steps, _ = _timed(compiled, "taylor", t_end, tol=float(np.finfo(float).eps))
        per_eval = d_seconds / d_evals
        per_step = t_seconds / t_steps
        decomposition = decompose_mechanics(mechanics)
        model = measured.taylor_equivalents(decomposition, 20)
        nodes = sum(decomposition.counts().values())
        print("   features", measured._taylor_features(decomposition))
        print(
            f"{name:22s} {decomposition.m:3d} {nodes:5d} {per_eval * 1e9:12.1f} "
            f"{per_step * 1e9:12.1f} {per_step / per_eval:8.2f} {model:7.2f} "
            f"{model / (per_step / per_eval):10.2f}",
            flush=True,
        )
    print(f"load average {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main(sys.argv[1:] or list(SCENES))
