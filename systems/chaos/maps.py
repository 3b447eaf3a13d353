"""Chaos maps: a grid of starts, each orbit's MEGNO and maximal exponent.

A grid lies on the Poincaré section at one energy (``section_grid``: the shown
coordinate and its momentum, the missing momentum solved as a click on the section
solves it, ``systems.section.states_on_section``) or over two state variables with the
rest of the state from the scene's start (``variable_grid``). Every start gets one
tangent vector (the same unit vector for all) and runs ``t_end`` in fixed steps in one
parallel compiled loop (``map_kernels.DRIVER_megno_parallel``, instantiated per
fixed-step family beside the drivers' own templates: the family's step as the drivers
use it, on the extended state of ``systems.chaos.variational``); MEGNO's running sums
are kept inside the loop, so nothing per step leaves it. With ``method="taylor"`` the
orbits take adaptive Taylor steps in SIMD batches instead, the variational equations and
MEGNO's integral in the series (``systems.chaos.taylor_map``).

``map_chunk(kernel, starts)`` is the unit of work: a chunk of starts in, an array of
indicators out, each row independent of the others and of how the grid is cut into
chunks (the same numbers whichever chunks, threads or machines compute it).
``chaos_map`` cuts a grid into chunks, calls ``progress`` and ``cancelled`` between them.

Thresholds (``chaotic_fraction``): MEGNO's mean <Y> above ``CHAOTIC_MEGNO`` = 4 (as
``lyapunov.megno_verdict``; regular orbits tend to 2, chaotic ones grow like
lambda t / 2); the maximal exponent above 3 ln(t) / t, three times the rate a deviation
growing linearly (a regular orbit's) shows at time t.
"""

from __future__ import annotations

import contextlib
import math
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field

import numpy as np

from systems.chaos.variational import NotApplicable, Tangent, extended

CHAOTIC_MEGNO = 4.0
INDICATORS = ("megno", "lyapunov")
DEFAULT_T_END = 500.0
"""Long enough for Hénon–Heiles' chaotic orbits at E = 1/8 to pass <Y> = 4 by far
(lambda ~ 0.05: <Y> ~ 12); a 200 x 200 map of it in well under a minute on two cores."""
IMPLICIT_T_END = 100.0
"""The default end time where the map's method is implicit (Gauss-Legendre, the default
for a non-separable H): each step iterates its stages, about 40 times a yoshida4 step
of Hénon–Heiles; the double pendulum's 100 x 100 map to t = 500 took 376 s on two cores.
Its chaotic orbits (lambda of order 1) pass <Y> = 4 long before t = 100."""
CHUNK = 256
"""Starts per call of the compiled loop, at least (``chunk_rows``): a progress report and
a cancel check apart."""
ROWS_PER_THREAD = 64
"""A chunk gives each of the loop's threads at least this many rows (``chunk_rows``): on
many cores, the Python between two calls and each call's last rows (one thread still
busy) would otherwise take a growing share of the time."""
STEPS_PER_PERIOD = 40
"""Fixed steps per fastest period at the scene's start for a map's default step: the
maps' verdicts, not the energy, set it (Hénon–Heiles' fraction at E = 1/8 moved by less
than 0.01 from 40 to 160 steps with yoshida4)."""


@dataclass(frozen=True)
class MapGrid:
    """The starts of a chaos map.

    Attributes
    ----------
    names : tuple of str
        The two axes' state variables (``"y"``, ``"p_y"``): x first.
    xs, ys : ndarray, shape (nx,), (ny,)
    starts : ndarray, shape (ny * nx, 2n)
        Row ``iy * nx + ix`` starts at (xs[ix], ys[iy]); NaN where no state is (a point
        of the section no momentum reaches at the energy).
    energy : float or None
        The section's energy (None for a grid over two variables).
    section : tuple (coordinate, value) or None
    """

    names: tuple[str, str]
    xs: np.ndarray
    ys: np.ndarray
    starts: np.ndarray
    energy: float | None = None
    section: tuple[int, float] | None = None

    @property
    def shape(self) -> tuple[int, int]:
        return len(self.ys), len(self.xs)

    @property
    def valid(self) -> np.ndarray:
        """(ny * nx,) bool: the rows that are states."""
        return np.isfinite(self.starts).all(axis=1)


def state_names(mechanics) -> list[str]:
    """The 2n state variables by name: coordinates then ``p_<q>`` momenta."""
    q = list(mechanics.scene.coordinates)
    return q + [f"p_{name}" for name in q]


