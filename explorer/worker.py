"""The integrator worker: streams blocks from ``systems.simulation`` in a ``QThread``.

Modelled on superqt's ``GeneratorWorker.work``: each turn of the loop checks abort, then
pause and the pending commands, then produces the next blocks and emits them, one signal
per frame carrying every trajectory's new block, never one signal per point. The numba
kernels release the GIL, so the GUI thread keeps running while a block is computed.

Each trajectory is one ``systems.simulation.Run`` for its whole life, whatever the
speed: every frame takes its next block. At a finite ``speed`` the block ends after the
first step that reaches ``speed`` times the frame's wall time past the last state, so the
mechanism moves at a watchable rate; at ``speed = inf`` it ends when ``CHUNK_SECONDS`` of
compiled stepping are spent. Pacing only decides where blocks end: the states, and the
step of a fixed-step method (chosen once per trajectory, never from the speed), are those
of a full-speed run. A change of method, step, tolerance or section starts new runs from
the trajectories' current states; a change of speed or diagnostics does not.

Responsive at any speed
-----------------------
- The loop never computes more than ``CHUNK_SECONDS`` (12 ms) between two looks at its
  commands (abort, pause, settings, added and removed orbits), so each acts within a
  chunk, well under 100 ms, even at full speed; at most one new run is made per turn
  (making one probes the default step: tens of ms).
- At most ``MAX_IN_FLIGHT`` frames are on their way to the GUI thread: the worker waits
  (still answering commands) until the GUI has taken one, so a busy GUI never finds a
  backlog of frames queued ahead of a click. At a finite speed each frame's time is
  waited out whatever the GUI does (only a command ends the wait early), so 1x is real
  time however fast the GUI takes the frames.
- The store takes a bounded number of rows that keep closed orbits curves. Every step
  is sampled (a block keeps up to ``FINE_POINTS`` states, so no stride skips a turn of
  the orbit; ``stride`` grows only while ``OVERSAMPLING`` or more samples are taken per
  state kept). Of those, ``arc_keep`` keeps the states that moved ``1 / ARC_RESOLUTION``
  of the orbit's size along the curve since the last one kept, and a token bucket lets
  at most ``rows_per_second`` rows a wall second through, for all trajectories together:
  past that, the most recent part (at least ``MIN_FRAGMENT`` rows) goes over after a gap
  row (``explorer.trajectories``), so no chord is drawn across what was left out.
- The energy guard and the diagnostics: runs are made without diagnostics (the guard then
  checks the last state of each block); ``H`` and the drawing's points are computed here
  for the states handed over. While ``H`` is wanted, every step is sampled (``stride``
  stays 1) and H at every step is summed up in min/max bins of time
  (``explorer.envelope``), handed over with the rows as ``diagnostics["envelope"]`` (an
  ``Envelope``), whatever the row budget leaves out: the energy plots draw those.
- Frames carry true counts: each block's ``steps`` and ``rhs_evaluations`` are those
  taken for that block (a ``Run`` block's are totals of its run), and ``Frame.steps``
  their sum, for ``RateMeter``.
"""

from __future__ import annotations

import dataclasses
import math
import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np
from PySide6.QtCore import QObject, QThread, Signal, Slot

from explorer.envelope import (
    GAP,
    MOMENTA,
    Envelope,
    bin_exponent,
    conserved_quantities,
    summarize,
    summarize_series,
)

