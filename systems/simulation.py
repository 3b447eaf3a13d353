"""Streaming integration: blocks of (t, state, diagnostics) for a wall-time budget each.

A ``Run`` is one trajectory with any method of ``systems.integrators.STEPPERS``;
``stream`` is the generator over its blocks. Each ``Block`` comes after about
``block_seconds``: the compiled loop runs as many steps as
fit the budget (calibrated from the previous block), keeps at most ``max_points`` states
(evenly spaced in steps), computes only the diagnostics asked for, and watches for
trouble: a non-finite state, an energy error past ``energy_tolerance``, an implicit solve
or a step size that gives up, a division by zero. Trouble ends the stream with a status
and a message instead of NaNs. Crossings of a Poincare section are found inside the
compiled loop and located by cubic Hermite interpolation.

``ensemble`` integrates many initial states in one parallel compiled loop.
"""

from __future__ import annotations

import itertools
import math
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field

import numpy as np

from systems.codegen import driver_module
from systems.growth import UNBOUNDED_GROWTH, GrowthWatch
from systems.integrators import STEPPERS, choose_method, get_stepper
from systems.integrators.codes import CLOCK_SIZE, Clock, Status
from systems.integrators.events import locate_crossings, periodic_brackets
from systems.integrators.registry import Stepper, make_runner
from systems.integrators.stepsize import drawing_step
from systems.limits import DEFAULT_ENERGY_TOLERANCE

PROBLEMS = (
    "non_finite", "singular", "energy_error", "stalled", "budget", "unstable", "inaccurate",
    "unbounded",
)  # fmt: skip
"""How a run can end other than ok; ``"inaccurate"`` only from ``systems.run_check``;
``"unbounded"``: a coordinate grew steadily by orders of magnitude (``systems.growth``)."""
STATUS_WORDS = {
    Status.NON_FINITE: "non_finite",
    Status.NOT_CONVERGED: "stalled",
    Status.BAD_TRANSFORM: "singular",
    Status.STEP_COLLAPSED: "stalled",
}
SINGULAR_GROWTH = 1e6
"""|dy/dt| this many times its initial size at a stop: the problem is a singularity."""
TERMS_GROWTH = 10.0
"""The energy guard measures |H - H0| against |H0| until the energy's terms (sum of
|p_i dq_i/dt|, 2T where T is quadratic) grow past this times their start (or |H0|);
beyond, against |H0| times their growth over this. Where the motion runs off, T and V
grow huge while H stays: their round-off, and a method's error relative to them, would
trip a guard relative to |H0| (a bead on a rotating wire, H = -1/2 with T ~ 1e11)."""


def parse_energy_tolerance(text: str) -> float | None:
    """``"off"`` -> None (no guard), a positive number -> that number; else ValueError."""
    text = str(text).strip().lower()
    if text in ("off", "none", "inf"):
        return None
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not (math.isfinite(value) and value > 0):
        raise ValueError(f"the energy tolerance must be a positive number or 'off', not {text!r}")
    return value


@dataclass(frozen=True)
class Block:
    """A piece of a trajectory.

    Attributes
    ----------
    t : ndarray, shape (k,)
    y : ndarray, shape (k, 2n)
        States ``(q, p)``; the last row is the latest state.
    diagnostics : dict of str to ndarray
        Only those asked for: ``"H"`` (k,), ``"qdot"`` (k, n), ``"points"``
        (k, npoints, 2).
    status : str
        ``"running"``, ``"ok"`` (reached t_end) or a problem from ``PROBLEMS``.
    message : str
        Empty while running; otherwise a sentence for the user.
    steps, rhs_evaluations : int
        Totals since the start of the run (for time-transformed methods, steps in
        fictitious time; for composition methods, gradient evaluations count as rhs).
    method : str
    events_t : ndarray, shape (e,)
        Times of the section crossings found in this block.
    events_y : ndarray, shape (e, 2n)
        States at those crossings.
    setting : str
        ``"dt"``, ``"ds"`` or ``"tol"``: what ``setting_value`` is.
    setting_value : float
        The step or tolerance in use (the default rule's when none was given).
    samples : int
        ``Run.advance(samples=...)``: the first ``samples`` rows are the states at the
        sample times asked for, at exactly those times (the rest: the latest state).
    """

    t: np.ndarray
    y: np.ndarray
    diagnostics: dict[str, np.ndarray]
    status: str
    message: str
    steps: int
    rhs_evaluations: int
    method: str
    events_t: np.ndarray = field(default_factory=lambda: np.empty(0))
    events_y: np.ndarray = field(default_factory=lambda: np.empty((0, 0)))
    setting: str = ""
    setting_value: float = math.nan
    samples: int = 0

    @property
    def finished(self) -> bool:
        return self.status != "running"


DIAGNOSTICS = {"H": "hamiltonian", "qdot": "velocities", "points": "drawing"}


def required_wants(method: str, diagnostics: Sequence[str] = ()) -> frozenset[str]:
    """What ``compile_system`` must provide for ``method`` and the ``diagnostics``."""
    wants = set(get_stepper(method).wants) | {"rhs"}
    wants |= {DIAGNOSTICS[d] for d in diagnostics}
    return frozenset(wants)


# -- one trajectory ------------------------------------------------------------------------


def _rhs_size(compiled, t: float, y: np.ndarray) -> float:
    try:
        with np.errstate(all="ignore"):
            return float(np.max(np.abs(compiled.rhs(t, y))))
    except ZeroDivisionError:
        return math.inf