def section_grid(
    compiled, section, energy: float, nx: int, ny: int, ranges: tuple[tuple, tuple]
) -> MapGrid:
    """Starts on the Poincaré section ``section`` (``systems.section.Section``) at H =
    ``energy``: (q_i, p_i) of the shown coordinate over ``ranges`` = ((q_lo, q_hi),
    (p_lo, p_hi)), p_j > 0 solved for."""
    from systems.section import states_on_section

    xs = np.linspace(*ranges[0], nx)
    ys = np.linspace(*ranges[1], ny)
    Q, P = np.meshgrid(xs, ys)
    starts = states_on_section(compiled, section, energy, Q.ravel(), P.ravel())
    names = state_names(compiled.mechanics)
    n = compiled.n
    axes = (names[section.shown], names[n + section.shown])
    return MapGrid(axes, xs, ys, starts, float(energy), (section.coordinate, section.value))


def variable_grid(
    compiled, names: tuple[str, str], nx: int, ny: int, ranges, y0: np.ndarray
) -> MapGrid:
    """Starts over two state variables ``names`` (coordinates or ``p_<q>`` momenta),
    the rest of the state from ``y0`` (2n,)."""
    every = state_names(compiled.mechanics)
    unknown = [name for name in names if name not in every]
    if unknown or names[0] == names[1]:
        raise ValueError(
            f"a map is over two different state variables of {', '.join(every)}, "
            f"not {', '.join(names)}"
        )
    i, j = every.index(names[0]), every.index(names[1])
    xs = np.linspace(*ranges[0], nx)
    ys = np.linspace(*ranges[1], ny)
    X, Yg = np.meshgrid(xs, ys)
    starts = np.repeat(np.asarray(y0, dtype=float)[None, :], nx * ny, axis=0)
    starts[:, i] = X.ravel()
    starts[:, j] = Yg.ravel()
    return MapGrid(tuple(names), xs, ys, starts)


def section_box(compiled, section, energy: float, size: int = 201) -> tuple[tuple, tuple]:
    """The smallest box (q_i, p_i) holding the section's allowed region at ``energy``,
    with 2 % margins: searched on a ``size``-point grid in boxes doubling from +-1."""
    from systems.section import forbidden

    half = 1.0
    for _ in range(12):
        axis = np.linspace(-half, half, size)
        Q, P = np.meshgrid(axis, axis)
        allowed = ~forbidden(compiled, section, energy, Q.ravel(), P.ravel()).reshape(Q.shape)
        if allowed.any():
            edge = allowed[0].any() or allowed[-1].any() or allowed[:, 0].any()
            if not (edge or allowed[:, -1].any()):
                rows, cols = np.flatnonzero(allowed.any(axis=1)), np.flatnonzero(allowed.any(0))
                step = axis[1] - axis[0]
                q = (axis[cols[0]] - step, axis[cols[-1]] + step)
                p = (axis[rows[0]] - step, axis[rows[-1]] + step)
                return _margin(q), _margin(p)
        half *= 2
    raise ValueError(
        f"the section's allowed region at energy {energy:g} is not bounded within "
        f"+-{half / 2:g}: give the map's ranges"
    )


def _margin(bounds: tuple[float, float]) -> tuple[float, float]:
    lo, hi = bounds
    pad = 0.02 * (hi - lo)
    return lo - pad, hi + pad


# -- the compiled loop ---------------------------------------------------------------------


@dataclass
class MapKernel:
    """One system's map loop, ready to run chunks: the tangent functions, the method's
    coefficients and step, how many steps.

    Build with ``map_kernel``; ``map_chunk(kernel, starts)`` runs it.
    """

    tangent: Tangent
    method: str
    dt: float
    t0: float
    t_end: float
    nsteps: int
    vector: np.ndarray
    loop: object = field(repr=False)
    fns: tuple = field(repr=False)
    coef: tuple = field(repr=False)
    _entry: object = field(default=None, repr=False)
    taylor: object = field(default=None, repr=False)
    """``method == "taylor"``: the extended system's ``taylor_map.TaylorMegno`` (adaptive
    steps at ``tol``; ``dt`` NaN and ``nsteps`` 0)."""
    tol: float = math.nan

    @property
    def t(self) -> float:
        """The time every orbit reaches (``t0 + nsteps dt``; ``t_end`` with taylor)."""
        if self.taylor is not None:
            return self.t_end
        return self.t0 + self.nsteps * self.dt


