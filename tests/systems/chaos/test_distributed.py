"""Chaos maps and orbit diagrams on a Dask cluster (issue 27 item 4): a two-worker
``LocalCluster`` computes the same numbers, bit for bit, as the local run; the
``dask`` argument's mistakes are refused with a message naming what to fix."""

import json
import sys

import numpy as np
import pytest

import phase_explorer as pe
from systems.usage import UsageError

GRID = (16, 12)
T_END = 40.0


@pytest.fixture(scope="module")
def scheduler(tmp_path_factory):
    """The address of a two-worker ``LocalCluster`` (spawned single-threaded processes,
    scratch space in a temporary directory), closed after the module's tests."""
    pytest.importorskip(
        "distributed", reason='dask is an optional extra, not installed: pip install -e ".[dask]"'
    )
    import dask
    from distributed import LocalCluster

    scratch = str(tmp_path_factory.mktemp("dask"))
    settings = {
        "distributed.worker.multiprocessing-method": "spawn",
        "temporary-directory": scratch,
    }
    with dask.config.set(settings):
        cluster = LocalCluster(
            n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None,
            local_directory=scratch, env={"NUMBA_NUM_THREADS": "1"},
        )  # fmt: skip
    try:
        yield cluster.scheduler_address
    finally:
        cluster.close()


def test_a_chaos_map_through_two_workers_equals_the_local_map_exactly(scheduler):
    henon = pe.load("henon_heiles")
    seen = []
    local = henon.chaosmap(GRID, energy=1 / 8, t_end=T_END)
    remote = henon.chaosmap(
        GRID, energy=1 / 8, t_end=T_END, dask=scheduler, progress=lambda d, n: seen.append((d, n))
    )
    orbits = int((local.status >= 0).sum())
    assert orbits > 60 and (local.status == 0).sum() == orbits
    assert np.array_equal(local.megno, remote.megno, equal_nan=True)
    assert np.array_equal(local.lyapunov, remote.lyapunov, equal_nan=True)
    assert np.array_equal(local.status, remote.status)
    assert local.chaotic_fraction == remote.chaotic_fraction
    assert seen[-1] == (orbits, orbits) and len(seen) > 2  # several chunks


def test_the_chaosmap_command_on_a_scheduler_writes_the_local_map(scheduler, tmp_path, capsys):
    from explorer.cli import main

    argv = ["chaosmap", "henon_heiles", "--grid", "9x7", "--t-end", "30", "--json"]
    assert main([*argv, "--out", str(tmp_path / "local.npz")]) == 0
    local = json.loads(capsys.readouterr().out)
    assert main([*argv, "--out", str(tmp_path / "remote.npz"), "--dask", scheduler]) == 0
    remote = json.loads(capsys.readouterr().out)
    assert remote["chaotic_fraction"] == local["chaotic_fraction"]
    a, b = np.load(tmp_path / "local.npz"), np.load(tmp_path / "remote.npz")
    for key in ("megno", "lyapunov", "megno_now", "status"):
        assert np.array_equal(a[key], b[key], equal_nan=True), key


def test_an_orbit_diagram_through_two_workers_equals_the_local_one_exactly(scheduler):
    pendulum = pe.load("driven_damped_pendulum")
    values = np.linspace(1.0, 1.1, 9)
    options = dict(transient=60.0, samples=6, start={"theta": -1.5707963, "theta_dot": 0.0})
    local = pendulum.bifurcation("A", values, **options)
    remote = pendulum.bifurcation("A", values, dask=scheduler, **options)
    assert (local.status == 0).all()
    assert np.array_equal(local.samples, remote.samples)
    assert np.array_equal(local.periods, remote.periods)
    assert np.isfinite(local.samples).all() and len(np.unique(local.samples[:, -1, 0])) == 9


@pytest.mark.parametrize("address", ["local", "tcp://host", "tcp://host:0", "http://h:8786", ""])
def test_a_malformed_dask_value_is_named(address):
    with pytest.raises(UsageError, match="dask takes auto .* tcp://HOST:PORT, not"):
        pe.load("henon_heiles").chaosmap((4, 4), t_end=1.0, dask=address)


def test_something_else_as_dask_is_named():
    with pytest.raises(UsageError, match="a distributed.Client, not int"):
        pe.load("henon_heiles").chaosmap((4, 4), t_end=1.0, dask=4)


def test_without_the_extra_dask_names_it(monkeypatch):
    monkeypatch.setitem(sys.modules, "distributed", None)  # import distributed fails
    with pytest.raises(UsageError, match=r'optional extra .*pip install -e "\.\[dask\]"'):
        pe.load("driven_damped_pendulum").bifurcation("A", [1.0, 1.1], dask="auto")


def test_a_worker_thread_rebuilds_a_scene_its_cache_has_not_seen(tmp_path, monkeypatch):
    """A Dask worker runs its tasks in threads, and one on another machine has a cache of
    its own: it derives the client's scene there, without the CPU-time limit only a main
    thread can enforce (it had raised RuntimeError, seen when a worker's cache missed)."""
    import threading

    from systems.chaos.distributed import SystemSpec
    from systems.compiled import compile_system
    from systems.mechanics import derive
    from systems.scene import load_scene

    spec = SystemSpec.of(compile_system(derive(load_scene("henon_heiles")), ("rhs",)))
    monkeypatch.setenv("PHASE_EXPLORER_CACHE", str(tmp_path / "another machine"))
    found = {}

    def task():
        try:
            found["compiled"] = spec.compile()
        except Exception as exc:  # noqa: BLE001 - reported below
            found["error"] = exc

    thread = threading.Thread(target=task)
    thread.start()
    thread.join(600)
    assert "error" not in found, found["error"]
    compiled = found["compiled"]
    assert compiled.mechanics.scene.name == "henon_heiles"
    y0 = compiled.initial_state()
    assert np.isfinite(compiled.rhs(0.0, y0)).all()
    assert (tmp_path / "another machine" / "derivations").is_dir()  # derived there, kept
