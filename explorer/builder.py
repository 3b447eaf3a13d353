"""Derivation and compilation off the GUI thread.

The editor (or the catalogue) sends a scene, as TOML text or as a ``Scene``; a worker in a
``QThread`` reads it, derives the mechanics and compiles the kernels, and sends back a
``Built`` value or a ``BuildFailure`` with the field and position of the problem. Requests
are numbered: a request overtaken by a newer one is skipped, and only the newest result
is delivered, so typing fast never shows a stale system.
"""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass

from PySide6.QtCore import QObject, QThread, Signal, Slot


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


def build(source, request: int = 0, *, interpreted_start: bool = False) -> Built:
    """Read (TOML text or the tables of one), derive and compile; raises the core's errors.

    With ``interpreted_start`` (the window), the kernels run as plain Python at once and
    numba compiles them in a child process (``systems.native_build``); otherwise (exports,
    sweeps, tests) numba compiles or loads every kernel the GUI calls before returning.
    """
    from systems.compiled import compile_system
    from systems.integrators import choose_method
    from systems.mechanics import derive
    from systems.native_build import compile_in_background
    from systems.scene import Scene, parse_scene, scene_from_dict
    from systems.simulation import DIAGNOSTICS, compile_natively
    from systems.start_check import check_start

    start = time.perf_counter()
    if isinstance(source, Scene):
        scene = source
    elif isinstance(source, dict):
        scene = scene_from_dict(source, source="<editor>")
    else:
        scene = parse_scene(source, source="<editor>")
    mechanics = derive(scene)
    method, reason = choose_method(mechanics)
    wants = wants_for(mechanics)
    compiled = compile_system(mechanics, wants, interpreted_start=interpreted_start)
    check_start(compiled)
    diagnostics = [d for d, want in DIAGNOSTICS.items() if want in wants]
    if interpreted_start:
        compile_in_background(compiled, method, diagnostics)
    else:
        compile_natively(compiled, method, diagnostics)
    return Built(request, scene, compiled, method, reason, time.perf_counter() - start)


FIRST_FRAME_WAIT = 1.0
"""Seconds the builder waits for the window's first frame before describing a system."""


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
    from explorer.commands.derive_cmd import readable

    return readable(mechanics, equilibria=False)  # they arrive apart (equilibria_found)


def equilibria_lines(mechanics) -> list[str]:
    """One sentence per equilibrium (virtual work), or why there are none."""
    from explorer.commands.derive_cmd import equilibria_sentences

    lines, note = equilibria_sentences(mechanics, digits=4)
    if not lines:
        return [f"no equilibrium: {note}" if note else "no equilibrium found"]
    return lines


class _BuildWorker(QObject):
    built = Signal(object)
    build_failed = Signal(object)
    described = Signal(int, str)
    equilibria_found = Signal(int, list)

    def __init__(self):
        super().__init__()
        self.latest = 0
        self._lock = threading.Lock()
        self.first_frame = threading.Event()

    @Slot(object)
    def build(self, job) -> None:
        request, source = job
        if request < self.latest:
            return  # overtaken by a newer request while waiting
        from systems.expressions import ExpressionError
        from systems.mechanics import DerivationError
        from systems.scene import SceneError

        try:
            result = build(source, request, interpreted_start=True)
        except (SceneError, ExpressionError, DerivationError, ValueError) as exc:
            self.build_failed.emit(failure_from(exc, request))
            return
        except Exception as exc:  # noqa: BLE001 - shown to the user, never lost
            self.build_failed.emit(failure_from(exc, request))
            return
        self.first_frame.clear()
        self.built.emit(result)
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
        warm_in_background()

    def request(self, source) -> int:
        """Build ``source`` (TOML text or a ``Scene``); returns the request number."""
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

    def stop(self) -> None:
        """End the thread (after the build in progress, if any); no results after this."""
        self._counter += 1  # any result still on its way is now stale
        self._worker.latest = self._counter
        if self._thread.isRunning():
            self._thread.quit()
            self._thread.wait()