def map_methods() -> tuple[str, ...]:
    """The methods a map runs: fixed-step ones with an ensemble loop, and taylor
    (adaptive, in SIMD batches: ``systems.chaos.taylor_map``)."""
    from systems.integrators.registry import STEPPERS

    return (*(name for name, s in STEPPERS.items() if s.family.ensemble), "taylor")


def default_map_method(mechanics) -> str:
    """yoshida4 where a splitting applies (a separable H without effects), rk4 for a
    damped or forced system (no structure to keep), else gauss_legendre4."""
    from systems.integrators.registry import STEPPERS

    if STEPPERS["yoshida4"].applies_to(mechanics) is None:
        return "yoshida4"
    if not mechanics.classification.hamiltonian_conserved:
        return "rk4"
    return "gauss_legendre4"


def default_t_end(method: str) -> float:
    """A map's end time by default: ``IMPLICIT_T_END`` for an implicit method (one with
    stages to solve), else ``DEFAULT_T_END``."""
    from systems.integrators.registry import STEPPERS

    stepper = STEPPERS.get(method)
    return IMPLICIT_T_END if stepper is not None and stepper.stages else DEFAULT_T_END


def map_kernel(
    tangent: Tangent,
    *,
    t_end: float | None = None,
    method: str | None = None,
    dt: float | None = None,
    t0: float = 0.0,
    tol: float | None = None,
) -> MapKernel:
    """The map loop of ``tangent``'s system: ``method`` (default ``default_map_method``)
    at step ``dt`` (default: ``STEPS_PER_PERIOD`` steps per fastest period at the
    scene's start) from ``t0`` to ``t_end`` (default ``default_t_end(method)``); with
    ``method="taylor"`` adaptive steps at ``tol`` (default machine epsilon) instead of
    ``dt``.

    Raises
    ------
    NotApplicable
        A method without an ensemble loop, or one that does not apply, with the reason.
    """
    from systems.chaos.lyapunov import method_refusal
    from systems.integrators.registry import STEPPERS
    from systems.integrators.stepsize import fastest_rate

    mechanics = tangent.mechanics
    method = method or default_map_method(mechanics)
    if method not in STEPPERS:
        raise NotApplicable(f"unknown method {method!r}; choose from {', '.join(map_methods())}")
    if method not in map_methods():
        raise NotApplicable(
            f"a chaos map runs fixed-step methods in one compiled loop (or taylor), not {method}; "
            f"choose from {', '.join(map_methods())}"
        )
    t_end = default_t_end(method) if t_end is None else t_end
    if not (math.isfinite(t_end) and t_end > t0):
        raise NotApplicable(f"the map's end time must be finite and after {t0:g}, not {t_end!r}")
    if method == "taylor":
        return _taylor_kernel(tangent, t_end, dt, t0, tol)
    if tol is not None:
        raise NotApplicable(f"{method} takes a step (dt), not a tolerance; taylor takes one")
    reason = method_refusal(mechanics, method)
    if reason:
        raise NotApplicable(reason)
    compiled = tangent.compiled
    if dt is None:
        rate = fastest_rate(compiled, t0, compiled.initial_state(t0))
        dt = 2 * math.pi / rate / STEPS_PER_PERIOD if rate > 0 else 0.01
        dt = (t_end - t0) / max(1, math.ceil((t_end - t0) / dt))  # whole steps to t_end
    if not (math.isfinite(dt) and dt > 0):
        raise NotApplicable(f"the step must be a positive number, not {dt!r}")
    nsteps = max(1, round((t_end - t0) / dt))
    stepper = STEPPERS[method]
    family = stepper.family
    n = compiled.n
    vector = np.ones(2 * n) / math.sqrt(2 * n)
    y0 = extended(compiled.initial_state(t0), vector[:, None])
    coef = family.coefficients(stepper, tangent, t0, y0, False)
    fns = tangent.functions(family.functions)
    from systems.chaos.map_kernels import loop_module  # numba: only once a map runs

    loop = getattr(loop_module(), f"{family.kernel}_megno_parallel")
    return MapKernel(
        tangent, method, float(dt), float(t0), float(t_end), nsteps, vector, loop, fns, coef
    )


