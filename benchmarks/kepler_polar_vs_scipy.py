"""Kepler e = 0.9, 100 orbits, polar coordinates (the generic non-separable path).

Time to reach a final position error <= 1e-6 with our compiled steppers, against scipy's
``solve_ivp`` DOP853 (its right-hand side is the same compiled function, so the ratio
measures the stepping loop). Both sweep their step or tolerance and the cheapest run
meeting the error counts. Target (issue 3): at least 30x shorter; issue 23: at least
150x warm. The scene is the catalogue's ``planetary_motion`` with the initial state of an
e = 0.9 orbit (a = 1).

Cold (issue 23: at least 10x): a fresh process on a cache that holds only the drivers
(``python main.py warm``, once per installation: ``warmup.copy_drivers``) derives the
scene, compiles its functions, loads the driver and runs the cheapest DOP853 setting of
the sweep; the imports and numba's start-up (paid while the window appears, before any
scene) are reported apart, not counted, as scipy's imports are not.
"""

from __future__ import annotations

import json
import math
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from _common import (
    ROOT,
    cache_env,
    compiled_scene,
    kepler_polar_state,
    report,
    run_to_end,
    warm_drivers,
)

E = 0.9
ORBITS = 100
TARGET = 1e-6


def position(y):
    return np.array([y[0] * math.cos(y[1]), y[0] * math.sin(y[1])])


def cheapest(runs):
    """The fastest (time, setting, error) with error <= TARGET, or None."""
    good = [r for r in runs if r[2] <= TARGET]
    return min(good) if good else None


COLD = r"""
import json, math, sys, time
start = time.perf_counter()
import numpy as np
from systems.compiled import compile_system
from systems.integrators.warmup import warm_numba
from systems.mechanics import derive
from systems.scene import load_scene
from systems.simulation import Run
imported = time.perf_counter()
warm_numba()
warmed = time.perf_counter()
y0, t_end, tol = np.array(json.loads(sys.argv[1])), float(sys.argv[2]), float(sys.argv[3])
mechanics = derive(load_scene("planetary_motion"))
derived = time.perf_counter()
compiled = compile_system(mechanics, ("rhs", "hamiltonian"))
built = time.perf_counter()
run = Run(compiled, method="dop853", y0=y0, t_end=t_end, tol=tol,
          max_points=64, energy_tolerance=math.inf)
while not run.finished:
    last = run.advance(math.inf)
done = time.perf_counter()
print(json.dumps({"imports": imported - start, "numba": warmed - imported,
                  "cold": done - warmed, "derive": derived - warmed, "compile": built - derived,
                  "run": done - built, "y": [float(v) for v in last.y[-1]]}))
"""


def cold_run(y0: np.ndarray, t_end: float, tol: float) -> tuple[float, np.ndarray, float, str]:
    """(seconds from a scene's text to the run's end, the final state, the imports and
    numba's start-up, the seconds by part) in a fresh process on a new cache holding
    only the drivers."""
    from systems.integrators.warmup import copy_drivers

    with tempfile.TemporaryDirectory() as cache:
        from systems.cache_integrity import cache_root

        if not copy_drivers(cache_root(), Path(cache)):
            raise RuntimeError("no compiled drivers to copy: run python main.py warm")
        out = subprocess.run(
            [sys.executable, "-c", COLD, json.dumps(y0.tolist()), repr(t_end), repr(tol)], cwd=ROOT,
            env=cache_env(cache), capture_output=True, text=True, check=True,
        )  # fmt: skip
    result = json.loads(out.stdout.strip().splitlines()[-1])
    parts = ", ".join(f"{key} {result[key]:.3f}" for key in ("derive", "compile", "run"))
    return result["cold"], np.array(result["y"]), result["imports"] + result["numba"], parts


def main() -> bool:
    from scipy.integrate import solve_ivp

    compiled = compiled_scene("planetary_motion")
    y0 = kepler_polar_state(E)
    t_end = 2 * math.pi * ORBITS
    exact = position(y0)
    print(f"Kepler e = {E}, {ORBITS} orbits, polar coordinates: time to position error <= 1e-6")

    ours = {}
    for method, settings in (
        ("gauss_legendre6", [2e-2 * 2 ** (-j / 2) for j in range(12)]),
        ("gauss_legendre4", [4e-3 * 2 ** (-j / 2) for j in range(10)]),
        ("dop853", [10.0**-k for k in range(9, 15)]),
    ):
        key = "tol" if method == "dop853" else "dt"
        run_to_end(compiled, method=method, y0=y0, t_end=1.0, **{key: settings[0]})  # compile
        runs = []
        for value in settings:
            last, wall = run_to_end(
                compiled, method=method, y0=y0, t_end=t_end, max_points=64,
                energy_tolerance=math.inf, **{key: value},
            )  # fmt: skip
            error = float(np.abs(position(last.y[-1]) - exact).max())
            runs.append((wall, value, error))
            if error <= TARGET:
                break
        ours[method] = cheapest(runs)
        if ours[method]:
            wall, value, error = ours[method]
            print(f"  ours {method:16s} {key}={value:.3g}: {wall:.4f} s (error {error:.2g})")
        else:
            print(f"  ours {method:16s} did not reach the error in the sweep")

    rhs, P, K = np.empty(4), compiled.parameters, compiled.kernels

    def fun(t, y):
        out = np.empty(4)
        K.rhs(t, y, P, out)
        return out

    del rhs
    runs = []
    for k in range(8, 15):
        rtol = 10.0**-k
        start = time.perf_counter()
        sol = solve_ivp(fun, (0.0, t_end), y0, method="DOP853", rtol=rtol, atol=rtol * 1e-2)
        wall = time.perf_counter() - start
        error = float(np.abs(position(sol.y[:, -1]) - exact).max())
        runs.append((wall, rtol, error))
        if error <= TARGET:
            break
    reference = cheapest(runs)
    if reference is None:
        print("  scipy DOP853 did not reach the error")
        return False
    wall, rtol, error = reference
    for _ in range(2):  # the chosen setting again: the best of three
        start = time.perf_counter()
        solve_ivp(fun, (0.0, t_end), y0, method="DOP853", rtol=rtol, atol=rtol * 1e-2)
        wall = min(wall, time.perf_counter() - start)
    print(f"  scipy solve_ivp DOP853 rtol={rtol:.0e}: {wall:.4f} s (error {error:.2g})")
    for method, best in ours.items():
        if best:
            print(f"  ratio scipy / {method}: {wall / best[0]:.3g}")
    best = min(b[0] for b in ours.values() if b)
    ok = report("best speed-up over scipy, warm", wall / best, ">= 150", wall / best >= 150)
    if not ours["dop853"]:
        return False
    warm_drivers()  # the environment's cache: the installation's drivers
    runs = [cold_run(y0, t_end, ours["dop853"][1]) for _ in range(3)]  # each on a new cache
    cold, y_end, start_up, parts = min(runs, key=lambda r: r[0])
    error = float(np.abs(position(y_end) - exact).max())
    print(
        f"  ours cold (derive + compile + driver load + run, dop853 tol="
        f"{ours['dop853'][1]:.0e}): {cold:.3f} s ({parts}), error {error:.2g}; imports and numba's"
        f" start-up apart {start_up:.2f} s"
    )
    good = error <= TARGET and wall / cold >= 10
    return report("speed-up over scipy, cold", wall / cold, ">= 10", good) and ok


if __name__ == "__main__":
    raise SystemExit(0 if main() else 1)
