"""Derivation and compilation off the GUI thread.

The editor (or the catalogue) sends a scene, as TOML text or as a ``Scene``; a worker in a
``QThread`` reads it, derives the mechanics and compiles the kernels, and sends back a
``Built`` value or a ``BuildFailure`` with the field and position of the problem. Requests
are numbered: a request overtaken by a newer one is skipped, and only the newest result
is delivered, so typing fast never shows a stale system.

``BuildService.stop`` does not wait for a build: it abandons the builder thread
(``systems.deadline.abandon``: sympy is pure Python, so a derivation ends within a few
bytecodes, wherever that is safe) and the layout threads likewise (a newer request only
cancels a layout: ``systems.deadline.cancel``, it stops at its next checkpoint, between
two lines of the derivation's layout or while it waits for the forked child in which the
equilibrium search runs ``sympy.solve``), kills those children, and returns within
``STOP_SECONDS``.
"""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass

from PySide6.QtCore import QObject, QThread, Signal, Slot

from explorer.worker import keep_until_finished
from systems.deadline import Abandoned, abandon, cancel, cancellable

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


def wants_for(mechanics) -> tuple[str, ...]:
    """What the GUI needs compiled: the right-hand side, H, velocities, drawing, T/V parts."""
    wants = ["rhs", "hamiltonian", "velocities"]
    scene = mechanics.scene
    if scene.drawing is not None and scene.drawing.points:
        wants.append("drawing")
    if mechanics.classification.separable and mechanics.separable_parts is not None:
        wants.append("separable")
    return tuple(wants)


def build(source, request: int = 0) -> Built:
    """Read (TOML text or the tables of one), derive and compile; raises the core's errors.

    A ``Scene`` is built as it is and TOML text is read strictly (``parse_scene``). A dict
    is the editor's document: it is read with ``drop_unfit=True``, so a drawing or
    ``[view]`` setting that does not fit the system is left out and listed in
    ``built.scene.warnings`` instead of failing the build.

    The system's functions are compiled (or loaded from numba's cache) here, a fraction
    of a second, and so is the chosen method's driver (compiled once per installation,
    ``python main.py warm``), so the first block comes in machine code.
    """
    from systems.compiled import compile_system
    from systems.integrators import choose_method
    from systems.mechanics import derive
    from systems.scene import Scene, parse_scene, scene_from_dict
    from systems.simulation import DIAGNOSTICS, precompile
    from systems.start_check import check_start

    start = time.perf_counter()
    if isinstance(source, Scene):
        scene = source
    elif isinstance(source, dict):  # the editor's document: what does not fit is left out
        scene = scene_from_dict(source, source="<editor>", drop_unfit=True)
    else:
        scene = parse_scene(source, source="<editor>")
    mechanics = derive(scene)
    method, reason = choose_method(mechanics)
    wants = wants_for(mechanics)
    compiled = compile_system(mechanics, wants)
    check_start(compiled)
    diagnostics = [d for d, want in DIAGNOSTICS.items() if want in wants]
    precompile(compiled, method, diagnostics=diagnostics)
    return Built(request, scene, compiled, method, reason, time.perf_counter() - start)


FIRST_FRAME_WAIT = 10.0
"""Seconds the builder waits at most for the window's first frame of a new system before
laying out its derivation (the window says at once when none is coming: paused, or the
run failed): laying out the derivation (sympy, holding the GIL) before the first block
of a large system made that block three times later."""


def _remaining(deadline: float) -> float:
    return max(0.0, deadline - time.monotonic())


def end_forked_children(deadline: float) -> bool:
    """Kill and reap this process's ``multiprocessing`` children; True if none is left.

    They are the bounded ``sympy.solve`` runs of the equilibrium search
    (``systems.textbook._numeric.run_bounded``), of the builder and of the Textbook dock;
    a killed one makes its ``run_bounded`` return None at once (no exact solutions), so
    the thread waiting for it goes on.
    """
    import multiprocessing

    children = multiprocessing.active_children()
    for child in children:
        child.kill()
    for child in children:
        child.join(max(0.05, _remaining(deadline)))
    return not any(child.is_alive() for child in children)


