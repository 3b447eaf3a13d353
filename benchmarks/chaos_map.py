"""A 200 x 200 Hénon–Heiles MEGNO map (issue 27): orbit-steps per second on one core, on
all cores and through a Dask ``LocalCluster``, and heyoka's ``ensemble_propagate_until``
on the same orbits at equal accuracy, in one run.

The map is the x = 0 section at E = 1/8 (half regular, half chaotic), t = 500, with the
map's default method and step (``systems.chaos.maps``: yoshida4, dt = 0.143). Targets:
the whole map under a minute on two cores, at least 1.8x from one core to two, and
within 1.5x of heyoka's time.

- *Cores*: the same map on one thread and on all (``numba.set_num_threads``), ``REPEAT``
  times each, interleaved, the fastest of each kept; the load average is printed beside
  the ratio (with other work on the cores the threads would share, the ratio says
  nothing), and each run's CPU time over its wall time and threads (below 100 % when a
  thread waited: for a core, or for the others at the end of a chunk).
- *LocalCluster*: ``systems.chaos.distributed.connect("auto")`` (one single-threaded
  worker process a core), every worker's kernel built first (``client.run``); the
  cluster's start and that build are timed apart from the map.
- *heyoka* (``pip install -e ".[bench]"``): the same orbits with the same tangent vector,
  MEGNO measured there too: the variational equations and Cincotta & Simó's
  integrals W' = t (delta . delta')/|delta|^2, Z' = 2 W / t, <Y> = Z / t, written by
  hand for Hénon–Heiles (the 1/t starts at t = 1e-8, W = Z = 0 there: the orbits run
  500 - 1e-8). Equal accuracy: the loosest tolerance of ``TOLERANCES`` whose median
  relative energy error at t = 500, over ``SAMPLE`` orbits of the grid, is at most the
  map's over the same orbits (its orbits' final states, ``map_chunk(final=...)``). Then
  the whole grid by ``ensemble_propagate_until`` (threads, one a core; in blocks of
  ``BLOCK`` orbits, as each orbit keeps a copy of the integrator, ~200 kB), and, as
  heyoka's fast path, by ``ensemble_propagate_until_batch`` (SIMD batches).
- *taylor* (issue 28): the same grid with ``method="taylor"`` (adaptive Taylor series at
  machine epsilon, the variational equations and MEGNO's integral in the series, SIMD
  batches on all threads: ``systems.chaos.taylor_map``) against the default map, runs
  interleaved, ``REPEAT`` each, the fastest kept; the orbits' energy error (median over
  ``SAMPLE`` orbits), the verdicts that differ, and the map on one thread equal to the
  map on all. ``--taylor`` runs this comparison alone.
"""

from __future__ import annotations

import math
import os
import sys
import time

import numpy as np
from _common import compiled_scene, report

SIZE = 200
ENERGY = 1 / 8
SAMPLE = 400
TOLERANCES = (1e-3, 1e-4, 1e-5, 1e-6, 1e-8, 1e-10, 1e-12, 1e-14)
BLOCK = 1000
T_START = 1e-8
REPEAT = 3
"""Runs on one thread and on all, interleaved; the fastest of each is kept."""


def _build_on_worker(spec) -> None:
    """Run on every worker by ``client.run``: its kernel built (derived, compiled)."""
    from systems.chaos import distributed

    distributed._map_kernel(spec)


