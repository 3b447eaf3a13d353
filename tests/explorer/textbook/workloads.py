"""Functions the Textbook's job runner tests send to worker processes.

A job's function is pickled by reference, so these live in a module that imports no Qt
(the test modules do): a worker that unpickles them stays free of PySide6.
"""

from __future__ import annotations

import os
import sys


def loop_forever(marker: str) -> None:
    """Python work that never ends (only ending the process stops it); creates the file
    ``marker`` first, to say it has begun."""
    with open(marker, "w"):
        pass
    x = 0
    while True:
        x += 1


def answer(value):
    return value


def fail(message: str) -> None:
    raise ValueError(message)


class Odd(Exception):
    def __init__(self, a, b):  # pickled with args=(a,) only: cannot be rebuilt
        super().__init__(a)
        self.b = b


def fail_oddly() -> None:
    raise Odd("odd failure", 2)


def pid() -> int:
    return os.getpid()


def qt_modules() -> list[str]:
    """The PySide6 modules imported in this process."""
    return sorted(name for name in sys.modules if name.startswith(("PySide6", "shiboken6")))


def run_and_list_qt(function, *args):
    """``function(*args)``, and the PySide6 modules imported after it ran."""
    return function(*args), qt_modules()
