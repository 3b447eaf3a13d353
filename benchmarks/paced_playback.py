"""Paced playback keeps to wall time (moved here from ``tests/explorer/test_worker.py``:
wall-clock bounds are benchmarks, never tests).

The worker at 1x with the stand-in run of the worker's tests (uniform motion, a few rows
a block: ``tests.explorer.test_worker.fake_runs``), in its own thread, the GUI thread's
event loop taking every frame at once (each taken frame wakes the worker, which must not
shorten the frame's time for it). Over ``SECONDS`` of wall time, measured:

- simulated time / wall time: 1 at 1x; a busy machine can only hold it back (target
  <= 1.35);
- frames made / the frames the frame rate allows (target <= 1.2).

Timings on a shared machine vary: read the numbers, not only PASS.
"""

from __future__ import annotations

import os
import time

os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")

import numpy as np  # noqa: E402
from _common import report  # noqa: E402

SECONDS = 2.0


def main() -> bool:
    from PySide6.QtWidgets import QApplication

    from explorer.worker import RunSettings, SimulationWorker, WorkerThread
    from tests.explorer.test_worker import fake_runs

    app = QApplication.instance() or QApplication([])

    def spin(seconds: float, condition=lambda: False) -> None:
        end = time.perf_counter() + seconds
        while time.perf_counter() < end and not condition():
            app.processEvents()
            time.sleep(0.002)

    print("paced playback at 1x")
    runs = fake_runs(points_per_block=3)
    worker = SimulationWorker(None, RunSettings(speed=1.0, t_end=1e9), runs=runs)
    worker.add_trajectory(0, np.zeros(2))
    runner = WorkerThread(worker)
    runner.start()
    try:
        spin(5.0, lambda: worker.frames >= 3)
        start, frames, begun = runs.runs[-1].t, worker.frames, time.perf_counter()
        spin(SECONDS)
        simulated, wall = runs.runs[-1].t - start, time.perf_counter() - begun
        made = worker.frames - frames
    finally:
        runner.stop()
    allowed = wall / RunSettings().frame_seconds
    print(f"  {simulated:.3f} s simulated in {wall:.3f} s; {made} frames ({allowed:.0f} allowed)")
    ok = report(
        "simulated / wall time at 1x", simulated / wall, "<= 1.35", simulated <= 1.35 * wall
    )
    return report("frames made / allowed", made / allowed, "<= 1.2", made <= 1.2 * allowed) and ok


if __name__ == "__main__":
    raise SystemExit(0 if main() else 1)
