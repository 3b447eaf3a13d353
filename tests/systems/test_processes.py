"""Symbolic work in worker processes (``systems.processes``): answers, errors, cancelling,
CPU-time limits, and nothing left behind."""

from __future__ import annotations

import importlib
import itertools
import os
import signal
import sys
import time

import pytest
import sympy

from systems import processes
from systems.cpu_limit import TimeLimitExceeded
from systems.scene import SceneError, parse_scene
from tests.slow_work import gone

WAIT = 60.0
"""Seconds a test waits at most for a worker (a busy machine; never a measurement)."""


def spin() -> None:
    x = 0
    while True:
        x += 1


def spin_in_c() -> None:
    sum(itertools.count())  # no bytecode to interrupt: only the kernel's limit ends it


def environment(name: str) -> str | None:
    return os.environ.get(name)


def modules_loaded(prefix: str) -> list[str]:
    return sorted(name for name in sys.modules if name.startswith(prefix))


def imported_by(names: list[str]) -> list[str]:
    before = set(sys.modules)
    for name in names:
        importlib.import_module(name)
    return sorted(set(sys.modules) - before)


def signal_handler(number: int):
    return signal.getsignal(number)


def unpicklable_value():
    return lambda: None


class Odd(Exception):
    def __init__(self, a, b):  # pickled with args=(a,) only: cannot be rebuilt
        super().__init__(a)
        self.b = b


def raise_odd():
    raise Odd("odd failure", 2)


def test_a_value_comes_back_from_another_process():
    job = processes.submit(os.getpid, what="asking the pid")
    assert job.result(WAIT) != os.getpid()
    assert job.done() and job.exception() is None


def test_errors_come_back_as_themselves_with_where_they_are():
    with pytest.raises(SceneError) as caught:
        processes.submit(parse_scene, "[system]\ncoordinates = 3\n").result(WAIT)
    local = pytest.raises(SceneError, parse_scene, "[system]\ncoordinates = 3\n").value
    assert str(caught.value) == str(local)
    assert getattr(caught.value, "field", None) == getattr(local, "field", None)


def test_what_cannot_cross_back_is_described():
    with pytest.raises(processes.RemoteError, match="odd failure") as caught:
        processes.submit(raise_odd).result(WAIT)
    assert caught.value.type_name == "Odd"
    with pytest.raises(processes.RemoteError, match="unpicklable_value"):
        processes.submit(unpicklable_value, what="unpicklable_value").result(WAIT)


def test_cancelling_ends_the_worker():
    job = processes.submit(spin, what="spinning")
    pid = job.pid
    job.cancel()
    with pytest.raises(processes.Cancelled):
        job.result(WAIT)
    assert gone(pid)
    assert job not in processes.running()


def test_a_cpu_limit_stops_python_work_naming_it():
    with pytest.raises(TimeLimitExceeded, match="spinning") as caught:
        processes.submit(spin, cpu_seconds=0.2, what="spinning").result(WAIT)
    assert caught.value.seconds == 0.2


def test_the_kernel_ends_work_that_no_signal_handler_reaches():
    """A loop in C never returns to the interpreter: RLIMIT_CPU ends the worker."""
    with pytest.raises(TimeLimitExceeded, match="summing"):
        processes.submit(spin_in_c, cpu_seconds=0.1, what="summing").result(WAIT)


def test_settings_are_the_callers_at_submit(monkeypatch):
    processes.submit(os.getpid).result(WAIT)  # the fork server runs already
    monkeypatch.setenv("PHASE_EXPLORER_DERIVE_SECONDS", "123")
    assert processes.submit(environment, "PHASE_EXPLORER_DERIVE_SECONDS").result(WAIT) == "123"
    monkeypatch.delenv("PHASE_EXPLORER_DERIVE_SECONDS")
    assert processes.submit(environment, "PHASE_EXPLORER_DERIVE_SECONDS").result(WAIT) is None


def test_workers_are_warm_and_never_load_qt():
    assert "sympy" in processes.submit(modules_loaded, "sympy").result(WAIT)
    assert processes.submit(modules_loaded, "PySide6").result(WAIT) == []


def test_the_windows_jobs_find_their_modules_imported():
    """The modules of the jobs a window submits (the Textbook's, the normal modes', the
    constraint forces', the build's and the typesetting's) are in the fork server: a
    job imported scipy's integrate, optimize and special itself before, 0.4 s of the
    0.5 s an equilibrium search took."""
    jobs = [
        "systems.textbook.jobs",
        "systems.normal_modes",
        "systems.constraint_forces",
        "systems.sources",
        "systems.typeset",
        "systems.report",
    ]
    assert processes.submit(imported_by, jobs).result(WAIT) == []


def test_ctrl_c_is_the_callers_to_handle():
    assert processes.submit(signal_handler, signal.SIGINT).result(WAIT) == signal.SIG_IGN


def test_cancel_all_leaves_no_worker():
    jobs = [processes.submit(spin, what=f"spinning {i}") for i in range(3)]
    pids = [job.pid for job in jobs]
    assert processes.cancel_all(WAIT)
    assert processes.running() == []
    assert all(gone(pid) for pid in pids)


def test_on_done_is_called_once_finished():
    seen = []
    job = processes.submit(os.getpid, on_done=seen.append)
    job.wait(WAIT)
    end = time.monotonic() + WAIT
    while not seen and time.monotonic() < end:
        time.sleep(0.01)  # the callback runs in the waiting thread, after done()
    assert seen == [job]


def test_a_derivation_runs_in_a_worker_and_crosses_back(monkeypatch):
    from systems.mechanics import derive
    from systems.scene import load_scene

    monkeypatch.setenv("PHASE_EXPLORER_DERIVATION_CACHE", "0")
    scene = load_scene("double_pendulum")
    there = processes.submit(derive, scene, what="deriving").result(WAIT)
    here = derive(scene)
    assert type(there) is type(here) and there.n == here.n == 2
    symbols = sorted(here.hamiltonian.free_symbols | {*here.p, *here.q}, key=str)
    point = {s: 0.3 + 0.1 * i for i, s in enumerate(symbols)}
    point_there = {sympy.Symbol(str(s), **s.assumptions0): v for s, v in point.items()}
    for a, b in zip(there.hamilton_equations, here.hamilton_equations, strict=True):
        assert float(a.subs(point_there)) == pytest.approx(float(b.subs(point)), rel=1e-12)


def test_a_script_without_a_main_guard_is_not_run_again_by_workers(tmp_path):
    """Workers never run the caller's main script again (multiprocessing would, for
    functions defined there): a script without ``if __name__ == "__main__"`` that opens
    the window or submits a job does so once."""
    import subprocess

    script = tmp_path / "unguarded.py"
    script.write_text(
        "import os\n"
        "from systems import processes\n"
        "print('script ran', flush=True)\n"
        "print('worker', processes.run(os.getpid, what='asking') != os.getpid(), flush=True)\n"
    )
    done = subprocess.run(
        [sys.executable, str(script)], capture_output=True, text=True, timeout=300
    )
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.splitlines() == ["script ran", "worker True"]


def test_the_builders_jobs_never_load_qt_in_a_worker():
    """What the window sends to workers lives in ``systems``: a worker unpickling it
    imports no Qt (it did, through explorer.builder, for 0.1 s a job)."""
    import pickle

    from explorer import builder

    for function in (builder.build_code, builder.describe, builder.equilibria_lines):
        assert pickle.loads(pickle.dumps(function)).__module__.startswith("systems.")
