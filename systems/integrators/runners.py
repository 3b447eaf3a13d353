"""Runners: one trajectory's state between calls of its family's compiled driver.

A runner owns what persists between calls (the state, its Kahan compensation, the clock,
the family's work arrays: Gauss-Legendre stage guesses, an adaptive step) and advances by
a budget of steps, optionally pausing after the first step that reaches a given time,
which never changes the solution. It returns an ``Outcome``: the states kept (at most
``max_points``), the ``Status``, the section crossings bracketed by steps, and counters.
``systems.simulation`` turns outcomes into ``Block``s. Which runner a method uses is
declared by its family in ``systems.integrators.registry``.
"""

from __future__ import annotations

import math
import types

import numpy as np

from systems.codegen import driver_module, entry_point
from systems.integrators.codes import CLOCK_SIZE, INFO_SIZE, Clock, Info, Status

MAX_EVENTS = 4096
JUMP_ROWS = 256
"""Rows a constrained family's driver call has beyond its strided output for the states on
both sides of an event's jump (an impact), at most."""
SUNDMAN_POWER = 0.75
"""g = (|f0| / |f|)^power in the Sundman transformation: g ~ r^1.5 near a 1/r singularity."""
ENDLESS = 1e300


def _as_python(function):
    """A generated work allocator run as plain Python, the generated functions it calls too.

    numba would spend about a second compiling each function that only allocates arrays
    (the ensembles' drivers call their own compiled copies). The allocators call other
    allocators only (``gauss_work`` calls ``_collocation_work``).
    """
    python = function.py_func
    env = dict(python.__globals__)
    for name in python.__code__.co_names:
        value = env.get(name)
        if hasattr(value, "py_func"):
            env[name] = _as_python(value)
    return types.FunctionType(python.__code__, env, python.__name__)


class Outcome:
    """A runner's advance: states ``t``, ``y`` (the first ``sampled`` rows are the states
    at the sample times asked for, the last row the latest state), how it ended, the
    section crossings and the counters."""

    __slots__ = ("t", "y", "code", "events", "steps", "evals", "sampled")

    def __init__(self, t, y, code, events, steps, evals, sampled=0):
        self.t, self.y, self.code, self.events = t, y, code, events
        self.steps, self.evals, self.sampled = steps, evals, sampled


