"""Command-line entry point: ``phase-explorer [COMMAND] ...`` or ``python main.py ...``.

Each command lives in its own module under ``explorer.commands`` exposing
``add_parser(subparsers)`` and ``run(args) -> int``. A user error exits with status 2
and one message naming the file, the field and the position. Ctrl+C, SIGTERM and SIGHUP
stop a command alike (``explorer.commands.stopping``), with status 128 + the signal.

When the program reading the output closes it early (``derive simple_pendulum | head
-1``), the command ends quietly with status 0, as most Unix tools seem to the shell:
the reader has what it wanted. An output that cannot be written (standard output on a
full disk) and any other error of the system (``OSError``) end with one message and
status 1, never a traceback.

``entry`` is what ``main.py`` and the ``phase-explorer`` script run: ``main``, then the
end of the process (see there for a command that started Qt).
"""

from __future__ import annotations

import argparse
import atexit
import faulthandler
import importlib
import os
import signal
import sys
from contextlib import nullcontext, suppress
from typing import NoReturn

COMMANDS = (
    "list", "derive", "run", "bench", "methods", "periodic", "lyapunov", "chaosmap",
    "bifurcation", "open", "export", "warm",
)  # fmt: skip


def _load(name: str):
    return importlib.import_module(f"explorer.commands.{name}_cmd")


def build_parser() -> argparse.ArgumentParser:
    """The argument parser with one subcommand per available command module."""
    parser = argparse.ArgumentParser(
        prog="phase-explorer",
        description="Lagrangian and Hamiltonian mechanics, derived and explored live. "
        "With no command, the application opens on the simple pendulum.",
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name in COMMANDS:
        try:
            module = _load(name)
        except ModuleNotFoundError as exc:
            if exc.name != f"explorer.commands.{name}_cmd":
                raise
            continue
        module.add_parser(sub)
    return parser


def entry(argv: list[str] | None = None) -> NoReturn:
    """Run ``main`` and end the process with its status.

    Once ``main`` has returned, the status is decided: Ctrl+C is ignored from there (a
    ``KeyboardInterrupt`` in the exit handlers printed a traceback). After a command that
    started Qt (the window, a replay, an export), the process ends without Python's
    teardown (``_end_qt``); any other ends as Python does.
    """
    status = 128 + signal.SIGINT
    try:
        status = main(argv)
    except KeyboardInterrupt:  # landed as ``main`` returned
        _say("stopped (Ctrl+C)")
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    _end_qt(status)
    sys.exit(status)


def _end_qt(status: int) -> None:
    """End the process with ``status`` at once if a ``QApplication`` exists.

    The exit handlers run first (worker processes end, temporary folders go, buffered
    output is written), but not PySide's: it deletes every Qt object Python still holds
    when their Python methods can no longer run, and a figure panel left to it (a view
    whose construction Ctrl+C interrupted, a closed window in a reference cycle) crashed
    the process with SIGSEGV in ``~QGraphicsWidget``, after its work was done. Nothing
    of Qt's needs its destructors here: no QSettings, no temporary files of Qt's.
    """
    core = sys.modules.get("PySide6.QtCore")
    if core is None or core.QCoreApplication.instance() is None:
        return
    for stream in (sys.stdout, sys.stderr):
        with suppress(OSError, ValueError):
            stream.flush()
    shutdown = getattr(core, "__moduleShutdown", None)  # PySide6's name for it
    if shutdown is not None:
        atexit.unregister(shutdown)
    atexit._run_exitfuncs()
    os._exit(status)


def main(argv: list[str] | None = None) -> int:
    """Parse ``argv`` and run the command; return the process exit status."""
    stdout = sys.stdout
    try:
        _name_crashes()
        sys.stdout = _Output(stdout)
        status = _main(argv)
        sys.stdout.flush()  # here, so that a closed or full output is caught below
        return status
    except BrokenPipeError:
        _discard_output(stdout)
        return 0
    except OutputError as exc:
        _discard_output(stdout)
        _say(f"error: could not write the output: {exc.strerror or exc}")
        return 1
    except OSError as exc:
        where = f": {exc.filename}" if exc.filename else ""
        _say(f"error: {exc.strerror or exc}{where}")
        return 1
    except KeyboardInterrupt:  # before any command: the parser built (imports), the fault handler
        _say("stopped (Ctrl+C)")
        return 128 + signal.SIGINT
    finally:
        if isinstance(sys.stdout, _Output):
            sys.stdout = stdout


def _name_crashes() -> None:
    """Python's fault handler on stderr: a crash in compiled code (Qt's, numba's) prints
    every thread's Python stack before the process ends, instead of nothing (a SIGSEGV
    at the end of a Qt command once left only its exit status: ``_end_qt``)."""
    if not faulthandler.is_enabled():
        with suppress(OSError, ValueError):  # a stderr without a descriptor
            faulthandler.enable(sys.stderr)


class OutputError(OSError):
    """Standard output could not be written (a full disk, an I/O error)."""


class _Output:
    """Standard output while a command runs: a failed write raises ``OutputError``, so
    that ``main`` tells it from the other errors of the system (a closed pipe stays a
    ``BrokenPipeError``). Everything else is the stream's own."""

    def __init__(self, stream):
        self._stream = stream

    def write(self, text: str) -> int:
        try:
            return self._stream.write(text)
        except BrokenPipeError:
            raise
        except OSError as exc:
            raise OutputError(exc.errno, exc.strerror) from exc

    def flush(self) -> None:
        try:
            self._stream.flush()
        except BrokenPipeError:
            raise
        except OSError as exc:
            raise OutputError(exc.errno, exc.strerror) from exc

    def __getattr__(self, name: str):
        return getattr(self._stream, name)


def _discard_output(stdout) -> None:
    """Point standard output at the null device, so that what is still buffered is
    dropped quietly when the interpreter exits (instead of failing again there)."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        try:
            os.dup2(devnull, stdout.fileno())
        finally:
            os.close(devnull)
    except (OSError, ValueError, AttributeError):
        pass  # not a file of the system (a test's capture): nothing will be flushed


def _say(message: str) -> None:
    """``message`` on stderr, unless stderr itself cannot be written."""
    try:
        print(message, file=sys.stderr)
    except (OSError, ValueError):
        pass


def _main(argv: list[str] | None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    command = args.command or "open"
    try:
        module = _load(command)
    except ModuleNotFoundError:
        parser.error(f"the command {command!r} is not available in this build")
    if args.command is None:
        args = parser.parse_args(["open"])
    from explorer.commands import stopping
    from explorer.commands.errors import UserError

    # the window's event loop runs no Python between events: a signal raised there would
    # land in whatever slot ran next, so only the other commands stop on SIGTERM this way
    signals = nullcontext() if command == "open" else stopping.stop_signals()
    try:
        with signals:
            status = int(module.run(args) or 0)
            if status < 128:  # not stopped and said so: was a signal's exception swallowed?
                stopping.check()
            return status
    except UserError as exc:
        _say(f"error: {exc}")
        return 2
    except KeyboardInterrupt:
        _say(f"stopped ({stopping.cause()})")
        return stopping.status()
    except Exception:
        if not stopping.requested():
            raise
        # the signal's exception was swallowed in code it interrupted, which then failed
        _say(f"stopped ({stopping.cause()})")
        return stopping.status()
