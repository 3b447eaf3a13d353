"""The integrator worker: streams blocks from ``systems.simulation`` in a ``QThread``.

Modelled on superqt's ``GeneratorWorker.work``: each turn of the loop checks abort, then
pause, then produces the next blocks and emits them, one signal per frame (about every
30 ms) carrying every trajectory's new block, never one signal per point. The numba
kernels release the GIL, so the GUI thread keeps running while a block is computed.

Each trajectory is one ``systems.simulation.Run`` for its whole life, whatever the
speed: every frame takes its next block. At a finite ``speed`` the block ends after the
first step that reaches ``speed`` times the frame's wall time past the last state, so the
mechanism moves at a watchable rate; at ``speed = inf`` it ends when the frame's time is
spent. Pacing only decides where blocks end: the states, and the step of a fixed-step
method (chosen once per trajectory, never from the speed), are those of a full-speed run.
A change of method, step, tolerance, section or diagnostics starts new runs from the
trajectories' current states; a change of speed does not.
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np
from PySide6.QtCore import QObject, QThread, Signal

from systems.deadline import Abandoned, abandon

FRAME_SECONDS = 0.03
ABANDON_AFTER = 0.25
"""Seconds ``WorkerThread.stop`` waits for the loop to see its abort before abandoning it."""
STOP_SECONDS = 5.0
"""How long ``WorkerThread.stop`` waits by default (closing the window passes less)."""
PROBLEM_STATUSES = ("non_finite", "singular", "energy_error", "stalled", "budget")


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
    energy_tolerance: float | None = 1e-2

    def with_(self, **changes) -> RunSettings:
        return replace(self, **changes)

    def run_options(self) -> dict:
        """What a ``Run`` is made with: everything but the pacing."""
        return dict(
            method=self.method,
            dt=self.dt,
            tol=self.tol,
            t_end=self.t_end,
            diagnostics=self.diagnostics,
            max_points=self.max_points,
            section=self.section,
            energy_tolerance=self.energy_tolerance,
        )


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
    run: object | None = None
    done: bool = False
    target: float | None = None  # paced playback: the simulated time due by this frame


def default_runs() -> Callable:
    """``systems.simulation.Run`` (imported on first use)."""
    from systems.simulation import Run

    return Run


class SimulationWorker(QObject):
    """Integrates any number of trajectories of one compiled system, frame by frame.

    Parameters
    ----------
    compiled : CompiledSystem
        Never mutated; a new system means a new worker.
    settings : RunSettings
    generation : int
        Stamped on every emitted ``Frame`` so late frames of a replaced worker are ignored.
    runs : callable, optional
        ``systems.simulation.Run`` or a factory with its signature, whose objects have
        ``advance(seconds, until) -> Block`` and ``finished``.
    """

    blocks_ready = Signal(object)
    failed = Signal(str)
    finished = Signal()

    def __init__(self, compiled, settings: RunSettings, generation: int = 0, runs=None):
        super().__init__()
        self.compiled = compiled
        self.generation = generation
        self._settings = settings
        self._runs = runs
        self._lock = threading.Lock()
        self._ident_lock = threading.Lock()
        self._ident: int | None = None  # the worker thread's, while ``work`` runs
        self._wake = threading.Event()
        self._abort = False
        self._paused = False
        self._steps_requested = 0
        self._tracks: dict[int, _Track] = {}
        self._pending: list[_Track] = []
        self._removed: set[int] = set()
        self._restart = False
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
        """New settings; runs restart from their current states unless only the pacing
        (speed, frame time) changed."""
        with self._lock:
            if settings.run_options() != self._settings.run_options():
                self._restart = True  # applied by the worker thread, between frames
            self._settings = settings
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

    def abandon(self) -> bool:
        """Raise ``Abandoned`` in the loop at its next bytecode (a block that will not end:
        a long interpreted step); True if the loop was running."""
        with self._ident_lock:
            if self._ident is None:
                return False
            abandon(self._ident)
            self._ident = None
            return True

    # -- the loop, in the worker thread ------------------------------------------------------

    def work(self) -> None:
        """Run until aborted; emits ``blocks_ready`` once per frame with new blocks."""
        try:
            with self._ident_lock:
                self._ident = threading.get_ident()
            try:
                self._loop()
            finally:
                with self._ident_lock:
                    self._ident = None
        except Abandoned:
            pass  # stopped from outside: nobody wants these blocks any more
        except Exception as exc:  # noqa: BLE001 - reported to the GUI, never lost
            self.failed.emit(f"{type(exc).__name__}: {exc}")
        finally:
            self.finished.emit()

    def _loop(self) -> None:
        if self._runs is None:
            self._runs = default_runs()
        while not self._abort:
            self._take_changes()
            if self._paused:
                with self._lock:
                    stepping = self._steps_requested > 0
                    self._steps_requested = max(0, self._steps_requested - 1)
                if not stepping:
                    self._idle(0.05)
                    continue
                for track in self._tracks.values():
                    track.target = None  # a single step always moves
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
            if self._restart:
                self._restart = False
                for track in self._tracks.values():
                    track.run = None
                    track.target = None
                    track.done = False

    def _advance(self, track: _Track, settings: RunSettings, count: int) -> list:
        if track.run is None:
            if track.t >= settings.t_end:
                track.done = True
                return []
            track.run = self._runs(self.compiled, y0=track.y, t0=track.t, **settings.run_options())
        until = math.inf
        if math.isfinite(settings.speed):
            # simulated time falls due at speed x wall time; a step longer than a frame's
            # share is taken only once it is due, and a machine that falls behind does not
            # pile up a debt of more than two frames
            frame = settings.speed * settings.frame_seconds
            due = track.t if track.target is None else track.target
            track.target = min(due + frame, track.t + 2 * frame)
            if track.t >= track.target:
                return []
            until = track.target
        block = track.run.advance(settings.frame_seconds / count, until)
        self._follow(track, block)
        if track.run.finished:
            track.done = True
        return [(track.key, block)]

    @staticmethod
    def _follow(track: _Track, block) -> None:
        if len(block.t):
            track.t = float(block.t[-1])
            track.y = np.array(block.y[-1], dtype=float)
        if block.status in PROBLEM_STATUSES:
            track.done = True


_orphans: list[QThread] = []
"""Threads that did not end in time: kept referenced, since a ``QThread`` destroyed while
running aborts the process."""


def keep_until_finished(thread: QThread) -> None:
    """Hold a reference to a thread that did not stop in time, until it has ended."""
    _orphans[:] = [t for t in _orphans if t.isRunning()]
    _orphans.append(thread)


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

    def stop(self, timeout: float = STOP_SECONDS, *, abandon: bool = False) -> bool:
        """Abort the loop and wait up to ``timeout`` seconds for the thread to end.

        The loop checks for abort between blocks of about 30 ms. With ``abandon`` (the
        window closing), a loop that has not seen it after ``ABANDON_AFTER`` seconds (a
        slow interpreted step) is abandoned; otherwise (a restart) it is only waited for,
        since it may be in numba's first compile of a method, which must not be cut
        short. A thread still running at the end is kept referenced until it ends (a
        ``QThread`` destroyed while running aborts the process); its frames carry an old
        generation and are ignored. Returns whether it ended.
        """
        self.worker.abort()
        self.thread.quit()
        if abandon:
            grace = min(ABANDON_AFTER, timeout)
            if self.thread.wait(round(1000 * grace)):
                return True
            self.worker.abandon()
            timeout -= grace
        if self.thread.wait(round(1000 * max(0.0, timeout))):
            return True
        keep_until_finished(self.thread)
        return False

    @property
    def running(self) -> bool:
        return self.thread.isRunning()
