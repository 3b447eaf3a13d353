"""Time limits on symbolic work, in whichever thread it runs.

sympy is pure Python, so a derivation can be stopped between two bytecodes: when a limit
passes, a timer raises ``TimeUp`` in the working thread with CPython's
``PyThreadState_SetAsyncExc``. That works in the main thread of the command line and in
the window's builder thread alike (a signal could only reach the main thread). ``TimeUp``
derives from ``BaseException`` so that sympy's own ``except Exception`` clauses cannot
swallow it, and the timer raises it again every half second until the limited block has
ended, in case one was caught anyway.

``abandon(thread)`` raises ``Abandoned`` the same way, so that closing the window ends a
derivation at once instead of waiting for it.
"""

from __future__ import annotations

import ctypes
import os
import threading
from collections.abc import Iterator
from contextlib import contextmanager

DEFAULT_SECONDS = 10.0
"""Default limit on deriving one scene (``PHASE_EXPLORER_DERIVE_SECONDS`` overrides it).
The catalogue's slowest scene derives in about 3 s on a shared CI machine, a 64-particle
FPU chain in about 5 s."""

REPEAT = 0.5


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
                self.fired = True
                _raise_in(self.ident, TimeUp)
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


def abandon(thread: threading.Thread | int) -> None:
    """Raise ``Abandoned`` in ``thread`` (a Thread or its ident) at its next bytecode.

    Code that blocks in C (a sleep, a lock, a child process) sees it only when it returns.
    """
    ident = thread if isinstance(thread, int) else thread.ident
    if ident is not None:
        _raise_in(ident, Abandoned)
