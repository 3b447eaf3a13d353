"""Time limits on symbolic work, and ending work nobody waits for, in any thread.

sympy is pure Python, so a derivation can be stopped between two bytecodes: when a limit
passes, a timer raises ``TimeUp`` in the working thread with CPython's
``PyThreadState_SetAsyncExc``. That works in the main thread of the command line and in
the window's builder thread alike (a signal could only reach the main thread). ``TimeUp``
derives from ``BaseException`` so that sympy's own ``except Exception`` clauses cannot
swallow it, and the timer raises it again every half second until the limited block has
ended, in case one was caught anyway.

An exception raised between two arbitrary bytecodes can break what the interpreter does
in Python: one landing in importlib just after it took the global import lock left that
lock held for ever, and every later import in any thread of the process waited on it (a
window that switched scenes quickly hung so). So an asynchronous exception is raised only
where the thread is ``interruptible``: no frame of importlib or numba on its stack (numba
cut short is broken for the rest of the process) and none of the standard library's lock
and process plumbing on top. Elsewhere it waits a few milliseconds and tries again.

Ending work is cooperative where it can be: ``cancel(thread)`` marks a thread, and the
thread raises ``Abandoned`` at its next ``checkpoint()``, which long loops call where
stopping is safe (between the lines of a derivation's layout, while waiting for a child
process). ``abandon(thread)`` also raises ``Abandoned`` asynchronously, for work that
passes no checkpoint (a derivation inside sympy, an interpreted step) and must end at once.
"""

from __future__ import annotations

import ctypes
import os
import sys
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager

DEFAULT_SECONDS = 10.0
"""Default limit on deriving one scene (``PHASE_EXPLORER_DERIVE_SECONDS`` overrides it).
The catalogue's slowest scene derives in about 3 s on a shared CI machine, a 64-particle
FPU chain in about 5 s."""

REPEAT = 0.5
RETRY = 0.002
"""Seconds before another try at raising in a thread that was not interruptible."""


class TimeUp(BaseException):  # noqa: N818 - it is a signal, not an error, inside sympy
    """Raised inside the limited thread when its time is up."""


class Abandoned(BaseException):  # noqa: N818
    """Raised inside a thread whose work nobody waits for any more."""


class TimeLimitExceeded(Exception):
    """A limited block ran out of time; ``what`` says what was being done."""

    def __init__(self, what: str, seconds: float):
        self.what = what
        self.seconds = seconds
        super().__init__(f"{what} took longer than {seconds:g} s and was stopped")


def limit_seconds() -> float:
    """The configured limit for a derivation: ``PHASE_EXPLORER_DERIVE_SECONDS`` or default."""
    raw = os.environ.get("PHASE_EXPLORER_DERIVE_SECONDS", "")
    try:
        value = float(raw)
    except ValueError:
        return DEFAULT_SECONDS
    return value if value > 0 else DEFAULT_SECONDS


def _raise_in(ident: int, exc_type: type[BaseException] | None) -> None:
    ctypes.pythonapi.PyThreadState_SetAsyncExc(
        ctypes.c_ulong(ident), ctypes.py_object(exc_type) if exc_type else None
    )


_IMPORTING = ("<frozen importlib", "<frozen zipimport")
"""Where the import machinery's frames come from: no exception under them."""
_NEVER_UNDER = frozenset({"numba", "llvmlite"})
"""Packages under whose frames no exception is raised: numba cut short in its compiler or
an import stays broken for the rest of the process."""
_NEVER_IN = frozenset(
    {
        "threading",
        "_weakrefset",
        "weakref",
        "logging",
        "multiprocessing",
        "concurrent",
        "queue",
        "subprocess",
        "selectors",
        "contextlib",
        "shiboken6",
        "PySide6",
        "systems.deadline",
    }
)
"""Modules (and packages) in whose own frames no exception is raised: their locks,
waiter lists and clean-ups are not written to survive one between two bytecodes."""
_TOP_FRAMES = 2
"""How many frames from the top are checked against ``_NEVER_IN`` (the exception starts
in the top one; the next may be in the middle of a clean-up that called it)."""
_THREAD_START = frozenset({"run", "_bootstrap_inner", "_bootstrap"})
"""``threading.Thread``'s frames below every thread's own: not plumbing at work."""


def interruptible(ident: int) -> bool:
    """Whether an exception may be raised in thread ``ident`` now: it has a Python frame,
    no frame of the import machinery or of ``_NEVER_UNDER`` anywhere on its
    stack, and none of ``_NEVER_IN`` among its top ``_TOP_FRAMES``."""
    frame = sys._current_frames().get(ident)
    if frame is None:
        return False
    depth = 0
    while frame is not None:
        if frame.f_code.co_filename.startswith(_IMPORTING):
            return False
        name = frame.f_globals.get("__name__", "")
        package = name.partition(".")[0]
        if package in _NEVER_UNDER:
            return False
        if (
            depth < _TOP_FRAMES
            and (name in _NEVER_IN or package in _NEVER_IN)
            and not (name == "threading" and frame.f_code.co_name in _THREAD_START)
        ):
            return False
        depth += 1
        frame = frame.f_back
    return True


def _raise_if_interruptible(ident: int, exc_type: type[BaseException]) -> bool:
    """Raise ``exc_type`` in ``ident`` if it is interruptible now; whether it was raised."""
    if not interruptible(ident):
        return False
    _raise_in(ident, exc_type)
    return True


def release_import_lock() -> int:
    """Release every level of the global import lock that this thread still holds; how
    many were. Called where an asynchronous exception is caught: one that landed in
    importlib despite ``interruptible`` (a race of a few bytecodes) must not leave the
    lock held and every import of the process waiting for ever."""
    import _imp

    released = 0
    while released < 1000:
        try:
            _imp.release_lock()
        except RuntimeError:  # not held by this thread (any more)
            break
        released += 1
    return released