def main(only_taylor: bool = False) -> bool:
    import numba

    from systems.chaos import maps
    from systems.chaos.variational import load_tangent
    from systems.section import Section

    print("chaos_map")
    compiled = compiled_scene("henon_heiles", ("rhs", "hamiltonian", "separable"))
    tangent = load_tangent(compiled)
    kernel = maps.map_kernel(tangent, t_end=maps.DEFAULT_T_END)
    section = Section(0, 0.0, 1)
    box = maps.section_box(compiled, section, ENERGY)
    grid = maps.section_grid(compiled, section, ENERGY, SIZE, SIZE, box)
    small = maps.section_grid(compiled, section, ENERGY, 4, 4, box)
    maps.chaos_map(kernel, small)  # compile
    orbits = int(grid.valid.sum())
    cores = os.cpu_count() or 1
    threads = numba.config.NUMBA_NUM_THREADS
    steps = orbits * kernel.nsteps
    if only_taylor:
        return _taylor(compiled, tangent, kernel, grid, small, threads)

    def timed(n_threads: int):
        numba.set_num_threads(n_threads)
        start, cpu = time.perf_counter(), time.process_time()
        result = maps.chaos_map(kernel, grid)
        wall, cpu = time.perf_counter() - start, time.process_time() - cpu
        return wall, cpu / (wall * n_threads), cpu, result

    loads = [os.getloadavg()[0]]
    runs = {1: [], threads: []}
    for _ in range(REPEAT):
        for n in runs:
            runs[n].append(timed(n))
            loads.append(os.getloadavg()[0])
    serial, _, serial_cpu, one = min(runs[1], key=lambda run: run[0])
    parallel, _, parallel_cpu, many = min(runs[threads], key=lambda run: run[0])

    def listed(n: int) -> str:
        return ", ".join(f"{wall:.1f} s ({busy:.0%})" for wall, busy, _, _ in runs[n])

    print(
        f"  {SIZE}x{SIZE} grid, {orbits} orbits on the section, {kernel.method} dt = "
        f"{kernel.dt:.3g}, t = {kernel.t:g}, {steps:.3g} orbit-steps: {steps / serial:.3g} "
        f"orbit-steps/s on 1 thread ({serial:.1f} s), {steps / parallel:.3g} on {threads} "
        f"({parallel:.1f} s; {cores} cores); runs on 1 thread {listed(1)}, on {threads} "
        f"{listed(threads)} (in parentheses: CPU time over wall time and threads, below 100 "
        "% when a thread waited for a core); chaotic fraction "
        f"{many.chaotic_fraction():.3f}; load average {min(loads):.1f} to {max(loads):.1f} "
        f"(above about {cores - threads + 1} other work takes the cores the threads would "
        "share: the speed-up then says nothing)"
    )
    same = _same(one, many)
    ok = report("same map on 1 and on all threads", float(same), "1 (bitwise)", same)
    ok &= report("whole map on all threads, s", parallel, "< 60", parallel < 60)
    speedup = serial / parallel
    target = 0.9 * min(cores, 2)
    ok &= report("speed-up, all threads vs one", speedup, f">= {target:.2g}", speedup >= target)
    ok &= _cluster(kernel, grid, many, steps)
    ok &= _heyoka(compiled, kernel, grid, many, (parallel, parallel_cpu, serial_cpu), cores)
    ok &= _taylor(compiled, tangent, kernel, grid, small, threads)
    return ok


def _taylor(compiled, tangent, kernel, grid, small, threads: int) -> bool:
    """The taylor map against the default one (see the module)."""
    import numba

    from systems.chaos import maps

    taylor = maps.map_kernel(tangent, t_end=kernel.t, method="taylor")
    maps.chaos_map(taylor, small)  # compile
    numba.set_num_threads(threads)
    loads = [os.getloadavg()[0]]
    runs: dict[str, list] = {"default": [], "taylor": []}
    for _ in range(REPEAT):
        for name, k in (("default", kernel), ("taylor", taylor)):
            start, cpu = time.perf_counter(), time.process_time()
            result = maps.chaos_map(k, grid)
            runs[name].append((time.perf_counter() - start, time.process_time() - cpu, result))
            loads.append(os.getloadavg()[0])
    (wall_d, cpu_d, default), (wall_t, cpu_t, found) = (
        min(runs[name], key=lambda run: run[0]) for name in ("default", "taylor")
    )
    starts = grid.starts[grid.valid]
    rows = np.random.default_rng(1).choice(len(starts), size=min(SAMPLE, len(starts)))
    sample = starts[rows]
    h0 = compiled.hamiltonian(0.0, sample)
    errors = {}
    for name, k in (("default", kernel), ("taylor", taylor)):
        final = np.empty_like(sample)
        maps.map_chunk(k, sample, final=final)
        errors[name] = float(np.median(np.abs(compiled.hamiltonian(0.0, final) - h0) / np.abs(h0)))
    done = (default.status == 0) & (found.status == 0)
    a, b = default.megno[done], found.megno[done]
    differ = int(np.count_nonzero((a > 4) != (b > 4)))
    numba.set_num_threads(1)
    start = time.perf_counter()
    one = maps.chaos_map(taylor, grid)
    serial = time.perf_counter() - start
    numba.set_num_threads(threads)
    print(
        f"  taylor map (adaptive, tol {taylor.tol:.2g}, SIMD batches) on {threads} threads: "
        f"{wall_t:.1f} s, CPU {cpu_t:.1f} s; the default ({kernel.method} dt "
        f"{kernel.dt:.3g}) {wall_d:.1f} s, CPU {cpu_d:.1f} s (fastest of {REPEAT}, "
        f"interleaved; runs taylor {', '.join(f'{r[0]:.1f}' for r in runs['taylor'])}, "
        f"default {', '.join(f'{r[0]:.1f}' for r in runs['default'])}); taylor on 1 "
        f"thread {serial:.1f} s; median relative energy error at t = {kernel.t:g}: taylor "
        f"{errors['taylor']:.2g}, default {errors['default']:.2g}; chaotic fraction taylor "
        f"{found.chaotic_fraction():.3f}, default {default.chaotic_fraction():.3f}; "
        f"verdicts (<Y> > 4) differing: {differ} of {int(done.sum())}; load average "
        f"{min(loads):.1f} to {max(loads):.1f}"
    )
    same = _same(one, found)
    ok = report("taylor map the same on 1 and on all threads", float(same), "1 (bitwise)", same)
    ratio = wall_t / wall_d
    return ok & report("taylor map / default map, wall", ratio, "(measured)", True)