class KernelRunner:
    """A run of one of the compiled families (``X_run`` of ``systems.codegen.driver_module``,
    given the scene's functions that the family declares).

    Parameters
    ----------
    compiled : CompiledSystem
    stepper : Stepper
    y0 : ndarray, shape (m,)
    t0, t_end : float
    value : float
        The step (``dt`` or fictitious ``ds``) of a fixed-step family, the tolerance of an
        adaptive one.
    section : ndarray (index, value, direction), shape (3,), or None
    compensated : bool
        Kahan-compensated sums where the family has them.
    finisher : Stepper, optional
        Time-transformed families: the fixed-step method that lands on ``t_end``.
    """

    def __init__(
        self, compiled, stepper, y0, t0, t_end, value, section, compensated=True, finisher=None
    ):
        self.c, self.s = compiled, stepper
        self.y = np.array(y0, dtype=float)
        self.m = len(self.y)
        self.comp = np.zeros(self.m)
        self.value = float(value)
        self.t_end = float(t_end)
        self.section = section
        self.compensated = compensated
        self.finisher = finisher
        self.clock = np.zeros(CLOCK_SIZE)
        self.clock[Clock.T] = self.clock[Clock.T0] = float(t0)
        self.clock[Clock.H] = self.value
        self.clock[Clock.T_END] = self.t_end if math.isfinite(self.t_end) else ENDLESS
        self.clock[Clock.T_PAUSE] = math.inf
        family = stepper.family
        self.coef = self._coefficients(t0)
        drivers = driver_module()
        # the family's loops, or their fused instance where the system offers its function
        self.kernel, functions = (
            (family.kernel, ()) if family.constrained else family.loops_for(compiled)
        )
        allocate = _as_python(getattr(drivers, f"{self.kernel}_work"))
        self.work = allocate(self.coef, self.m)
        sample_work = _as_python(getattr(drivers, f"{self.kernel}_sample_work"))
        self.spare = (  # the loop's scratch (its ``spare``: it allocates nothing itself)
            (np.empty(self.m), np.empty(self.m), np.empty(CLOCK_SIZE)),
            sample_work(self.coef, self.m),
            (np.empty(self.m), np.empty(self.m), np.empty(CLOCK_SIZE)),
        )
        if family.constrained:
            self.fns = compiled.constraint_functions()
        else:
            self.fns = compiled.functions(functions)
        self.loop = getattr(drivers, f"{self.kernel}_run")
        self._entries = {}  # the loop's machine code for this run's argument types
        self.sampled = 0  # sample times the last call answered (one row each)
        # the start of the last step a call with samples took (y, comp, clock; nan time:
        # none): the next call answers the times inside that step from there
        self.last_step = (np.empty(self.m), np.empty(self.m), np.full(CLOCK_SIZE, math.nan))

    def _coefficients(self, t0: float) -> tuple:
        """The kernel's ``coef`` (the family's; a runner may append its own settings)."""
        return self.s.family.coefficients(self.s, self.c, t0, self.y, self.compensated)

    @property
    def t(self) -> float:
        return float(self.clock[Clock.T])

    def _call(self, nsteps: int, stride: int, until: float, samples=None):
        m = self.m
        # only a constrained family's events jump: the others' calls allocate no more
        cap = nsteps // stride + 1 + (JUMP_ROWS if self.s.family.constrained else 0)
        if samples is not None:
            cap = len(samples) + 2  # the last row free: ``advance`` puts the latest state there
        out = (np.empty(cap), np.empty((cap, m)), np.empty((MAX_EVENTS, 2)))
        out += (np.empty((MAX_EVENTS, 2, m)),)
        self._rows = out[:2]
        info = np.zeros(INFO_SIZE, dtype=np.int64)
        self.clock[Clock.T_PAUSE] = until
        state = (self.y, self.comp, self.clock)
        limits = (int(nsteps), int(stride))
        args = (self.fns, state, self.c.parameters, self.coef, self.work, self.spare, limits)
        args += (self.section,)
        if samples is None:
            self.last_step[2][Clock.T] = math.nan  # steps without samples: not kept
        else:
            samples = (samples, *self.last_step)
        args += (samples, out, info)
        key = samples is None
        entry = self._entries.get(key)
        if entry is None:
            entry = self._entries[key] = entry_point(self.loop, args)
        entry(*args)
        self.sampled = int(info[Info.SAMPLED])
        n_out, n_ev = int(info[Info.OUTPUTS]), int(info[Info.EVENTS])
        return (
            out[0][:n_out],
            out[1][:n_out],
            Status(int(info[Info.STATUS])),
            (out[2][:n_ev], out[3][:n_ev]),
            int(info[Info.STEPS]),
            int(info[Info.EVALUATIONS]),
        )

    def advance(
        self, nsteps: int, max_points: int, until: float = math.inf, samples=None
    ) -> Outcome:
        """Up to ``nsteps`` steps, stopping after the first that reaches ``until``.

        With ``samples`` (ndarray of ascending times): the states at exactly those times
        (the family's ``X_sample`` in the compiled loop), instead of ``max_points``
        evenly spaced; stops after the last. The outcome's first ``sampled`` rows are
        they, the last row is the latest state.
        """
        stride = max(1, math.ceil(nsteps / max(max_points - 1, 1)))
        t_before = self.t
        if samples is not None:
            stride = 1
            samples = np.ascontiguousarray(samples, dtype=float)
        t, y, code, events, steps, evals = self._call(nsteps, stride, until, samples)
        ts, ys, evs = [t], [y], [events]
        sampled = self.sampled
        if code == Status.OVERSHOT:
            rest = None if samples is None else samples[sampled:]
            code, more_steps, more_evals, more = self._land(ts, ys, evs, steps, t_before, rest)
            steps += more_steps
            evals += more_evals
            sampled += more
        self.sampled = sampled
        if code == Status.END:
            self.clock[Clock.T] = self.t_end
        if samples is not None and len(ts) == 1:  # the samples, then the latest state, always
            # into the row the call left free after its rows (no copy of thousands of rows)
            n = len(t)
            t, y = self._rows[0][: n + 1], self._rows[1][: n + 1]
            t[n] = self.t
            y[n] = self.y
            return Outcome(t, y, code, _merge_events(evs, self.m), steps, evals, sampled)
        t = np.concatenate(ts)
        y = np.concatenate(ys) if ys else np.empty((0, self.m))
        if samples is not None:
            t = np.append(t, self.t)
            y = np.vstack([y, self.y[None, :]])
        else:
            t, y = _with_last(t, y, self.t, self.y)  # the driver leaves y at the last good state
        return Outcome(t, y, code, _merge_events(evs, self.m), steps, evals, sampled)

    def answer(self, samples) -> tuple[np.ndarray, np.ndarray]:
        """The states at ``samples`` (ascending times before the current one, inside the
        last step a call with samples took: those after that call's last time, which a
        step reaching the end time passed), without stepping."""
        samples = np.ascontiguousarray(samples, dtype=float)
        t, y, *_ = self._call(0, 1, math.inf, samples)
        return t, y

    def _land(self, ts, ys, evs, steps, t_before, samples) -> tuple[Status, int, int, int]:
        """The next step would pass ``t_end``: reach it exactly, answering the sample
        times left (``samples``, or None). Returns the new status, the steps and
        evaluations it took and the samples it answered (rows appended to ``ys``).
        Adaptive steps never pass it (the step clamps itself to the end), so here it has
        been reached."""
        return Status.END, 0, 0, 0


