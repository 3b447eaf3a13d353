"""Derivation and compilation off the GUI thread.

The editor (or the catalogue) sends a scene, as TOML text or as a ``Scene``. A worker
process (``systems.processes``) reads it, derives the mechanics and writes the system's
functions as LLVM IR, limited in CPU time; the builder thread (a ``QThread`` that only
waits for it) then turns that IR into machine code, milliseconds of LLVM, and sends
back a ``Built`` value or a ``BuildFailure`` with the field and position of the problem.
Requests are numbered: a request overtaken by a newer one is skipped, and only the
newest result is delivered, so typing fast never shows a stale system.

The derivation's layout runs in worker processes too, after the window has drawn the
new system's first frame: the derivation with its equations in LaTeX
(``systems.typeset``, shown at once as text), then their glyphs set in type, then the
equilibrium search. A newer
request or ``BuildService.stop`` ends the processes still working for an older one: no
thread of the window ever runs sympy, and nothing is interrupted but a process.
"""

from __future__ import annotations

import math
import threading
import time
from dataclasses import dataclass

from PySide6.QtCore import QObject, QThread, Signal, Slot

from explorer.worker import keep_until_finished
from systems import processes
from systems.report import equilibria_lines
from systems.sources import build_code, derive_source, wants_for
from systems.typeset import typeset_as_text as describe
from systems.typeset import with_outlines

STOP_SECONDS = 0.8
"""How long ``BuildService.stop`` may take: closing the window must take under a second."""


@dataclass(frozen=True)
class Built:
    """A scene ready to run: its compiled system and the automatic method choice."""

    request: int
    scene: object
    compiled: object
    method: str
    reason: str
    seconds: float


@dataclass(frozen=True)
class BuildFailure:
    """Why a scene could not be built, where the physics core says it went wrong."""

    request: int
    message: str
    field: str | None = None
    position: int | None = None
    reason: str = ""


def compile_built(
    mechanics, request: int = 0, start: float | None = None, code=None, t_end: float = math.inf
) -> Built:
    """Compile a derived system for the window and choose its method.

    The system's functions become machine code here, in milliseconds (from ``code``,
    ``systems.sources.build_code``'s, written in a worker; written here when None), and
    the chosen method's driver is loaded (compiled once per installation, ``python
    main.py warm``), so the first block comes in machine code.
    """
    from systems.compiled import load_system, system_code
    from systems.integrators import choose_method
    from systems.integrators.measured import measured_choice
    from systems.simulation import DIAGNOSTICS, precompile
    from systems.start_check import check_start

    start = time.perf_counter() if start is None else start
    method, reason = choose_method(mechanics)
    wants = wants_for(mechanics)
    if code is None:
        code = system_code(mechanics, wants)
    compiled = load_system(mechanics, code)
    check_start(compiled)
    # the window's run is endless (``t_end``): the measured choice keeps a symplectic
    # method there; a finite run (an export) is priced over its length, as `run` is
    method, reason = measured_choice(compiled, method, reason, 0.0, compiled.initial_state(), t_end)
    diagnostics = [d for d, want in DIAGNOSTICS.items() if want in wants]
    precompile(compiled, method, diagnostics=diagnostics)
    return Built(request, mechanics.scene, compiled, method, reason, time.perf_counter() - start)


def build(source, request: int = 0, t_end: float = math.inf) -> Built:
    """Read, derive and compile in this process (the command line, a sweep, tests), for a
    run to ``t_end`` (the method's choice is measured over it)."""
    start = time.perf_counter()
    return compile_built(derive_source(source), request, start, t_end=t_end)


FIRST_FRAME_WAIT = 10.0
"""Seconds the builder waits at most for the window's first frame of a new system before
laying out its derivation (the window says at once when none is coming: paused, or the
run failed): on two cores the layout's processes would compete with the first blocks."""

LAYOUT_SECONDS = 30.0
"""CPU seconds each part of a layout may take in its worker (the readable derivation; the
equilibrium search, which has its own limit within)."""


def _remaining(deadline: float) -> float:
    return max(0.0, deadline - time.monotonic())


def failure_from(exc: Exception, request: int) -> BuildFailure:
    return BuildFailure(
        request=request,
        message=str(exc),
        field=getattr(exc, "field", None),
        position=getattr(exc, "position", None),
        reason=getattr(exc, "reason", str(exc)),
    )


class _Layout:
    """The layout of one build: its thread, and the worker job it waits for."""

    def __init__(self):
        self.stopped = threading.Event()
        self.job: processes.Job | None = None
        self.thread: threading.Thread | None = None

    def stop(self) -> None:
        self.stopped.set()
        job = self.job
        if job is not None:
            job.cancel()


