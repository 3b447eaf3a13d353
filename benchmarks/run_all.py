"""Run every benchmark script; print their ratios; exit 1 if any target was missed.

Timings are measured in one run on this machine (not timed tests): a loaded machine
misses throughput targets that an idle one meets, so read the numbers, not just PASS.
"""

from __future__ import annotations

import importlib
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

SCRIPTS = (
    "catalogue_defaults",
    "throughput",
    "kepler_polar_vs_scipy",
    "kepler_cartesian_vs_rebound",
    "compile_latency",
    "gui_latency",
    "max_speed",
    "paced_playback",
    "run_output",
    "large_systems",
    "scene_switches",
    "worker_latency",
    "window_close",
    "chaos_map",
)


def main() -> int:
    results = {}
    for name in SCRIPTS:
        module = importlib.import_module(name)
        results[name] = bool(module.main())
        print()
    for name, ok in results.items():
        print(f"{'PASS' if ok else 'MISS'}  {name}")
    return 0 if all(results.values()) else 1


if __name__ == "__main__":
    raise SystemExit(main())
