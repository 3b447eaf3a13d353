"""The integrator worker: streams blocks from ``systems.simulation`` in a ``QThread``.

Modelled on superqt's ``GeneratorWorker.work``: each turn of the loop checks abort, then
pause, then produces the next blocks and emits them, one signal per frame (about every
30 ms) carrying every trajectory's new block, never one signal per point. The numba
kernels release the GIL, so the GUI thread keeps running while a block is computed.

Two pacing modes:

- *paced* (``speed`` finite): each frame advances every trajectory by ``speed`` times the
  frame's wall time (a ``stream`` to that time, from the last state), so the mechanism
  moves at a watchable rate. The step of a fixed-step method is chosen once per
  trajectory and each frame covers a whole number of steps, so pacing never changes the
  numerical method's step;
- *full speed* (``speed = inf``): each trajectory keeps one open ``stream`` generator and
  every frame takes its next block (a Poincaré section filling up, an export).
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, replace

import numpy as np
from PySide6.QtCore import QObject, QThread, Signal

FRAME_SECONDS = 0.03
MIN_STEPS_PER_FRAME = 8
ENDLESS = 1e12
"""Horizon of an endless full-speed run (the fixed-step runners need a finite ``t_end``)."""
PROBLEM_STATUSES = ("non_finite", "singular", "energy_error", "stalled")


@dataclass(frozen=True)
class RunSettings:
    """How to integrate: method, step or tolerance, speed and what to compute alongside."""

    method: str | None = None
    dt: float | None = None
    tol: float | None = None
    speed: float = 1.0
    t_end: float = math.inf
    diagnostics: tuple[str, ...] = ()
    frame_seconds: float = FRAME_SECONDS
    max_points: int = 4096
    section: tuple[int, float, int] | None = None

    def with_(self, **changes) -> RunSettings:
        return replace(self, **changes)


@dataclass(frozen=True)
class Frame:
    """What one ``blocks_ready`` signal carries: the worker's generation and its blocks."""

    generation: int
    blocks: tuple[tuple[int, object], ...]
    wall_seconds: float


@dataclass
class _Track:
    key: int
    t: float
    y: np.ndarray
    generator: Iterator | None = None
    done: bool = False
    step: float | None = None
    whole_steps: bool = False


def default_stream() -> Callable:
    """``systems.simulation.stream`` (imported on first use)."""
    from systems.simulation import stream

    return stream


def fixed_step(compiled, method: str | None, track: _Track) -> tuple[float | None, bool]:
    """The engine's default step for the method at the track's state, and whether it is
    a step in physical time (so a frame can cover a whole number of them).

    Computed once per trajectory with an unbounded horizon, so that paced frames (short
    ``stream`` calls) keep the step a long run would use. ``(None, False)`` for adaptive
    methods, which choose their own steps from the tolerance.
    """
    if method is None:
        return None, False
    from systems.integrators import get_stepper
    from systems.integrators.stepsize import default_step, fictitious_step

    stepper = get_stepper(method)
    if stepper.family in ("composition", "gauss"):
        return default_step(compiled, stepper, track.t, track.y, math.inf), True
    if stepper.family == "logh":  # a fictitious-time step
        return fictitious_step(compiled, stepper, track.t, track.y, math.inf), False
    return None, False


