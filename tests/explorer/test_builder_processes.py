"""The builder's worker processes: a newer request ends an older layout's, a derivation
that runs past its CPU time fails with a message naming it, and stopping leaves none."""

from __future__ import annotations

import pytest

from systems import processes
from tests.slow_work import crawl_describing, crawl_then_derive, gone

WAIT_MS = 60000
"""How long a test waits at most (a busy machine; never a measurement)."""


@pytest.fixture
def service(qtbot):
    from explorer.builder import BuildService

    builder = BuildService()
    yield builder
    builder.stop()


def _layout_jobs(service) -> list:
    return [layout.job for layout in service._worker._layouts if layout.job is not None]


def test_a_newer_request_ends_the_older_layouts_worker(qtbot, service, monkeypatch):
    import explorer.builder

    monkeypatch.setattr(explorer.builder, "describe", crawl_describing)
    built = []
    service.built.connect(built.append)
    service.request(_text("simple_pendulum"))
    qtbot.waitUntil(lambda: len(built) == 1, timeout=WAIT_MS)
    service.frame_shown()  # the window drew the first frame: the layout begins
    qtbot.waitUntil(lambda: any(not job.done() for job in _layout_jobs(service)), timeout=WAIT_MS)
    (old,) = [job for job in _layout_jobs(service) if not job.done()]
    service.request(_text("harmonic_oscillator"))
    qtbot.waitUntil(old.done, timeout=WAIT_MS)
    with pytest.raises(processes.Cancelled):
        old.result()
    qtbot.waitUntil(lambda: gone(old.pid), timeout=WAIT_MS)
    qtbot.waitUntil(lambda: len(built) == 2, timeout=WAIT_MS)


def test_a_derivation_past_its_cpu_time_fails_naming_it(qtbot, service, monkeypatch):
    import explorer.builder

    monkeypatch.setenv("PHASE_EXPLORER_DERIVE_SECONDS", "0.2")
    monkeypatch.setattr(explorer.builder, "build_code", crawl_then_derive)
    failures = []
    service.build_failed.connect(failures.append)
    service.request(_text("simple_pendulum"))
    qtbot.waitUntil(lambda: bool(failures), timeout=WAIT_MS)
    assert "deriving the scene" in failures[0].message
    assert "CPU time" in failures[0].message
    assert not service.deriving


def test_stopping_during_a_derivation_leaves_no_worker(qtbot, service, monkeypatch):
    import explorer.builder

    monkeypatch.setattr(explorer.builder, "build_code", crawl_then_derive)
    service.request(_text("simple_pendulum"))
    qtbot.waitUntil(lambda: service.deriving, timeout=WAIT_MS)
    job = service._worker._job
    assert service.stop()
    qtbot.waitUntil(lambda: gone(job.pid), timeout=WAIT_MS)
    # let go by its waiting thread, which a busy machine may keep a moment
    qtbot.waitUntil(lambda: job not in processes.running(), timeout=WAIT_MS)


def _text(name: str) -> str:
    from systems.scene import SCENES_DIR

    return (SCENES_DIR / f"{name}.toml").read_text(encoding="utf-8")