def _taylor_kernel(tangent: Tangent, t_end: float, dt, t0: float, tol) -> MapKernel:
    """``map_kernel``'s taylor map: the extended system's batch function
    (``taylor_map.TaylorMegno``), adaptive steps at ``tol``."""
    from systems.chaos import taylor_map

    if dt is not None:
        raise NotApplicable("taylor is adaptive: it takes a tolerance, not a step (dt)")
    tol = float(np.finfo(float).eps) if tol is None else float(tol)
    if not (1e-16 <= tol <= 1.0):
        raise NotApplicable(f"the tolerance must be between 1e-16 and 1, not {tol!r}")
    reason = taylor_map.refusal(tangent.mechanics)
    if reason:
        raise NotApplicable(reason)
    megno = taylor_map.TaylorMegno(tangent.mechanics)
    n = tangent.n
    vector = np.ones(2 * n) / math.sqrt(2 * n)
    return MapKernel(
        tangent, "taylor", math.nan, float(t0), float(t_end), 0, vector, None, (), (),
        taylor=megno, tol=tol,
    )  # fmt: skip


def extended_rows(starts: np.ndarray, vector: np.ndarray) -> np.ndarray:
    """``variational.extended`` of every row of ``starts`` (N, 2n) with the one tangent
    vector ``vector`` (2n,), as one contiguous array (N, 4n) = (q, dq, p, dp) per row
    (a Python loop over the rows was a serial 4 us a row between the compiled calls)."""
    N, m = starts.shape
    n = m // 2
    Y = np.empty((N, 2 * m))
    Y[:, :n] = starts[:, :n]
    Y[:, n : 2 * n] = vector[:n]
    Y[:, 2 * n : 3 * n] = starts[:, n:]
    Y[:, 3 * n :] = vector[n:]
    return Y


