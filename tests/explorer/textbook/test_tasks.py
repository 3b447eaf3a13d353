"""The Textbook's job pool (``explorer.textbook.tasks``): a superseded or shut-down job
stops at ``systems.deadline``'s checkpoints too, not only at its own ``cancel.check()``."""

from __future__ import annotations

import multiprocessing
import time

from explorer.textbook.tasks import TaskRunner
from systems.textbook._numeric import POLL_SECONDS, run_bounded


def _waits_for_a_child(seconds: float, *, cancel):
    """A job like the equilibrium search's exact solve: a forked child it waits for."""
    return run_bounded(time.sleep, (seconds,), seconds)


def test_shutdown_ends_a_job_waiting_for_its_forked_child(qtbot):
    runner = TaskRunner()
    results = []
    runner.submit("solve", _waits_for_a_child, 30.0, on_done=results.append)
    qtbot.waitUntil(lambda: multiprocessing.active_children() != [], timeout=5000)
    start = time.monotonic()
    assert runner.shutdown(5000)
    assert time.monotonic() - start < 10 * POLL_SECONDS + 1.0
    assert multiprocessing.active_children() == []  # killed and reaped
    assert results == []


def test_a_newer_job_supersedes_one_waiting_for_its_child(qtbot):
    runner = TaskRunner()
    results = []
    runner.submit("solve", _waits_for_a_child, 30.0, on_done=results.append)
    qtbot.waitUntil(lambda: multiprocessing.active_children() != [], timeout=5000)
    runner.submit("solve", lambda *, cancel: "newest", on_done=results.append)
    qtbot.waitUntil(lambda: results == ["newest"], timeout=5000)
    qtbot.waitUntil(lambda: runner.pending == 0, timeout=2000)  # the old one ended
    assert multiprocessing.active_children() == []
    assert runner.shutdown(1000)
