"""Stopping a job early, where it runs in the caller's own process.

The window does not use this: it runs each job in a worker process and ends the process
when the result is no longer wanted (``systems.processes``). A caller that runs a job
itself can pass a ``Cancel`` and set it from elsewhere (another thread, a signal
handler): the job's loops check it between steps. A job's symbolic parts are limited by
``systems.cpu_limit``, which works only in a process's main thread: that is where a job
runs.
"""

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
    def is_set(self) -> bool:
        """Whether ``set`` was called."""
        return self._event.is_set()

    def __job_key__(self) -> str:
        """A token changes no job's answer (``derivation_cache.remembered_job``)."""
        return ""

    def check(self) -> None:
        """Raise ``Cancelled`` if ``set`` was called.

        Raises
        ------
        Cancelled
        """
        if self._event.is_set():
            raise Cancelled


NEVER = Cancel()
