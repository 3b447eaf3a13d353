"""Stroboscopic sections and orbit (bifurcation) diagrams of periodically driven systems.

When the explicit time dependence of a system is periodic (t only in sines and cosines
of commensurate frequencies: ``systems.textbook.floquet.periodicity``), its Poincaré
section is stroboscopic: the state once per period T of the drive, at t0 + k T.
``drive_period(compiled)`` says whether and at which T.

An orbit diagram scans one parameter: for each value, the orbit from the same start
runs a transient of whole periods, then ``samples`` periods more, and the state at the
end of each is kept. Every value is one row of one parallel compiled loop with its own
parameters, by one of two methods (``default_strobe_method`` chooses):

- *taylor* (where it applies): ``kernels.taylor_batch_strobe_parallel``, the rows in
  batches of SIMD lanes (``TaylorKernels.sweep``: the batch coefficient function with
  each lane's own parameters), each lane its own adaptive steps at the tolerance and
  its samples at t0 + k T (T its own drive's period) from the series' dense output:
  each row bitwise the single run ``Run(method="taylor", strobe=T)`` at its value;
- a fixed-step method (``map_kernels.DRIVER_strobe_parallel``): each row its own step,
  ``per_period`` steps per period of the drive at that value, so every sample falls on
  a step's end and nothing is interpolated.

``strobe_chunk`` is the unit of work (a chunk of parameter rows in, their samples out),
each row independent of the others.

``periods(diagram)`` counts the distinct samples of each row: 1, 2, 4, ... on the way
to chaos by period doubling, 0 where none repeats within the samples (chaotic, or
quasi-periodic, or not settled).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from systems.chaos.map_kernels import loop_module
from systems.chaos.maps import default_map_method

PER_PERIOD = 200
"""Fixed steps per period of the drive (rk4: the driven damped pendulum's period-1
orbit at A = 1.06 is then kept to about 1e-7 a period)."""
DEFAULT_TRANSIENT_PERIODS = 300
DEFAULT_SAMPLES = 64
CHUNK = 64
"""Values per call of the compiled loop, at least (``maps.chunk_rows``)."""
ROWS_PER_THREAD = 8


def default_strobe_method(mechanics) -> str:
    """taylor wherever it applies, else the chaos maps' fixed-step default
    (``maps.default_map_method``: rk4 for a damped or forced system).

    Measured (``benchmarks/orbit_diagram.py``, 32 values in a regular range, the
    samples against taylor at 1e-16): on the catalogue's four periodically driven
    scenes taylor at machine epsilon was 4 to 9 orders of magnitude more accurate than
    the fixed-step default at ``PER_PERIOD`` steps a period (driven damped pendulum
    9e-12 against 5e-7, Kapitza 5e-14 against 2e-9, Mathieu 9e-14 against 3e-5 with
    yoshida4, variable-length pendulum 7e-11 against 1e-4) and 4.8 to 9 times faster
    over two runs (its steps fit the orbit, the fixed ones the worst part of the
    period). The choice is fixed by that measurement, not timed at run time."""
    from systems.integrators.registry import STEPPERS

    if STEPPERS["taylor"].applies_to(mechanics) is None:
        return "taylor"
    return default_map_method(mechanics)


def drive_frequencies(mechanics) -> list | None:
    """The angular frequencies (sympy, in the parameters) of the sines and cosines through
    which alone t enters Hamilton's equations (effects included), or None when the
    system is autonomous or t enters otherwise."""
    from systems.textbook.floquet import NotPeriodic, time_harmonics

    if not mechanics.classification.time_dependent:
        return None
    try:
        omegas = time_harmonics(
            list(mechanics.hamilton_equations), mechanics.t, list(mechanics.params.values())
        )
    except NotPeriodic:
        return None
    return omegas or None


def period_at(mechanics, omegas: list, values: dict[str, float]) -> float | None:
    """The common period of ``omegas`` at the parameter ``values`` (None: incommensurate
    or all 0 there)."""
    from systems.textbook.floquet import common_period

    numbers = {mechanics.params[k]: float(v) for k, v in values.items() if k in mechanics.params}
    return common_period([float(w.xreplace(numbers)) for w in omegas])


def drive_period(compiled, parameters: dict[str, float] | None = None) -> float | None:
    """The period of the drive of ``compiled`` at its parameters (updated by
    ``parameters``), or None when the system is autonomous or its time dependence is not
    periodic there: the period of its stroboscopic section."""
    omegas = drive_frequencies(compiled.mechanics)
    if omegas is None:
        return None
    values = dict(zip(compiled.parameter_names, map(float, compiled.parameters), strict=True))
    values.update(parameters or {})
    return period_at(compiled.mechanics, omegas, values)


@dataclass(frozen=True)
class OrbitDiagram:
    """An orbit diagram.

    Attributes
    ----------
    parameter : str
    values : ndarray, shape (N,)
        The parameter's values.
    samples : ndarray, shape (N, K, 2n)
        The state at the end of each of the K periods after the transient; NaN past
        where a row stopped.
    periods_T : ndarray, shape (N,)
        The drive's period at each value.
    status : ndarray of int, shape (N,)
        0 every period reached, else the ``Status`` that stopped the row, -1 not computed
        (cancelled).
    tol : float or None
        taylor's tolerance (None: ``method`` is fixed-step, ``per_period`` steps a
        period).
    steps : ndarray of int, shape (N,), or None
        The steps each orbit took (``strobe_chunk``'s).
    """

    parameter: str
    values: np.ndarray
    samples: np.ndarray
    periods_T: np.ndarray
    status: np.ndarray
    names: tuple[str, ...]
    method: str
    per_period: int
    transient_periods: int
    t0: float
    wall_s: float
    complete: bool
    tol: float | None = None
    steps: np.ndarray | None = None

    @property
    def checked(self) -> str:
        """What the numbers were checked against, in words (no energy: the drive changes
        it, and the damping too)."""
        if self.tol is None:
            return (
                f"{self.method}, {self.per_period} fixed steps a period of the drive: no "
                "error estimate (the drive changes the energy, so it is not checked)"
            )
        done = self.steps[self.status == 0] if self.steps is not None else np.zeros(0)
        taken = f"; {int(done.min())} to {int(done.max())} steps an orbit" if len(done) else ""
        return (
            f"taylor at tolerance {self.tol:.3g}: every step sized by Jorba and Zou's rule "
            "so that the series' last terms are about the tolerance of the state (an "
            "estimate of the local error, not a bound), no step collapsed or went "
            f"non-finite in the orbits that completed; the samples from the series{taken}; "
            "the drive changes the energy, so it is not checked"
        )

    def variable(self, name: str, wrap: bool = False) -> np.ndarray:
        """(N, K) samples of the state variable ``name``; an angle ``wrap``ped to (-pi, pi]."""
        column = self.samples[:, :, self.names.index(name)]
        if wrap:
            column = np.pi - np.mod(np.pi - column, 2 * np.pi)
        return column


@dataclass
class StrobeKernel:
    """The strobe loop of one compiled system and method (``strobe_kernel``)."""

    compiled: object
    method: str
    parameter: int
    per_period: int
    transient_periods: int
    samples: int
    t0: float
    omegas: list
    loop: object
    fns: tuple
    coef: tuple
    _entry: object = None
    tol: float | None = None
    """taylor's tolerance (None for a fixed-step method)."""
    lanes: int = 0
    """taylor's SIMD lanes a batch."""


def strobe_kernel(
    compiled,
    parameter: str,
    *,
    transient: float | None = None,
    samples: int = DEFAULT_SAMPLES,
    method: str | None = None,
    per_period: int | None = None,
    t0: float = 0.0,
    tol: float | None = None,
) -> StrobeKernel:
    """The strobe loop of ``compiled`` scanning ``parameter``.

    ``transient`` (a time) is rounded up to whole periods of the drive at the scene's
    values (default ``DEFAULT_TRANSIENT_PERIODS`` periods). ``method``: a fixed-step
    method with an ensemble loop (``per_period`` steps a period, default
    ``PER_PERIOD``), or ``"taylor"`` (adaptive steps at ``tol``, default machine
    epsilon); by default ``default_strobe_method``'s.

    Raises
    ------
    ValueError
        An unknown parameter, an autonomous or not periodically driven system, a method
        that does not apply or has no ensemble loop, settings out of range; the message
        says what to give instead.
    """
    from systems.integrators.registry import STEPPERS

    names = list(compiled.parameter_names)
    period = drive_period(compiled)
    if period is None:
        raise ValueError(
            "an orbit diagram samples once per period of a periodic drive; this system's "
            "time dependence is not periodic at its parameter values"
            if compiled.mechanics.classification.time_dependent
            else "an orbit diagram samples once per period of a periodic drive; this "
            "system does not depend on t (scan it with chaosmap instead)"
        )
    if parameter not in names:
        known = ", ".join(names) or "none"
        raise ValueError(f"the scene has no parameter {parameter!r} (its parameters: {known})")
    mechanics = compiled.mechanics
    method = method or default_strobe_method(mechanics)
    stepper = STEPPERS.get(method)
    if stepper is None or not (stepper.family.ensemble or method == "taylor"):
        usable = [name for name, s in STEPPERS.items() if s.family.ensemble]
        raise ValueError(
            f"an orbit diagram runs a fixed-step method ({', '.join(usable)}) or taylor, "
            f"not {method!r}"
        )
    if tol is not None and method != "taylor":
        raise ValueError(
            f"{method} takes a number of steps a period, not a tolerance (taylor does)"
        )
    if per_period is not None and method == "taylor":
        raise ValueError("taylor takes a tolerance, not a number of steps a period (its own steps)")
    reason = stepper.applies_to(mechanics)
    if reason:
        raise ValueError(reason)
    if not (isinstance(samples, int) and 1 <= samples <= 100_000):
        raise ValueError(f"the samples per value must be from 1 to 100000, not {samples!r}")
    if transient is None:
        periods = DEFAULT_TRANSIENT_PERIODS
    elif not (math.isfinite(transient) and transient >= 0):
        raise ValueError(f"the transient must be a time of at least 0, not {transient!r}")
    else:
        periods = math.ceil(transient / period - 1e-9)
    family = stepper.family
    y0 = compiled.initial_state(t0)
    if method == "taylor":
        return _taylor_kernel(compiled, stepper, names.index(parameter), periods, samples, t0, tol)
    coef = family.coefficients(stepper, compiled, t0, y0, False)
    fns = compiled.functions(family.functions)
    loop = getattr(loop_module(), f"{family.kernel}_strobe_parallel")
    return StrobeKernel(
        compiled, method, names.index(parameter), int(per_period or PER_PERIOD), int(periods),
        samples, float(t0), drive_frequencies(mechanics), loop, fns, coef,
    )  # fmt: skip


def _taylor_kernel(compiled, stepper, parameter: int, periods: int, samples: int, t0, tol):
    """``strobe_kernel``'s taylor loop (``kernels.taylor_batch_strobe_parallel``): the
    batch function with parameters per lane (``TaylorKernels.sweep``), the double-double
    orders and ``coef`` of a taylor run at ``tol`` (``runners.TaylorRunner``'s)."""
    from systems.codegen import driver_module

    y0 = compiled.initial_state(t0)
    if tol is None:
        tol = stepper.family.default_setting(compiled, stepper, t0, y0, math.inf)
    problem = stepper.setting_error(None, tol)
    if problem:
        raise ValueError(problem)
    runner = stepper.family.runner(compiled, stepper, y0, t0, math.inf, float(tol), None)
    function, lanes, width = compiled.taylor().sweep()
    coef = (width, *runner.coef[1:])  # the columns of the sweep's out, not the scalar's
    return StrobeKernel(
        compiled, "taylor", parameter, 0, int(periods), samples, float(t0),
        drive_frequencies(compiled.mechanics), driver_module().taylor_batch_strobe_parallel,
        (function, runner.fns[1]), coef, tol=float(tol), lanes=lanes,
    )  # fmt: skip


def strobe_chunk(
    kernel: StrobeKernel, values: np.ndarray, y0: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The samples of the orbits from ``y0`` (2n,) at the parameter's ``values`` (N,):
    the unit of an orbit diagram's work.

    Returns
    -------
    samples : ndarray, shape (N, K, 2n)
    periods : ndarray, shape (N,)
        The drive's period at each value (NaN where it is not periodic: the row is not run).
    status : ndarray of int, shape (N,)
    steps : ndarray of int, shape (N,)
        The steps each orbit took (a fixed-step row that stopped early: -1, not counted;
        a row not run: 0).
    """
    from systems.codegen import entry_point
    from systems.integrators.codes import CLOCK_SIZE, Clock, Status

    compiled = kernel.compiled
    values = np.asarray(values, dtype=float)
    N = len(values)
    m = 2 * compiled.n
    P = np.repeat(np.asarray(compiled.parameters, dtype=float)[None, :], N, axis=0)
    P[:, kernel.parameter] = values
    base = dict(zip(compiled.parameter_names, map(float, compiled.parameters), strict=True))
    name = compiled.parameter_names[kernel.parameter]
    periods = np.array(
        [
            period_at(compiled.mechanics, kernel.omegas, {**base, name: v}) or math.nan
            for v in values
        ]
    )
    out = np.full((N, kernel.samples, m), np.nan)
    status = np.full(N, -1, dtype=np.int64)
    counts = np.zeros(N, dtype=np.int64)
    run = np.flatnonzero(np.isfinite(periods))
    if not len(run):
        return out, periods, status, counts
    Y = np.ascontiguousarray(np.repeat(np.asarray(y0, dtype=float)[None, :], len(run), axis=0))
    Pr = np.ascontiguousarray(P[run])
    clock = np.zeros(CLOCK_SIZE)
    clock[Clock.T] = clock[Clock.T0] = kernel.t0
    clock[Clock.T_END] = clock[Clock.T_PAUSE] = math.inf
    part = np.full((len(run), kernel.samples, m), np.nan)
    part_status = np.zeros(len(run), dtype=np.int64)
    if kernel.tol is not None:
        # as Run(strobe=T) makes its times: t0 + T k, k a float
        k = np.arange(kernel.transient_periods + 1, kernel.transient_periods + kernel.samples + 1)
        times = np.ascontiguousarray(kernel.t0 + periods[run, None] * k[None, :].astype(float))
        steps = np.zeros(len(run), dtype=np.int64)
        fb, fd = kernel.fns
        args = (fb, fd, Y, clock, Pr, kernel.coef, times, kernel.lanes, part, part_status, steps)
    else:
        H = np.ascontiguousarray(periods[run] / kernel.per_period)
        limits = (kernel.transient_periods, kernel.per_period, kernel.samples)
        args = (kernel.fns, Y, clock, H, Pr, kernel.coef, limits, part, part_status)
    if kernel._entry is None:
        kernel._entry = entry_point(kernel.loop, args)
    kernel._entry(*args)
    if kernel.tol is not None:
        part_status[part_status == int(Status.END)] = int(Status.RUNNING)
        counts[run] = steps
    else:
        total = (kernel.transient_periods + kernel.samples) * kernel.per_period
        counts[run] = np.where(part_status == 0, total, -1)
    out[run], status[run] = part, part_status
    return out, periods, status, counts


def chunk_values(kernel: StrobeKernel, least: int = CHUNK) -> int:
    """Values a chunk: ``least``, or as many as keep every thread of the compiled loop
    busy where that is more (``maps.chunk_rows``): ``ROWS_PER_THREAD`` rows a thread for
    a fixed-step method, a batch of SIMD lanes a thread for taylor (whose threads take
    batches, not rows)."""
    from systems.chaos.maps import chunk_rows

    return chunk_rows(least, kernel.lanes if kernel.tol is not None else ROWS_PER_THREAD)


def orbit_diagram(
    kernel: StrobeKernel,
    values: np.ndarray,
    *,
    y0: np.ndarray | None = None,
    chunk: int | None = None,
    progress: Callable[[int, int], None] | None = None,
    cancelled: Callable[[], bool] | None = None,
    client=None,
) -> OrbitDiagram:
    """The orbit diagram over ``values`` (N,) of the kernel's parameter, every orbit from
    ``y0`` (default: the scene's start); ``chunk`` (default ``chunk_values(kernel)``),
    ``progress``, ``cancelled`` and ``client`` (the chunks computed on a Dask cluster)
    as ``maps.chaos_map``'s."""
    from systems.chaos.maps import each_chunk, state_names

    start = time.perf_counter()
    compiled = kernel.compiled
    values = np.asarray(values, dtype=float)
    y0 = compiled.initial_state(kernel.t0) if y0 is None else np.asarray(y0, dtype=float)
    N, m = len(values), 2 * compiled.n
    samples = np.full((N, kernel.samples, m), np.nan)
    periods = np.full(N, np.nan)
    status = np.full(N, -1, dtype=np.int64)
    steps = np.zeros(N, dtype=np.int64)
    chunk = chunk or chunk_values(kernel)
    chunks = each_chunk(
        strobe_chunk, kernel, np.arange(N), lambda index: (values[index], y0), chunk=chunk,
        client=client, cancelled=cancelled, progress=progress,
    )  # fmt: skip
    done = 0
    for index, (found, drive, stopped, taken) in chunks:
        samples[index], periods[index], status[index], steps[index] = found, drive, stopped, taken
        done += len(index)
    return OrbitDiagram(
        parameter=compiled.parameter_names[kernel.parameter], values=values, samples=samples,
        periods_T=periods, status=status, names=tuple(state_names(compiled.mechanics)),
        method=kernel.method, per_period=kernel.per_period,
        transient_periods=kernel.transient_periods, t0=kernel.t0,
        wall_s=time.perf_counter() - start, complete=done == N, tol=kernel.tol, steps=steps,
    )  # fmt: skip


def periods(
    diagram: OrbitDiagram, tolerance: float = 1e-4, angles: tuple[int, ...] = ()
) -> np.ndarray:
    """The period of each row in periods of the drive: the smallest p <= K / 2 with
    every sample within ``tolerance`` (relative to the state's size, at least 1) of the
    one p before it; 0 where there is none. Coordinates in ``angles`` (state indices)
    are compared modulo 2 pi.

    Returns
    -------
    ndarray of int, shape (N,)
    """
    S = diagram.samples
    N, K, _ = S.shape
    result = np.zeros(N, dtype=np.int64)
    for r in range(N):
        rows = S[r].copy()
        if not np.isfinite(rows).all():
            continue
        for i in angles:  # a turning angle's size says nothing of its precision
            rows[:, i] = np.pi - np.mod(np.pi - rows[:, i], 2 * np.pi)
        scale = max(1.0, float(np.abs(rows).max()))
        for p in range(1, K // 2 + 1):
            gap = rows[p:] - rows[:-p]
            for i in angles:
                gap[:, i] = np.pi - np.mod(np.pi - gap[:, i], 2 * np.pi)
            if np.abs(gap).max() <= tolerance * scale:
                result[r] = p
                break
    return result


__all__ = [
    "OrbitDiagram", "StrobeKernel", "chunk_values", "default_strobe_method", "drive_period",
    "orbit_diagram", "periods", "strobe_chunk", "strobe_kernel",
]  # fmt: skip
