"""Signals that stop a command: Ctrl+C, SIGTERM and SIGHUP alike.

A logout, ``kill`` or a service manager stopping the program sends SIGTERM (a closed
terminal, SIGHUP); left to their default they end the process at once, losing what a
command would keep on Ctrl+C (the rows a ``run --out`` has integrated) and leaving its
temporary files. Inside ``stop_signals()`` all three raise ``KeyboardInterrupt`` in the
main thread and are remembered, so every command stops the same way for all three;
``status()`` then gives the exit status that names the signal (128 + its number, 130
for Ctrl+C).

An exception raised by a signal handler can be lost: C code that calls Python and
clears whatever error comes back (numba's dispatcher, typing an argument of a compiled
function) swallows the ``KeyboardInterrupt``, then fails with a confused ``TypeError``
(``_get_jit_address() missing 1 required positional argument``) or goes on: an endless
run went on for ever after SIGTERM. So loops ask ``requested()`` at each step
(``check()`` raises for them) and take any error after a signal for the stop, and a
command that ends, or fails, after a signal is reported as stopped by it.
``deferred(what)`` holds a first signal while a short piece of work that should not be
cut (a finished run's file being written) ends, then stops.
"""

from __future__ import annotations

import functools
import signal
import sys
import threading
from collections.abc import Iterator
from contextlib import contextmanager

HANDLED = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)

_received: list[int] = []


def _raise(signum: int, frame) -> None:
    _received.append(signum)
    raise KeyboardInterrupt


@contextmanager
def stop_signals() -> Iterator[None]:
    """Inside the block, Ctrl+C, SIGTERM and SIGHUP raise ``KeyboardInterrupt`` and are
    remembered (``requested``, ``cause``, ``status``).

    A signal the process was started with ignored (``nohup``; SIGINT of a job started in
    the background) stays ignored. The previous handlers come back when the block ends.
    Outside the main thread (where Python cannot set handlers) this does nothing.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    _received.clear()
    hook = sys.unraisablehook
    sys.unraisablehook = functools.partial(_unraisable, hook)
    try:
        with _handled_by(_raise):
            yield
    finally:
        sys.unraisablehook = hook


def _unraisable(hook, unraisable) -> None:
    """``sys.unraisablehook`` inside ``stop_signals``: a signal's ``KeyboardInterrupt``
    raised where Python cannot pass it on (a weak reference's callback, such as the
    import system's module locks, or a ``__del__``) is not printed as "Exception ignored"
    with a traceback; the signal is remembered and the command stops by ``check``.
    Anything else goes to ``hook``."""
    if not (isinstance(unraisable.exc_value, KeyboardInterrupt) and _received):
        hook(unraisable)


def requested() -> bool:
    """Whether a stop signal has come since ``stop_signals()`` began."""
    return bool(_received)


def check() -> None:
    """Raise ``KeyboardInterrupt`` if a stop signal has come (its exception may have
    been swallowed on the way: see the module's description)."""
    if _received:
        raise KeyboardInterrupt


def cause() -> str:
    """What stopped the command: "Ctrl+C", "SIGTERM" or "SIGHUP"."""
    return name(_received[0]) if _received else "Ctrl+C"


def status() -> int:
    """The exit status of a command stopped by a signal: 128 + the signal's number."""
    return 128 + (_received[0] if _received else signal.SIGINT)


def name(signum: int) -> str:
    """How a signal is called in messages: "Ctrl+C" for SIGINT, else "SIGTERM"..."""
    return "Ctrl+C" if signum == signal.SIGINT else signal.Signals(signum).name


@contextmanager
def deferred(what: str) -> Iterator[None]:
    """Inside the block a first Ctrl+C, SIGTERM or SIGHUP waits for the block to end.

    It is announced on stderr (``Ctrl+C: finishing WHAT first (Ctrl+C again abandons
    it)``, then ``finished WHAT``) and raised as ``KeyboardInterrupt`` when the block
    has ended, so ``cause()`` and ``status()`` name it as usual. A second signal raises
    at once. A signal ignored when the block starts stays ignored; outside the main
    thread this does nothing.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    held: list[int] = []

    def hold(signum: int, frame) -> None:
        if held:
            raise KeyboardInterrupt
        held.append(signum)
        _received.append(signum)
        again = "Ctrl+C again" if signum == signal.SIGINT else "a second signal"
        _say(f"{name(signum)}: finishing {what} first ({again} abandons it)")

    with _handled_by(hold):
        yield
    if held:
        _say(f"finished {what}")
        raise KeyboardInterrupt


def _say(message: str) -> None:
    try:
        print(message, file=sys.stderr)
    except (OSError, RuntimeError, ValueError):
        pass  # stderr closed, or busy when a signal came: the stop happens all the same


@contextmanager
def _handled_by(handler) -> Iterator[None]:
    """``handler`` for every signal of ``HANDLED`` the process does not ignore, the
    previous handlers back afterwards."""
    previous = {}
    for signum in HANDLED:
        if signal.getsignal(signum) is not signal.SIG_IGN:
            previous[signum] = signal.signal(signum, handler)
    try:
        yield
    finally:
        for signum, before in previous.items():
            signal.signal(signum, signal.SIG_DFL if before is None else before)