def _same(a, b) -> bool:
    return bool((a.status == b.status).all()) and bool(
        np.array_equal(a.megno, b.megno, equal_nan=True)
        and np.array_equal(a.lyapunov, b.lyapunov, equal_nan=True)
    )


def _cluster(kernel, grid, local, steps: int) -> bool:
    """The map through ``connect("auto")``: start, the workers' build, the map."""
    import importlib.util

    from systems.chaos import distributed, maps

    if importlib.util.find_spec("distributed") is None:
        print('  LocalCluster: skipped (pip install -e ".[dask]")')
        return True
    start = time.perf_counter()
    with distributed.connect("auto") as client:
        started = time.perf_counter() - start
        workers = len(client.scheduler_info()["workers"])
        start = time.perf_counter()
        client.run(_build_on_worker, distributed.map_spec(kernel))
        built = time.perf_counter() - start
        load = os.getloadavg()[0]
        start = time.perf_counter()
        result = maps.chaos_map(kernel, grid, client=client)
        wall = time.perf_counter() - start
    print(
        f"  LocalCluster of {workers} one-thread workers: started in {started:.1f} s, "
        f"kernels built on the workers in {built:.1f} s, the map in {wall:.1f} s "
        f"({steps / wall:.3g} orbit-steps/s; load average {load:.1f})"
    )
    same = _same(local, result)
    return report("same map through the LocalCluster", float(same), "1 (bitwise)", same)


def _heyoka(compiled, kernel, grid, local, timing: tuple, cores: int) -> bool:
    """heyoka's ensemble on the same orbits at equal accuracy (see the module); ``timing``:
    the map's wall and CPU seconds on all threads, and its CPU seconds on one."""
    from systems.chaos import maps

    try:
        import heyoka as hy
    except ImportError:
        print('  heyoka: skipped (pip install -e ".[bench]")')
        return True
    starts = grid.starts[grid.valid]
    rows = np.random.default_rng(1).choice(len(starts), size=min(SAMPLE, len(starts)))
    sample = starts[rows]
    h0 = compiled.hamiltonian(0.0, sample)
    final = np.empty_like(sample)
    maps.map_chunk(kernel, sample, final=final)
    ours = float(np.median(np.abs(compiled.hamiltonian(0.0, final) - h0) / np.abs(h0)))
    t_end = kernel.t
    vector = kernel.vector
    system = _heyoka_system(hy)
    chosen, errors = None, []
    for tol in TOLERANCES:
        ta = hy.taylor_adaptive(system, [0.0] * 10, tol=tol, time=T_START)
        ends = np.empty_like(sample)
        for i, y in enumerate(sample):
            ta.time = T_START
            ta.state[:] = np.concatenate([y, vector, [0.0, 0.0]])
            ta.propagate_until(t_end)
            ends[i] = ta.state[:4]
        error = float(np.median(np.abs(compiled.hamiltonian(0.0, ends) - h0) / np.abs(h0)))
        errors.append(f"{tol:g}: {error:.2g}")
        if error <= ours:
            chosen = (tol, ta)
            break
    print(
        f"  accuracy over {len(sample)} orbits of the grid to t = {t_end:g}, median relative "
        f"energy error: the map's {ours:.2g}; heyoka's at tolerance {', '.join(errors)}"
    )
    if chosen is None:
        print("  heyoka: no tolerance tried was as accurate as the map")
        return False
    tol, ta = chosen

    def gen(copy, i):
        copy.time = T_START
        copy.state[:] = np.concatenate([block[i], vector, [0.0, 0.0]])
        return copy

    megno = np.empty(len(starts))
    heyoka_steps = 0
    load = os.getloadavg()[0]
    start, cpu = time.perf_counter(), time.process_time()
    for first in range(0, len(starts), BLOCK):
        block = starts[first : first + BLOCK]
        found = hy.ensemble_propagate_until(
            ta, t_end, len(block), gen, algorithm="thread", max_workers=cores
        )
        for i, (copy, *rest) in enumerate(found):
            megno[first + i] = copy.state[9] / copy.time
            heyoka_steps += rest[3]
    wall, cpu = time.perf_counter() - start, time.process_time() - cpu
    batch_wall, batch_cpu = _heyoka_batch(hy, system, tol, starts, vector, t_end, cores)
    parallel, parallel_cpu, serial_cpu = timing
    ours_megno = local.megno[grid.valid.reshape(local.megno.shape)]
    agree = float(np.mean((megno > 4) == (ours_megno > 4)))
    print(
        f"  heyoka {hy.__version__} (Taylor, tolerance {tol:g}), the same {len(starts)} orbits "
        f"with MEGNO: ensemble_propagate_until on {cores} threads {wall:.1f} s, CPU "
        f"{cpu:.1f} s ({heyoka_steps:.3g} adaptive steps, {heyoka_steps / wall:.3g} "
        f"orbit-steps/s; load average {load:.1f}); ensemble_propagate_until_batch (SIMD "
        f"{hy.recommended_simd_size()}) {batch_wall:.1f} s, CPU {batch_cpu:.1f} s; chaotic "
        f"fraction {np.mean(megno > 4):.3f}, the same verdict (<Y> > 4) as the map for "
        f"{agree:.3f} of the orbits. The map: {parallel:.1f} s, CPU {parallel_cpu:.1f} s on "
        f"all threads, CPU {serial_cpu:.1f} s on one (CPU seconds are the comparison that "
        "load changes least)"
    )
    ratio = parallel / wall
    return report(
        "map on all threads / heyoka's ensemble_propagate_until", ratio, "<= 1.5", ratio <= 1.5
    )