def end_left_limits(ident: int) -> None:
    """Stop the ``systems.deadline`` time limits a thread that has ended left armed.

    ``time_limit`` starts its watcher thread before it enters its ``try``; ``Abandoned``
    landing while ``Thread.start`` waits for the watcher to run skips the ``finally`` that
    would stop it. Left alone, the watcher would raise ``TimeUp`` into that thread id (a
    new thread may have it by then) every half second from its limit on, and the id
    would stay marked as inside a limit, so a new thread with it would run unlimited.
    A stopgap until ``systems.deadline`` arms the watcher inside its ``try``.
    """
    from systems import deadline

    for thread in threading.enumerate():
        limit = getattr(getattr(thread, "_target", None), "__self__", None)
        if isinstance(limit, deadline._Limit) and limit.ident == ident:
            limit.finish()
    deadline._active.pop(ident, None)


def _reap(child, deadline: float) -> None:
    if child.poll() is None:
        child.kill()
    try:
        child.wait(max(0.1, _remaining(deadline)))  # reaped: no zombie left behind
    except Exception:  # noqa: BLE001 - TimeoutExpired: the caller sees poll() is None
        pass


def failure_from(exc: Exception, request: int) -> BuildFailure:
    return BuildFailure(
        request=request,
        message=str(exc),
        field=getattr(exc, "field", None),
        position=getattr(exc, "position", None),
        reason=getattr(exc, "reason", str(exc)),
    )


def describe(mechanics) -> str:
    """The derivation laid out for a person (as ``derive`` prints it)."""
    from systems.report import readable

    return readable(mechanics, equilibria=False)  # they arrive apart (equilibria_found)


def equilibria_lines(mechanics) -> list[str]:
    """One sentence per equilibrium (virtual work), or why there are none."""
    from systems.report import equilibria_sentences

    lines, note = equilibria_sentences(mechanics, digits=4)
    if not lines:
        return [f"no equilibrium: {note}" if note else "no equilibrium found"]
    return lines


class _BuildWorker(QObject):
    """Builds in the builder thread; lays out what a build derived in a layout thread.

    The layout (the readable derivation, about a second of sympy printing, and the
    equilibrium search, up to ``SEARCH_SECONDS``) runs in its own thread, so that the next
    request is built at once; a newer request abandons the layout still running for an
    older one, whose results nobody would see.
    """

    built = Signal(object)
    build_failed = Signal(object)
    described = Signal(int, str)
    equilibria_found = Signal(int, list)

    def __init__(self):
        super().__init__()
        self.latest = 0
        self._lock = threading.Lock()
        self._ident: int | None = None  # the builder thread's, while a build runs
        self._layouts: list[threading.Thread] = []  # started, maybe still running
        self.first_frame = threading.Event()

    @Slot(object)
    def build(self, job) -> None:
        request, source = job
        if request < self.latest:
            return  # overtaken by a newer request while waiting
        self.abandon_layout()
        try:
            with cancellable():
                with self._lock:
                    self._ident = threading.get_ident()
                try:
                    self._build(request, source)
                finally:
                    with self._lock:
                        self._ident = None
        except Abandoned:
            pass  # the window closed: nobody waits for this build any more

    def abandon(self) -> int | None:
        """End the build in progress within a few bytecodes; returns the thread's ident
        if one was running. The layout thread is abandoned too.

        ``systems.deadline.abandon`` raises ``Abandoned`` only inside ``build``'s
        ``cancellable`` block, and only where the thread is interruptible.
        """
        self.abandon_layout(at_once=True)
        with self._lock:
            ident, self._ident = self._ident, None
            if ident is not None:
                abandon(ident)
            return ident

    def abandon_layout(self, *, at_once: bool = False) -> list[threading.Thread]:
        """Ask the layouts of older builds still running to stop at their next checkpoint
        (usually a fraction of a second away, up to seconds for a large system's
        accelerations); ``at_once`` (the window closing) abandons them as well, so that
        they end within a few bytecodes. Returns their threads."""
        with self._lock:
            self._layouts = [thread for thread in self._layouts if thread.is_alive()]
            for thread in self._layouts:
                (abandon if at_once else cancel)(thread)
            return list(self._layouts)

    def _build(self, request: int, source) -> None:
        from systems.expressions import ExpressionError
        from systems.mechanics import DerivationError
        from systems.scene import SceneError

        try:
            result = build(source, request)
        except (SceneError, ExpressionError, DerivationError, ValueError) as exc:
            self.build_failed.emit(failure_from(exc, request))
            return
        except Exception as exc:  # noqa: BLE001 - shown to the user, never lost
            self.build_failed.emit(failure_from(exc, request))
            return
        self.first_frame.clear()
        self.built.emit(result)
        # an older layout that has not reached a checkpoint while this build ran (a large
        # system's accelerations) would hold the GIL beside the new one: it ends now
        self.abandon_layout(at_once=True)
        layout = threading.Thread(
            target=self._lay_out, args=(request, result), name="scene-layout", daemon=True
        )
        with self._lock:
            self._layouts.append(layout)
        layout.start()

    def _lay_out(self, request: int, result: Built) -> None:
        try:
            with cancellable():
                if request < self.latest:  # overtaken before it could be asked to stop
                    return
                self._describe(request, result)
        except Abandoned:
            pass  # a newer request or the window closing: nobody waits for this layout

    def _describe(self, request: int, result: Built) -> None:
        # The derivation's pretty-printing holds the GIL for a second or so: let the
        # window draw the first frame of the new system before it (the motion first).
        self.first_frame.wait(FIRST_FRAME_WAIT)
        if request < self.latest:
            return
        try:
            text = describe(result.compiled.mechanics)
        except Exception as exc:  # noqa: BLE001 - the derivation itself succeeded
            text = f"(the derivation could not be laid out: {exc})"
        self.described.emit(request, text)
        if request < self.latest:
            return
        try:
            lines = equilibria_lines(result.compiled.mechanics)
        except Exception as exc:  # noqa: BLE001 - the derivation itself succeeded
            lines = [f"equilibria not found: {exc}"]
        self.equilibria_found.emit(request, lines)


