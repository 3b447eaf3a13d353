"""Steps per second of the compiled loops, and the ensemble's use of both cores.

Targets (issue 3): pendulum leapfrog >= 2e7 steps/s for one trajectory; double pendulum
with Gauss-Legendre 4 >= 5e5 steps/s; an ensemble of 1000 pendulums uses both cores.
"""

from __future__ import annotations

import os

import numpy as np
from _common import best_time, compiled_scene, report


def single(compiled, method: str, steps: int, dt: float) -> float:
    from systems.simulation import stream

    def go():
        for _ in stream(compiled, method=method, dt=dt, t_end=steps * dt, block_seconds=1.0,
                        max_points=64):  # fmt: skip
            pass

    go()  # compile
    return steps / best_time(go)


def main() -> bool:
    import numba

    from systems.simulation import ensemble

    print("throughput")
    ok = True
    pendulum = compiled_scene("simple_pendulum", ("rhs", "hamiltonian", "separable"))
    rate = single(pendulum, "leapfrog", 20_000_000, 1e-3)
    ok &= report("pendulum leapfrog, steps/s", rate, ">= 2e7", rate >= 2e7)
    double = compiled_scene("double_pendulum")
    rate = single(double, "gauss_legendre4", 500_000, 1e-3)
    ok &= report("double pendulum gauss_legendre4, steps/s", rate, ">= 5e5", rate >= 5e5)

    Y0 = np.column_stack([np.linspace(0.1, 3.0, 1000), np.zeros(1000)])
    cores = os.cpu_count() or 1

    def run_ensemble():
        ensemble(pendulum, Y0, method="yoshida4", t_end=200.0, dt=1e-3, samples=10)

    run_ensemble()
    numba.set_num_threads(1)
    serial = best_time(run_ensemble, 2)
    numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
    parallel = best_time(run_ensemble, 2)
    speedup = serial / parallel
    steps = 1000 * 200_000 / parallel
    print(f"  ensemble of 1000 pendulums: {steps:.3g} steps/s on {numba.get_num_threads()} "
          f"threads ({cores} cores)")  # fmt: skip
    ok &= report(
        "ensemble speed-up, threads vs one", speedup, f">= {0.75 * min(cores, 2):.2g} (both cores)",
        speedup >= 0.75 * min(cores, 2),
    )  # fmt: skip
    return ok


if __name__ == "__main__":
    raise SystemExit(0 if main() else 1)
