"""GUI responsiveness: the double pendulum at full speed with 100 000 points in view.

Runs ``explorer.benchmark`` in a fresh process (offscreen Qt unless a display is set) and
prints the GUI thread's event latency (95th percentile) and the phase panel's redraw rate.
Targets (issue 4): p95 latency under 30 ms, at least 30 redraws per second.

``POINTS`` is most of what the store keeps of a trajectory (``DEFAULT_CAPACITY``, 131 072
rows): the store thins a trajectory before it would pass its capacity, so a run never
holds the capacity itself (asking for a million points, as this benchmark once did, waited
for ever).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys

from _common import ROOT

POINTS = 100_000

CODE = f"""
import json
from explorer.benchmark import measure
print(json.dumps(measure("double_pendulum", {POINTS}, 5.0)))
"""


def main() -> bool:
    env = dict(os.environ)
    if not env.get("DISPLAY"):
        env.setdefault("QT_QPA_PLATFORM", "offscreen")
    out = subprocess.run(
        [sys.executable, "-c", CODE], cwd=ROOT, env=env, capture_output=True, text=True,
        check=True, timeout=600,
    )  # fmt: skip
    r = json.loads(out.stdout.strip().splitlines()[-1])
    print(f"{r['scene']} at full speed ({r['method']}), {r['points']:,} points in view")
    print(f"GUI event latency p95: {r['latency_p95_ms']:.1f} ms (target < 30 ms)")
    print(f"phase-panel redraws: {r['redraws_per_s']:.1f} per second (target >= 30)")
    return r["latency_p95_ms"] < 30.0 and r["redraws_per_s"] >= 30.0


if __name__ == "__main__":
    raise SystemExit(0 if main() else 1)