class BuildService(QObject):
    """Builds scenes in a background thread; delivers only the newest request's result.

    Signals
    -------
    built(Built)
    build_failed(BuildFailure)
    described(int, str)   the readable derivation of a built request (arrives later)
    equilibria_found(int, list)   its equilibria, one sentence each (arrives last)
    busy_changed(bool)
    """

    built = Signal(object)
    build_failed = Signal(object)
    described = Signal(int, str)
    equilibria_found = Signal(int, list)
    busy_changed = Signal(bool)
    _requested = Signal(object)

    def __init__(self, parent: QObject | None = None):
        super().__init__(parent)
        self._counter = 0
        self._stopped = False
        self._warm_thread: threading.Thread | None = None
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

    def _on_worker_described(self, request: int, text: str) -> None:
        if request == self._counter:
            self.described.emit(request, text)

    def _on_worker_equilibria_found(self, request: int, lines: list) -> None:
        if request == self._counter:
            self.equilibria_found.emit(request, lines)

    def stop(self, timeout: float = STOP_SECONDS) -> bool:
        """End the builder thread and its layout threads; no results after this.

        The build in progress is abandoned, not waited for. Returns True if every thread
        and child process of the builder has ended within ``timeout`` seconds; a thread
        that has not (stuck in C code) is kept referenced until it ends.
        """
        deadline = time.monotonic() + timeout
        self._stopped = True
        self._counter += 1  # any result still on its way is now stale
        self._worker.latest = self._counter
        self._worker.first_frame.set()  # a builder waiting for the first frame goes on
        abandoned = self._worker.abandon()
        stopped = end_forked_children(deadline)
        if self._thread.isRunning():
            self._thread.quit()
            if not self._thread.wait(round(1000 * _remaining(deadline))):
                keep_until_finished(self._thread)
                stopped = False
        if abandoned is not None and not self._thread.isRunning():
            end_left_limits(abandoned)
        for layout in self._worker.abandon_layout(at_once=True):
            layout.join(_remaining(deadline))
            stopped = stopped and not layout.is_alive()
        warm = self._warm_thread  # numba's warm-up is short and must not be interrupted
        if warm is not None:
            warm.join(_remaining(deadline))
            stopped = stopped and not warm.is_alive()
        return stopped
