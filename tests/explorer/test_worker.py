"""The worker thread: one signal per frame, pause, single step, abort, pacing."""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np
import pytest

from explorer.buffers import GrowingArray
from explorer.worker import RunSettings, SimulationWorker, WorkerThread


@dataclass(frozen=True)
class FakeBlock:
    t: np.ndarray
    y: np.ndarray
    diagnostics: dict = field(default_factory=dict)
    status: str = "running"
    message: str = ""
    steps: int = 0
    rhs_evaluations: int = 0
    method: str = "fake"


def fake_runs(points_per_block: int = 500):
    """A stand-in for ``systems.simulation.Run``: uniform motion, many points a block."""
    calls = []

    class FakeRun:
        def __init__(self, compiled, *, y0, t0, t_end, **options):
            calls.append(dict(t0=t0, t_end=t_end, **options))
            self.t, self.t_end, self.finished = t0, t_end, False
            self.untils = []

        def advance(self, seconds=0.03, until=math.inf):
            self.untils.append((self.t, until))
            end = min(self.t + 1.0, self.t_end, until)
            ts = np.linspace(self.t, end, points_per_block + 1)[1:]
            ys = np.column_stack([ts, np.ones_like(ts)])
            self.t = ts[-1]
            self.finished = self.t >= self.t_end
            runs.append(self)
            return FakeBlock(ts, ys, steps=len(ts), status="ok" if self.finished else "running")

    runs: list = []
    FakeRun.calls = calls
    FakeRun.runs = runs
    return FakeRun


def run_worker(qtbot, settings, runs, until, timeout=5000):
    worker = SimulationWorker(None, settings, runs=runs)
    frames = []
    worker.blocks_ready.connect(frames.append)
    worker.add_trajectory(0, np.zeros(2))
    runner = WorkerThread(worker)
    runner.start()
    try:
        qtbot.waitUntil(lambda: until(frames), timeout=timeout)
    finally:
        runner.stop()
    assert not runner.running
    return worker, frames


def test_one_signal_per_frame_carries_every_point(qtbot):
    runs = fake_runs(points_per_block=500)
    settings = RunSettings(speed=math.inf, t_end=20.0)
    worker, frames = run_worker(qtbot, settings, runs, lambda f: len(f) >= 5)
    points = sum(len(block.t) for frame in frames for _, block in frame.blocks)
    assert points >= 5 * 500
    # one signal per frame, never one per point: a frame hands over a block of at least
    # 256 rows (the newest part when the store's rate is exceeded), the last one less
    assert len(frames) == worker.frames <= points / 256 + 1
    assert all(frame.generation == 0 for frame in frames)


def test_paced_frames_advance_by_speed_times_frame_time(qtbot):
    runs = fake_runs()
    settings = RunSettings(method=None, speed=2.0, frame_seconds=0.02)
    _, frames = run_worker(qtbot, settings, runs, lambda f: len(f) >= 4)
    assert len(runs.calls) == 1  # one run for the trajectory, throttled, never restarted
    spans = [until - t for t, until in runs.runs[0].untils[:4]]
    assert spans == pytest.approx([0.04] * 4)


def test_paced_playback_keeps_to_wall_time_when_the_gui_takes_frames_at_once(qtbot):
    # each frame the GUI takes wakes the worker (it may send the next): at a finite
    # speed that must not shorten the frame's time, or 1x runs many times faster
    runs = fake_runs(points_per_block=3)
    worker = SimulationWorker(None, RunSettings(speed=1.0, t_end=1e9), runs=runs)
    worker.add_trajectory(0, np.zeros(2))
    runner = WorkerThread(worker)
    runner.start()
    try:
        qtbot.waitUntil(lambda: worker.frames >= 3, timeout=5000)
        start, frames, begun = runs.runs[-1].t, worker.frames, time.perf_counter()
        qtbot.wait(1000)
        simulated, wall = runs.runs[-1].t - start, time.perf_counter() - begun
        made = worker.frames - frames
    finally:
        runner.stop()
    # paced, it goes on; how closely it keeps to wall time (1x: a simulated second a
    # second, no more frames than the frame rate allows) is benchmarks/paced_playback.py's
    assert simulated > 0 and made > 0 and wall > 0


def test_a_speed_change_keeps_the_run_and_a_method_change_restarts_it(qtbot):
    runs = fake_runs()
    worker = SimulationWorker(None, RunSettings(speed=1.0, t_end=1e9), runs=runs)
    frames = []
    worker.blocks_ready.connect(frames.append)
    worker.add_trajectory(0, np.zeros(2))
    runner = WorkerThread(worker)
    runner.start()
    try:
        qtbot.waitUntil(lambda: len(frames) >= 2, timeout=5000)
        worker.set_settings(worker.settings.with_(speed=math.inf))
        qtbot.waitUntil(lambda: len(frames) >= 6, timeout=5000)
        assert len(runs.calls) == 1
        worker.set_settings(worker.settings.with_(method="rk4"))
        qtbot.waitUntil(lambda: len(runs.calls) == 2, timeout=5000)
    finally:
        runner.stop()
    assert runs.calls[1]["method"] == "rk4" and runs.calls[1]["t0"] > 0


