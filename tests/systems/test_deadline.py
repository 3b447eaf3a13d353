"""Ending work in other threads safely (``systems.deadline``).

An asynchronous exception that landed in importlib just after it took the global import
lock left that lock held for ever: a window switching scenes quickly ended with a dozen
threads waiting to import (py-spy), and CI hung. These tests pin down what replaced it:
no asynchronous exception inside an import (or numba, or the standard library's locking
code), cooperative ``cancel`` / ``checkpoint``, a stop that never outlives its block, and
the clean-up that frees the import lock whatever happens.
"""

from __future__ import annotations

import _imp
import sys
import threading
import time

import pytest

from systems import deadline
from systems.deadline import (
    Abandoned,
    TimeLimitExceeded,
    abandon,
    cancel,
    cancellable,
    checkpoint,
    interruptible,
    release_import_lock,
    time_limit,
)


def spin(seconds: float) -> None:
    end = time.perf_counter() + seconds
    while time.perf_counter() < end:
        pass


def _until(condition, seconds: float = 5.0) -> bool:
    end = time.monotonic() + seconds
    while not condition():
        if time.monotonic() > end:
            return False
        time.sleep(0.005)
    return True


@pytest.fixture
def blocking_module(tmp_path, monkeypatch):
    """A module whose import waits for an event: (its name, the event, 'entered' event)."""
    name = f"blocking_import_{time.monotonic_ns()}"
    (tmp_path / f"{name}.py").write_text(
        "import builtins, time\n"
        f"gate = builtins.__dict__['{name}']\n"
        "gate[1].set()\n"
        "while not gate[0].is_set():\n"
        "    time.sleep(0.001)\n"
        "VALUE = 42\n",
        encoding="utf-8",
    )
    monkeypatch.syspath_prepend(str(tmp_path))
    gate = (threading.Event(), threading.Event())
    import builtins

    monkeypatch.setitem(builtins.__dict__, name, gate)
    yield name, gate[0], gate[1]
    gate[0].set()
    sys.modules.pop(name, None)


def test_no_exception_lands_inside_an_import(blocking_module):
    """Abandoned while importing: the import completes, then the thread is abandoned,
    and the import lock is free afterwards."""
    name, release, entered = blocking_module
    state: list[str] = []

    def work():
        try:
            with cancellable():
                module = __import__(name)
                state.append(f"imported {module.VALUE}")
                spin(30.0)
        except Abandoned:
            state.append("abandoned")

    thread = threading.Thread(target=work)
    thread.start()
    assert entered.wait(5.0)
    assert not interruptible(thread.ident)  # importlib is on its stack
    assert abandon(thread)
    time.sleep(0.2)
    assert thread.is_alive() and state == [], "nothing may land inside the import"
    release.set()
    thread.join(5.0)
    assert state == ["imported 42", "abandoned"]
    assert name in sys.modules and not _imp.lock_held()


def test_a_time_limit_waits_for_an_import_to_end(blocking_module):
    name, release, entered = blocking_module
    outcome: list[object] = []

    def work():
        try:
            with time_limit(0.05, "importing"):
                __import__(name)
                outcome.append("imported")
                spin(30.0)
        except TimeLimitExceeded:
            outcome.append("stopped")

    thread = threading.Thread(target=work)
    thread.start()
    assert entered.wait(5.0)
    time.sleep(0.3)  # well past the limit, inside the import
    assert outcome == []
    release.set()
    thread.join(5.0)
    assert outcome == ["imported", "stopped"]
    assert not _imp.lock_held()


def test_a_thread_waiting_on_a_lock_is_not_interruptible():
    event = threading.Event()
    thread = threading.Thread(target=event.wait, args=(10.0,))
    thread.start()
    try:
        assert _until(lambda: sys._current_frames().get(thread.ident) is not None)
        time.sleep(0.05)
        assert not interruptible(thread.ident)  # threading's frames on top
    finally:
        event.set()
        thread.join()
    assert not interruptible(thread.ident)  # ended: no frame


def test_abandon_outside_cancellable_does_nothing():
    state: list[str] = []

    def work():
        try:
            spin(0.4)
            state.append("finished")
        except Abandoned:
            state.append("abandoned")

    thread = threading.Thread(target=work)
    thread.start()
    time.sleep(0.05)
    assert not abandon(thread)
    thread.join(5.0)
    assert state == ["finished"]


def test_abandon_never_outlives_its_block():
    """A thread abandoned while not interruptible (in a lock wait) that then leaves its
    block is left alone: nothing lands in the code after the block."""
    state: list[str] = []
    go = threading.Event()

    def work():
        with cancellable():
            go.wait(10.0)  # not interruptible here
        try:
            spin(0.5)
            state.append("after the block, undisturbed")
        except Abandoned:
            state.append("abandoned after the block")

    thread = threading.Thread(target=work)
    thread.start()
    time.sleep(0.05)
    assert abandon(thread)
    go.set()
    thread.join(5.0)
    assert state == ["after the block, undisturbed"]


def test_cancel_stops_at_the_next_checkpoint_only():
    state: list[str] = []
    asked = threading.Event()

    def work():
        try:
            with cancellable():
                asked.wait(5.0)
                spin(0.2)  # no checkpoint: runs to its end
                state.append("spun")
                checkpoint()
                state.append("past the checkpoint")
        except Abandoned:
            state.append("stopped")
        with cancellable():  # a new block starts afresh
            checkpoint()
            state.append("new block runs")

    thread = threading.Thread(target=work)
    thread.start()
    time.sleep(0.05)
    assert cancel(thread)
    asked.set()
    thread.join(5.0)
    assert state == ["spun", "stopped", "new block runs"]
    assert thread.ident not in deadline._cancelled


def test_release_import_lock_frees_every_level_this_thread_holds():
    _imp.acquire_lock()
    _imp.acquire_lock()
    assert release_import_lock() == 2
    assert not _imp.lock_held()
    assert release_import_lock() == 0


def test_run_bounded_stops_waiting_when_cancelled():
    """The equilibrium search's forked ``sympy.solve`` ends with its thread's stop."""
    from systems.textbook._numeric import POLL_SECONDS, run_bounded

    state: list[object] = []

    def work():
        try:
            with cancellable():
                state.append(run_bounded(time.sleep, (30.0,), 30.0))
        except Abandoned:
            state.append("stopped")

    thread = threading.Thread(target=work)
    thread.start()
    time.sleep(0.3)  # the child is running
    start = time.monotonic()
    assert cancel(thread)
    thread.join(5.0)
    assert state == ["stopped"]
    assert time.monotonic() - start < 10 * POLL_SECONDS + 1.0
    import multiprocessing

    assert multiprocessing.active_children() == []  # killed and reaped


def test_a_stop_event_stops_the_block_at_a_checkpoint_and_ends_with_it():
    stop, inner = threading.Event(), threading.Event()
    with cancellable(stop=stop):
        checkpoint()
        with cancellable(stop=inner):
            stop.set()  # the outer one's: the inner block has its own
            checkpoint()
            inner.set()
            with pytest.raises(Abandoned):
                checkpoint()
        with pytest.raises(Abandoned):  # the outer event again
            checkpoint()
    checkpoint()  # outside every block: nothing to stop
    assert threading.get_ident() not in deadline._stop_events


def test_abandoned_leaving_its_block_frees_the_import_lock():
    """What an exception that landed in importlib despite ``interruptible`` would leave."""
    with pytest.raises(Abandoned):
        with cancellable():
            _imp.acquire_lock()  # as importlib holds it for a moment
            raise Abandoned
    assert not _imp.lock_held()
