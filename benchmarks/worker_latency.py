"""What sending symbolic work to a worker process costs (``systems.processes``).

For each scene, with its derivation cached: ``derive_source`` in this process, and the
same through a worker (fork from the fork server, arguments and result pickled), plus an
empty job (``os.getpid``). Target: a cached derivation through a worker within 0.15 s
(the window's build of a scene opened again), an empty job within 0.05 s. Run alone:
``python benchmarks/worker_latency.py``.
"""

from __future__ import annotations

import os

from _common import best_time, report

SCENES = ("simple_pendulum", "double_pendulum", "henon_heiles", "rolling_disk", "fpu_chain")
DERIVE_TARGET = 0.15
EMPTY_TARGET = 0.05


def main() -> bool:
    from systems import processes
    from systems.scene import SCENES_DIR
    from systems.sources import derive_source

    processes.start()
    processes.run(os.getpid)  # the fork server has imported sympy
    print("worker latency (best of 5; derivations cached)")
    empty = best_time(lambda: processes.run(os.getpid), repeat=5)
    ok = report("empty job", empty, f"<= {EMPTY_TARGET} s", empty <= EMPTY_TARGET)
    for name in SCENES:
        text = (SCENES_DIR / f"{name}.toml").read_text(encoding="utf-8")
        derive_source(text)  # cached from here on
        here = best_time(lambda text=text: derive_source(text), repeat=5)
        there = best_time(lambda text=text: processes.run(derive_source, text), repeat=5)
        print(f"  {name:18s} in this process {here:.4f} s, through a worker {there:.4f} s")
        ok &= report(
            f"{name} through a worker", there, f"<= {DERIVE_TARGET} s", there <= DERIVE_TARGET
        )
    return ok


if __name__ == "__main__":
    raise SystemExit(0 if main() else 1)