FRAME_SECONDS = 0.03
CHUNK_SECONDS = 0.012
"""Wall time of compiled stepping between two looks at the commands, at most."""
MAX_IN_FLIGHT = 2
"""Frames emitted that the GUI thread has not taken yet, at most."""
ACK_SECONDS = 1.0
"""How long the worker waits for the GUI to take a frame before sending the next anyway."""
FINE_POINTS = 1 << 17
"""States a block may keep: every step (or every ``stride``-th), as long as a chunk takes
fewer; fewer for large systems (``FINE_VALUES``)."""
FINE_VALUES = 1 << 19
"""Numbers (states times their size plus one) a block may keep: 4 MB."""
OVERSAMPLING = 4
"""States sampled per state kept along the curve, at least (the stride adapts to it)."""
MAX_STRIDE = 1 << 12
ARC_RESOLUTION = 64.0
"""Kept states per unit of orbit size along the curve (the size of each coordinate is its
range in the block, about its trend), at most."""
ROWS_PER_SECOND = 2048.0
"""Rows per wall second the store takes from all trajectories together, at most: what the
panels redraw every frame grows with it (at 4096 the window's event latency at full speed
reached hundreds of ms, at 1024 it stayed under 5 ms; benchmarks/max_speed.py)."""
BURST_SECONDS = 8.0
"""The token bucket holds this many seconds' worth of rows: a run's first seconds, or a
newly launched orbit's, go over whole."""
MIN_FRAGMENT = 256
"""Rows of a part handed over after a gap, at least: until the bucket holds that many, a
trajectory's rows wait (a closed orbit of the default step is drawn a few turns at a
time)."""
STOP_SECONDS = 5.0
"""How long ``WorkerThread.stop`` waits by default (closing the window passes less)."""
DIAGNOSTIC_FUNCTIONS = {"H": "hamiltonian", "qdot": "velocities", "points": "drawing"}


@dataclass(frozen=True)
class RunSettings:
    """How to integrate: method, step or tolerance, speed and what to compute alongside.

    ``max_points`` is the states a run's block keeps (every step up to that many);
    ``rows_per_second`` bounds the rows handed to the store per wall second;
    ``max_step`` bounds an adaptive method's steps (``systems.simulation.Run``): by
    default so that what is drawn follows the motion between the steps' ends;
    ``strobe`` is a stroboscopic section's period (``Run(strobe=...)``: its events are
    the states once per period of the drive).
    """

    method: str | None = None
    dt: float | None = None
    tol: float | None = None
    speed: float = 1.0
    t_end: float = math.inf
    diagnostics: tuple[str, ...] = ()
    frame_seconds: float = FRAME_SECONDS
    max_points: int = FINE_POINTS
    section: tuple[int, float, int] | None = None
    strobe: float | None = None
    energy_tolerance: float | None = 1e-2
    rows_per_second: float = ROWS_PER_SECOND
    max_step: float | str = "drawing"

    def with_(self, **changes) -> RunSettings:
        return replace(self, **changes)

    def run_options(self) -> dict:
        """What a ``Run`` is made with: everything but the pacing and the diagnostics
        (computed by the worker for the states it keeps)."""
        return dict(
            method=self.method,
            dt=self.dt,
            tol=self.tol,
            t_end=self.t_end,
            max_points=self.max_points,
            section=self.section,
            strobe=self.strobe,
            energy_tolerance=self.energy_tolerance,
            max_step=self.max_step,
        )


@dataclass(frozen=True)
class Frame:
    """What one ``blocks_ready`` signal carries: the worker's generation and its blocks.

    Each block's ``steps`` and ``rhs_evaluations`` are those taken for it (not the totals
    of its run); ``wall_seconds`` is the time the frame took to compute.
    """

    generation: int
    blocks: tuple[tuple[int, object], ...]
    wall_seconds: float
    iteration: int = 0  # the turn of the worker's loop that made it
    made_at: float = 0.0  # ``time.perf_counter()`` when it was emitted
    ready_at: float = 0.0  # when its blocks were ready (before waiting for the GUI)

    @property
    def steps(self) -> int:
        """Integrator steps taken for this frame, all trajectories together."""
        return sum(int(block.steps) for _, block in self.blocks)


class RateMeter:
    """Steps per second of wall time, over the frames of the last ``window`` seconds.

    ``add(now, steps)`` records the steps a frame brought at time ``now`` (seconds, e.g.
    ``time.perf_counter()``); ``rate()`` divides the steps after the first recorded frame
    of the window by the time since it, so it is exact for any spacing of frames.

    Parameters
    ----------
    window : float
        Seconds of history the rate is taken over.
    """

    def __init__(self, window: float = 1.0):
        self.window = float(window)
        self._samples: deque[tuple[float, int]] = deque()
        self._sum = 0  # steps of the samples after the first

    def add(self, now: float, steps: int) -> None:
        """Record ``steps`` integrator steps that arrived at wall time ``now``."""
        if self._samples:
            self._sum += int(steps)
        self._samples.append((float(now), int(steps)))
        while len(self._samples) > 2 and self._samples[1][0] <= now - self.window:
            self._samples.popleft()
            self._sum -= self._samples[0][1]

    def rate(self, now: float | None = None) -> float | None:
        """Steps per second, or None without two frames (or, given ``now``, when the
        last frame is older than the window: nothing is running)."""
        if len(self._samples) < 2:
            return None
        first, last = self._samples[0][0], self._samples[-1][0]
        if now is not None and now - last > self.window:
            return None
        if last <= first:
            return None
        return self._sum / (last - first)

    def clear(self) -> None:
        self._samples.clear()
        self._sum = 0


