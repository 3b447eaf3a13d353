"""Compile latency: time to the first block of a newly opened scene, and the second time.

Each measurement is a fresh Python process with its own kernel cache directory. Numba's
own start-up (about half a second, once per process) is paid first by
``systems.integrators.warmup.warm_numba``, as the application does while its window
appears, and reported apart. Then the scene is derived and printed, and streamed as the
application streams it: from the kernels' plain-Python twin while numba compiles them in
a child process (``systems.native_build``), switching to machine code when they are ready.
The first open derives and prints, and numba compiles in the background; the second open,
in a new process, loads the derivation and the machine code from the caches. Reported:
the time to the first block, and when the compiled kernels took over (with the steps per
second of the stream before and after).
Targets (issue 3): the first block well under a second; under 0.2 s the second time.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile

from _common import ROOT, report

PROBE = r"""
import json, time
start = time.perf_counter()
from systems.compiled import compile_system
from systems.mechanics import derive
from systems.native_build import compile_in_background
from systems.scene import load_scene
from systems.simulation import required_wants, stream
from systems.integrators import choose_method
from systems.integrators.warmup import warm_numba
warm_start = time.perf_counter()
warm_numba()
imported = time.perf_counter()
mech = derive(load_scene({scene!r}))
method, _ = choose_method(mech)
compiled = compile_system(mech, required_wants(method, ("H",)), interpreted_start=True)
built = time.perf_counter()
done_event = compile_in_background(compiled, method, ("H",))
blocks = stream(compiled, method=method, t_end=1e12, diagnostics=("H",))
block = next(blocks)
first = time.perf_counter()
while not compiled.handed_over and not done_event.is_set():
    block = next(blocks)
native_at = time.perf_counter()
steps_before = block.steps
for _ in range(10):
    block = next(blocks)
after = time.perf_counter()
print(json.dumps({{"import": warm_start - start, "warm": imported - warm_start,
                   "derive_compile": built - imported, "first_block": first - built,
                   "total": first - imported, "method": method,
                   "native_after": native_at - imported,
                   "rate_before": steps_before / max(native_at - built, 1e-9),
                   "rate_after": (block.steps - steps_before) / (after - native_at),
                   "error": repr(compiled.kernels.error) if not compiled.handed_over else None}}))
"""


def measure(scene: str, cache: str) -> dict:
    env = dict(os.environ, PHASE_EXPLORER_CACHE=cache, NUMBA_CACHE_DIR=cache)
    out = subprocess.run(
        [sys.executable, "-c", PROBE.format(scene=scene)], cwd=ROOT, env=env,
        capture_output=True, text=True, check=True,
    )  # fmt: skip
    return json.loads(out.stdout.strip().splitlines()[-1])


def main() -> bool:
    print("compile latency (fresh process each; derive + compile + first block)")
    ok = True
    for scene in ("simple_pendulum", "double_pendulum", "kepler_cartesian"):
        with tempfile.TemporaryDirectory() as cache:
            first = measure(scene, cache)
            second = measure(scene, cache)
        print(
            f"  {scene} ({first['method']}): numba start-up {first['warm']:.3f} s; "
            f"first open {first['total']:.3f} s (derive+print {first['derive_compile']:.3f}, "
            f"first block {first['first_block']:.3f}), compiled from "
            f"{first['native_after']:.2f} s ({first['rate_before']:.3g} -> "
            f"{first['rate_after']:.3g} steps/s); second open {second['total']:.3f} s "
            f"(derive+print {second['derive_compile']:.3f}, first block "
            f"{second['first_block']:.3f}), compiled from {second['native_after']:.2f} s"
        )
        if first["error"] or second["error"]:
            print(f"    native build failed: {first['error'] or second['error']}")
            ok = False
        ok &= report(f"{scene} first open, s", first["total"], "< 1", first["total"] < 1.0)
        ok &= report(f"{scene} second open, s", second["total"], "< 0.2", second["total"] < 0.2)
    return ok


if __name__ == "__main__":
    raise SystemExit(0 if main() else 1)