class FixedStepRunner(KernelRunner):
    """Fixed steps ``dt``; t = t0 + k dt exactly. One shorter step lands on ``t_end``."""

    def _land(self, ts, ys, evs, steps, t_before, samples):
        remaining = self.t_end - self.t
        if remaining <= 1e-12 * max(abs(self.t_end), self.value):
            if samples is None or not len(samples):
                return Status.END, 0, 0, 0
            # already there: the times left at the end get the last state
            at_end = samples[samples <= self.t_end * (1 + 1e-12) + 1e-300]
            ts.append(at_end.copy())
            ys.append(np.repeat(self.y[None, :], len(at_end), axis=0))
            return Status.END, 0, 0, len(at_end)
        self.clock[Clock.T0] = self.t
        self.clock[Clock.K] = 0.0
        self.clock[Clock.H] = remaining
        # with samples (none left, too): the landing step's start is kept for ``answer``
        t, y, code, events, more, evals = self._call(1, 1, math.inf, samples)
        ts.append(t)
        ys.append(y)
        evs.append(events)
        return code, more, evals, self.sampled if samples is not None else 0


class TimeTransformedRunner(KernelRunner):
    """Steps of fixed size in a fictitious time; the physical steps follow the motion.

    The last stretch to ``t_end`` is covered by the family's ``finisher``, a fixed-step
    method, with substeps half as long as the recent physical steps.
    """

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self.recent_dt = math.inf
        self.finishing = None  # the finisher's run that landed on t_end

    def answer(self, samples) -> tuple[np.ndarray, np.ndarray]:
        if self.finishing is not None:
            return self.finishing.answer(samples)
        return super().answer(samples)

    def advance(
        self, nsteps: int, max_points: int, until: float = math.inf, samples=None
    ) -> Outcome:
        t_before = self.t
        outcome = super().advance(nsteps, max_points, until, samples)
        if outcome.steps:
            self.recent_dt = (self.t - t_before) / outcome.steps
        return outcome

    def _land(self, ts, ys, evs, steps, t_before, samples):
        if steps:
            self.recent_dt = (self.t - t_before) / steps
        remaining = self.t_end - self.t
        if remaining <= 0.0:
            return Status.END, 0, 0, 0
        nsub = max(2, math.ceil(2.0 * remaining / min(self.recent_dt, remaining)))
        sub = FixedStepRunner(
            self.c, self.finisher, self.y, self.t, self.t_end, remaining / nsub, self.section,
            self.compensated,
        )  # fmt: skip
        sub.comp[:] = self.comp
        self.finishing = sub
        answered = steps = evals = 0
        if samples is None:
            outcome = sub.advance(nsub + 1, 2)
            evs.append(outcome.events)
            steps, evals = outcome.steps, outcome.evals
        while samples is not None:
            # the times left, answered by the finisher's samples: a call stops after its
            # last time (without times, after a step), keeping that step's start for
            # ``answer``
            outcome = sub.advance(nsub + 1 - steps, 2, samples=samples[answered:])
            ts.append(outcome.t[: outcome.sampled])
            ys.append(outcome.y[: outcome.sampled])
            evs.append(outcome.events)
            answered += outcome.sampled
            steps += outcome.steps
            evals += outcome.evals
            if outcome.code != Status.RUNNING or not (outcome.steps or outcome.sampled):
                break
        self.y[:] = sub.y
        self.comp[:] = sub.comp
        if outcome.code == Status.END:
            self.clock[Clock.T] = self.t_end
        return outcome.code, steps, evals, answered


