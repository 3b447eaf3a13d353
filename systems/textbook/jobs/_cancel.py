"""Cancelling a job whose result is no longer wanted (a newer one superseded it, or the
window is closing)."""

from __future__ import annotations

import threading


class Cancelled(Exception):
    """Raised inside a job whose result is no longer wanted."""


class Cancel:
    """A flag a job checks between steps: ``check()`` raises ``Cancelled`` once set."""

    def __init__(self) -> None:
        self._event = threading.Event()

    def set(self) -> None:
        """Ask the job to stop at its next ``check``."""
        self._event.set()

    @property
    def event(self) -> threading.Event:
        """The flag itself, for ``systems.deadline.cancellable(stop=...)``."""
        return self._event

    @property
    def is_set(self) -> bool:
        """Whether ``set`` was called."""
        return self._event.is_set()

    def check(self) -> None:
        """Raise ``Cancelled`` if ``set`` was called.

        Raises
        ------
        Cancelled
        """
        if self._event.is_set():
            raise Cancelled


NEVER = Cancel()
