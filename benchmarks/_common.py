"""Shared helpers of the benchmark scripts: scenes, timing, printing ratios."""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))


WARM_DRIVERS = r"""
import json, time
start = time.perf_counter()
from systems.codegen import driver_module
from systems.integrators.warmup import warm_drivers
imported = time.perf_counter()
seconds = warm_drivers()
print(json.dumps({"seconds": seconds, "imports": imported - start,
                  "drivers": driver_module().__name__}))
"""


def cache_env(cache: str | Path | None = None, **extra: str) -> dict:
    """The environment of a benchmark's child process: ``PHASE_EXPLORER_CACHE=cache`` (if
    given) and ``extra``. ``NUMBA_CACHE_DIR`` is removed: numba's cache files then sit
    beside the generated modules in the cache directory, so a copy of that directory
    (``shutil.copytree``, which keeps the files' times) is a warm cache too, where
    ``NUMBA_CACHE_DIR`` would key them by each module's absolute path."""
    env = dict(os.environ, **extra)
    if cache is not None:
        env["PHASE_EXPLORER_CACHE"] = str(cache)
    env.pop("NUMBA_CACHE_DIR", None)
    return env


def warm_drivers(cache: str | Path | None = None) -> dict:
    """Compile the stepping loops into ``cache`` (default: the environment's cache) in a
    fresh process, as ``python main.py warm`` does once per installation: ~45 s on an
    empty cache, ~1 s once compiled. Returns ``{"seconds", "imports", "drivers"}``:
    ``warm_drivers``'s seconds, the imports' and the drivers' module name."""
    out = subprocess.run(
        [sys.executable, "-c", WARM_DRIVERS], cwd=ROOT, env=cache_env(cache),
        capture_output=True, text=True, check=True,
    )  # fmt: skip
    return json.loads(out.stdout.strip().splitlines()[-1])


def compiled_scene(name: str, wants=("rhs", "hamiltonian")):
    from systems.compiled import compile_system
    from systems.mechanics import derive
    from systems.scene import load_scene

    return compile_system(derive(load_scene(name)), wants)


def best_time(function, repeat: int = 3) -> float:
    """Minimum wall time of ``function()`` over ``repeat`` calls (seconds)."""
    best = math.inf
    for _ in range(repeat):
        start = time.perf_counter()
        function()
        best = min(best, time.perf_counter() - start)
    return best


def run_to_end(compiled, **kwargs):
    """(final block, wall seconds) of a stream run to ``t_end``."""
    from systems.simulation import stream

    start = time.perf_counter()
    last = None
    for block in stream(compiled, **kwargs):
        last = block
    return last, time.perf_counter() - start


def kepler_polar_state(e: float, a: float = 1.0) -> np.ndarray:
    """(r, theta, p_r, p_theta) at apocentre, k = m = 1."""
    r = a * (1 + e)
    return np.array([r, 0.0, 0.0, math.sqrt(a * (1 - e * e))])


def kepler_cartesian_state(e: float, a: float = 1.0) -> np.ndarray:
    """(x, y, p_x, p_y) at apocentre, k = m = 1."""
    r = a * (1 + e)
    return np.array([r, 0.0, 0.0, math.sqrt(a * (1 - e * e)) / r])


def report(label: str, value: float, target: str, ok: bool) -> bool:
    mark = "PASS" if ok else "MISS"
    print(f"  [{mark}] {label}: {value:.4g}  (target {target})")
    return ok