class AdaptiveRunner(KernelRunner):
    """Compiled adaptive DOP853: ``value`` is the relative tolerance (absolute: 1% of it).

    ``max_step`` bounds every step (inf: the error control alone decides).
    """

    def __init__(
        self, compiled, stepper, y0, t0, t_end, value, section, *args, max_step=math.inf, **kw
    ):
        super().__init__(compiled, stepper, y0, t0, t_end, value, section, *args, **kw)
        self.rtol, self.atol = self.value, self.value * 1e-2
        self.max_step = float(max_step)
        self.coef = (*self.coef, self.rtol, self.atol, self.max_step)
        h = _initial_step(compiled, t0, self.y, self.rtol, self.atol, t_end)
        self.clock[Clock.H] = min(h, self.max_step)


DOUBLE_DOUBLE_BELOW = float(np.finfo(float).eps)
"""Taylor tolerances below this (machine epsilon, the default) carry the state and the
series' orders 1 and 2 in double-double (``systems.taylor.double``, built then and only
then): Kepler's 100 periods to about 1e-13 instead of 1e-12..1e-11 (docs/internals.md,
the Taylor section, for what it costs)."""


class TaylorRunner(KernelRunner):
    """The Taylor family: ``value`` is the tolerance, which sets the order (Jorba and
    Zou's ``ceil(-ln(tol)/2 + 1)``, at least 2: 20 at machine epsilon); each step's length
    comes from the last two coefficients, at most ``max_step``. Below
    ``DOUBLE_DOUBLE_BELOW`` (and compensated) the state and orders 1 and 2 are
    double-double: ``fns`` gets the scene's ``taylor_double`` as its second function,
    else a function never called (``systems.taylor.double.no_double``)."""

    def __init__(
        self, compiled, stepper, y0, t0, t_end, value, section, *args, max_step=math.inf, **kw
    ):
        from systems.taylor import double

        self.max_step = float(max_step)
        super().__init__(compiled, stepper, y0, t0, t_end, value, section, *args, **kw)
        if self.double:
            self.fns = (*self.fns, compiled.taylor().double().function)
        else:
            self.fns = (*self.fns, double.no_double())

    def _coefficients(self, t0: float) -> tuple:
        from systems.taylor.coefficients import jorba_zou

        order = max(2, jorba_zou(self.value))
        factor = math.exp(-0.7 / (order - 1)) / math.e**2  # heyoka's safety factor
        double = bool(self.compensated and self.value < DOUBLE_DOUBLE_BELOW)
        return (*super()._coefficients(t0), order, self.max_step, factor, double)

    @property
    def double(self) -> bool:
        """Whether the state and orders 1 and 2 are double-double."""
        return bool(self.coef[5])

    @property
    def order(self) -> int:
        """The order of the series."""
        return int(self.coef[2])


def _initial_step(compiled, t0, y, rtol, atol, t_end) -> float:
    """Hairer's first guess of an adaptive step from the sizes of y and f at the start."""
    f0 = compiled.rhs(t0, y)
    scale = atol + rtol * np.abs(y)
    d0, d1 = np.linalg.norm(y / scale), np.linalg.norm(f0 / scale)
    h = 1e-6 if d0 < 1e-5 or d1 < 1e-5 else 0.01 * d0 / d1
    if math.isfinite(t_end):
        h = min(h, t_end - t0)
    return h