def map_chunk(
    kernel: MapKernel, starts: np.ndarray, *, final: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """The indicators of the orbits from ``starts``: the unit of a map's work.

    Parameters
    ----------
    kernel : MapKernel
    starts : ndarray, shape (N, 2n)
        Finite states (leave out a grid's NaN rows).
    final : ndarray, shape (N, 2n), optional
        Receives each orbit's state at the end (or where it stopped): the accuracy of
        the map's orbits (``benchmarks/chaos_map.py`` compares their energy).

    Returns
    -------
    values : ndarray, shape (N, 3)
        Per orbit: MEGNO's mean <Y>, the maximal exponent's estimate ln|delta(t)| / t
        and MEGNO's Y(t), at ``kernel.t`` (or where the orbit stopped).
    status : ndarray of int, shape (N,)
        0 (``Status.RUNNING``) for an orbit that reached the end, else what stopped it.
    """
    from systems.codegen import entry_point
    from systems.integrators.codes import CLOCK_SIZE, Clock

    starts = np.asarray(starts, dtype=float)
    if kernel.taylor is not None:
        from systems.chaos.taylor_map import taylor_megno_rows

        return taylor_megno_rows(
            kernel.taylor, kernel.tangent.parameters, starts, kernel.vector, kernel.t0,
            kernel.t_end, kernel.tol, final=final,
        )  # fmt: skip
    N = len(starts)
    Y = extended_rows(starts, kernel.vector)
    clock = np.zeros(CLOCK_SIZE)
    clock[Clock.T] = clock[Clock.T0] = kernel.t0
    clock[Clock.H] = kernel.dt
    clock[Clock.T_END] = clock[Clock.T_PAUSE] = math.inf
    values = np.full((N, 3), np.nan)
    status = np.zeros(N, dtype=np.int64)
    if N == 0:
        return values, status
    limits = (kernel.nsteps, 1)
    args = (kernel.fns, Y, clock, kernel.tangent.parameters, kernel.coef, limits, values, status)
    if kernel._entry is None:
        kernel._entry = entry_point(kernel.loop, args)
    kernel._entry(*args)
    if final is not None:
        n = kernel.tangent.n
        final[:, :n], final[:, n:] = Y[:, :n], Y[:, 2 * n : 3 * n]
    return values, status


@dataclass(frozen=True)
class ChaosMap:
    """A finished (or cancelled) map.

    Attributes
    ----------
    grid : MapGrid
    megno, lyapunov, megno_now : ndarray, shape (ny, nx)
        NaN where the grid has no state, where the orbit stopped (see ``status``) or
        where a cancelled map did not reach.
    status : ndarray of int, shape (ny, nx)
        -1 no state or not computed, 0 reached the end, else the ``Status`` that stopped it.
    """

    grid: MapGrid
    megno: np.ndarray
    lyapunov: np.ndarray
    megno_now: np.ndarray
    status: np.ndarray
    method: str
    dt: float
    t_end: float
    wall_s: float
    complete: bool

    def values(self, indicator: str) -> np.ndarray:
        """(ny, nx) of ``"megno"`` or ``"lyapunov"``."""
        return {"megno": self.megno, "lyapunov": self.lyapunov}[indicator]

    def threshold(self, indicator: str) -> float:
        """Above it an orbit counts as chaotic (see the module)."""
        if indicator == "megno":
            return CHAOTIC_MEGNO
        return 3 * math.log(self.t_end) / self.t_end

    def chaotic_fraction(self, indicator: str = "megno") -> float:
        """The fraction of the orbits that reached the end whose indicator is above
        ``threshold``; NaN if none did."""
        done = self.status == 0
        if not done.any():
            return math.nan
        return float(np.mean(self.values(indicator)[done] > self.threshold(indicator)))


def chaos_map(
    kernel: MapKernel,
    grid: MapGrid,
    *,
    chunk: int | None = None,
    progress: Callable[[int, int], None] | None = None,
    cancelled: Callable[[], bool] | None = None,
    client=None,
) -> ChaosMap:
    """The map of ``grid`` by ``kernel``, ``chunk`` starts per compiled call (default
    ``chunk_rows(CHUNK, ROWS_PER_THREAD)``).

    ``progress(done, total)`` is called after each chunk (rows with a state); a true
    ``cancelled()`` between chunks ends the map early (``complete`` False). With a
    ``distributed.Client`` as ``client`` the chunks (smaller where the cluster's threads
    would otherwise wait: ``distributed.chunk_size``) are computed on its workers
    (``systems.chaos.distributed``), the same numbers as here.
    """
    start = time.perf_counter()
    rows = np.flatnonzero(grid.valid)
    total = grid.starts.shape[0]
    values = np.full((total, 3), np.nan)
    status = np.full(total, -1, dtype=np.int64)
    chunk = chunk or chunk_rows(CHUNK, ROWS_PER_THREAD)
    chunks = each_chunk(
        map_chunk, kernel, rows, lambda index: (grid.starts[index],), chunk=chunk,
        client=client, cancelled=cancelled, progress=progress,
    )  # fmt: skip
    done = 0
    for index, (v, s) in chunks:
        v[s != 0] = np.nan
        values[index], status[index] = v, s
        done += len(index)
    shape = grid.shape
    return ChaosMap(
        grid=grid,
        megno=values[:, 0].reshape(shape),
        lyapunov=values[:, 1].reshape(shape),
        megno_now=values[:, 2].reshape(shape),
        status=status.reshape(shape),
        method=kernel.method,
        dt=kernel.dt,
        t_end=kernel.t,
        wall_s=time.perf_counter() - start,
        complete=done == len(rows),
    )


def chunk_rows(least: int, per_thread: int) -> int:
    """Rows a chunk: ``least``, or ``per_thread`` for each of the compiled loop's threads
    (``numba.get_num_threads()``) where that is more."""
    import numba

    return max(least, per_thread * numba.get_num_threads())


def each_chunk(
    compute: Callable,
    kernel,
    rows: np.ndarray,
    arguments: Callable[[np.ndarray], tuple],
    *,
    chunk: int,
    client=None,
    cancelled: Callable[[], bool] | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> Iterator[tuple[np.ndarray, tuple]]:
    """``(index, compute(kernel, *arguments(index)))`` for chunks ``index`` of ``rows``
    (N,), ``chunk`` rows each: here one after the other, or with a ``distributed.Client``
    on its workers, in the order they finish (``distributed.submitted``). Stops early
    when ``cancelled()`` is true before a chunk is taken; ``progress(done, N)`` after
    each chunk the caller has taken. ``compute`` is ``map_chunk`` or
    ``bifurcation.strobe_chunk``."""
    if client is not None:
        from systems.chaos import distributed

        chunk = distributed.chunk_size(client, len(rows), chunk)
    pieces = [rows[first : first + chunk] for first in range(0, len(rows), chunk)]
    if client is None:
        results = ((index, compute(kernel, *arguments(index))) for index in pieces)
    else:
        task, spec = distributed.remote(compute, kernel)
        results = distributed.submitted(client, task, spec, list(map(arguments, pieces)), pieces)
    done = 0
    with contextlib.closing(results):
        for _ in pieces:
            if cancelled is not None and cancelled():
                return
            index, result = next(results)
            yield index, result
            done += len(index)
            if progress is not None:
                progress(done, len(rows))


__all__ = [
    "CHAOTIC_MEGNO", "ChaosMap", "MapGrid", "MapKernel", "chaos_map", "chunk_rows", "default_t_end",
    "each_chunk",
    "extended_rows", "map_chunk", "map_kernel", "map_methods", "section_box", "section_grid",
    "variable_grid",
]  # fmt: skip
