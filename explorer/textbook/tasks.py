"""A small pool of background jobs for the Textbook tabs.

``TaskRunner.submit(key, function, *args, on_done=..., on_failed=...)`` runs
``function(*args, cancel=Cancel)`` in a private ``QThreadPool`` (two threads). A newer job
with the same key supersedes an older one: the older one's ``Cancel`` is set (loops and
right-hand sides check it, and so do ``systems.deadline``'s checkpoints: the equilibrium
search's scan and its wait for a forked ``sympy.solve``) and its result, if it still
arrives, is dropped. Results are
delivered on the GUI thread through a queued signal. ``shutdown`` cancels everything and
waits for the threads.
"""

from __future__ import annotations

import itertools
import traceback
from collections.abc import Callable
from dataclasses import dataclass

from PySide6.QtCore import QObject, QRunnable, QThreadPool, Signal

from systems.deadline import Abandoned, cancellable
from systems.textbook.jobs import Cancel, Cancelled

THREADS = 2


@dataclass
class _Job:
    token: int
    key: str
    cancel: Cancel
    on_done: Callable[[object], None]
    on_failed: Callable[[str], None] | None


class _Runnable(QRunnable):
    def __init__(self, runner: TaskRunner, job: _Job, function: Callable, args: tuple):
        super().__init__()
        self.setAutoDelete(True)
        self._runner = runner
        self._job = job
        self._function = function
        self._args = args

    def run(self) -> None:
        job = self._job
        try:
            with cancellable(stop=job.cancel.event):
                job.cancel.check()
                result = self._function(*self._args, cancel=job.cancel)
        except (Cancelled, Abandoned):
            outcome = (job.token, "cancelled", None)
        except Exception as exc:  # noqa: BLE001 - shown in the tab, never lost
            detail = "".join(traceback.format_exception_only(type(exc), exc)).strip()
            outcome = (job.token, "failed", detail)
        else:
            outcome = (job.token, "done", result)
        self._runner._finished.emit(outcome)


class TaskRunner(QObject):
    """Runs textbook computations off the GUI thread; newest job per key wins.

    Signals
    -------
    busy_changed(bool)
        True when the first job starts, False when none is left.
    """

    busy_changed = Signal(bool)
    _finished = Signal(object)

    def __init__(self, parent: QObject | None = None, threads: int = THREADS):
        super().__init__(parent)
        self.pool = QThreadPool(self)
        self.pool.setMaxThreadCount(threads)
        self.pool.setExpiryTimeout(2000)
        self._tokens = itertools.count(1)
        self._jobs: dict[int, _Job] = {}
        self._latest: dict[str, int] = {}
        self._closed = False
        self._finished.connect(self._on_finished)

    @property
    def pending(self) -> int:
        """Jobs submitted whose outcome has not been delivered yet."""
        return len(self._jobs)

    def submit(
        self,
        key: str,
        function: Callable,
        *args,
        on_done: Callable[[object], None],
        on_failed: Callable[[str], None] | None = None,
    ) -> int:
        """Run ``function(*args, cancel=...)``; returns the job's token (0 once shut down)."""
        if self._closed:
            return 0
        self.cancel(key)
        token = next(self._tokens)
        job = _Job(token, key, Cancel(), on_done, on_failed)
        self._jobs[token] = job
        self._latest[key] = token
        if len(self._jobs) == 1:
            self.busy_changed.emit(True)
        self.pool.start(_Runnable(self, job, function, args))
        return token

    def cancel(self, key: str | None = None) -> None:
        """Cancel the job of ``key`` (every job when None); their results are dropped."""
        for job in self._jobs.values():
            if key is None or job.key == key:
                job.cancel.set()
        if key is None:
            self._latest.clear()
        else:
            self._latest.pop(key, None)

    def _on_finished(self, outcome) -> None:
        token, status, value = outcome
        job = self._jobs.pop(token, None)
        if not self._jobs:
            self.busy_changed.emit(False)
        if job is None or self._closed or self._latest.get(job.key) != token:
            return
        del self._latest[job.key]
        if status == "done":
            job.on_done(value)
        elif status == "failed" and job.on_failed is not None:
            job.on_failed(value)

    def wait(self, msecs: int = 30000) -> bool:
        """Block until every started job has finished (for tests and shutdown)."""
        return self.pool.waitForDone(msecs)

    def shutdown(self, msecs: int = 10000) -> bool:
        """Cancel everything, drop queued jobs and wait for the running ones."""
        self._closed = True
        self.cancel()
        self.pool.clear()
        done = self.pool.waitForDone(msecs)
        self._jobs.clear()
        return done
