"""Max speed is smooth and honest (issue 10, item 4): the window at full speed.

Runs in a fresh process (offscreen Qt unless a display is set): the window on the simple
pendulum with two launched orbits at "max" speed. Measured (timings on a shared machine
vary: read the numbers, not only PASS):

- how long each control takes to act in the worker, from the click to the frame (or
  state) that shows it, timed when the worker had that frame ready (``Frame.ready_at``,
  before it waits for the GUI thread to take earlier frames: that delay is the redraws',
  measured apart as the event latency): clear (the orbits leave the worker, watched from
  a separate thread), speed max -> 1x (the first paced frame), 1x -> max (the first
  full-speed frame), method (the first frame of the new method), pause (the last frame
  ready), reset (the old worker's thread has ended; then the new worker's first frame,
  which also waits for the window to rebuild its panels). Each five times, the worst
  reported (target: 100 ms);
- the GUI thread's event latency at full speed, against the same window paused (the
  reference): the redraws' cost, which is the panels' (reported, no target here), and the
  time each method's kernels take to load the first time one is chosen (numba's cache);
- the worker's own cost: its steps per second at full speed (three orbits, frames into a
  store) against a bare ``Run.advance`` loop of the same method, both in the same process
  without the window (target: at least 0.6 of it);
- the steps per second a ``RateMeter`` shows against the steps the frames brought over
  the same interval (must agree within 5 %: the old window showed 3.7e10);
- the rows the store holds and the process's resident memory after 5 s and after 25 s
  at full speed (target: the rows stay under the capacity, memory grows < 40 MB).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys

from _common import ROOT, report

CODE = r"""
import json, math, threading, time
import numpy as np
from PySide6.QtCore import QEventLoop, QTimer
from explorer.app import application, create_window
from explorer.worker import RateMeter

app = application()
window = create_window("simple_pendulum")
window.show()


def spin(condition=lambda: False, limit=1.0):
    # a real event loop that sleeps when idle (a loop of processEvents would hold the GIL
    # and starve the worker thread); a 2 ms timer looks at the condition
    loop = QEventLoop()
    end = time.perf_counter() + limit

    def check():
        if condition() or time.perf_counter() >= end:
            loop.quit()

    timer = QTimer()
    timer.setInterval(2)
    timer.timeout.connect(check)
    timer.start()
    loop.exec()
    timer.stop()
    return condition()


def rss_mb():
    with open("/proc/self/status") as status:
        for line in status:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024
    return float("nan")


def event_latency(seconds):
    late, last = [], [time.perf_counter()]

    def tick():
        now = time.perf_counter()
        late.append(max(now - last[0] - 0.005, 0.0))
        last[0] = now

    probe = QTimer()
    probe.setInterval(5)
    probe.timeout.connect(tick)
    probe.start()
    spin(limit=seconds)
    probe.stop()
    return float(np.percentile(late, 95))


spin(lambda: window.worker is not None and window.store.main is not None, 120)
spin(lambda: window.compiled.handed_over, 300)
for theta in (0.6, 2.5):
    window.phase_view.launch_at(theta, 0.0)
max_index = window.controls.speed_combo.count() - 1
one_index = [window.controls.speed_combo.itemText(i) for i in range(max_index)].index("1×")
made = []  # frames of the current worker, as the worker made them (any thread)


def watch():
    window.worker.blocks_ready.connect(made.append)


watch()
spin(limit=1.0)
window.controls.play_button.click()
spin(limit=0.5)
paused_latency = event_latency(2.0)
window.controls.play_button.click()
window.controls.speed_combo.setCurrentIndex(max_index)
spin(limit=2.0)
full_latency = event_latency(3.0)


def first_made(start, test, limit=5.0):
    # when the worker had the frame ready: the GUI thread's delay in taking it is the
    # redraws' (measured apart as the event latency)
    def found():
        return [f.ready_at for f in list(made) if f.ready_at >= start and test(f)]
    spin(lambda: bool(found()), limit)
    times = found()
    return (min(times) - start) if times else math.inf


def spans(frame):
    out = []
    for _, block in frame.blocks:
        real = np.isfinite(block.y[:, 0])
        if real.sum() > 1:
            out.append(float(np.ptp(block.t[real])))
    return out


