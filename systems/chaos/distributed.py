"""Chaos maps and orbit diagrams on a Dask cluster (issue 27 item 4).

A map's or a diagram's rows are independent (``maps.map_chunk``, ``bifurcation.
strobe_chunk``), so a grid cut into chunks can be computed anywhere: each chunk is one
Dask task, and each worker loads the scene from its TOML text, derives and compiles
the system (once per worker process and system: ``_map_kernel``, ``_strobe_kernel``) and
runs the same compiled loop on its chunk as the local run does. On the same machine
(a ``LocalCluster``) the workers load the same machine code from the cache, so the
result is the local one bit for bit; on other machines it is, as far as their numba
compiles the same instructions (a different CPU may fuse multiplies and adds
differently).

Dask is an optional extra (``pip install -e ".[dask]"``): nothing here imports it
before ``connect`` is called, and without it ``connect`` says which extra to install.

Workers. ``connect("auto")`` starts a ``LocalCluster`` of single-threaded worker
processes, one a core, started by spawn (never forked from this process, whose numba
threads a fork would copy half-alive), their scratch space inside the cache directory
(``PHASE_EXPLORER_CACHE``), each worker's compiled loop on one thread. A remote worker
(``dask worker tcp://HOST:PORT``) runs a chunk's loop on its machine's cores divided by
the worker's threads (``_task_threads``).
"""

from __future__ import annotations

import contextlib
import dataclasses
import functools
import os
import re
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass

import numpy as np

from systems.usage import UsageError, cli_name

EXTRA = 'pip install -e ".[dask]"'
ADDRESS = re.compile(r"(tcp|tls)://[^\s:/]+:(\d{1,5})")
CONNECT_TIMEOUT_S = 10
"""How long ``connect`` waits for a scheduler to answer."""


def check_address(address: str, spell: Callable[[str], str] = cli_name) -> str:
    """``address`` if it is ``"auto"`` or a scheduler's ``tcp://HOST:PORT`` (or ``tls://``).

    Raises
    ------
    UsageError
        Naming the option (``spell("dask")``) and the two forms it takes.
    """
    text = str(address).strip()
    match = ADDRESS.fullmatch(text)
    if text == "auto" or (match and 0 < int(match.group(2)) < 65536):
        return text
    raise UsageError(
        f"{spell('dask')} takes auto (a cluster of this machine's cores) or a Dask "
        f"scheduler's address tcp://HOST:PORT, not {address!r}"
    )


def require_dask(spell: Callable[[str], str] = cli_name) -> None:
    """Raise ``UsageError`` naming the extra when ``dask.distributed`` is not installed."""
    try:
        import distributed  # noqa: F401
    except ImportError as exc:
        raise UsageError(
            f"{spell('dask')} needs Dask, an optional extra that is not installed: {EXTRA} "
            '(or pip install "dask[distributed]")'
        ) from exc


@contextlib.contextmanager
def connect(
    address: str, *, workers: int | None = None, spell: Callable[[str], str] = cli_name
) -> Iterator[object]:
    """A ``distributed.Client`` of ``address`` (see ``check_address``), closed on exit
    (with the cluster ``"auto"`` started).

    Parameters
    ----------
    address : str
        ``"auto"``: a ``LocalCluster`` of ``workers`` (default: one a core) spawned
        single-threaded processes; else an existing scheduler's address.

    Raises
    ------
    UsageError
        A malformed address, the extra not installed, or no scheduler answering.
    """
    address = check_address(address, spell)
    require_dask(spell)
    import dask
    from distributed import Client, LocalCluster

    from systems.cache_integrity import cache_root

    scratch = str(cache_root() / "dask")
    settings = {
        "distributed.worker.multiprocessing-method": "spawn",
        "temporary-directory": scratch,
    }
    with dask.config.set(settings):
        if address == "auto":
            cores = os.cpu_count() or 1
            cluster = LocalCluster(
                n_workers=workers or cores, threads_per_worker=1, processes=True,
                dashboard_address=None, local_directory=scratch,
                env={"NUMBA_NUM_THREADS": "1"},
            )  # fmt: skip
            client = Client(cluster)
        else:
            cluster = None
            try:
                client = Client(address, timeout=f"{CONNECT_TIMEOUT_S}s")
            except (OSError, TimeoutError) as exc:
                raise UsageError(
                    f"no Dask scheduler answered at {address} within {CONNECT_TIMEOUT_S} s: "
                    "start one with `dask scheduler` and workers with `dask worker "
                    f"{address}`, or give {spell('dask')} auto"
                ) from exc
    try:
        yield client
    finally:
        client.close()
        if cluster is not None:
            cluster.close()


# -- what a worker needs to rebuild a kernel ----------------------------------------------


@dataclass(frozen=True)
class SystemSpec:
    """A compiled system as text a worker rebuilds it from: the scene's TOML, its name,
    the functions compiled and the parameter values (k,)."""

    scene: str
    name: str
    wanted: tuple[str, ...]
    parameters: tuple[float, ...]

    @classmethod
    def of(cls, compiled) -> SystemSpec:
        scene = compiled.mechanics.scene
        return cls(
            scene.to_toml(), scene.name, tuple(sorted(compiled.wanted)),
            tuple(map(float, compiled.parameters)),
        )  # fmt: skip

    def compile(self):
        """The ``CompiledSystem`` (in this process, from the cache where it is there)."""
        from systems.compiled import compile_system
        from systems.mechanics import derive
        from systems.scene import parse_scene

        scene = parse_scene(self.scene, source=f"<{self.name or 'scene'}>", name=self.name)
        # a worker runs its tasks in threads, where no CPU-time limit can act; the client
        # derived this scene within its limit, and a worker on another machine (another
        # cache) derives it again
        compiled = compile_system(derive(scene, limited=False), self.wanted)
        return compiled.with_parameters(np.array(self.parameters))