class _Limit:
    def __init__(self, ident: int, seconds: float):
        self.ident = ident
        self.seconds = seconds
        self.lock = threading.Lock()
        self.over = False
        self.fired = False
        self.stop = threading.Event()
        self.timer = threading.Thread(target=self._watch, name="time-limit", daemon=True)

    def _watch(self) -> None:
        wait = self.seconds
        while not self.stop.wait(wait):
            with self.lock:
                if self.over:
                    return
                if not _raise_if_interruptible(self.ident, TimeUp):
                    wait = RETRY
                    continue
                self.fired = True
            wait = REPEAT

    def finish(self) -> None:
        with self.lock:
            self.over = True
            if self.fired:
                _raise_in(self.ident, None)  # clear one still pending, raised nowhere else
        self.stop.set()


_active: dict[int, int] = {}
"""How many limits are open per thread (they nest; only the outermost one is armed)."""


@contextmanager
def time_limit(seconds: float | None, what: str) -> Iterator[None]:
    """Stop the block after ``seconds`` of wall time with ``TimeLimitExceeded(what)``.

    ``None`` means no limit. Nested limits keep the outer one only.
    """
    ident = threading.get_ident()
    if seconds is None or _active.get(ident):
        yield
        return
    limit = _Limit(ident, seconds)
    late = None
    try:  # armed inside the try: an exception landing during start still finishes it
        _active[ident] = 1
        limit.timer.start()
        yield
    except TimeUp:
        release_import_lock()
        late = TimeLimitExceeded(what, seconds)
    finally:
        abandoned = False
        while True:  # the timer (or an abandon) may land while this clean-up runs
            try:
                limit.finish()
                _active.pop(ident, None)
                break
            except TimeUp:
                continue
            except Abandoned:
                abandoned = True
        if abandoned:
            raise Abandoned
    if late is not None:
        raise late


_cancelled: set[int] = set()
"""Idents of the threads asked to stop (``cancel``, ``abandon``) while ``cancellable``."""
_cancellable: dict[int, int] = {}
"""Idents of the threads inside ``cancellable``, with its nesting depth."""
_stop_events: dict[int, threading.Event] = {}
"""Per thread inside ``cancellable(stop=...)``: an event whose setting also stops it."""
_marks = threading.Lock()


@contextmanager
def cancellable(stop: threading.Event | None = None) -> Iterator[None]:
    """Mark the block's thread as one that ``cancel`` and ``abandon`` may stop; setting
    ``stop`` (the owner's own flag) stops it at a ``checkpoint()`` too.

    A request to stop it outlives neither the block nor the thread (idents are reused);
    an asynchronous ``Abandoned`` that lands while the block is being left is dropped
    (the block is ending anyway). An ``Abandoned`` leaving the block first frees any
    level of the import lock the thread still holds (``release_import_lock``).
    """
    ident = threading.get_ident()
    with _marks:
        _cancellable[ident] = _cancellable.get(ident, 0) + 1
        outer = _stop_events.get(ident)
        if stop is not None:
            _stop_events[ident] = stop
    try:
        yield
    except Abandoned:
        release_import_lock()  # in case one landed in an import despite ``interruptible``
        raise
    finally:
        while True:
            try:
                with _marks:
                    depth = _cancellable.pop(ident, 1) - 1
                    if depth:
                        _cancellable[ident] = depth
                    else:
                        _cancelled.discard(ident)
                    if outer is None:
                        _stop_events.pop(ident, None)
                    else:
                        _stop_events[ident] = outer
                break
            except Abandoned:
                continue


def cancelled() -> bool:
    """Whether this thread was asked to stop (``cancel``, ``abandon``, its ``stop``)."""
    ident = threading.get_ident()
    if ident in _cancelled:
        return True
    stop = _stop_events.get(ident)
    return stop is not None and stop.is_set()


def checkpoint() -> None:
    """Raise ``Abandoned`` if this thread was asked to stop (``cancelled()``)."""
    if cancelled():
        raise Abandoned


def _ident_of(thread: threading.Thread | int) -> int | None:
    return thread if isinstance(thread, int) else thread.ident


def cancel(thread: threading.Thread | int) -> bool:
    """Ask ``thread`` (a Thread or its ident) to stop at its next ``checkpoint()``;
    whether it is inside ``cancellable`` (otherwise nothing is asked)."""
    ident = _ident_of(thread)
    with _marks:
        if ident is None or ident not in _cancellable:
            return False
        _cancelled.add(ident)
        return True


def abandon(thread: threading.Thread | int) -> bool:
    """Raise ``Abandoned`` in ``thread`` (a Thread or its ident), inside its
    ``cancellable`` block, as soon as it is ``interruptible`` or at its next
    ``checkpoint()``, whichever comes first; whether it was inside such a block.

    Code that blocks in C (a sleep, a lock, a child process) sees it only when it returns.
    Where the thread is not interruptible at once, a daemon thread tries again every
    ``RETRY`` seconds until it is or the thread has left the block.
    """
    ident = _ident_of(thread)
    if ident is None or not cancel(ident):
        return False
    if not _try_abandon(ident):
        threading.Thread(target=_abandon_later, args=(ident,), name="abandon", daemon=True).start()
    return True


def _try_abandon(ident: int) -> bool:
    """True once there is nothing more to do: raised, or the block was left."""
    with _marks:  # the block cannot be left meanwhile
        if ident not in _cancelled:
            return True
        return _raise_if_interruptible(ident, Abandoned)


def _abandon_later(ident: int) -> None:
    while not _try_abandon(ident) and ident in sys._current_frames():
        time.sleep(RETRY)