def watch_thread(condition, limit=5.0):
    # polls from a thread of its own, so the GUI thread's delays do not count
    seen = []

    def poll():
        end = time.perf_counter() + limit
        while time.perf_counter() < end:
            if condition():
                seen.append(time.perf_counter())
                return
            time.sleep(0.0005)

    thread = threading.Thread(target=poll)
    thread.start()
    return thread, seen


methods = ["leapfrog", "yoshida4"]
combo = window.controls.method_combo
first_use = {}
for name in methods:  # each method's kernels loaded once (numba's cache), timed apart
    index = [combo.itemData(i) for i in range(combo.count())].index(name)
    start = time.perf_counter()
    combo.setCurrentIndex(index)
    first_use[name] = first_made(start, lambda f: any(b.method == name for _, b in f.blocks))
    spin(limit=0.3)

latency = {k: [] for k in ("clear", "speed max->1x", "speed 1x->max", "method", "pause",
                           "reset: old worker ended", "reset: first frame")}
for repeat in range(5):
    for theta in (0.6, 2.5):
        window.phase_view.launch_at(theta, 0.0)
    spin(lambda: len(window.worker.tracked) == 3, 5.0)
    spin(limit=0.3)
    worker = window.worker
    thread, seen = watch_thread(lambda: worker.tracked == (0,))
    start = time.perf_counter()
    window.controls.clear_button.click()
    spin(lambda: not thread.is_alive(), 6.0)
    thread.join()
    latency["clear"].append((seen[0] - start) if seen else math.inf)

    start = time.perf_counter()
    window.controls.speed_combo.setCurrentIndex(one_index)
    latency["speed max->1x"].append(first_made(
        start, lambda f: bool(spans(f)) and max(spans(f)) <= 0.1))
    spin(limit=0.2)
    start = time.perf_counter()
    window.controls.speed_combo.setCurrentIndex(max_index)
    latency["speed 1x->max"].append(first_made(
        start, lambda f: bool(spans(f)) and max(spans(f)) > 1.0))
    spin(limit=0.2)

    name = methods[repeat % 2]
    index = [combo.itemData(i) for i in range(combo.count())].index(name)
    start = time.perf_counter()
    combo.setCurrentIndex(index)
    latency["method"].append(first_made(
        start, lambda f: any(b.method == name for _, b in f.blocks)))
    spin(limit=0.2)

    start = time.perf_counter()
    window.controls.play_button.click()
    spin(limit=0.5)
    late = [f.ready_at for f in list(made) if f.ready_at >= start]
    latency["pause"].append((max(late) - start) if late else 0.0)
    window.controls.play_button.click()
    spin(limit=0.3)

    old = window.runner
    thread, seen = watch_thread(lambda: not old.running)
    start = time.perf_counter()
    window.controls.reset_button.click()
    made.clear()
    watch()
    thread.join()
    latency["reset: old worker ended"].append((seen[0] - start) if seen else math.inf)
    latency["reset: first frame"].append(first_made(start, lambda f: True))
    window.controls.speed_combo.setCurrentIndex(max_index)
    spin(limit=0.3)

# full speed: the rate shown against the steps the frames brought, memory, rows
spin(limit=5.0)
rows_5 = window.store.rows
rss_5 = rss_mb()
made.clear()
spin(limit=20.0)
frames = list(made)
meter = RateMeter(window=2.0)
for frame in frames:
    meter.add(frame.made_at, frame.steps)
first_in = min(f.made_at for f in frames if f.made_at >= frames[-1].made_at - 2.0)
tail = [f for f in frames if f.made_at > first_in]
brought_rate = sum(f.steps for f in tail) / (frames[-1].made_at - first_in)
worker_rate = sum(f.steps for f in frames[1:]) / (frames[-1].made_at - frames[0].made_at)
rows_25 = window.store.rows
rss_25 = rss_mb()
capacity = sum(t.capacity for t in window.store)
method = window.store.main.method
compiled = window.compiled
window.close()
spin(limit=0.5)

# the worker's own cost: its steps/s against a bare Run loop of the same method, both in
# this process without the window (three orbits; frames go to a store, as in the window)
from explorer.trajectories import TrajectoryStore
from explorer.worker import RunSettings, SimulationWorker, WorkerThread
from systems.simulation import Run

