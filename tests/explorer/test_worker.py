"""The worker thread: one signal per frame, pause, single step, abort, pacing."""

from __future__ import annotations

import math
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


def fake_stream(points_per_block: int = 500):
    """A stand-in for ``systems.simulation.stream``: uniform motion, many points a block."""
    calls = []

    def stream(compiled, *, y0, t0, t_end, dt=None, block_seconds=0.03, **options):
        calls.append(dict(t0=t0, t_end=t_end, dt=dt, **options))
        t = t0
        while t < t_end:
            ts = np.linspace(t, min(t + 1.0, t_end), points_per_block + 1)[1:]
            ys = np.column_stack([ts, np.ones_like(ts)])
            t = ts[-1]
            yield FakeBlock(ts, ys, steps=len(ts), status="ok" if t >= t_end else "running")

    stream.calls = calls
    return stream


def run_worker(qtbot, settings, stream, until, timeout=5000):
    worker = SimulationWorker(None, settings, stream=stream)
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
    stream = fake_stream(points_per_block=500)
    settings = RunSettings(speed=math.inf, t_end=20.0)
    worker, frames = run_worker(qtbot, settings, stream, lambda f: len(f) >= 5)
    points = sum(len(block.t) for frame in frames for _, block in frame.blocks)
    assert points >= 5 * 500
    assert len(frames) == worker.frames <= points / 500
    assert all(frame.generation == 0 for frame in frames)


def test_paced_frames_advance_by_speed_times_frame_time(qtbot):
    stream = fake_stream()
    settings = RunSettings(method=None, speed=2.0, frame_seconds=0.02)
    _, frames = run_worker(qtbot, settings, stream, lambda f: len(f) >= 4)
    spans = [call["t_end"] - call["t0"] for call in stream.calls[:4]]
    assert spans == pytest.approx([0.04] * 4)


def test_pause_then_single_step_then_abort(qtbot):
    stream = fake_stream()
    worker = SimulationWorker(None, RunSettings(speed=1.0), stream=stream)
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
    def failing(compiled, **options):
        yield FakeBlock(
            np.array([0.1]), np.array([[np.nan, 0.0]]), status="non_finite", message="NaN"
        )

    worker, frames = run_worker(qtbot, RunSettings(speed=math.inf), failing, lambda f: len(f) >= 1)
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