@dataclass
class _Track:
    key: int
    t: float
    y: np.ndarray
    run: object | None = None
    done: bool = False
    target: float | None = None  # paced playback: the simulated time due by this frame
    run_steps: int = 0  # totals of the current run at its last block
    run_evaluations: int = 0
    seconds_per_step: float = 0.0
    stride: int = 1  # steps per state sampled (``_adapt_stride``)
    tokens: float = math.nan  # rows the store may take now (token bucket)
    refilled: float = 0.0
    cut: bool = False  # rows were left out since the last one handed over
    fresh: bool = True  # its run is new: its first block is handed over whatever the bucket
    owed_steps: int = 0  # counts of blocks not handed over yet
    owed_evaluations: int = 0
    owed_events: list = dataclasses.field(default_factory=list)
    origin: tuple[float, np.ndarray] | None = None  # where its first run began
    envelope: Envelope | None = None  # bins of H not handed over yet
    momenta: Envelope | None = None  # bins of the conserved momenta not handed over yet
    H0: float = math.nan  # H at ``origin``
    summed: bool | None = None  # H of the steps so far was summed up (None: never yet)
    withheld: tuple | None = None  # the last chunk whose states waited for the row budget


def default_runs() -> Callable:
    """``systems.simulation.Run`` (imported on first use)."""
    from systems.simulation import Run

    return Run


