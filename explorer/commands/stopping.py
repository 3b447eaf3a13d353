"""Signals that stop a command: SIGTERM and SIGHUP handled as Ctrl+C.

A logout, ``kill`` or a service manager stopping the program sends SIGTERM (a closed
terminal, SIGHUP); left to their default they end the process at once, losing what a
command would keep on Ctrl+C (the rows a ``run --out`` has integrated) and leaving its
temporary files. Inside ``stop_signals()`` they raise ``KeyboardInterrupt`` in the main
thread as SIGINT does, so every command stops the same way for all three; ``status()``
then gives the exit status that names the signal (128 + its number, 130 for Ctrl+C).
``deferred(what)`` holds a first signal while a short piece of work that should not be
cut (a finished run's file being written) ends, then stops.
"""

from __future__ import annotations

import signal
import sys
import threading
from collections.abc import Iterator
from contextlib import contextmanager

HANDLED = (signal.SIGTERM, signal.SIGHUP)

_received: list[int] = []


def _raise(signum: int, frame) -> None:
    _received.append(signum)
    raise KeyboardInterrupt


@contextmanager
def stop_signals() -> Iterator[None]:
    """Inside the block, SIGTERM and SIGHUP raise ``KeyboardInterrupt`` like Ctrl+C.

    A signal the process was started with ignored (``nohup``) stays ignored. The previous
    handlers come back when the block ends. Outside the main thread (where Python cannot
    set handlers) this does nothing.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    _received.clear()
    previous = {}
    for signum in HANDLED:
        handler = signal.getsignal(signum)
        if handler is not signal.SIG_IGN:
            previous[signum] = signal.signal(signum, _raise)
    try:
        yield
    finally:
        for signum, handler in previous.items():
            signal.signal(signum, signal.SIG_DFL if handler is None else handler)


def cause() -> str:
    """What stopped the command: "Ctrl+C", "SIGTERM" or "SIGHUP"."""
    return signal.Signals(_received[0]).name if _received else "Ctrl+C"


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
        if signum != signal.SIGINT:
            _received.append(signum)
        again = "Ctrl+C again" if signum == signal.SIGINT else "a second signal"
        _say(f"{name(signum)}: finishing {what} first ({again} abandons it)")

    previous = {}
    for signum in (signal.SIGINT, *HANDLED):
        handler = signal.getsignal(signum)
        if handler is not signal.SIG_IGN:
            previous[signum] = signal.signal(signum, hold)
    try:
        yield
    finally:
        for signum, handler in previous.items():
            signal.signal(signum, signal.SIG_DFL if handler is None else handler)
    if held:
        _say(f"finished {what}")
        raise KeyboardInterrupt


def _say(message: str) -> None:
    try:
        print(message, file=sys.stderr)
    except (OSError, RuntimeError, ValueError):
        pass  # stderr closed, or busy when a signal came: the stop happens all the same
