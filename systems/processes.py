"""Symbolic work in worker processes: stopped by ending the process, limited in CPU time.

The window never runs sympy in its own process: a thread there would hold the GIL the
drawing needs, and could only be stopped by an exception raised into it. ``submit(f,
*args)`` runs ``f(*args)`` in a new worker process and returns a ``Job`` at once;
``Job.cancel()`` ends the process, and a time limit is the worker's CPU time
(``systems.cpu_limit`` in its main thread).

Workers are forked from a *fork server* (``multiprocessing``'s ``forkserver``), a process
started once, without threads, that has sympy, symengine and the derivation imported
(``PRELOAD``): every worker starts warm in a few milliseconds, and nothing ever forks the
window's own process, whose threads (Qt's among them) make a fork unsafe. Where there is
no fork server (Windows), workers are spawned and pay the imports.

What crosses between the processes is pickled: the function (by its module and name, so
it must be importable), its arguments, and its value or exception. A ``CompiledSystem``
crosses as its ``Mechanics`` and is compiled again in the worker. The worker's
environment is the caller's ``PHASE_EXPLORER_*`` settings at ``submit`` (the fork server's
own is as it was when it started).
"""

from __future__ import annotations

import multiprocessing
import os
import pickle
import resource
import signal
import threading
import traceback
from collections.abc import Callable
from multiprocessing import spawn
from multiprocessing.connection import wait as wait_for

from systems.cpu_limit import TimeLimitExceeded, cpu_limit

PRELOAD = [
    "sympy",
    "symengine",
    "numpy",
    "systems.scene",
    "systems.mechanics",
    "systems.compiled",
    "numba.core.datamodel",
    "systems.sources",
    "systems.report",
    "systems.typeset",
    "matplotlib.textpath",  # mathtext, which sets the derivation's equations in type
    "systems.textbook.equilibria",
    "systems.textbook.jobs",  # scipy.integrate, optimize, special: 0.4 s of each job
    "systems.normal_modes",
    "systems.constraint_forces",
]
"""Modules the fork server imports once, so that every worker starts with them."""

GRACE_SECONDS = 2.0
"""CPU seconds past a job's limit after which the kernel ends its worker (``RLIMIT_CPU``),
should the limit's exception have been swallowed."""

_ENVIRONMENT_PREFIX = "PHASE_EXPLORER_"


class Cancelled(Exception):  # noqa: N818 - what happened, not an error
    """The job was cancelled: its worker was ended before it answered."""


class WorkerFailed(RuntimeError):
    """The worker ended without an answer (killed from outside, or it crashed)."""


class RemoteError(Exception):
    """An exception from a worker that could not cross back as itself.

    Attributes
    ----------
    type_name : str
        The original exception's class name.
    field, position, reason
        Copied from the original where it had them (the editor shows where the error is).
    """

    def __init__(self, type_name: str, message: str, details: dict):
        super().__init__(type_name, message, details)
        self.type_name = type_name
        self.message = message
        for key, value in details.items():
            setattr(self, key, value)

    def __str__(self) -> str:
        return self.message


_WORKER_PREFIX = "phase-explorer: "


def _preparation_data(name: str, _original=spawn.get_preparation_data) -> dict:
    """What a new process is told to set up, without the main script for our workers.

    ``multiprocessing`` runs the parent's main script again in every worker it does not
    fork directly (``forkserver``, ``spawn``), to find functions defined there. Ours are
    all in ``systems``; running the script again would open a second window from a
    script without an ``if __name__ == "__main__"`` guard, and costs an import each time.
    """
    data = _original(name)
    if name.startswith(_WORKER_PREFIX):
        data.pop("init_main_from_path", None)
        data.pop("init_main_from_name", None)
    return data


spawn.get_preparation_data = _preparation_data


def _context():
    if "forkserver" in multiprocessing.get_all_start_methods():
        context = multiprocessing.get_context("forkserver")
        context.set_forkserver_preload(PRELOAD)
        return context
    return multiprocessing.get_context("spawn")


_lock = threading.Lock()
_jobs: set[Job] = set()
_state = {"context": None}


def context():
    """The ``multiprocessing`` context workers are started from (made once)."""
    with _lock:
        if _state["context"] is None:
            _state["context"] = _context()
        return _state["context"]