overhead = {}
for name in ("yoshida8", "leapfrog"):
    run = Run(compiled, method=name, max_points=64, energy_tolerance=None)
    for _ in range(20):
        run.advance(0.012)
    begun, steps = time.perf_counter(), run.steps
    while time.perf_counter() - begun < 3.0:
        run.advance(0.012)
    bare = (run.steps - steps) / (time.perf_counter() - begun)
    store = TrajectoryStore(n_points=len(compiled.point_names))
    worker = SimulationWorker(compiled, RunSettings(method=name, speed=math.inf,
                                                    diagnostics=("H", "points")))
    brought = []

    def take(frame):
        for key, block in frame.blocks:
            store.append(key, block)
        brought.append((time.perf_counter(), frame.steps))

    worker.blocks_ready.connect(take)
    for k in range(3):
        y0 = compiled.initial_state() * (1.0 - 0.3 * k)
        worker.add_trajectory(store.add(y0).key, y0)
    runner = WorkerThread(worker)
    runner.start()
    spin(limit=1.0)
    brought.clear()
    spin(limit=3.0)
    runner.stop()
    rate = sum(s for _, s in brought[1:]) / (brought[-1][0] - brought[0][0])
    overhead[name] = (rate, bare)
print(json.dumps(dict(
    latency={k: max(v) for k, v in latency.items()},
    latency_median={k: float(np.median(v)) for k, v in latency.items()},
    paused_latency=paused_latency, full_latency=full_latency,
    rate_shown=meter.rate(), rate_brought=brought_rate, window_rate=worker_rate,
    overhead=overhead, first_use=first_use,
    rows_5=rows_5, rows_25=rows_25, capacity=capacity, rss_5=rss_5, rss_25=rss_25,
    method=method,
)))
"""


def measure() -> dict:
    env = dict(os.environ)
    if not env.get("DISPLAY"):
        env.setdefault("QT_QPA_PLATFORM", "offscreen")
    out = subprocess.run(
        [sys.executable, "-c", CODE], cwd=ROOT, env=env, capture_output=True, text=True,
        check=True, timeout=900,
    )  # fmt: skip
    return json.loads(out.stdout.strip().splitlines()[-1])


def main() -> bool:
    r = measure()
    print(f"max speed: simple pendulum with two launched orbits ({r['method']})")
    ok = True
    for name, seconds in r["latency"].items():
        median = r["latency_median"][name]
        label = f"{name}: worst of 5 (median {1e3 * median:.0f} ms), ms"
        if name == "reset: first frame":  # includes the window rebuilding its panels
            print(f"  {label}: {1e3 * seconds:.4g}")
            continue
        ok &= report(label, 1e3 * seconds, "<= 100", seconds <= 0.1)
    print(
        f"  GUI event latency p95: {1e3 * r['full_latency']:.0f} ms at full speed, "
        f"{1e3 * r['paused_latency']:.0f} ms paused (the redraws' cost)"
    )
    print(
        "  first use of a method in the process (numba loads its kernels): "
        + ", ".join(f"{name} {1e3 * seconds:.0f} ms" for name, seconds in r["first_use"].items())
    )
    print(f"  steps/s in the window at full speed: {r['window_rate']:.3g}")
    for name, (rate, bare) in r["overhead"].items():
        ok &= report(f"{name}: worker steps/s ({rate:.3g}) / bare Run ({bare:.3g})",
                     rate / bare, ">= 0.6", rate / bare >= 0.6)  # fmt: skip
    shown = r["rate_shown"] / r["rate_brought"]
    ok &= report("steps/s shown / steps brought per second", shown, "1 +- 0.05",
                 abs(shown - 1) <= 0.05)  # fmt: skip
    print(f"  store rows after 5 s {r['rows_5']:,}, after 25 s {r['rows_25']:,} "
          f"(capacity {r['capacity']:,})")  # fmt: skip
    ok &= report("store rows after 25 s / capacity", r["rows_25"] / r["capacity"], "<= 1",
                 r["rows_25"] <= r["capacity"])  # fmt: skip
    growth = r["rss_25"] - r["rss_5"]
    ok &= report("resident memory growth from 5 s to 25 s, MB", growth, "< 40", growth < 40)
    return ok


if __name__ == "__main__":
    raise SystemExit(0 if main() else 1)
