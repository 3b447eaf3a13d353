"""The Textbook tabs' background jobs, each in a worker process.

``TaskRunner.submit(key, function, *args, on_done=..., on_failed=...)`` runs
``function(*args)`` in a worker process of its own (``systems.processes``), under a CPU
limit of ``CPU_SECONDS``. A newer job with the same key supersedes an older one: the
older one's process is ended at once, whatever it is doing (no cancel token is passed:
a job runs with ``systems.textbook.jobs.NEVER``), and its result is never delivered.
Results and failures are delivered on the GUI thread through a queued signal; ``on_done``
gets the value, ``on_failed`` a one-line message. ``shutdown`` ends every worker and waits
(bounded) for the threads that wait for them.

A job's function is pickled by reference: it must be a module-level function of a module
that does not import Qt (``systems.textbook.jobs``), or the worker would import PySide6.
Its arguments and its value are pickled too.
"""

from __future__ import annotations

import itertools
import threading
import time
import traceback
from collections.abc import Callable
from dataclasses import dataclass, field

from PySide6.QtCore import QObject, Qt, Signal

from systems import processes
from systems.textbook.jobs import Cancelled

CPU_SECONDS = 60.0
"""CPU seconds a job may use before it is stopped with a message naming it: generous, as
the equilibrium search bounds itself at 15 s; only runaway symbolic work reaches it (a job
that runs a long integration asks for more: ``submit(..., cpu_seconds=...)``)."""


@dataclass
class _Job:
    token: int
    key: str
    on_done: Callable[[object], None]
    on_failed: Callable[[str], None] | None
    process: processes.Job | None = None
    reported: threading.Event = field(default_factory=threading.Event)
    """Set once the outcome has been handed to the GUI thread's queue (or never will be)."""


class _Relay(QObject):
    """Carries outcomes from the threads that wait for the workers to the GUI thread. It
    has no parent and those threads hold it, so it is alive whenever they emit."""

    finished = Signal(object)


class TaskRunner(QObject):
    """Runs textbook computations in worker processes; newest job per key wins.

    Signals
    -------
    busy_changed(bool)
        True when the first job starts, False when none is left.
    """

    busy_changed = Signal(bool)

    def __init__(self, parent: QObject | None = None, cpu_seconds: float = CPU_SECONDS):
        super().__init__(parent)
        self.cpu_seconds = cpu_seconds
        self._tokens = itertools.count(1)
        self._jobs: dict[int, _Job] = {}
        self._latest: dict[str, int] = {}
        self._closed = False
        self._relay = _Relay()
        self._relay.finished.connect(self._on_finished, Qt.ConnectionType.QueuedConnection)

    @property
    def pending(self) -> int:
        """Jobs submitted whose outcome has not been delivered yet."""
        return len(self._jobs)

    @property
    def running(self) -> int:
        """Jobs whose worker process has not finished."""
        return sum(
            1 for job in self._jobs.values() if job.process is not None and not job.process.done()
        )

    def pids(self) -> list[int]:
        """The process ids of the workers still running."""
        return [
            job.process.pid
            for job in self._jobs.values()
            if job.process is not None and not job.process.done()
        ]

    def submit(
        self,
        key: str,
        function: Callable,
        *args,
        on_done: Callable[[object], None],
        on_failed: Callable[[str], None] | None = None,
        what: str = "",
        cpu_seconds: float | None = None,
    ) -> int:
        """Run ``function(*args)`` in a worker process; returns the job's token (0 once
        shut down).

        Parameters
        ----------
        key : str
            A newer job with the same key ends this one.
        function : callable
            Module-level, in a module that does not import Qt.
        on_done : callable
            Called on the GUI thread with the value.
        on_failed : callable, optional
            Called on the GUI thread with a one-line message if the job raised (or ran
            out of CPU time, or its worker died).
        what : str
            What the job does, for messages (by default from the function's name).
        cpu_seconds : float, optional
            The job's CPU limit, if not the runner's (a long numeric run).
        """
        if self._closed:
            return 0
        self.cancel(key)
        token = next(self._tokens)
        job = _Job(token, key, on_done, on_failed)
        self._jobs[token] = job
        self._latest[key] = token
        if len(self._jobs) == 1:
            self.busy_changed.emit(True)
        relay = self._relay

        def report(process: processes.Job) -> None:  # in the thread that waited for it
            try:
                relay.finished.emit(_outcome(token, process))
            except RuntimeError:  # the relay's C++ side is gone: nobody is left to tell
                pass
            finally:
                job.reported.set()

        try:
            job.process = processes.submit(
                function,
                *args,
                cpu_seconds=self.cpu_seconds if cpu_seconds is None else cpu_seconds,
                what=what or _what(function),
                on_done=report,
            )
        except Exception as exc:  # noqa: BLE001 - no worker (arguments that do not pickle)
            job.reported.set()
            relay.finished.emit((token, "failed", _one_line(exc)))
        return token

    def cancel(self, key: str | None = None) -> None:
        """End the job of ``key`` (every job when None); their results are dropped."""
        for job in list(self._jobs.values()):
            if (key is None or job.key == key) and job.process is not None:
                job.process.cancel()
        if key is None:
            self._latest.clear()
        else:
            self._latest.pop(key, None)

    def _on_finished(self, outcome) -> None:
        token, status, value = outcome
        job = self._jobs.pop(token, None)
        if job is None:
            return
        if not self._jobs:
            self.busy_changed.emit(False)
        if self._closed or self._latest.get(job.key) != token:
            return
        del self._latest[job.key]
        if status == "done":
            job.on_done(value)
        elif status == "failed" and job.on_failed is not None:
            job.on_failed(value)

    def wait(self, msecs: int = 30000) -> bool:
        """Block until every job started has finished and its outcome is queued for the
        GUI thread (delivered when events are next processed); False if ``msecs`` passed
        first."""
        return self._wait_reported(list(self._jobs.values()), msecs)

    def shutdown(self, msecs: int = 10000) -> bool:
        """End every worker and wait up to ``msecs`` for the threads waiting for them;
        nothing is delivered afterwards. True if they all finished."""
        self._closed = True
        jobs = list(self._jobs.values())
        self.cancel()
        done = self._wait_reported(jobs, msecs)
        self._jobs.clear()
        if jobs:
            self.busy_changed.emit(False)
        return done

    @staticmethod
    def _wait_reported(jobs: list[_Job], msecs: int) -> bool:
        end = time.monotonic() + msecs / 1000.0
        return all(job.reported.wait(max(0.0, end - time.monotonic())) for job in jobs)


def _outcome(token: int, process: processes.Job) -> tuple[int, str, object]:
    """``(token, status, value)`` of a finished job: ``"done"`` with its value,
    ``"failed"`` with a message, or ``"cancelled"``."""
    try:
        value = process.result(0)
    except (processes.Cancelled, Cancelled):
        return token, "cancelled", None
    except Exception as exc:  # noqa: BLE001 - shown in the tab, never lost
        return token, "failed", _one_line(exc)
    return token, "done", value


def _one_line(exc: BaseException) -> str:
    """``"ValueError: the reason"``: the exception as its last traceback line."""
    if isinstance(exc, processes.RemoteError):
        if exc.message.startswith(f"{exc.type_name}:"):
            return exc.message.strip()
        return f"{exc.type_name}: {exc.message}".strip()
    return "".join(traceback.format_exception_only(type(exc), exc)).strip()


def _what(function: Callable) -> str:
    name = getattr(function, "__name__", "a computation").strip("_").replace("_", " ")
    return f"the Textbook's {name}"