def test_pause_then_single_step_then_abort(qtbot):
    worker = SimulationWorker(None, RunSettings(speed=1.0), runs=fake_runs())
    frames = []
    worker.blocks_ready.connect(frames.append)
    worker.pause()
    worker.add_trajectory(0, np.zeros(2))
    runner = WorkerThread(worker)
    runner.start()
    qtbot.wait(200)
    assert frames == []
    worker.step()
    qtbot.waitUntil(lambda: len(frames) == 1, timeout=3000)
    qtbot.wait(150)
    assert len(frames) == 1
    runner.stop()
    assert not runner.running


def test_stops_a_trajectory_with_a_problem(qtbot):
    class Failing:
        def __init__(self, compiled, **options):
            self.finished = False

        def advance(self, seconds=0.03, until=math.inf):
            self.finished = True
            return FakeBlock(
                np.array([0.1]), np.array([[np.nan, 0.0]]), status="non_finite", message="NaN"
            )

    worker, frames = run_worker(qtbot, RunSettings(speed=math.inf), Failing, lambda f: len(f) >= 1)
    qtbot.wait(100)
    assert len(frames) == 1 and frames[0].blocks[0][1].status == "non_finite"


def test_growing_array_doubles_and_keeps_rows():
    buffer = GrowingArray((2,), capacity=4)
    for k in range(10):
        buffer.extend(np.full((3, 2), k))
    assert len(buffer) == 30 and buffer.capacity == 32
    assert (buffer.data[::3, 0] == np.arange(10)).all()
    view = buffer.data
    assert view.base is not None  # a view, not a copy
    buffer.extend_missing(2)
    assert np.isnan(buffer.data[-2:]).all()


def test_real_stream_keeps_a_fixed_step_across_frames(qtbot):
    from explorer.builder import build
    from systems.scene import load_scene

    built = build(load_scene("harmonic_oscillator"))
    settings = RunSettings(method=built.method, speed=1.0)
    worker = SimulationWorker(built.compiled, settings)
    frames = []
    worker.blocks_ready.connect(frames.append)
    worker.add_trajectory(0, built.compiled.initial_state())
    runner = WorkerThread(worker)
    runner.start()
    try:
        qtbot.waitUntil(lambda: len(frames) >= 6, timeout=60000)
    finally:
        runner.stop()
    t = np.concatenate([block.t for frame in frames for _, block in frame.blocks])
    steps = np.diff(t)
    assert steps == pytest.approx(np.full_like(steps, steps[0]), rel=1e-9)


def _states(qtbot, compiled, method, speed, t_stop):
    settings = RunSettings(method=method, speed=speed, t_end=t_stop)
    worker = SimulationWorker(compiled, settings)
    frames = []
    worker.blocks_ready.connect(frames.append)
    worker.add_trajectory(0, compiled.initial_state())
    runner = WorkerThread(worker)
    runner.start()
    try:
        qtbot.waitUntil(
            lambda: any(b.status != "running" for f in frames for _, b in f.blocks), timeout=60000
        )
    finally:
        runner.stop()
    blocks = [block for frame in frames for _, block in frame.blocks]
    t = np.concatenate([b.t for b in blocks])
    y = np.concatenate([b.y for b in blocks])
    return dict(zip(t.tolist(), map(tuple, y.tolist()), strict=True)), blocks


@pytest.mark.parametrize("method", ["yoshida8", "gauss_legendre6"])
def test_playback_speed_never_changes_the_states(qtbot, method):
    # the same orbit at 1x and at max speed passes through the same states, bitwise
    from explorer.builder import build
    from systems.scene import load_scene

    built = build(load_scene("simple_pendulum"))
    compiled = built.compiled
    paced, blocks = _states(qtbot, compiled, method, 20.0, 3.0)
    fast, _ = _states(qtbot, compiled, method, math.inf, 3.0)
    common = sorted(set(paced) & set(fast))
    assert len(common) > 10 and common[-1] == 3.0
    assert all(paced[t] == fast[t] for t in common)
    assert blocks[-1].setting == "dt" and blocks[-1].setting_value > 0


def test_paced_playback_keeps_to_the_speed_when_a_step_is_longer_than_a_frame(qtbot):
    # steps of 0.05 at 0.1x with 20 ms frames: a step falls due every 25 frames, so
    # simulated time keeps pace with speed x wall time instead of one step a frame
    class CoarseRun:
        def __init__(self, compiled, *, y0, t0, t_end, **options):
            self.t, self.finished = t0, False

        def advance(self, seconds=0.03, until=math.inf):
            self.t += 0.05
            return FakeBlock(np.array([self.t]), np.array([[self.t, 0.0]]), steps=1)

    settings = RunSettings(speed=0.1, frame_seconds=0.02, t_end=1e9)
    worker = SimulationWorker(None, settings, runs=CoarseRun)
    frames = []
    worker.blocks_ready.connect(frames.append)
    worker.add_trajectory(0, np.zeros(2))
    runner = WorkerThread(worker)
    runner.start()
    qtbot.wait(1500)
    runner.stop()
    simulated = max(block.t[-1] for frame in frames for _, block in frame.blocks)
    assert 0.05 <= simulated <= 0.25  # about 0.1 x 1.5 s, not 75 steps' worth (3.75)
