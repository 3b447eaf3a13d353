"""Limits on the CPU time of symbolic work, in a process's main thread.

Symbolic work runs in the main thread of a process: the command line's, or a worker
process's (``systems.processes``, where the window sends it). A limit counts the
process's CPU time (``ITIMER_PROF``), so a machine busy with other work does not make it
fire early. When it passes, the ``SIGPROF`` handler raises ``TimeUp`` in the main thread,
between two bytecodes of whatever sympy is doing; ``cpu_limit`` turns it into
``TimeLimitExceeded`` naming what was being done.

The handler runs in the very thread it interrupts, so it can look at that thread's stack
first: under a frame of the import machinery, numba or llvmlite (whose state an exception
would leave broken, the import lock held for ever) it waits ``RETRY`` seconds of CPU and
looks again. ``TimeUp`` derives from ``BaseException`` so that sympy's ``except
Exception`` clauses cannot swallow it; it is raised again every ``REPEAT`` seconds until
the limited block has ended, in case one was caught anyway.

No other thread can be interrupted so (a signal handler runs in the main thread only):
work in another thread is bounded by running it in a worker process. ``cpu_limit`` in a
thread other than the main one raises ``RuntimeError``.
"""

from __future__ import annotations

import itertools
import os
import signal
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass

DEFAULT_SECONDS = 10.0
"""Default limit on deriving one scene, in CPU seconds (``PHASE_EXPLORER_DERIVE_SECONDS``
overrides it). The catalogue's slowest scene derives in about 3 s, a 64-particle FPU
chain in about 5 s."""

REPEAT = 0.5
"""CPU seconds before ``TimeUp`` is raised again in a block that caught it."""
RETRY = 0.002
"""CPU seconds before another look, when the stack was not safe to interrupt."""

_IMPORTING = ("<frozen importlib", "<frozen zipimport")
_NEVER_UNDER = frozenset({"numba", "llvmlite"})
"""Packages under whose frames nothing is raised: numba cut short in its compiler stays
broken for the rest of the process."""


class TimeUp(BaseException):  # noqa: N818 - a signal, not an error, inside sympy
    """Raised in the main thread when a limit has passed; ``token`` names the limit."""

    def __init__(self, token: int):
        super().__init__(token)
        self.token = token


class TimeLimitExceeded(Exception):
    """A limited block ran out of CPU time; ``what`` says what was being done."""

    def __init__(self, what: str, seconds: float):
        self.what = what
        self.seconds = seconds
        super().__init__(what, seconds)

    def __str__(self) -> str:
        return f"{self.what} took longer than {self.seconds:g} s of CPU time and was stopped"


def limit_seconds() -> float:
    """The configured limit for a derivation: ``PHASE_EXPLORER_DERIVE_SECONDS`` or default."""
    raw = os.environ.get("PHASE_EXPLORER_DERIVE_SECONDS", "")
    try:
        value = float(raw)
    except ValueError:
        return DEFAULT_SECONDS
    return value if value > 0 else DEFAULT_SECONDS


def cpu_seconds() -> float:
    """CPU time used by this process so far (all threads), in seconds."""
    return time.process_time()


@dataclass
class _Limit:
    token: int
    end: float  # process CPU time at which it passes
    fired: bool = False


_limits: list[_Limit] = []
"""The open limits, outermost first (main thread only)."""
_tokens = itertools.count(1)
_installed = False


def _interruptible(frame) -> bool:
    while frame is not None:
        if frame.f_code.co_filename.startswith(_IMPORTING):
            return False
        package = frame.f_globals.get("__name__", "").partition(".")[0]
        if package in _NEVER_UNDER:
            return False
        frame = frame.f_back
    return True


def _arm(seconds: float) -> None:
    signal.setitimer(signal.ITIMER_PROF, max(seconds, 1e-6))


def _arm_next() -> None:
    """Set the timer to the nearest end among the open limits (or stop it)."""
    pending = [limit.end for limit in _limits if not limit.fired]
    if pending:
        _arm(min(pending) - cpu_seconds())
    elif _limits:
        _arm(REPEAT)
    else:
        signal.setitimer(signal.ITIMER_PROF, 0)


def _on_timer(_signum, frame) -> None:
    now = cpu_seconds()
    passed = [limit for limit in _limits if limit.end <= now]
    if not passed:
        _arm_next()  # fired early, or for a limit since closed
        return
    if not _interruptible(frame):
        _arm(RETRY)
        return
    outermost = passed[0]  # an outer limit ends the inner blocks too
    outermost.fired = True
    _arm(REPEAT)  # raised again if caught and the block goes on
    raise TimeUp(outermost.token)


@contextmanager
def cpu_limit(seconds: float | None, what: str) -> Iterator[None]:
    """Stop the block after ``seconds`` of this process's CPU time with
    ``TimeLimitExceeded(what, seconds)``; ``None`` means no limit.

    Limits nest: an inner one that passes stops its own block only; an outer one that
    passes stops every block inside it, and only the outer ``cpu_limit`` reports it.

    Raises
    ------
    RuntimeError
        Outside the main thread, where no signal handler can interrupt the work.
    """
    if seconds is None:
        yield
        return
    if threading.current_thread() is not threading.main_thread():
        raise RuntimeError(
            f"{what}: a CPU-time limit works in a process's main thread only "
            "(send the work to systems.processes)"
        )
    global _installed
    limit = _Limit(next(_tokens), cpu_seconds() + seconds)
    mask = {signal.SIGPROF}
    signal.pthread_sigmask(signal.SIG_BLOCK, mask)
    try:
        if not _installed:  # kept for good: a SIGPROF still pending must find it
            signal.signal(signal.SIGPROF, _on_timer)
            _installed = True
        _limits.append(limit)
        _arm_next()
    finally:
        signal.pthread_sigmask(signal.SIG_UNBLOCK, mask)
    late = None
    try:
        yield
    except TimeUp as exc:
        if exc.token != limit.token:
            raise  # an outer limit passed: its own block reports it
        late = TimeLimitExceeded(what, seconds)
    finally:
        signal.pthread_sigmask(signal.SIG_BLOCK, mask)  # no TimeUp during the clean-up
        try:
            _limits.remove(limit)
            _arm_next()
        finally:
            # a SIGPROF still pending is handled here: it raises only for an outer limit
            # that has passed, which is then this block's caller's to report
            signal.pthread_sigmask(signal.SIG_UNBLOCK, mask)
    if late is not None:
        raise late