def start() -> None:
    """Start the fork server now, so that the first job does not wait for its imports.

    Returns at once; the server imports ``PRELOAD`` in its own process.
    """
    ctx = context()
    if ctx.get_start_method() == "forkserver":
        from multiprocessing import forkserver

        forkserver.ensure_running()


class Job:
    """One function call in its own worker process.

    Parameters
    ----------
    function : callable
        Importable by module and name (it is pickled by reference).
    args, kwargs
        Picklable arguments.
    cpu_seconds : float or None
        The worker's CPU time limit; past it ``result()`` raises ``TimeLimitExceeded``.
    what : str
        What the job does, for messages ("deriving the equations of motion").
    on_done : callable, optional
        Called with the finished job, in a waiting thread (not the caller's).
    """

    def __init__(
        self,
        function: Callable,
        args: tuple = (),
        kwargs: dict | None = None,
        *,
        cpu_seconds: float | None = None,
        what: str = "",
        on_done: Callable[[Job], None] | None = None,
    ):
        self.what = what or getattr(function, "__name__", "a job")
        self.cpu_seconds = cpu_seconds
        self._on_done = on_done
        self._finished = threading.Event()
        self._cancelled = False
        self._value = None
        self._error: BaseException | None = None
        if _answered(self, function, args, kwargs or {}):
            return
        environment = {k: v for k, v in os.environ.items() if k.startswith(_ENVIRONMENT_PREFIX)}
        ctx = context()
        receiver, sender = ctx.Pipe(duplex=False)
        self._process = ctx.Process(
            target=_work,
            args=(sender, function, args, kwargs or {}, cpu_seconds, self.what, environment),
            name=f"{_WORKER_PREFIX}{self.what}",
            daemon=True,
        )
        with _lock:
            _jobs.add(self)
        try:
            self._process.start()
        except BaseException:
            with _lock:
                _jobs.discard(self)
            receiver.close()
            raise
        finally:
            sender.close()
        self._receiver = receiver
        self.pid = self._process.pid
        self._waiter = threading.Thread(target=self._wait, name=f"job: {self.what}", daemon=True)
        self._waiter.start()

    def done(self) -> bool:
        """Whether the job has finished (answered, failed or been cancelled)."""
        return self._finished.is_set()

    def wait(self, timeout: float | None = None) -> bool:
        """Wait until the job has finished; whether it has."""
        return self._finished.wait(timeout)

    def cancel(self) -> None:
        """End the worker now; ``result()`` raises ``Cancelled`` unless it had answered."""
        self._cancelled = True
        if self._finished.is_set():
            return
        try:
            self._process.kill()
        except (OSError, ValueError, AttributeError):
            pass  # ended meanwhile

    def result(self, timeout: float | None = None):
        """The function's value, or the exception it raised (re-raised here).

        Raises
        ------
        Cancelled
            ``cancel()`` ended the worker first.
        TimeLimitExceeded
            The job ran past its CPU limit.
        WorkerFailed
            The worker ended without an answer otherwise.
        TimeoutError
            ``timeout`` seconds passed first (the job goes on).
        """
        if not self._finished.wait(timeout):
            raise TimeoutError(f"{self.what} has not finished within {timeout:g} s")
        if self._error is not None:
            raise self._error
        return self._value

    def exception(self) -> BaseException | None:
        """The exception ``result()`` raises, once finished (None for a value)."""
        self._finished.wait()
        return self._error

    def _wait(self) -> None:
        message = None
        try:
            wait_for([self._receiver, self._process.sentinel])
            if self._receiver.poll():
                message = self._receiver.recv()
        except (EOFError, OSError):
            message = None
        except Exception as exc:  # noqa: BLE001 - an answer that does not unpickle
            message = ("error", RemoteError(type(exc).__name__, f"{self.what}: {exc}", {}))
        finally:
            self._receiver.close()
        self._process.join()
        if message is not None and message[0] == "ok":
            self._value = message[1]
        elif message is not None:
            self._error = message[1]
        elif self._cancelled:
            self._error = Cancelled(f"{self.what} was cancelled")
        elif self._process.exitcode == -signal.SIGXCPU and self.cpu_seconds is not None:
            self._error = TimeLimitExceeded(self.what, self.cpu_seconds)
        else:
            self._error = WorkerFailed(
                f"{self.what}: the worker process ended without an answer "
                f"(exit code {self._process.exitcode})"
            )
        try:
            self._process.close()
        except ValueError:
            pass
        with _lock:
            _jobs.discard(self)
        self._finished.set()
        if self._on_done is not None:
            self._on_done(self)