def arc_keep(
    t: np.ndarray,
    y: np.ndarray,
    before: np.ndarray | None,
    resolution: float,
    before_t: float | None = None,
) -> np.ndarray:
    """Which states to keep so that kept neighbours stay close along the curve.

    Each coordinate is measured in units of its range over the block about its linear
    trend (an angle that keeps turning is measured by its wobble, not by how far it
    went); a state is kept when the path since the last kept one has grown past a
    multiple of ``1 / resolution``, and the last state always, and both states of a jump
    (two at one time: an impact). A block too short to have a size is kept whole.

    Parameters
    ----------
    t : ndarray, shape (k,)
    y : ndarray, shape (k, m)
    before : ndarray, shape (m,), or None
        The state before the block (the last one kept).
    resolution : float
    before_t : float, optional
        The time of ``before``: a first row at that time with another state is the other
        side of a jump, and kept.

    Returns
    -------
    ndarray of bool, shape (k,)
    """
    k = len(t)
    keep = np.ones(k, dtype=bool)
    if k < 3 or not np.isfinite(y).all():
        return keep
    # both rows of an impact (arriving, leaving, at one time): the jump, not a chord
    jump = np.flatnonzero(t[1:] == t[:-1])
    leaving = before is not None and t[0] == before_t and not np.array_equal(y[0], before)
    # the size of each coordinate about its trend, from at most ~1000 of the states
    sample = slice(None, None, max(1, k // 1024))
    ts, ys = t[sample], y[sample]
    with np.errstate(over="ignore", invalid="ignore"):  # states that blew up: told below
        dt = ts - ts.mean()
        spread = float((dt * dt).sum())
        centred = ys - ys.mean(axis=0)
        slope = (dt[:, None] * centred).sum(axis=0) / spread if spread > 0 else 0.0 * centred[0]
        residual = centred - dt[:, None] * slope
        size = residual.max(axis=0) - residual.min(axis=0)
        scale = np.abs(ys).max(axis=0) + size
    if not (np.isfinite(size).all() and np.isfinite(scale).all()):
        return keep  # too large to measure (a run blowing up, stopped after this block)
    used = np.flatnonzero(size > 1e-9 * np.maximum(scale, 1e-300))
    if not len(used):
        return keep
    previous = y[0] if before is None or not np.isfinite(before).all() else before
    squares = np.zeros(k)
    with np.errstate(over="ignore", invalid="ignore"):  # steps past 1e308: infinite, kept
        for j in used:  # column by column: no (k, m) temporaries
            column = y[:, j]
            step = np.empty(k)
            step[0] = column[0] - previous[j]
            np.subtract(column[1:], column[:-1], out=step[1:])
            step *= resolution / size[j]
            squares += step * step
    mark = np.floor(np.cumsum(np.sqrt(squares, out=squares)))
    keep[0] = mark[0] >= 1
    keep[1:] = mark[1:] > mark[:-1]
    keep[-1] = True
    keep[jump] = keep[jump + 1] = True
    keep[0] |= leaving
    return keep


def _diagnostics(compiled, wanted, t: np.ndarray, y: np.ndarray) -> dict:
    """The ``wanted`` diagnostics of the states (t, y), NaN in gap rows."""
    out: dict[str, np.ndarray] = {}
    if compiled is None or not wanted or not len(t):
        return out
    real = np.isfinite(y).all(axis=1)
    for name in wanted:
        function = DIAGNOSTIC_FUNCTIONS.get(name)
        if function is None or function not in getattr(compiled, "wanted", ()):
            continue
        with np.errstate(all="ignore"):
            values = np.asarray(getattr(compiled, function)(t[real], y[real]), dtype=float)
        full = np.full((len(t), *values.shape[1:]), np.nan)
        full[real] = values
        out[name] = full
    return out


class _Receipt(QObject):
    """Lives in the GUI thread: counts the frames the GUI's event loop has taken."""

    def __init__(self, wake: threading.Event):
        super().__init__()
        self.taken = 0
        self._wake = wake

    @Slot(object)
    def take(self, _frame) -> None:
        self.taken += 1
        self._wake.set()


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
        ``advance(seconds, until) -> Block`` (a dataclass) and ``finished``.

    Attributes
    ----------
    frames : int
        Frames emitted.
    iterations : int
        Turns of the loop (each looks at the commands once).
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
        self._wake = threading.Event()
        self._abort = False
        self._paused = False
        self._steps_requested = 0
        self._tracks: dict[int, _Track] = {}
        self._pending: list[_Track] = []
        self._removed: set[int] = set()
        self._restart = False
        self._changed = False  # a command waits for the loop (read without the lock)
        self._made_run = False  # a run was made in this turn of the loop
        self._receipt = _Receipt(self._wake)  # in the creating (GUI) thread
        self._connected = False
        self._quantities: list | None = None  # the conserved momenta (``_want_momenta``)
        self._want_momenta(settings)
        self.frames = 0
        self.iterations = 0

    # -- called from the GUI thread --------------------------------------------------------

    def add_trajectory(self, key: int, y0: np.ndarray, t0: float = 0.0) -> None:
        with self._lock:
            self._pending.append(_Track(key, float(t0), np.array(y0, dtype=float)))
            self._changed = True
        self._wake.set()

    def remove_trajectory(self, key: int) -> None:
        with self._lock:
            self._removed.add(key)
            self._changed = True
        self._wake.set()

    def _want_momenta(self, settings: RunSettings) -> None:
        """Make the conserved momenta's functions here, in the GUI thread, once they are
        wanted (``explorer.envelope.MOMENTA``)."""
        if self._quantities is None and MOMENTA in settings.diagnostics:
            try:
                self._quantities = conserved_quantities(self.compiled)
            except Exception:  # noqa: BLE001 - no envelope: the plot draws the rows
                self._quantities = []

    def set_settings(self, settings: RunSettings) -> None:
        """New settings; runs restart from their current states unless only the pacing
        (speed, frame time, rows) or the diagnostics changed."""
        self._want_momenta(settings)
        with self._lock:
            if settings.run_options() != self._settings.run_options():
                self._restart = True  # applied by the worker thread, between chunks
            self._changed = True  # a paced wait ends: the new speed applies at once
            self._settings = settings
        self._wake.set()

    @property
    def settings(self) -> RunSettings:
        return self._settings

    def pause(self) -> None:
        self._paused = True
        self._wake.set()

    def resume(self) -> None:
        self._paused = False
        self._wake.set()

    @property
    def paused(self) -> bool:
        return self._paused

    @property
    def tracked(self) -> tuple[int, ...]:
        """Keys of the trajectories the loop integrates, as of its last look at the
        commands."""
        with self._lock:
            return tuple(self._tracks)

    def step(self) -> None:
        """While paused: advance one frame (at full speed, one frame of 1x: the first
        step at or past ``frame_seconds`` of simulated time)."""
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
            if not self._connected:
                # connected last, so its slot runs after every consumer's: a frame counts
                # as taken once the GUI has handled it
                self.blocks_ready.connect(self._receipt.take)
                self._connected = True
            self._loop()
        except Exception as exc:  # noqa: BLE001 - reported to the GUI, never lost
            self.failed.emit(f"{type(exc).__name__}: {exc}")
        finally:
            self.finished.emit()

    def _loop(self) -> None:
        if self._runs is None:
            self._runs = default_runs()
        while not self._abort:
            self.iterations += 1
            self._take_changes()
            stepping = False
            if self._paused:
                with self._lock:
                    stepping = self._steps_requested > 0
                    self._steps_requested = max(0, self._steps_requested - 1)
                if not stepping:
                    self._flush_withheld()
                    self._idle(0.05)
                    continue
            active = [track for track in self._tracks.values() if not track.done]
            if not active:
                self._idle(0.05)
                continue
            start = time.perf_counter()
            settings = self._settings
            paced = math.isfinite(settings.speed)
            if stepping:
                for track in active:
                    track.target = None  # a single step always moves
                if not paced:
                    # one frame of 1x, whatever the speed: at full speed a chunk's steps
                    # are planned for its wall time (tens of time units)
                    settings, paced = settings.with_(speed=1.0), True
            chunks = self._frame(active, settings, paced, start)
            blocks = []
            for track in active:
                block = self._hand_over(track, chunks.get(track.key, []), settings, len(active))
                if block is not None:
                    blocks.append((track.key, block))
            self._emit(blocks, start)
            if paced:
                self._wait_out(start + settings.frame_seconds)

    def _emit(self, blocks: list, start: float) -> None:
        """Send a frame of ``blocks`` (if any) once the GUI has room for it."""
        ready = time.perf_counter()
        if blocks and not self._abort:
            self._wait_for_room()
            if not self._abort:
                self.frames += 1
                frame = Frame(
                    self.generation,
                    tuple(blocks),
                    ready - start,
                    self.iterations,
                    time.perf_counter(),
                    ready,
                )
                self.blocks_ready.emit(frame)

    def _flush_withheld(self) -> None:
        """Paused: hand over the latest states of the runs whose last chunks waited for
        the row budget, so that what is shown is where the runs are (a single step then
        moves on from there, not from where the last rows handed over were)."""
        start = time.perf_counter()
        blocks = []
        for track in list(self._tracks.values()):
            if track.withheld is not None:
                block, before, _, _ = track.withheld
                chunk = (block, before, 0, 0)
                handed = self._hand_over(track, [chunk], self._settings, len(self._tracks), True)
                if handed is not None:
                    blocks.append((track.key, handed))
        self._emit(blocks, start)

    def _interrupted(self) -> bool:
        return self._abort or self._paused or self._changed

    def _frame(self, active: list[_Track], settings: RunSettings, paced: bool, start: float):
        """The chunks of this frame, per trajectory key: one chunk each at full speed; at a
        finite speed, chunks until each trajectory reaches the time due (or the frame's
        time is spent, or a command waits). At most one new run is made per turn (making
        one costs tens of ms: the default step is probed), so a restart of many orbits
        never keeps the loop from its commands."""
        chunks: dict[int, list] = {}
        share = min(settings.frame_seconds, CHUNK_SECONDS) / len(active)
        self._made_run = False
        if not paced:
            for track in active:
                if self._abort:
                    break
                track.target = None  # paced playback, when it comes back, starts from here
                chunk = self._chunk(track, settings, share, math.inf)
                if chunk is not None:
                    chunks.setdefault(track.key, []).append(chunk)
            return chunks
        frame = settings.speed * settings.frame_seconds
        due = []
        for track in active:
            # simulated time falls due at speed x wall time; a step longer than a frame's
            # share is taken only once it is due, and a machine that falls behind does not
            # pile up a debt of more than two frames
            goal = track.t if track.target is None else track.target
            track.target = min(goal + frame, track.t + 2 * frame)
            if track.t < track.target:
                due.append(track)
        deadline = start + settings.frame_seconds
        first = True
        while due and not self._abort:
            if not first and (self._interrupted() or time.perf_counter() > deadline):
                break
            first = False
            for track in due:
                chunk = self._chunk(track, settings, share, track.target)
                if chunk is not None:
                    chunks.setdefault(track.key, []).append(chunk)
            due = [t for t in due if t.run is not None and not t.done and t.t < (t.target or 0.0)]
        return chunks

    def _chunk(self, track: _Track, settings: RunSettings, seconds: float, until: float):
        """One ``advance`` of the track's run: (block, (t, state) before, steps, evaluations),
        None if there is nothing to do (or its run is to be made next turn)."""
        if track.run is None:
            if track.t >= settings.t_end:
                track.done = True
                return None
            if self._made_run:
                return None
            self._made_run = True
            if track.origin is None:
                track.origin = (track.t, track.y)
            # a restart (another method or step) probes from where the orbit began: that
            # probe is remembered, one from here would cost tens of ms while a click waits
            track.run = self._runs(
                self.compiled,
                y0=track.y,
                t0=track.t,
                probe_start=track.origin,
                **settings.run_options(),
            )
            track.run_steps = track.run_evaluations = 0
            track.fresh = True
        if "H" in settings.diagnostics:
            track.stride = 1  # H is summed up at every step (``_sum_up``)
        if track.seconds_per_step > 0:
            # the states sampled (one every ``stride`` steps) stay under max_points
            points = min(settings.max_points, FINE_VALUES // (len(track.y) + 1))
            seconds = min(seconds, 0.8 * points * track.stride * track.seconds_per_step)
            if hasattr(track.run, "max_points"):
                steps = seconds / track.seconds_per_step
                planned = getattr(track.run, "nsteps", None)
                if isinstance(planned, int):
                    # a run takes the steps it planned from its last block, whatever
                    # ``seconds`` says now (a block slowed by the GUI thread holding the
                    # GIL plans few, the next is fast): keep every ``stride``-th of them,
                    # and plan no more than fit, or the run would stride further itself
                    # and join states a good part of an orbit apart (chords)
                    steps = max(1, min(planned, int(points * track.stride)))
                    track.run.nsteps = steps
                track.run.max_points = int(min(points, steps / track.stride + 2))
        before = (track.t, track.y)
        started = time.perf_counter()
        block = track.run.advance(seconds, until)
        elapsed = time.perf_counter() - started
        steps = int(block.steps)
        evaluations = int(block.rhs_evaluations)
        if steps >= track.run_steps:
            steps, track.run_steps = steps - track.run_steps, steps
        if evaluations >= track.run_evaluations:
            evaluations, track.run_evaluations = (
                evaluations - track.run_evaluations,
                evaluations,
            )
        if steps > 0:
            track.seconds_per_step = elapsed / steps
        self._sum_up(track, block, before, settings)
        self._follow(track, block)
        if track.run.finished:
            track.done = True
        return block, before, steps, evaluations

    def _sum_up(self, track: _Track, block, before, settings: RunSettings) -> None:
        """Sum up H at every state of ``block`` in bins (``explorer.envelope``), owed to
        the store with the rows; from the state ``before`` too when the steps before it
        were not summed up (the start, or after H was not wanted: a gap)."""
        compiled = self.compiled
        if (
            "H" not in settings.diagnostics
            or compiled is None
            or "hamiltonian" not in getattr(compiled, "wanted", ())
        ):
            if track.summed:
                track.summed = False
            return
        t = np.asarray(block.t, dtype=float)
        if not len(t):
            return
        y = np.asarray(block.y, dtype=float).reshape(len(t), -1)
        t0, y0 = track.origin if track.origin is not None else before
        with np.errstate(all="ignore"):
            if not math.isfinite(track.H0):
                track.H0 = float(compiled.hamiltonian(t0, np.asarray(y0)[None, :])[0])
            if not track.summed:
                t = np.concatenate([[before[0]], t])
                y = np.concatenate([np.asarray(before[1], dtype=float)[None, :], y])
            H = compiled.hamiltonian(t, y)
        exponent = bin_exponent(float(t[-1]) - t0)
        bins = summarize(t, H, t0, track.H0, exponent)
        if len(bins) and track.summed is False:
            bins[0, GAP] = 1.0
        if track.envelope is None:
            track.envelope = Envelope(capacity=1 << 20)
        track.envelope.add(exponent, bins)
        quantities = self._quantities if MOMENTA in settings.diagnostics else None
        if quantities:
            with np.errstate(all="ignore"):
                values = np.stack([np.asarray(f(t, y), dtype=float) for _, f in quantities], axis=1)
            bins = summarize_series(t, values, t0, exponent)
            if len(bins) and track.summed is False:
                bins[0, -1] = 1.0
            if track.momenta is None:
                track.momenta = Envelope(capacity=1 << 20, quantities=len(quantities))
            track.momenta.add(exponent, bins)
        track.summed = True

    def _hand_over(
        self, track: _Track, chunks: list, settings: RunSettings, count: int, flush: bool = False
    ):
        """The block the store gets for this frame (None: nothing, or it waits).

        The chunks' states are thinned along the curve (``arc_keep``) from the newest
        back, only as far as the token bucket lets rows through: past it, the newest part
        goes after a gap row, and when the bucket holds less than ``MIN_FRAGMENT`` rows
        the frame's states wait out (their counts and section crossings never do), unless
        they all fit and either follow on from the last rows handed over or are paced
        playback, or the run is new (a launch or a change of method shows at once), or the
        worker is paused. ``flush``: the chunks waited before (their counts and crossings
        are owed already); they go over now.
        """
        if not chunks:
            return None
        last = chunks[-1][0]
        if not flush:
            track.owed_steps += sum(c[2] for c in chunks)
            track.owed_evaluations += sum(c[3] for c in chunks)
            for block, _, _, _ in chunks:
                events_t = getattr(block, "events_t", None)
                if events_t is not None and len(events_t):
                    track.owed_events.append((np.asarray(events_t), np.asarray(block.events_y)))
        track.withheld = None
        now = time.perf_counter()
        rate = settings.rows_per_second / count
        burst = max(rate * BURST_SECONDS, MIN_FRAGMENT)
        if math.isnan(track.tokens):
            track.tokens, track.refilled = burst, now
        track.tokens = min(burst, track.tokens + rate * (now - track.refilled))
        track.refilled = now
        sampled = sum(len(block.t) for block, _, _, _ in chunks)
        fresh, track.fresh = track.fresh, False
        paced = math.isfinite(settings.speed)
        # after a gap, a fragment waits until it can be long enough to show the motion;
        # paced playback hands its few rows over at once (they fit)
        cut = track.cut and not paced
        short = track.tokens < MIN_FRAGMENT and (cut or sampled > track.tokens)
        if short and not fresh and last.status == "running" and not (flush or self._paused):
            track.cut = True
            track.withheld = chunks[-1]
            return None  # this frame's states are left out; the counts wait
        room = max(int(track.tokens), 1)
        parts = []
        rows = 0
        for index in range(len(chunks) - 1, -1, -1):
            block, before, _, _ = chunks[index]
            t = np.asarray(block.t, dtype=float)
            y = np.asarray(block.y, dtype=float).reshape(len(t), -1)
            keep = arc_keep(t, y, before[1], ARC_RESOLUTION, before_t=before[0])
            self._adapt_stride(track, keep, every_step="H" in settings.diagnostics)
            parts.append((t[keep], y[keep]))
            rows += int(keep.sum())
            if rows >= room:
                track.cut = track.cut or index > 0
                break
        t = np.concatenate([p[0] for p in reversed(parts)])
        y = np.concatenate([p[1] for p in reversed(parts)])
        if len(t) > room:
            t, y = t[len(t) - room :], y[len(t) - room :]
            track.cut = True
        track.tokens -= len(t)
        if track.cut and len(t):
            t = np.concatenate([t[:1], t])
            y = np.concatenate([np.full((1, y.shape[1]), np.nan), y])
            track.cut = False
        fields = {f.name for f in dataclasses.fields(last)}
        diagnostics = _diagnostics(self.compiled, settings.diagnostics, t, y)
        if track.envelope is not None and len(track.envelope):
            diagnostics["envelope"] = track.envelope
            track.envelope = None
        if track.momenta is not None and len(track.momenta):
            diagnostics["momenta_envelope"] = track.momenta
            track.momenta = None
        changes = dict(
            t=t,
            y=y,
            diagnostics=diagnostics,
            steps=track.owed_steps,
            rhs_evaluations=track.owed_evaluations,
        )
        if "events_t" in fields:
            events = track.owed_events
            m = y.shape[1]
            changes["events_t"] = np.concatenate([e[0] for e in events]) if events else np.empty(0)
            changes["events_y"] = (
                np.concatenate([e[1].reshape(-1, m) for e in events])
                if events
                else np.empty((0, m))
            )
        track.owed_steps = track.owed_evaluations = 0
        track.owed_events = []
        return replace(last, **changes)

    @staticmethod
    def _adapt_stride(track: _Track, keep: np.ndarray, every_step: bool = False) -> None:
        """Sample every ``stride``-th step while the curve keeps at most one state in
        ``OVERSAMPLING``: cheap steps are not all copied out only to be thinned. Every
        step while H is summed up (a few per cent of the stepping)."""
        if every_step:
            track.stride = 1
            return
        sampled = len(keep)
        if sampled < 64:
            return
        kept = max(int(keep.sum()), 1)
        if kept * OVERSAMPLING * 2 < sampled:
            track.stride = min(track.stride * 2, MAX_STRIDE)
        elif kept * OVERSAMPLING > sampled:
            track.stride = max(track.stride // 2, 1)

    def _wait_for_room(self) -> None:
        """Wait until fewer than ``MAX_IN_FLIGHT`` frames are on their way to the GUI
        (at most ``ACK_SECONDS``, and never past an abort); commands that come meanwhile
        are taken at once."""
        give_up = time.perf_counter() + ACK_SECONDS
        while self.frames - self._receipt.taken >= MAX_IN_FLIGHT and not self._abort:
            left = give_up - time.perf_counter()
            if left <= 0:
                break
            self._wake.wait(min(left, 0.05))
            self._wake.clear()
            if self._changed:
                self._take_changes()

    def _idle(self, seconds: float) -> None:
        if seconds > 0 and not self._abort:
            self._wake.wait(seconds)
            self._wake.clear()

    def _wait_out(self, deadline: float) -> None:
        """Paced playback: wait until ``deadline`` (``time.perf_counter()``), or until a
        command comes. The GUI taking a frame wakes the loop too (so that a full-speed
        loop waiting for room goes on at once); here that must not end the wait, or the
        frames, and with them the simulated time, would come as fast as the GUI takes
        them instead of once per frame time."""
        while not self._interrupted():
            left = deadline - time.perf_counter()
            if left <= 0:
                return
            self._wake.wait(left)
            self._wake.clear()

    def _take_changes(self) -> None:
        with self._lock:
            self._changed = False
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

    @staticmethod
    def _follow(track: _Track, block) -> None:
        if len(block.t):
            track.t = float(block.t[-1])
            track.y = np.array(block.y[-1], dtype=float)
        if block.status not in ("running", "ok"):  # one of simulation.PROBLEMS
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

    def stop(self, timeout: float = STOP_SECONDS) -> bool:
        """Abort the loop and wait up to ``timeout`` seconds for the thread to end.

        The loop checks for abort between blocks of about 30 ms (compiled steps release
        the GIL; nothing is ever raised into the thread). A thread still running at the
        end is kept referenced until it ends (a ``QThread`` destroyed while running
        aborts the process); its frames carry an old generation and are ignored. Returns
        whether it ended.
        """
        self.worker.abort()
        self.thread.quit()
        if self.thread.wait(round(1000 * max(0.0, timeout))):
            return True
        keep_until_finished(self.thread)
        return False

    @property
    def running(self) -> bool:
        return self.thread.isRunning()
