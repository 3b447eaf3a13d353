"""The Textbook's job runner (``explorer.textbook.tasks``): every job in a worker process,
ended (not asked) when superseded or shut down, results on the GUI thread, failures as
one line, and nothing of Qt in the workers."""

from __future__ import annotations

import pytest

from explorer.textbook.tasks import TaskRunner
from systems import processes
from systems.compiled import compile_system
from systems.mechanics import derive
from systems.scene import load_scene
from systems.textbook import jobs
from tests.explorer.textbook import workloads
from tests.slow_work import gone

WAIT_MS = 30000
"""How long a test waits at most for a worker (a busy machine; never a measurement)."""


def running_pids() -> set[int]:
    return {job.pid for job in processes.running()}


@pytest.fixture
def runner(qtbot):
    runner = TaskRunner()
    yield runner
    assert runner.shutdown(WAIT_MS)


def _looping(qtbot, runner, key, tmp_path, done, failed) -> int:
    """Submit a job that loops for ever; its worker's pid once it is in the loop."""
    marker = tmp_path / f"{key}.started"
    before = set(runner.pids())
    runner.submit(
        key, workloads.loop_forever, str(marker), on_done=done.append, on_failed=failed.append
    )
    qtbot.waitUntil(marker.exists, timeout=WAIT_MS)
    (pid,) = set(runner.pids()) - before
    return pid


def test_cancelling_a_job_that_loops_ends_its_worker_and_delivers_nothing(qtbot, runner, tmp_path):
    done, failed = [], []
    pid = _looping(qtbot, runner, "spin", tmp_path, done, failed)
    assert pid in running_pids() and not gone(pid)
    runner.cancel("spin")
    qtbot.waitUntil(lambda: gone(pid) and runner.pending == 0, timeout=WAIT_MS)
    assert pid not in running_pids()
    qtbot.wait(20)
    assert done == [] and failed == []


def test_a_newer_job_ends_the_one_it_supersedes(qtbot, runner, tmp_path):
    done, failed = [], []
    pid = _looping(qtbot, runner, "spin", tmp_path, done, failed)
    runner.submit("spin", workloads.answer, "newest", on_done=done.append)
    qtbot.waitUntil(lambda: done == ["newest"], timeout=WAIT_MS)
    qtbot.waitUntil(lambda: gone(pid) and runner.pending == 0, timeout=WAIT_MS)
    assert failed == []


def test_failures_come_as_one_line(qtbot, runner):
    failed = []
    runner.submit("a", workloads.fail, "bad input", on_done=print, on_failed=failed.append)
    runner.submit("b", workloads.fail_oddly, on_done=print, on_failed=failed.append)
    qtbot.waitUntil(lambda: len(failed) == 2, timeout=WAIT_MS)
    # the one that cannot cross back as itself keeps its name and message
    assert sorted(failed) == ["Odd: odd failure", "ValueError: bad input"]


def test_a_runaway_job_is_stopped_by_its_cpu_limit_naming_what_it_did(qtbot, tmp_path):
    runner = TaskRunner(cpu_seconds=0.5)
    failed = []
    runner.submit(
        "spin",
        workloads.loop_forever,
        str(tmp_path / "started"),
        on_done=print,
        on_failed=failed.append,
        what="spinning for a test",
    )
    qtbot.waitUntil(lambda: failed != [], timeout=WAIT_MS)
    assert "TimeLimitExceeded" in failed[0]
    assert "spinning for a test took longer than 0.5 s of CPU time" in failed[0]
    assert runner.shutdown(WAIT_MS)


def test_shutdown_ends_every_worker_and_delivers_nothing(qtbot, tmp_path):
    runner = TaskRunner()
    done, failed = [], []
    pids = [_looping(qtbot, runner, key, tmp_path, done, failed) for key in ("one", "two")]
    assert runner.pending == 2
    assert runner.shutdown(WAIT_MS)
    assert all(gone(pid) for pid in pids)
    assert not running_pids() & set(pids)
    assert runner.submit("three", workloads.answer, 3, on_done=done.append) == 0
    qtbot.wait(50)
    assert done == [] and failed == []


def test_wait_returns_once_every_job_has_answered(qtbot, runner):
    done = []
    for k in range(3):
        runner.submit(f"k{k}", workloads.answer, k, on_done=done.append)
    assert runner.wait(WAIT_MS)
    qtbot.waitUntil(lambda: sorted(done) == [0, 1, 2], timeout=WAIT_MS)
    assert runner.pending == 0


def test_textbook_jobs_run_in_workers_without_qt(qtbot, runner):
    compiled = compile_system(derive(load_scene("planetary_motion")), ("rhs", "hamiltonian"))
    done = []
    runner.submit(
        "reduction",
        workloads.run_and_list_qt,
        jobs.reduction_with_curves,
        compiled,
        on_done=done.append,
        on_failed=pytest.fail,
    )
    qtbot.waitUntil(lambda: done != [], timeout=WAIT_MS)
    (setup, curves), qt = done[0]
    assert qt == []
    assert setup.reduction.cyclic == ("theta",)
    assert curves.turning == pytest.approx([1.0, 3.0], rel=1e-6)
    # the sliders' curves come from the functions made in the worker
    again = jobs.reduction_curves(setup, jobs.parameters_of(compiled), setup.p_cyclic)
    assert again.turning == pytest.approx(curves.turning)