def _heyoka_system(hy) -> list:
    """Hénon–Heiles, one tangent vector and MEGNO's integrals W, Z as heyoka's ODEs
    (state x, y, p_x, p_y, dx, dy, dp_x, dp_y, W, Z)."""
    x, y, px, py, dx, dy, dpx, dpy, w, _ = hy.make_vars(
        "x", "y", "px", "py", "dx", "dy", "dpx", "dpy", "W", "Z"
    )
    ddpx = -(1 + 2 * y) * dx - 2 * x * dy
    ddpy = -2 * x * dx + (2 * y - 1) * dy
    rate = (dx * dpx + dy * dpy + dpx * ddpx + dpy * ddpy) / (
        dx * dx + dy * dy + dpx * dpx + dpy * dpy
    )
    t = hy.time
    names = hy.make_vars("x", "y", "px", "py", "dx", "dy", "dpx", "dpy", "W", "Z")
    rhs = [px, py, -x - 2 * x * y, -y - x * x + y * y, dpx, dpy, ddpx, ddpy, t * rate, 2 * w / t]
    return list(zip(names, rhs, strict=True))


def _heyoka_batch(hy, system, tol, starts, vector, t_end, cores) -> tuple[float, float]:
    """Wall and CPU seconds of the grid by ``ensemble_propagate_until_batch`` (SIMD
    batches)."""
    size = hy.recommended_simd_size()
    count = math.ceil(len(starts) / size)
    padded = np.concatenate([starts, np.repeat(starts[-1:], count * size - len(starts), 0)])
    tb = hy.taylor_adaptive_batch(system, np.zeros((10, size)), tol=tol, time=[T_START] * size)

    def gen(copy, i):
        state = np.zeros((10, size))
        state[:4] = padded[i * size : (i + 1) * size].T
        state[4:8] = vector[:, None]
        copy.set_time([T_START] * size)
        copy.state[:] = state
        return copy

    start, cpu = time.perf_counter(), time.process_time()
    for first in range(0, count, BLOCK):
        n = min(BLOCK, count - first)

        def shifted(copy, i, first=first):
            return gen(copy, first + i)

        hy.ensemble_propagate_until_batch(
            tb, t_end, n, shifted, algorithm="thread", max_workers=cores
        )
    return time.perf_counter() - start, time.process_time() - cpu


if __name__ == "__main__":
    raise SystemExit(0 if main(only_taylor="--taylor" in sys.argv[1:]) else 1)