class ScipyRunner:
    """scipy's Radau, BDF or LSODA stepping on the compiled rhs (for stiff systems);
    ``max_step`` bounds every step."""

    def __init__(
        self, compiled, stepper, y0, t0, t_end, value, section, compensated=True,
        finisher=None, *, max_step=math.inf,
    ):  # fmt: skip
        from scipy.integrate import BDF, LSODA, Radau

        cls = {"radau": Radau, "bdf": BDF, "lsoda": LSODA}[stepper.name]
        self.c, self.s = compiled, stepper
        self.m = len(y0)
        self.evals = 0
        self.value = float(value)

        def fun(t, y):
            self.evals += 1
            return compiled.rhs(t, y)

        bound = t_end if math.isfinite(t_end) else ENDLESS
        tol = max(self.value, 1e-12)
        self.solver = cls(
            fun, t0, np.array(y0, dtype=float), bound, rtol=tol, atol=tol * 1e-2,
            max_step=float(max_step),
        )  # fmt: skip
        self.section = section
        self.t_end = t_end

    @property
    def t(self) -> float:
        return float(self.solver.t)

    @property
    def y(self) -> np.ndarray:
        return self.solver.y

    def advance(self, nsteps: int, max_points: int, until: float = math.inf) -> Outcome:
        ts, ys, evs = [], [], []
        steps, code = 0, Status.RUNNING
        index, value, direction = -1, 0.0, 0.0
        if self.section is not None:
            index, value, direction = int(self.section[0]), self.section[1], self.section[2]
        evals0 = self.evals
        for _ in range(nsteps):
            t_old, y_old = self.solver.t, self.solver.y.copy()
            self.solver.step()
            if self.solver.status == "failed":
                code = Status.STEP_COLLAPSED
                break
            steps += 1
            y = self.solver.y
            if not np.all(np.isfinite(y)):
                code = Status.NON_FINITE
                break
            ts.append(self.solver.t)
            ys.append(y.copy())
            if index >= 0 and _crosses(y_old[index] - value, y[index] - value, direction):
                evs.append((np.array([[t_old, self.solver.t]]), np.stack([y_old, y])[None]))
            if self.solver.status == "finished":
                code = Status.END
                break
            if self.solver.t >= until:
                break
        t = np.array(ts)
        y = np.array(ys).reshape(len(ts), self.m)
        t, y = _thin(t, y, max_points)
        if code != Status.NON_FINITE and (not len(t) or t[-1] != self.t):
            t, y = _with_last(t, y, self.t, self.y)
        return Outcome(t, y, code, _merge_events(evs, self.m), steps, self.evals - evals0)


def _crosses(before: float, after: float, direction: float) -> bool:
    return (direction >= 0 and before < 0.0 <= after) or (direction <= 0 and before > 0.0 >= after)


def _with_last(t: np.ndarray, y: np.ndarray, t_last: float, y_last: np.ndarray):
    """Make sure the latest state ends the block (a stride may have skipped it).

    The driver's last output time and the runner's may differ in the last bits (a landing
    on t_end): the same instant, which must not appear twice. A last row at exactly
    ``t_last`` with another state is the state before an event's jump: both stay.
    """
    jump = len(t) and t[-1] == t_last and not np.array_equal(y[-1], y_last)
    if len(t) and not jump and math.isclose(t[-1], t_last, rel_tol=1e-12, abs_tol=1e-300):
        t, y = t.copy(), y.copy()
        t[-1], y[-1] = t_last, y_last
        return t, y
    return np.append(t, t_last), np.vstack([y, y_last[None, :]])


def _thin(t: np.ndarray, y: np.ndarray, max_points: int):
    """At most ``max_points`` rows, evenly spaced in index, the last always kept."""
    if len(t) <= max_points:
        return t, y
    index = np.unique(np.linspace(0, len(t) - 1, max_points).round().astype(int))
    return t[index], y[index]


def _merge_events(evs, m: int):
    if not evs:
        return np.empty((0, 2)), np.empty((0, 2, m))
    return np.concatenate([e[0] for e in evs]), np.concatenate([e[1] for e in evs])