class _BuildWorker(QObject):
    """Builds in the builder thread; lays out what a build derived in a layout thread.

    Both only wait for worker processes (and compile, in the builder thread): a newer
    request or ``stop`` ends those processes, and the waiting threads go on at once.
    """

    built = Signal(object)
    build_failed = Signal(object)
    described = Signal(int, object)
    equilibria_found = Signal(int, list)

    def __init__(self):
        super().__init__()
        self.latest = 0
        self.stopped = False
        self._lock = threading.Lock()
        self._job: processes.Job | None = None  # the derivation in progress
        self._layouts: list[_Layout] = []
        self.first_frame = threading.Event()

    @Slot(object)
    def build(self, job) -> None:
        request, source = job
        if request < self.latest or self.stopped:
            return  # overtaken by a newer request while waiting
        self.stop_layouts()
        start = time.perf_counter()
        try:
            mechanics, code = self._derive(source)
        except processes.Cancelled:
            return  # the window closed: nobody waits for this build any more
        except Exception as exc:  # noqa: BLE001 - shown to the user, never lost
            self.build_failed.emit(failure_from(exc, request))
            return
        if request < self.latest or self.stopped:
            return
        try:
            result = compile_built(mechanics, request, start, code)
        except Exception as exc:  # noqa: BLE001 - shown to the user, never lost
            self.build_failed.emit(failure_from(exc, request))
            return
        layout = _Layout()
        layout.thread = threading.Thread(
            target=self._lay_out, args=(request, result, layout), name="scene-layout", daemon=True
        )
        with self._lock:
            # checked with the list under the lock: a window closed while this build
            # compiled (stop) must neither miss the layout nor have its first frame undone
            # (the layout then waited FIRST_FRAME_WAIT for a frame that never came)
            if request < self.latest or self.stopped:
                return
            self.first_frame.clear()
            self._layouts = [old for old in self._layouts if old.thread.is_alive()]
            self._layouts.append(layout)
        self.built.emit(result)
        layout.thread.start()

    def _derive(self, source):
        from systems.cpu_limit import limit_seconds

        job = processes.Job(
            build_code,
            (source,),
            # the derivation's and the writing's own limits (limit_seconds) report an
            # overrun; this one is their backstop, and bounds reading the scene too
            cpu_seconds=3 * limit_seconds() + 5.0,
            what="reading and deriving the scene",
        )
        with self._lock:
            self._job = job
        if self.stopped:
            job.cancel()
        try:
            return job.result()
        finally:
            with self._lock:
                self._job = None

    def stop(self) -> list[threading.Thread]:
        """End the derivation and every layout in progress; returns the layout threads."""
        with self._lock:
            self.stopped = True
            job = self._job
        if job is not None:
            job.cancel()
        threads = self.stop_layouts()
        self.first_frame.set()  # a layout waiting for the first frame goes on, and ends
        return threads

    def stop_layouts(self) -> list[threading.Thread]:
        """End the layouts of older builds (their processes); returns their threads."""
        with self._lock:
            layouts, self._layouts = self._layouts, []
        for layout in layouts:
            layout.stop()
        return [layout.thread for layout in layouts if layout.thread is not None]

    def _lay_out(self, request: int, result: Built, layout: _Layout) -> None:
        # the motion first: on two cores the layout's processes would slow the first frame
        self.first_frame.wait(FIRST_FRAME_WAIT)
        mechanics = result.compiled.mechanics
        typeset = self._part(layout, describe, mechanics, "laying out the derivation")
        if typeset is None or request < self.latest:
            return
        if isinstance(typeset, Exception):
            typeset = f"(the derivation could not be laid out: {typeset})"
        self.described.emit(request, typeset)
        if not isinstance(typeset, str):
            typeset = self._part(layout, with_outlines, typeset, "setting the equations in type")
            if typeset is None or request < self.latest:
                return
            if not isinstance(typeset, Exception):  # else they stay shown as text
                self.described.emit(request, typeset)
        lines = self._part(layout, equilibria_lines, mechanics, "the equilibrium search")
        if lines is None or request < self.latest:
            return
        if isinstance(lines, Exception):
            lines = [f"equilibria not found: {lines}"]
        self.equilibria_found.emit(request, lines)

    @staticmethod
    def _part(layout: _Layout, function, value, what: str):
        """``function(value)`` in a worker: its result, its exception, or None if the
        layout was stopped."""
        if layout.stopped.is_set():
            return None
        job = processes.Job(function, (value,), cpu_seconds=LAYOUT_SECONDS, what=what)
        layout.job = job
        if layout.stopped.is_set():
            job.cancel()
        try:
            return job.result()
        except processes.Cancelled:
            return None
        except Exception as exc:  # noqa: BLE001 - the derivation itself succeeded
            return exc