def _answered(job: Job, function: Callable, args: tuple, kwargs: dict) -> bool:
    """Finish ``job`` without a process if ``function`` remembers its answer on disk
    (``derivation_cache.remembered_job``: its ``from_cache``) and has it; ``on_done`` is
    then called from a thread of its own, as after a worker."""
    from_cache = getattr(function, "from_cache", None)
    if from_cache is None:
        return False
    from systems.derivation_cache import MISSING

    try:
        value = from_cache(*args, **kwargs)
    except Exception:  # noqa: BLE001 - any doubt: the worker computes it as always
        return False
    if value is MISSING:
        return False
    job._value = value
    job._process = None
    job.pid = None
    job._finished.set()
    if job._on_done is not None:
        threading.Thread(target=job._on_done, args=(job,), name=f"job: {job.what}").start()
    return True


def submit(
    function: Callable,
    *args,
    cpu_seconds: float | None = None,
    what: str = "",
    on_done: Callable[[Job], None] | None = None,
    **kwargs,
) -> Job:
    """Start ``function(*args, **kwargs)`` in a worker process; see ``Job``."""
    return Job(function, args, kwargs, cpu_seconds=cpu_seconds, what=what, on_done=on_done)


def run(function: Callable, *args, cpu_seconds: float | None = None, what: str = "", **kwargs):
    """``submit(...).result()``: the calling thread waits (it can be ended by ``cancel_all``)."""
    return submit(function, *args, cpu_seconds=cpu_seconds, what=what, **kwargs).result()


def running() -> list[Job]:
    """The jobs whose workers have not finished."""
    with _lock:
        return [job for job in _jobs if not job.done()]


def cancel_all(timeout: float = 1.0) -> bool:
    """Cancel every job of this process and wait up to ``timeout`` s for their waiting
    threads; True if all have finished."""
    import time

    jobs = running()
    for job in jobs:
        job.cancel()
    end = time.monotonic() + timeout
    return all(job.wait(max(0.0, end - time.monotonic())) for job in jobs)


# -- in the worker ---------------------------------------------------------------------------


def _work(sender, function, args, kwargs, cpu_seconds, what, environment) -> None:
    """The worker's main thread: one call, one answer, then the process ends."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl+C is the caller's to handle
    for key in [k for k in os.environ if k.startswith(_ENVIRONMENT_PREFIX)]:
        del os.environ[key]
    os.environ.update(environment)
    try:
        resource.setrlimit(resource.RLIMIT_CORE, (0, 0))
        if cpu_seconds is not None:
            _, hard = resource.getrlimit(resource.RLIMIT_CPU)
            soft = int(resource.getrusage(resource.RUSAGE_SELF).ru_utime + cpu_seconds)
            soft += int(GRACE_SECONDS) + 1
            if hard == resource.RLIM_INFINITY or soft < hard:
                resource.setrlimit(resource.RLIMIT_CPU, (soft, hard))
    except (ValueError, OSError):
        pass  # no backstop; the limit's exception still applies
    try:
        with cpu_limit(cpu_seconds, what):
            message = ("ok", function(*args, **kwargs))
    except BaseException as exc:  # noqa: BLE001 - every failure goes back to the caller
        message = ("error", _portable(exc))
    try:
        sender.send(message)
    except Exception as exc:  # noqa: BLE001 - a value that does not pickle
        sender.send(("error", RemoteError(type(exc).__name__, f"{what}: {exc}", {})))
    finally:
        sender.close()


_DETAILS = ("field", "position", "reason", "what", "seconds", "source")


def _portable(exc: BaseException) -> BaseException:
    """``exc`` itself if it survives pickling, else a ``RemoteError`` with its message."""
    try:
        copy = pickle.loads(pickle.dumps(exc))
        if type(copy) is type(exc) and str(copy) == str(exc):
            return exc
    except Exception:  # noqa: BLE001 - not picklable: described instead
        pass
    details = {}
    for key in _DETAILS:
        value = getattr(exc, key, None)
        if isinstance(value, str | int | float) or value is None and hasattr(exc, key):
            details[key] = value
    message = str(exc) or type(exc).__name__
    if not isinstance(exc, Exception):
        message = "".join(traceback.format_exception_only(type(exc), exc)).strip()
    return RemoteError(type(exc).__name__, message, details)
