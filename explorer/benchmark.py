"""GUI responsiveness while integrating at full speed: ``python -m explorer.benchmark``.

Opens the window (offscreen unless a platform is set) on the double pendulum at full
speed, waits until the main trajectory holds ``--points`` points, then for ``--seconds``
measures the GUI thread's event latency (how late a 5 ms probe timer fires) and the rate
at which panels are redrawn. Prints both figures; it is a benchmark, not a timed test.
"""

from __future__ import annotations

import argparse
import math
import os
import time


def measure(scene: str = "double_pendulum", points: int = 1_000_000, seconds: float = 5.0) -> dict:
    os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")
    import numpy as np
    from PySide6.QtCore import QEventLoop, QTimer

    from explorer.app import application, create_window

    app = application()
    window = create_window(scene)
    window.show()

    def spin_until(condition, limit: float) -> None:
        end = time.perf_counter() + limit
        while not condition() and time.perf_counter() < end:
            app.processEvents(QEventLoop.ProcessEventsFlag.AllEvents, 20)

    spin_until(lambda: window.worker is not None and window.store.main is not None, 120)
    window.controls.speed_combo.setCurrentIndex(window.controls.speed_combo.count() - 1)
    assert math.isinf(window.settings.speed)
    start = time.perf_counter()
    # the store is bounded (it thins old samples): wait for what it can hold at most
    wanted = min(points, window.store.main.capacity)
    spin_until(lambda: len(window.store.main.t) >= wanted, 600)
    fill_seconds = time.perf_counter() - start
    reached = len(window.store.main.t)

    lateness: list[float] = []
    last = [time.perf_counter()]
    probe = QTimer()
    probe.setInterval(5)

    def on_probe() -> None:
        now = time.perf_counter()
        lateness.append(max(now - last[0] - 0.005, 0.0))
        last[0] = now

    probe.timeout.connect(on_probe)
    redraws_before = window.redraws
    painted_before = window.panel_refreshes
    probe.start()
    start = time.perf_counter()
    spin_until(lambda: False, seconds)
    elapsed = time.perf_counter() - start
    probe.stop()
    result = {
        "scene": scene,
        "points": len(window.store.main.t),
        "points_at_start": reached,
        "fill_seconds": fill_seconds,
        "latency_p95_ms": 1e3 * float(np.percentile(lateness, 95)),
        "latency_median_ms": 1e3 * float(np.median(lateness)),
        "timer_ticks_per_s": (window.redraws - redraws_before) / elapsed,
        "redraws_per_s": (window.panel_refreshes - painted_before) / elapsed,
        "method": window.store.main.method,
    }
    window.close()
    return result


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scene", default="double_pendulum")
    parser.add_argument("--points", type=int, default=1_000_000)
    parser.add_argument("--seconds", type=float, default=5.0)
    args = parser.parse_args(argv)
    r = measure(args.scene, args.points, args.seconds)
    print(
        f"{r['scene']} at full speed ({r['method']}), {r['points']:,} points in view "
        f"(filled in {r['fill_seconds']:.1f} s)"
    )
    print(
        f"GUI event latency: p95 {r['latency_p95_ms']:.1f} ms, median "
        f"{r['latency_median_ms']:.1f} ms (target p95 < 30 ms)"
    )
    print(f"phase-panel redraws: {r['redraws_per_s']:.1f} per second (target >= 30)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
