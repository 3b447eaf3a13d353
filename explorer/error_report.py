"""Unexpected errors in the window: shown in the status bar, the traceback one click away.

An exception that escapes a Qt slot goes to ``sys.excepthook`` (PySide calls it); one that
ends a Python thread goes to ``threading.excepthook``. ``ErrorReporter.install`` takes over
both while a window lives: the error is handed to the GUI thread as the ``reported``
signal (the window shows it and keeps running), then passed on to the hook that was there
before (the interpreter's prints it on stderr; pytest-qt's fails the test).

If someone else replaced the hooks after ours (pytest-qt does, around each test phase),
``uninstall`` cannot take ours out of their chain; it then leaves them inert: they pass
every error to the interpreter's own hooks and nothing to a closed window.
"""

from __future__ import annotations

import sys
import threading
import traceback
from collections.abc import Callable

from PySide6.QtCore import QObject, Signal


class ErrorReporter(QObject):
    """Routes uncaught exceptions of any thread to the ``reported`` signal.

    Signals
    -------
    reported(str, str)
        One line (``"ZeroDivisionError: division by zero"``) and the whole traceback.
        Emitted from whichever thread raised; connected slots run on the GUI thread.
    """

    reported = Signal(str, str)

    def __init__(self, parent: QObject | None = None):
        super().__init__(parent)
        self._previous_hook: Callable | None = None
        self._previous_thread_hook: Callable | None = None
        self._seen: set[str] = set()
        self._active = False
        self._reporting = threading.local()  # an error while reporting one is not reported

    def install(self) -> None:
        """Take over ``sys.excepthook`` and ``threading.excepthook`` (idempotent)."""
        if self._active:
            return
        self._active = True
        self._previous_hook = sys.excepthook
        self._previous_thread_hook = threading.excepthook
        sys.excepthook = self._excepthook
        threading.excepthook = self._thread_excepthook

    def uninstall(self) -> None:
        """Give the hooks back, unless someone replaced ours meanwhile (then leave theirs)."""
        if not self._active:
            return
        self._active = False
        if sys.excepthook == self._excepthook:
            sys.excepthook = self._previous_hook
        if threading.excepthook == self._thread_excepthook:
            threading.excepthook = self._previous_thread_hook
        self._previous_hook = self._previous_thread_hook = None

    def report(self, exc_type, exc, tb, where: str = "") -> bool:
        """Emit ``reported`` for one exception.

        Returns whether it was the first report of this error (same type and message),
        so that a slot failing 40 times a second prints its traceback once.
        """
        if getattr(self._reporting, "busy", False):
            return True
        summary = "".join(traceback.format_exception_only(exc_type, exc)).strip()
        if where:
            summary = f"{summary} (in {where})"
        details = "".join(traceback.format_exception(exc_type, exc, tb))
        first = summary not in self._seen
        self._seen.add(summary)
        self._reporting.busy = True
        try:
            self.reported.emit(summary, details)
        except RuntimeError:  # the reporter's C++ side is gone (window deleted)
            pass
        finally:
            self._reporting.busy = False
        return first

    def _excepthook(self, exc_type, exc, tb) -> None:
        if not self._active:
            sys.__excepthook__(exc_type, exc, tb)
            return
        if self.report(exc_type, exc, tb):
            (self._previous_hook or sys.__excepthook__)(exc_type, exc, tb)

    def _thread_excepthook(self, args) -> None:
        if args.exc_type is SystemExit:
            return
        if not self._active:
            threading.__excepthook__(args)
            return
        name = getattr(args.thread, "name", "a thread")
        if self.report(args.exc_type, args.exc_value, args.exc_traceback, name):
            (self._previous_thread_hook or threading.__excepthook__)(args)