@dataclass(frozen=True)
class MapSpec:
    """A ``maps.MapKernel`` as its settings (``map_kernel`` rebuilds it)."""

    system: SystemSpec
    method: str
    dt: float
    t0: float
    t_end: float
    tol: float | None = None
    """taylor's tolerance (its ``dt`` is NaN)."""


@dataclass(frozen=True)
class StrobeSpec:
    """A ``bifurcation.StrobeKernel`` as its settings."""

    system: SystemSpec
    method: str
    parameter: str
    per_period: int
    transient_periods: int
    samples: int
    t0: float
    tol: float | None = None
    """taylor's tolerance (None: a fixed-step method)."""


def map_spec(kernel) -> MapSpec:
    taylor = kernel.method == "taylor"
    return MapSpec(
        SystemSpec.of(kernel.tangent.compiled), kernel.method, kernel.dt, kernel.t0, kernel.t_end,
        kernel.tol if taylor else None,
    )  # fmt: skip


def strobe_spec(kernel) -> StrobeSpec:
    compiled = kernel.compiled
    return StrobeSpec(
        SystemSpec.of(compiled), kernel.method, compiled.parameter_names[kernel.parameter],
        kernel.per_period, kernel.transient_periods, kernel.samples, kernel.t0, kernel.tol,
    )  # fmt: skip


@functools.lru_cache(maxsize=4)
def _map_kernel(spec: MapSpec):
    from systems.chaos.maps import map_kernel
    from systems.chaos.variational import load_tangent

    tangent = load_tangent(spec.system.compile())
    dt = None if spec.method == "taylor" else spec.dt
    return map_kernel(
        tangent, t_end=spec.t_end, method=spec.method, dt=dt, t0=spec.t0, tol=spec.tol
    )


@functools.lru_cache(maxsize=4)
def _strobe_kernel(spec: StrobeSpec):
    from systems.chaos.bifurcation import strobe_kernel

    options = {"tol": spec.tol} if spec.method == "taylor" else {"per_period": spec.per_period}
    kernel = strobe_kernel(
        spec.system.compile(), spec.parameter, samples=spec.samples, method=spec.method,
        t0=spec.t0, **options,
    )  # fmt: skip
    return dataclasses.replace(kernel, transient_periods=spec.transient_periods, _entry=None)


def _task_threads() -> None:
    """Give this task's compiled loop the worker's share of its machine's cores: the
    cores over the worker's threads (``NUMBA_NUM_THREADS`` at most)."""
    import numba

    try:
        from distributed import get_worker

        nthreads = get_worker().state.nthreads
    except (ImportError, ValueError, AttributeError):
        nthreads = 1
    share = max(1, (os.cpu_count() or 1) // max(1, nthreads))
    numba.set_num_threads(min(share, numba.config.NUMBA_NUM_THREADS))


def map_task(spec: MapSpec, starts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A worker's chunk of a map: ``maps.map_chunk`` of ``starts`` (N, 2n)."""
    from systems.chaos.maps import map_chunk

    _task_threads()
    return map_chunk(_map_kernel(spec), starts)


def strobe_task(
    spec: StrobeSpec, values: np.ndarray, y0: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A worker's chunk of an orbit diagram: ``bifurcation.strobe_chunk`` of ``values`` (N,)."""
    from systems.chaos.bifurcation import strobe_chunk

    _task_threads()
    return strobe_chunk(_strobe_kernel(spec), values, y0)


def chunk_size(client, rows: int, chunk: int) -> int:
    """At most ``chunk`` rows a task, and at least four tasks for each of the cluster's
    worker threads where the rows allow (at least 8 rows a task): every worker busy
    to the end."""
    info = client.scheduler_info()
    threads = sum(w.get("nthreads", 1) for w in info.get("workers", {}).values()) or 1
    return max(1, min(chunk, max(8, -(-rows // (4 * threads)))))


def remote(compute: Callable, kernel) -> tuple[Callable, object]:
    """The task a worker runs for ``compute(kernel, ...)`` (``maps.map_chunk`` or
    ``bifurcation.strobe_chunk``) and the spec it rebuilds ``kernel`` from."""
    if compute.__name__ == "map_chunk":
        return map_task, map_spec(kernel)
    if compute.__name__ == "strobe_chunk":
        return strobe_task, strobe_spec(kernel)
    raise ValueError(f"no task computes {compute.__name__} on a cluster")


def submitted(
    client, task: Callable, spec, chunks: Sequence[tuple], keys: Sequence
) -> Iterator[tuple[object, tuple]]:
    """``(key, task(spec, *chunk))`` for every chunk, in the order they finish on the
    cluster. Closing the generator early (a cancel) cancels what has not run."""
    from distributed import as_completed

    spec_future = client.scatter(spec, broadcast=True)
    futures = {
        client.submit(task, spec_future, *chunk, pure=False): key
        for chunk, key in zip(chunks, keys, strict=True)
    }
    try:
        for future in as_completed(futures):
            yield futures[future], future.result()
    finally:
        client.cancel(list(futures))


__all__ = [
    "EXTRA", "MapSpec", "StrobeSpec", "SystemSpec", "check_address", "chunk_size", "connect",
    "map_spec", "remote",
    "map_task", "require_dask", "strobe_spec", "strobe_task", "submitted",
]  # fmt: skip