class SimulationWorker(QObject):
    """Integrates any number of trajectories of one compiled system, frame by frame.

    Parameters
    ----------
    compiled : CompiledSystem
        Never mutated; a new system means a new worker.
    settings : RunSettings
    generation : int
        Stamped on every emitted ``Frame`` so late frames of a replaced worker are ignored.
    stream : callable, optional
        ``systems.simulation.stream`` or a function with its signature.
    """

    blocks_ready = Signal(object)
    failed = Signal(str)
    finished = Signal()

    def __init__(self, compiled, settings: RunSettings, generation: int = 0, stream=None):
        super().__init__()
        self.compiled = compiled
        self.generation = generation
        self._settings = settings
        self._stream = stream
        self._lock = threading.Lock()
        self._wake = threading.Event()
        self._abort = False
        self._paused = False
        self._steps_requested = 0
        self._tracks: dict[int, _Track] = {}
        self._pending: list[_Track] = []
        self._removed: set[int] = set()
        self.frames = 0

    # -- called from the GUI thread --------------------------------------------------------

    def add_trajectory(self, key: int, y0: np.ndarray, t0: float = 0.0) -> None:
        with self._lock:
            self._pending.append(_Track(key, float(t0), np.array(y0, dtype=float)))
        self._wake.set()

    def remove_trajectory(self, key: int) -> None:
        with self._lock:
            self._removed.add(key)
        self._wake.set()

    def set_settings(self, settings: RunSettings) -> None:
        with self._lock:
            self._settings = settings
            for track in self._tracks.values():
                track.generator = None
                track.step = None
        self._wake.set()

    @property
    def settings(self) -> RunSettings:
        return self._settings

    def pause(self) -> None:
        self._paused = True

    def resume(self) -> None:
        self._paused = False
        self._wake.set()

    @property
    def paused(self) -> bool:
        return self._paused

    def step(self) -> None:
        """While paused: advance one frame."""
        with self._lock:
            self._steps_requested += 1
        self._wake.set()

    def abort(self) -> None:
        self._abort = True
        self._wake.set()

    # -- the loop, in the worker thread ------------------------------------------------------

    def work(self) -> None:
        """Run until aborted; emits ``blocks_ready`` once per frame with new blocks."""
        try:
            if self._stream is None:
                self._stream = default_stream()
            while not self._abort:
                self._take_changes()
                if self._paused:
                    with self._lock:
                        stepping = self._steps_requested > 0
                        self._steps_requested = max(0, self._steps_requested - 1)
                    if not stepping:
                        self._idle(0.05)
                        continue
                active = [track for track in self._tracks.values() if not track.done]
                if not active:
                    self._idle(0.05)
                    continue
                start = time.perf_counter()
                settings = self._settings
                blocks = []
                for track in active:
                    if self._abort:
                        break
                    blocks.extend(self._advance(track, settings, len(active)))
                elapsed = time.perf_counter() - start
                if blocks and not self._abort:
                    self.frames += 1
                    self.blocks_ready.emit(Frame(self.generation, tuple(blocks), elapsed))
                if math.isfinite(settings.speed):
                    self._idle(settings.frame_seconds - elapsed)
        except Exception as exc:  # noqa: BLE001 - reported to the GUI, never lost
            self.failed.emit(f"{type(exc).__name__}: {exc}")
        finally:
            self.finished.emit()

    def _idle(self, seconds: float) -> None:
        if seconds > 0 and not self._abort:
            self._wake.wait(seconds)
            self._wake.clear()

    def _take_changes(self) -> None:
        with self._lock:
            for track in self._pending:
                self._tracks[track.key] = track
            self._pending.clear()
            for key in self._removed:
                self._tracks.pop(key, None)
            self._removed.clear()

    def _advance(self, track: _Track, settings: RunSettings, count: int) -> list:
        budget = settings.frame_seconds / count
        options = dict(
            method=settings.method,
            tol=settings.tol,
            diagnostics=settings.diagnostics,
            max_points=settings.max_points,
            section=settings.section,
        )
        blocks = []
        if math.isfinite(settings.speed):
            if track.step is None:
                track.step, track.whole_steps = fixed_step(self.compiled, settings.method, track)
                if settings.dt is not None:
                    track.step = settings.dt
                elif track.step and track.whole_steps:  # smooth curves: several steps a frame
                    frame = settings.speed * settings.frame_seconds
                    track.step = min(track.step, frame / MIN_STEPS_PER_FRAME)
            target = track.t + settings.speed * settings.frame_seconds
            if track.step and track.whole_steps:  # the method's step stays the same
                steps = max(1, round(settings.speed * settings.frame_seconds / track.step))
                target = track.t + steps * track.step
            target = min(target, settings.t_end)
            if target <= track.t:
                track.done = True
                return blocks
            generator = self._stream(
                self.compiled,
                y0=track.y,
                t0=track.t,
                t_end=target,
                dt=track.step,
                block_seconds=budget,
                **options,
            )
            for block in generator:
                blocks.append((track.key, block))
                self._follow(track, block)
                if track.done or self._abort:
                    break
            if track.t >= settings.t_end:
                track.done = True
            return blocks
        if track.generator is None:
            track.generator = self._stream(
                self.compiled,
                y0=track.y,
                t0=track.t,
                t_end=min(settings.t_end, track.t + ENDLESS),
                dt=settings.dt,
                block_seconds=budget,
                **options,
            )
        try:
            block = next(track.generator)
        except StopIteration:
            track.done = True
            return blocks
        blocks.append((track.key, block))
        self._follow(track, block)
        return blocks

    @staticmethod
    def _follow(track: _Track, block) -> None:
        if len(block.t):
            track.t = float(block.t[-1])
            track.y = np.array(block.y[-1], dtype=float)
        if block.status in PROBLEM_STATUSES:
            track.done = True


class WorkerThread:
    """A ``SimulationWorker`` moved to its own ``QThread``; ``stop`` ends both cleanly."""

    def __init__(self, worker: SimulationWorker):
        self.worker = worker
        self.thread = QThread()
        self.thread.setObjectName(f"simulation-{worker.generation}")
        worker.moveToThread(self.thread)
        self.thread.started.connect(worker.work)
        worker.finished.connect(self.thread.quit)

    def start(self) -> None:
        self.thread.start()

    def stop(self) -> None:
        """Abort the loop and wait for the thread to end.

        The wait has no time limit on purpose: a ``QThread`` destroyed while running
        aborts the process. The loop checks for abort between blocks of about 30 ms, and a
        block in progress (compiled code) finishes within its wall-time budget.
        """
        self.worker.abort()
        self.thread.quit()
        self.thread.wait()

    @property
    def running(self) -> bool:
        return self.thread.isRunning()