class BuildService(QObject):
    """Builds scenes in a background thread; delivers only the newest request's result.

    Signals
    -------
    built(Built)
    build_failed(BuildFailure)
    described(int, object)   the derivation of a built request, a ``Typeset`` (arrives
        later: first with its equations as text, then again set in type), or a text
        saying why it could not be laid out
    equilibria_found(int, list)   its equilibria, one sentence each (arrives last)
    busy_changed(bool)
    """

    built = Signal(object)
    build_failed = Signal(object)
    described = Signal(int, object)
    equilibria_found = Signal(int, list)
    busy_changed = Signal(bool)
    _requested = Signal(object)

    def __init__(self, parent: QObject | None = None):
        super().__init__(parent)
        self._counter = 0
        self._stopped = False
        self._warm_thread: threading.Thread | None = None
        # no fork server yet: a scene derived before is built from the disk in this
        # process (``build_code.from_cache``), and the server's imports (0.9 s of CPU)
        # are paid by the first job the disk cannot answer
        self._thread = QThread()
        self._thread.setObjectName("scene-builder")
        self._worker = _BuildWorker()
        self._worker.moveToThread(self._thread)
        self._requested.connect(self._worker.build)
        self._worker.built.connect(self._on_worker_built)
        self._worker.build_failed.connect(self._on_worker_build_failed)
        self._worker.described.connect(self._on_worker_described)
        self._worker.equilibria_found.connect(self._on_worker_equilibria_found)
        self._thread.start()

    def frame_shown(self) -> None:
        """The window drew a frame: the builder may go on to lay out the derivation.

        Numba's own half-second start-up begins then too (once per process), so that a
        scene opened later loads its cached machine code at once; started earlier, it
        held the GIL while the first scene was getting ready to draw.
        """
        from systems.integrators.warmup import warm_in_background

        self._worker.first_frame.set()
        if not self._stopped:
            self._warm_thread = warm_in_background()

    @property
    def awaits_frame(self) -> bool:
        """True while the builder waits for the window to show a new system's motion."""
        return not self._worker.first_frame.is_set()

    def request(self, source) -> int:
        """Build ``source`` (TOML text or a ``Scene``); returns the request number.

        After ``stop`` nothing is built and 0 is returned.
        """
        if self._stopped:
            return 0
        self._counter += 1
        self._worker.latest = self._counter
        self._requested.emit((self._counter, source))
        self.busy_changed.emit(True)
        return self._counter

    @property
    def deriving(self) -> bool:
        """True while a worker process derives a requested scene."""
        job = self._worker._job
        return job is not None and not job.done()

    @property
    def latest(self) -> int:
        return self._counter

    def _on_worker_built(self, result: Built) -> None:
        if result.request == self._counter:
            self.busy_changed.emit(False)
            self.built.emit(result)

    def _on_worker_build_failed(self, failure: BuildFailure) -> None:
        if failure.request == self._counter:
            self.busy_changed.emit(False)
            self.build_failed.emit(failure)

    def _on_worker_described(self, request: int, derivation) -> None:
        if request == self._counter:
            self.described.emit(request, derivation)

    def _on_worker_equilibria_found(self, request: int, lines: list) -> None:
        if request == self._counter:
            self.equilibria_found.emit(request, lines)

    def stop(self, timeout: float = STOP_SECONDS) -> bool:
        """End the builder thread, its layout threads and their processes; no results
        after this.

        Returns True if every thread has ended within ``timeout`` seconds; one that has
        not (compiling, in C) is kept referenced until it ends.
        """
        deadline = time.monotonic() + timeout
        self._stopped = True
        self._counter += 1  # any result still on its way is now stale
        self._worker.latest = self._counter
        layouts = self._worker.stop()  # sets first_frame: a waiting layout goes on, ends
        stopped = True
        if self._thread.isRunning():
            self._thread.quit()
            if not self._thread.wait(round(1000 * _remaining(deadline))):
                keep_until_finished(self._thread)
                stopped = False
        for layout in layouts:
            layout.join(_remaining(deadline))
            stopped = stopped and not layout.is_alive()
        warm = self._warm_thread  # numba's warm-up is short and must not be interrupted
        if warm is not None:
            warm.join(_remaining(deadline))
            stopped = stopped and not warm.is_alive()
        return stopped