class Run:
    """One trajectory, advanced block by block for as long as the caller likes.

    Everything that makes the solution what it is lives here for the whole run: the
    runner (state, Kahan compensation, stage guesses, adaptive step), the step or
    tolerance, and the energy baseline. How fast the caller asks for blocks, and up to
    which time (``advance(until=...)``), changes only where blocks begin and end, never
    the states: a paced window and a full-speed export pass through the same states.

    Parameters
    ----------
    compiled : CompiledSystem
        Must provide ``required_wants(method, diagnostics)``.
    method : str or None
        A key of ``STEPPERS``; None chooses automatically (``choose_method``).
    y0 : ndarray, shape (2n,), optional
        Initial ``(q, p)``; the scene's initial state by default.
    dt, tol
        Fixed step (fictitious-time step for time-transformed methods) or tolerance of
        adaptive methods, whichever the method takes (``ValueError`` for the other);
        defaults from the method family's rule.
    diagnostics : sequence of {"H", "qdot", "points"}
    section : (index, value, direction), optional
        Record crossings of ``y[index] = value`` (direction +1 upward, -1 downward,
        0 both) in ``Block.events_t``/``events_y``. On an angle coordinate
        (``systems.angles.angle_coordinates``) every ``value + 2 pi j`` is crossed: the
        compiled loop then records every step and the crossings are found here.
    energy_tolerance : float or None
        Stop with ``"energy_error"`` when H (if conserved and compiled) drifts by more than
        this, relative to |H(y0)| (absolute when |H(y0)| < 1e-8; relative to the size of
        the energy's terms once they have grown by ``TERMS_GROWTH``); where damping can
        only take energy away (``Classification.dissipative``), when H rises above H(y0)
        by more than this. Stop with ``"unbounded"`` when a coordinate has grown steadily
        by ``systems.growth.UNBOUNDED_GROWTH``. None: never, and no ``"unstable"`` either
        (a demonstration of a method's growth).
    compensated : bool
        Kahan-compensated summation of the state in the fixed-step and log-H loops, so
        round-off grows like sqrt(t) (Brouwer's law). Off only for comparisons.
    max_steps : int or None
        Stop with ``"budget"`` after this many steps (a fixed-step run that would need
        more is refused at once). None: no budget.
    probe_start : (t, y), optional
        Where the orbit began, if not ``(t0, y0)``: a run restarted part way along an
        orbit (another method) passes it, so the default step's probe run there is
        remembered, not run again (``stepsize.default_step``), and a conserved energy is
        measured from H there.
    max_step : float or "drawing"
        The longest step an adaptive method may take (inf: as long as its error control
        allows). A drawing needs a bound: DOP853 crosses motion it integrates exactly,
        such as a free flight, in one step, and the states kept are only its ends.
        ``"drawing"``: ``stepsize.drawing_step`` from where the orbit began
        (``probe_start`` or the start). Fixed-step methods ignore it.
    strobe : float, optional
        A stroboscopic section: the states at exactly t0 + k ``strobe`` (k = 1, 2, ...;
        the period of a periodic drive, ``systems.chaos.bifurcation.drive_period``) are
        the blocks' events (``events_t``, ``events_y``), found inside the compiled loop as
        ``advance(samples=...)`` finds them (where ``takes_samples``; not with scipy's
        solvers). Not with a ``section``.
    """

    def __init__(
        self,
        compiled,
        *,
        method: str | None = None,
        y0: np.ndarray | None = None,
        t0: float = 0.0,
        t_end: float = math.inf,
        dt: float | None = None,
        tol: float | None = None,
        diagnostics: Sequence[str] = (),
        max_points: int = 4096,
        section: tuple[int, float, int] | None = None,
        energy_tolerance: float | None = DEFAULT_ENERGY_TOLERANCE,
        compensated: bool = True,
        max_steps: int | None = None,
        probe_start: tuple[float, np.ndarray] | None = None,
        max_step: float | str = math.inf,
        strobe: float | None = None,
    ):
        if method is None:
            method, _ = choose_method(compiled.mechanics)
        stepper = get_stepper(method)
        for d in diagnostics:
            if d not in DIAGNOSTICS:
                raise ValueError(f"unknown diagnostic {d!r}; choose from {sorted(DIAGNOSTICS)}")
        missing = required_wants(method, diagnostics) - compiled.wanted
        if missing:
            raise ValueError(
                f"method {method!r} with diagnostics {list(diagnostics)} needs the compiled "
                f"functions {sorted(missing)}; pass them to compile_system"
            )
        if not t_end > t0:
            raise ValueError("t_end must be after t0")
        if max_step != "drawing" and not (isinstance(max_step, int | float) and max_step > 0):
            raise ValueError(f"max_step must be a positive number or 'drawing', not {max_step!r}")
        problem = stepper.setting_error(dt, tol)
        if problem:
            raise ValueError(problem)
        self.compiled, self.stepper, self.method = compiled, stepper, method
        self.diagnostics, self.max_points = tuple(diagnostics), max_points
        self.section = section
        self.section_period: float | None = None
        if strobe is not None and not (math.isfinite(strobe) and strobe > 0 and section is None):
            raise ValueError(f"strobe must be a positive period without a section, not {strobe!r}")
        self.strobe = None if strobe is None else float(strobe)
        self._strobe_next = 1  # the next stroboscopic time is t0 + strobe * this
        self.t_end = t_end
        self.max_steps = max_steps
        self.y0 = compiled.initial_state(t0) if y0 is None else np.array(y0, dtype=float)
        numeric = compiled.constraints()
        if y0 is not None and numeric is not None and np.all(np.isfinite(self.y0)):
            self.y0 = numeric.project(t0, self.y0)  # a start off the constraints: onto them
        self.t0 = t0
        self.steps = self.evals = 0
        self.finished = False
        self.good = (t0, self.y0.copy())  # the last state handed out
        self.nsteps = 16 if stepper.family.kernel else 4
        self.setting = stepper.setting
        self.energy_tolerance = math.inf if energy_tolerance is None else energy_tolerance
        self.guarded = energy_tolerance is not None
        names = tuple(getattr(getattr(compiled.mechanics, "scene", None), "coordinates", ()))
        n = len(self.y0) // 2
        if len(names) != n:
            names = tuple(f"q{i + 1}" for i in range(n))
        self.growth = GrowthWatch(names, self.y0)
        self.f0 = _rhs_size(compiled, t0, self.y0)
        self.runner = None
        if not np.isfinite(self.f0) or not np.all(np.isfinite(self.y0)):
            self.setting_value = math.nan
            return
        value = dt if dt is not None else tol
        if value is None:
            value = stepper.default_setting(compiled, t0, self.y0, t_end, probe_start)
        self.setting_value = float(value)
        sec = None if section is None else np.array(section, dtype=float)
        self.section_period = _section_period(compiled, section)
        if self.section_period is not None:
            sec = None  # the compiled loop knows one level only: crossings found in advance
        if max_step == "drawing":
            start = (t0, self.y0) if probe_start is None else probe_start
            max_step = drawing_step(compiled, float(start[0]), np.asarray(start[1], float), t_end)
        self.max_step = float(max_step)
        self.unstable = (
            _unstable_step(compiled, stepper, t0, self.y0, self.setting_value, t_end)
            if dt is not None
            and stepper.family.name == "runge_kutta"
            and energy_tolerance is not None  # the guard off: growth is what is shown
            else None
        )
        self.runner = make_runner(
            compiled, stepper, self.y0, t0, t_end, self.setting_value, sec, compensated,
            max_step=self.max_step,
        )  # fmt: skip
        c = compiled.mechanics.classification
        self.watch_energy = c.hamiltonian_conserved and "hamiltonian" in compiled.wanted
        # damping can only take energy away: H rising above its start is the method's
        dissipative = getattr(c, "dissipative", None)
        values = dict(zip(compiled.parameter_names, compiled.parameters, strict=True))
        self.watch_rise = (
            not self.watch_energy
            and dissipative is not None
            and "hamiltonian" in compiled.wanted
            and all(values.get(name, 0.0) > 0 for name in dissipative)
        )
        watched = self.watch_energy or self.watch_rise
        # a conserved energy is measured from where the orbit began (a run restarted part
        # way along it, with another method or guard, goes on measuring the same error)
        o_t, o_y = (t0, self.y0) if probe_start is None or not self.watch_energy else probe_start
        o_t, o_y = float(o_t), np.asarray(o_y, dtype=float)
        self.H0 = float(compiled.hamiltonian(o_t, o_y[None, :])[0]) if watched else 0.0
        self.H_scale = abs(self.H0) if abs(self.H0) > 1e-8 else 1.0
        self.terms0 = max(self._terms(o_t, o_y), self.H_scale) if watched else 1.0
        self.f0 = max(self.f0, 1e-300)

    def _terms(self, t: float, y: np.ndarray) -> float:
        """sum |p_i dq_i/dt| at (t, y): twice the kinetic energy where T is quadratic."""
        n = len(y) // 2
        try:
            with np.errstate(all="ignore"):
                qdot = np.asarray(self.compiled.rhs(t, y), dtype=float)[:n]
                size = float(np.sum(np.abs(y[n:] * qdot)))
        except ZeroDivisionError:
            return 0.0
        return size if math.isfinite(size) else 0.0

    def energy_scale(self, t: float, y: np.ndarray) -> float:
        """What the energy guard divides |H - H0| by at (t, y) (see ``TERMS_GROWTH``)."""
        grown = self._terms(t, y) / (TERMS_GROWTH * self.terms0)
        return self.H_scale * max(1.0, grown)

    @property
    def t(self) -> float:
        return self.good[0] if self.runner is None else self.runner.t

    def answer(self, samples: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The states at ``samples`` (ascending times inside the last step, which reached
        the end time: times a last ``advance(samples=...)`` did not have), as exactly as
        ``advance`` gives them. Only where ``takes_samples``."""
        return self.runner.answer(samples)

    @property
    def takes_samples(self) -> bool:
        """True if ``advance(samples=...)`` finds the sample states in the compiled loop."""
        return self.stepper.family.kernel is not None and self.section_period is None

    def _block(self, t, y, status, message, diag=None, events=None, samples=0) -> Block:
        if status != "running":
            self.finished = True
        ev_t, ev_y = events if events is not None else (np.empty(0), np.empty((0, len(self.y0))))
        return Block(
            t=t, y=y, diagnostics=diag or {}, status=status, message=message, steps=self.steps,
            rhs_evaluations=self.evals, method=self.method, events_t=ev_t, events_y=ev_y,
            setting=self.setting, setting_value=self.setting_value, samples=samples,
        )  # fmt: skip

    def stop(self, status: str, message: str) -> Block:
        """End the run here: a block of the last good state with ``status`` and ``message``."""
        t_good, y_good = self.good
        return self._block(np.array([t_good]), y_good[None, :], status, message)

    def _over_budget(self) -> str:
        return (
            f"the step budget of {self.max_steps:,} steps ran out at t = {self.t:.6g} "
            f"({self.method}, {self.setting} = {self.setting_value:.3g}); raise it "
            "(--max-steps), shorten the run or use a larger step or tolerance"
        )

    def _dense(self) -> dict:
        """How ``locate_crossings`` interpolates this run's steps: DOP853's dense output,
        a Taylor step's series (of the run's order) or cubic Hermite."""
        family = self.stepper.family.name
        if family == "taylor":
            return {"dense": "taylor", "order": self.runner.order}
        return {"dense": family == "dop853"}

    def _periodic_crossings(self, before, t: np.ndarray, y: np.ndarray):
        """Crossings of the section on an angle among ``before`` and the steps (t, y)."""
        index, value, direction = self.section
        bt, by, levels = periodic_brackets(
            np.concatenate([[before[0]], t]),
            np.concatenate([before[1][None, :], y]),
            int(index),
            float(value),
            float(direction),
            self.section_period,
        )
        if not len(bt):
            return None
        return locate_crossings(self.compiled, bt, by, int(index), levels, **self._dense())

    def advance(self, seconds: float = 0.03, until: float = math.inf, samples=None) -> Block:
        """The next block: about ``seconds`` of computing, ending early after the first
        step that reaches ``until``.

        ``samples`` (ascending times, ndarray): the block's first ``Block.samples`` rows
        are the states at exactly those times, found inside the compiled loop (each
        family's ``X_sample`` in ``systems.integrators.kernels``: a shortened step of the
        method, or DOP853's dense output), which returns after the last (the latest state
        ends the block, as always); ignored where the method has no compiled loop or a
        section on an angle needs every step (``takes_samples``).
        """
        if self.finished:
            raise RuntimeError("this run has finished")
        if self.runner is None:
            self.finished = True
            return self._block(
                np.array([self.t0]), self.y0[None, :], "singular",
                f"the equations of motion are singular at the initial state (|dy/dt| = "
                f"{self.f0:.3g}): a collision, r = 0 or a coordinate singularity; move it",
            )  # fmt: skip
        endless = math.isinf(self.t_end)
        if self.max_steps is not None and self.steps == 0 and self.setting == "dt" and not endless:
            needed = (self.t_end - self.t0) / self.setting_value
            if needed > self.max_steps:
                return self.stop(
                    "budget",
                    f"this run needs {needed:.3g} steps of dt = {self.setting_value:.3g}, "
                    f"more than the step budget of {self.max_steps:,}; raise it "
                    "(--max-steps), shorten the run or use a larger step",
                )
        nsteps = self.nsteps
        if self.max_steps is not None:
            if self.steps >= self.max_steps:
                return self.stop("budget", self._over_budget())
            nsteps = min(nsteps, self.max_steps - self.steps)
        start = time.perf_counter()
        before = self.good
        strobing = samples is None and self.strobe is not None and self.takes_samples
        if strobing:  # the stroboscopic section: the states at t0 + k strobe
            k = self._strobe_next
            samples = self.t0 + self.strobe * np.arange(k, k + STROBE_CHUNK, dtype=float)
        # a section on an angle needs every step: thinned to max_points after the search
        points = nsteps + 2 if self.section_period is not None else self.max_points
        try:
            if samples is not None and self.takes_samples:
                out = self.runner.advance(nsteps, points, until, samples)
            else:
                out = self.runner.advance(nsteps, points, until)
        except ZeroDivisionError as exc:
            return self.stop(
                "singular", _division(exc) + f"; the last good state is at t = {self.good[0]:.6g}"
            )
        elapsed = time.perf_counter() - start
        self.steps += out.steps
        self.evals += out.evals
        status, message = "running", ""
        if out.code == Status.END:
            status = "ok"
        elif out.code in STATUS_WORDS:
            status, message = STATUS_WORDS[out.code], _explain(out.code, self.stepper, self.runner)
        elif self.max_steps is not None and self.steps >= self.max_steps:
            status, message = "budget", self._over_budget()
        t, y = out.t, out.y
        events = None
        if self.section_period is not None and len(t):
            events = self._periodic_crossings(before, t, y)
            t, y = _thin(t, y, self.max_points)
        diag = _diagnostics(self.compiled, self.diagnostics, t, y)
        if self.watch_energy and status in ("running", "ok", "budget") and len(t):
            H = diag["H"] if "H" in diag else self.compiled.hamiltonian(t[-1], y[-1:])
            worst = float(np.max(np.abs(H - self.H0)))
            # the scale is at least H_scale: only an error past that needs the terms'
            scale = self.H_scale
            if not worst <= self.energy_tolerance * scale:
                scale = self.energy_scale(float(t[-1]), y[-1])
            worst /= scale
            if not math.isfinite(worst):
                status = "energy_error"
                message = f"the energy became non-finite by t = {t[-1]:.6g} (the numbers overflow)"
            elif not worst <= self.energy_tolerance:
                status = "energy_error"
                against = "" if scale == self.H_scale else f" of the energy's scale {scale:.3g}"
                message = (
                    f"the energy error reached {worst:.3g}{against} (tolerance "
                    f"{self.energy_tolerance:g}) by t = {t[-1]:.6g}; reduce the step or "
                    "tolerance, or raise the energy tolerance (--energy-tolerance, 'off')"
                )
        if self.watch_rise and status in ("running", "ok", "budget") and len(t):
            H = diag["H"] if "H" in diag else self.compiled.hamiltonian(t[-1], y[-1:])
            rise = float(np.max(H - self.H0)) / self.H_scale
            if not rise <= self.energy_tolerance:
                status = "energy_error"
                message = (
                    f"the energy rose by {rise:.3g} of its start (tolerance "
                    f"{self.energy_tolerance:g}) by t = {t[-1]:.6g}, though the damping "
                    f"can only take energy away: {self.method} is unstable or inaccurate "
                    "at this step; reduce the step or tolerance"
                )
        found = self.growth.update(t, y) if len(t) else None
        if (
            found is not None
            and self.guarded
            and status in ("running", "ok", "energy_error")
            and _grows(self.compiled, float(t[found[0]]), y[found[0]], found[1])
        ):
            row, growth = found  # the run ends where the growth became plain
            t, y = t[: row + 1], y[: row + 1]
            diag = _diagnostics(self.compiled, self.diagnostics, t, y)
            status, message = "unbounded", _unbounded(growth)
        if status == "ok" and self.unstable is not None:
            status, message = "unstable", self.unstable
        if status in ("non_finite", "energy_error", "stalled") and len(t):
            growth = self.growth.grown(float(t[-1]), y[-1])
            if growth is not None and _grows(self.compiled, float(t[-1]), y[-1], growth):
                status, message = "unbounded", _unbounded(growth, message)
        if status in PROBLEMS and status not in (
            "singular", "budget", "unstable", "unbounded"
        ) and len(t):  # fmt: skip
            status, message = _diagnose(
                self.compiled, self.runner, t[-1], y[-1], self.f0, status, message
            )
        if self.section is not None and self.section_period is None and len(out.events[0]):
            events = locate_crossings(
                self.compiled, out.events[0], out.events[1], int(self.section[0]),
                float(self.section[1]), **self._dense(),
            )  # fmt: skip
        sampled = out.sampled if samples is not None and self.takes_samples else 0
        if strobing and sampled:
            events = (np.array(t[:sampled]), np.array(y[:sampled]))
            self._strobe_next += sampled
        block = self._block(t, y, status, message, diag, events, sampled)
        if len(t):
            self.good = (float(t[-1]), np.array(y[-1]))
        if out.steps > 0:
            rate = elapsed / out.steps
            target = seconds / max(rate, 1e-12)
            self.nsteps = int(min(max(target, self.nsteps / 4, 1), self.nsteps * 8, 1e9))
        return block


AMPLIFICATION_LIMIT = 2.0
"""A fixed step whose method would multiply a mode the motion does not amplify by more
than this over the run (at most ``AMPLIFICATION_PERIODS`` of it) makes the run end
``"unstable"``, not ok."""
AMPLIFICATION_PERIODS = 100


def _unstable_step(compiled, stepper, t0: float, y0: np.ndarray, dt: float, t_end: float):
    """Why a fixed step ``dt`` of an explicit Runge-Kutta method is unstable for the
    motion near ``y0`` (None if it is not, or cannot be told).

    The method multiplies each mode of the linearised motion, ``exp(dt lambda)`` exactly,
    by the polynomial ``R(dt lambda)`` (Euler 1 + z, RK4 the exponential's series to
    z**4). Where ``|R| > 1`` on a mode that does not grow (Re lambda <= 0: an
    oscillation, a damped one), the numbers grow while the motion does not.
    """
    from systems.integrators.stepsize import jacobian

    J = jacobian(lambda y: compiled.rhs(t0, y), np.asarray(y0, dtype=float))
    if J is None:
        return None
    eigenvalues = np.linalg.eigvals(J)
    z = dt * eigenvalues[eigenvalues.real <= 1e-12 * np.abs(eigenvalues).max(initial=0.0)]
    if not len(z):
        return None
    R = sum(z**k / math.factorial(k) for k in range(stepper.order + 1))
    growth = np.abs(R)
    worst = int(np.argmax(growth))
    if not growth[worst] > 1.0:
        return None
    rate = float(np.abs(eigenvalues).max())
    span = AMPLIFICATION_PERIODS * 2 * math.pi / rate if rate > 0 else math.inf
    steps = min(t_end - t0, span) / dt
    amplification = math.exp(min(steps * math.log(growth[worst]), 700.0))
    if not amplification > AMPLIFICATION_LIMIT:
        return None
    return (
        f"dt = {dt:.3g} is beyond {stepper.name}'s stability for this motion: a mode of "
        f"frequency {abs(z[worst].imag) / dt:.3g} (damping {-z[worst].real / dt:.3g}) is "
        f"multiplied by {growth[worst]:.4g} a step, {amplification:.3g} over the run, where "
        f"the motion does not grow; take dt below {_stable_step(stepper.order, z[worst] / dt):.3g}"
    )


def _stable_step(order: int, eigenvalue: complex) -> float:
    """The largest step at which the Runge-Kutta polynomial of ``order`` does not grow
    on ``eigenvalue`` (bisection from below; 0 where none does, as Euler on an
    undamped oscillation)."""

    def grows(h: float) -> bool:
        z = h * eigenvalue
        return abs(sum(z**k / math.factorial(k) for k in range(order + 1))) > 1.0

    lo, hi = 0.0, 1.0 / max(abs(eigenvalue), 1e-300)
    while not grows(hi) and hi < 1e6 / max(abs(eigenvalue), 1e-300):
        lo, hi = hi, 2 * hi
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        lo, hi = (lo, mid) if grows(mid) else (mid, hi)
    return lo


def _section_period(compiled, section) -> float | None:
    """2 pi when the section cuts an angle coordinate of ``compiled``, else None."""
    if section is None:
        return None
    index = int(section[0])
    mechanics = getattr(compiled, "mechanics", None)
    if mechanics is None or not 0 <= index < compiled.n:
        return None  # a momentum is never an angle
    from systems.angles import TWO_PI, angle_coordinates

    name = mechanics.scene.coordinates[index]
    return TWO_PI if name in angle_coordinates(mechanics) else None


def _thin(t: np.ndarray, y: np.ndarray, max_points: int) -> tuple[np.ndarray, np.ndarray]:
    """At most ``max_points`` rows, evenly spaced in index, the last always kept."""
    if len(t) <= max_points:
        return t, y
    index = np.unique(np.linspace(0, len(t) - 1, max(max_points, 2)).round().astype(int))
    return t[index], y[index]


def stream(compiled, *, block_seconds: float = 0.03, **options) -> Iterator[Block]:
    """Integrate ``compiled`` and yield ``Block``s, each after about ``block_seconds``.

    ``options`` are those of ``Run`` (method, y0, t0, t_end, dt or tol, diagnostics,
    max_points, section, energy_tolerance, compensated, max_steps).

    Yields
    ------
    Block
        The last one has status ``"ok"`` (at ``t_end``) or a problem; an endless run
        (``t_end = inf``) yields until the caller stops iterating.
    """
    run = Run(compiled, **options)
    while not run.finished:
        yield run.advance(block_seconds)


class Sampler:
    """A run's states at given simulation times, one at a time, for any length of run.

    Iterating yields ``(t, y)``: the start, then the state at each of ``times`` (an
    iterable, possibly endless): with a compiled loop at exactly that time, as accurate
    as the steps (``Run.advance``); with scipy's solvers or a section on an angle, the
    state of the first step at or after it. A run that stops early (a problem) ends with
    its last state, before the next time. The samples depend on the times
    only, never on how fast the machine is, and nothing else is kept but the events, so
    memory does not grow with the length of the run. Ctrl+C (SIGINT) ends the iteration
    between blocks with ``interrupted`` set.

    Attributes (after iterating)
    ----------------------------
    last : Block or None
        The last block (its status and message say how the run ended).
    worst : float
        The largest |H - H0| seen in any block (0 without the ``"H"`` diagnostic).
    violation : float or None
        The largest violation of the constraints over the states of every block
        (``constraints.Numeric.violation``: |Phi|, |a . qdot + b|, and how far a unilateral
        g(q, t) >= 0 is passed; None for a scene without constraints).
    interrupted : bool
    events_t : list of float
    events_y : list of ndarray, shape (2n,)
        Section crossings found on the way (with a ``section``).
    """

    def __init__(self, run: Run, times):
        self.run = run
        self.times = times
        self.last: Block | None = None
        self.worst = 0.0
        self.interrupted = False
        self.constraints = run.compiled.constraints()
        self.violation = None if self.constraints is None else 0.0
        self.events_t: list[float] = []
        self.events_y: list[np.ndarray] = []
        self._H0: float | None = None

    def __iter__(self) -> Iterator[tuple[float, np.ndarray]]:
        for t, y in self.chunks():
            for i in range(len(t)):
                yield float(t[i]), y[i]

    def chunks(self) -> Iterator[tuple[np.ndarray, np.ndarray]]:
        """What iterating yields, a block at a time: (t (k,), y (k, 2n)), fresh arrays
        (a caller that keeps thousands of samples needs no Python step per row)."""
        run = self.run
        if self.constraints is not None:
            self.violation = self.constraints.violation(run.t0, run.y0[None])
        yield np.array([run.t0]), run.y0[None].copy()
        try:
            if run.takes_samples:
                yield from self._sampled()
            else:
                for t, y in self._paused():
                    yield np.array([t]), y[None]
        except KeyboardInterrupt:
            self.interrupted = True
            return
        if self.last is None:  # nothing to integrate: the start is all there is
            self.last = run.advance(0.25)

    def _record(self, block: Block) -> None:
        """What a block adds to the events, the energy change and the violation."""
        run = self.run
        self.last = block
        self.events_t.extend(map(float, block.events_t))
        self.events_y.extend(np.array(block.events_y))
        if "H" in block.diagnostics and len(block.t):
            if self._H0 is None:
                self._H0 = float(run.compiled.hamiltonian(run.t0, run.y0[None])[0])
            with np.errstate(all="ignore"):
                change = np.max(np.abs(block.diagnostics["H"] - self._H0))
            self.worst = max(self.worst, float(change))
        if self.constraints is not None and len(block.t):
            worst = self.constraints.violation(block.t, block.y)
            self.violation = max(self.violation, worst)

    def _sampled(self) -> Iterator[tuple[np.ndarray, np.ndarray]]:
        """The samples found by the compiled loop, ``SAMPLE_CHUNK`` times a call at most:
        one Python block for thousands of samples."""
        run = self.run
        take = _taker(self.times)
        t_last = run.t0
        pending = np.empty(0)
        exhausted = False
        block = None

        def pull(pending):
            """``pending`` and up to ``SAMPLE_CHUNK`` more times, each after all before it."""
            more = take(SAMPLE_CHUNK)
            floor = pending[-1] if len(pending) else t_last
            if len(more) and more[0] > floor and np.all(more[1:] > more[:-1]):
                kept = more  # ascending already (linspace's): no running maximum
            else:
                above = np.maximum.accumulate(np.concatenate([[floor], more]))[:-1]
                kept = more[more > above]
            return np.concatenate([pending, kept]), len(more) < SAMPLE_CHUNK

        while not run.finished:
            if not exhausted and len(pending) < SAMPLE_CHUNK:
                pending, exhausted = pull(pending)
            if not len(pending):
                break
            block = run.advance(0.25, samples=pending[:SAMPLE_CHUNK])
            self._record(block)
            answered = block.samples  # one row each, in order; the last row: the latest state
            pending = pending[answered:]
            if answered:
                t_last = float(block.t[answered - 1])
                # views: each block's rows are arrays of their own, which nothing writes
                yield block.t[:answered], block.y[:answered]
        if block is None or not run.finished:
            return
        end = float(block.t[-1])
        while block.status == "ok":
            # the last step reached the end past times the last call did not have
            if not exhausted and (not len(pending) or pending[-1] < end):
                pending, exhausted = pull(pending)
            inside = int(np.searchsorted(pending, end))  # the times before the end
            if inside:
                t, y = run.answer(pending[:inside])
                pending = pending[len(t) :]
                if len(t):
                    t_last = float(t[-1])
                    yield t, y
                if len(t) < inside:
                    break  # not found in the last step (none should be): the end follows
            if exhausted or len(pending):
                break
        if len(block.t) and end > t_last:
            yield block.t[-1:].copy(), block.y[-1:].copy()  # the end, or where it stopped

    def _paused(self) -> Iterator[tuple[float, np.ndarray]]:
        """The samples by runs paused at each time (scipy's solvers, angle sections)."""
        run = self.run
        t_last = run.t0
        for target in self.times:
            if target <= run.t0:
                continue
            while run.t < target and not run.finished:
                self._record(run.advance(0.25, until=target))
            last = self.last
            if last is not None and len(last.t) and last.t[-1] > t_last:
                t_last = float(last.t[-1])
                yield t_last, np.array(last.y[-1])
            if run.finished:
                break


def _taker(times) -> Callable[[int], np.ndarray]:
    """A function giving the next ``k`` of ``times`` (an array, or any iterable, possibly
    endless) as a float array of at most ``k``: slices of an array, not a Python step per
    time (10 000 times cost 0.35 ms through an iterator)."""
    if isinstance(times, np.ndarray):
        source = np.asarray(times, dtype=float).ravel()
        start = 0

        def sliced(k: int) -> np.ndarray:
            nonlocal start
            chunk = source[start : start + k]
            start += len(chunk)
            return chunk

        return sliced
    iterator = iter(times)
    return lambda k: np.fromiter(itertools.islice(iterator, k), dtype=float)


SAMPLE_CHUNK = 16384
"""Sample times handed to the compiled loop in one call at most: ``run``'s default 10 000
rows in one (with 4096, three calls' Python cost 0.3 ms, a sixth of the double
pendulum's integration)."""
STROBE_CHUNK = 64
"""Stroboscopic times handed to one compiled call (``Run(strobe=...)``)."""


def _diagnose(compiled, runner, t: float, y: np.ndarray, f0: float, status: str, message: str):
    """Tell a singularity from a step that is merely too long, after a stop at (t, y).

    A short accurate adaptive run from the last good state over the next few steps shows
    whether |dy/dt| runs away (or the adaptive step collapses too): then the problem is a
    singularity of the equations (a collision, r = 0, a coordinate pole), named as such.
    Otherwise the message says how fast the motion gets there.
    """
    size = _rhs_size(compiled, t, y)
    peak, collapsed, t_stop = size, False, t
    horizon = 4.0 * getattr(runner, "value", 0.0) if runner.s.setting == "dt" else 0.0
    if math.isfinite(size) and horizon > 0.0 and "rhs" in compiled.wanted:
        probe = make_runner(compiled, STEPPERS["dop853"], y, t, t + horizon, 1e-8, None)
        try:
            out = probe.advance(20000, 20000)
        except ZeroDivisionError:
            out = None
        collapsed = out is None or out.code in (Status.NON_FINITE, Status.STEP_COLLAPSED)
        if out is not None and len(out.t):
            t_stop = float(out.t[-1])
            sizes = [_rhs_size(compiled, ti, yi) for ti, yi in zip(out.t, out.y, strict=True)]
            peak = max(peak, *sizes)
    if collapsed or not peak < SINGULAR_GROWTH * f0:
        where = t_stop if collapsed else t
        return "singular", (
            f"the equations are singular near t = {where:.6g} (|dy/dt| grows from "
            f"{f0:.3g} to {peak:.3g}: a collision, r = 0 or a coordinate singularity); "
            f"stopped at t = {t:.6g}. " + message
        )
    if peak > 10.0 * size:
        message += (
            f" (|dy/dt| grows to {peak:.3g} within the next steps, from {size:.3g} here;"
            " an adaptive method such as dop853 follows that)"
        )
    return status, message


GROWS_OVER_DECADE = 3.0
"""An accurate run over one decade's time of a growth: its largest |q| in the last
third this many times that in the first third (10^(2/3) = 4.6 for e^(rate t)), or the
growth is the method's."""


def _grows(compiled, t: float, y: np.ndarray, growth) -> bool:
    """Whether the equations themselves carry ``growth`` on from (t, y): a short accurate
    DOP853 run over the time of one decade (ln 10 / rate)."""
    if not (math.isfinite(growth.rate) and growth.rate > 0) or not np.all(np.isfinite(y)):
        return False
    if abs(y[growth.index]) > np.finfo(float).max / 10.0:
        # a decade more is past the largest double: no run can follow it, and the steady
        # decades the watch recorded up to here are the evidence (the bead's r at 1.7e308
        # was called singular when its last block ended there)
        return True
    horizon = math.log(10.0) / growth.rate
    probe = make_runner(
        compiled, STEPPERS["dop853"], y, t, t + horizon, 1e-10, None, max_step=horizon / 30
    )
    try:
        with np.errstate(all="ignore"):
            out = probe.advance(20000, 4096)
    except ZeroDivisionError:
        return False
    if out.code != Status.END:
        return False
    size = np.abs(np.concatenate([[y[growth.index]], out.y[:, growth.index]]))
    times = np.concatenate([[t], out.t])
    first = size[times <= t + horizon / 3].max()
    last = size[times >= t + 0.67 * horizon].max(initial=0.0)
    return bool(last >= GROWS_OVER_DECADE * first)


def _unbounded(growth, then: str = "") -> str:
    """The message of a run stopped as ``"unbounded"``: which coordinate, how far, how fast."""
    if then:
        return f"{growth.sentence()}; then {then}"
    return (
        f"{growth.sentence()} (stopped at {UNBOUNDED_GROWTH:.0e} times its start scale; "
        "turn the energy guard off to follow it further: --energy-tolerance off)"
    )


def _division(exc: Exception) -> str:
    return (
        f"a division by zero in the equations of motion ({exc}): the state reached a "
        "singularity (a collision, r = 0, or a coordinate singularity)"
    )


def _explain(code: Status, stepper: Stepper, runner) -> str:
    t = runner.t
    if code == Status.NON_FINITE:
        return (
            f"the state became non-finite after t = {t:.6g}; the last finite state is "
            "shown. Reduce the step or tolerance, or check the equations"
        )
    if code == Status.NOT_CONVERGED and stepper.family.constrained:
        return (
            f"the projection onto the constraints did not converge at t = {t:.6g}: their "
            "Jacobian dPhi/dq may lose rank there; reduce the step or tolerance"
        )
    if code == Status.NOT_CONVERGED:
        return (
            f"the implicit {stepper.name} solve did not converge at t = {t:.6g}; reduce the "
            "step (the motion is too fast for it there)"
        )
    if code == Status.BAD_TRANSFORM:
        return (
            f"the time transformation of {stepper.name} broke down at t = {t:.6g} "
            "(it needs V < 0 and T - E > 0); choose another method"
        )
    return f"the step size of {stepper.name} collapsed at t = {t:.6g}"


def _diagnostics(compiled, wanted: Sequence[str], t: np.ndarray, y: np.ndarray) -> dict:
    out: dict[str, np.ndarray] = {}
    if not len(t):
        return out
    if "H" in wanted:
        out["H"] = compiled.hamiltonian(t, y)
    if "qdot" in wanted:
        out["qdot"] = compiled.velocities(t, y)
    if "points" in wanted:
        out["points"] = compiled.drawing(t, y)
    return out


def precompile(compiled, method: str, y0: np.ndarray | None = None, **kwargs) -> float:
    """Compile (or load from the cache) the kernels ``method`` uses, by a throwaway run.

    For a build thread: the first block of the real run then comes without compile
    latency. Returns the seconds it took. ``kwargs`` go to ``stream`` (``dt``, ``tol``).
    """
    start = time.perf_counter()
    y0 = compiled.initial_state() if y0 is None else np.asarray(y0, dtype=float)
    if get_stepper(method).setting != "tol" and kwargs.get("tol") is None:
        kwargs.pop("tol", None)
        kwargs["dt"] = kwargs.get("dt") or 1e-10  # any step compiles the loop; skip choosing one
    for _ in stream(compiled, method=method, y0=y0, t_end=1e-9, energy_tolerance=None,
                    **kwargs):  # fmt: skip
        pass
    return time.perf_counter() - start


def run_to_end(compiled, **kwargs) -> tuple[list[Block], Block]:
    """All blocks of a finite run (``t_end`` required) and the last one."""
    blocks = list(stream(compiled, **kwargs))
    return blocks, blocks[-1]


# -- ensembles -------------------------------------------------------------------------


def ensemble(
    compiled,
    Y0: np.ndarray,
    *,
    method: str,
    t_end: float,
    dt: float | None = None,
    t0: float = 0.0,
    samples: int = 100,
    tol: float | None = None,
    batched: bool = True,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Integrate many initial states at once in one parallel compiled loop.

    Parameters
    ----------
    Y0 : ndarray, shape (N, 2n)
    method : str
        A composition or Gauss-Legendre stepper (fixed steps ``dt``), or ``taylor``
        (adaptive: each row its own steps at the tolerance ``tol``, default the
        family's; the samples from its series).
    batched : bool
        For taylor: the rows in batches of SIMD lanes (``Family.batch``); False, one row
        at a time (``X_ensemble_adaptive_parallel``). The states are the same.
    samples : int
        States kept per trajectory (evenly spaced; for an adaptive method at
        ``t0 + (t_end - t0) j / samples``, j = 1..samples, the last at ``t_end``).

    Returns
    -------
    t : ndarray, shape (m,)
    Y : ndarray, shape (N, m, 2n)
        Rows past a failure keep their last good values (see ``status``).
    status : ndarray of int, shape (N,)
        ``Status`` codes: 0 (``RUNNING``) fine, else what stopped the row.
    """
    stepper = get_stepper(method)
    family = stepper.family
    kernel = family.ensemble_kernel
    if kernel is None:
        raise ValueError(f"ensembles run fixed-step methods or taylor, not {method!r}")
    Y = np.array(Y0, dtype=float, copy=True)
    N, m = Y.shape
    loop = getattr(driver_module(), kernel)
    if family.adaptive_ensemble:
        t, out, status = _adaptive_ensemble(
            compiled, stepper, loop, Y, t0, t_end, samples, tol, batched
        )
    else:
        if dt is None:
            raise ValueError(f"an ensemble of {method!r} needs its step dt")
        nsteps = max(1, int(round((t_end - t0) / dt)))
        stride = max(1, nsteps // samples)
        count = nsteps // stride
        out = np.full((N, count, m), np.nan)
        status = np.zeros(N, dtype=np.int64)
        coef = family.coefficients(stepper, compiled, t0, Y[0], False)
        clock = np.zeros(CLOCK_SIZE)
        clock[Clock.T] = clock[Clock.T0] = t0
        clock[Clock.H] = dt
        clock[Clock.T_END] = clock[Clock.T_PAUSE] = math.inf
        limits = (nsteps, stride)
        fns = compiled.functions(family.functions)
        loop(fns, Y, clock, compiled.parameters, coef, limits, out, status)
        t = t0 + dt * stride * np.arange(1, count + 1)
    # rows that failed keep their last good sample instead of NaN
    for r in np.flatnonzero(status):
        good = np.flatnonzero(np.all(np.isfinite(out[r]), axis=1))
        if len(good):
            out[r, good[-1] + 1 :] = out[r, good[-1]]
    return t, out, status


ENSEMBLE_MAX_STEPS = 10**9
"""The most steps of one row of an adaptive ensemble."""


def _adaptive_ensemble(compiled, stepper, loop, Y, t0, t_end, samples, tol, batched):
    """``ensemble`` of an adaptive family (``X_ensemble_adaptive_parallel``): the coef,
    functions and clock of a runner from the first row (the same for every row: the
    tolerance and the family's constants), each row to ``t_end``. Returns (t, out,
    status) with ``status`` 0 for a row that reached the end."""
    if not math.isfinite(t_end) or t_end <= t0:
        raise ValueError(f"an adaptive ensemble needs a finite end after t0, not {t_end!r}")
    N, m = Y.shape
    value = (
        tol
        if tol is not None
        else stepper.family.default_setting(compiled, stepper, t0, Y[0], t_end)
    )
    runner = stepper.family.runner(compiled, stepper, Y[0], t0, t_end, value, None)
    clock = runner.clock.copy()
    clock[Clock.T_PAUSE] = math.inf
    count = max(1, int(samples))
    t = t0 + (t_end - t0) * np.arange(1, count + 1) / count
    t[-1] = t_end
    out = np.full((N, count, m), np.nan)
    status = np.zeros(N, dtype=np.int64)
    steps = np.zeros(N, dtype=np.int64)
    batch = stepper.family.batch
    if batch is not None and batched:
        kernel, function = batch
        fb = compiled.functions((function,))[0]
        lanes = compiled.taylor().batch()[1]
        loop = getattr(driver_module(), kernel)
        fd = runner.fns[1]  # taylor's double-double orders (asked by runner.coef) or none
        loop(fb, fd, Y, clock, compiled.parameters, runner.coef, t, lanes, out, status, steps)
    else:
        limits = (ENSEMBLE_MAX_STEPS, 1)
        loop(runner.fns, Y, clock, compiled.parameters, runner.coef, t, limits, out, status, steps)
    status[status == int(Status.END)] = int(Status.RUNNING)
    return t, out, status
