"""Shared helpers of the benchmark scripts: scenes, timing, printing ratios."""

from __future__ import annotations

import math
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))


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
