"""Work-precision sweeps: what accuracy costs in time, one curve per method.

``sweep`` runs each method over a range of step sizes (fixed-step and log-H methods) or
tolerances (adaptive ones) to the same end time, and records the wall time of the
integration (compilation excluded), the final-state error against a reference, and the
maximum relative energy error. The reference is exact where one is known (linear
systems through the matrix exponential; Kepler orbits after whole periods) and otherwise
a converged DOP853 run, checked against a second one: where the motion is chaotic they
part, and the sweep ends where they still agree. ``WorkPrecision.reference`` says which
reference, and why the horizon is shorter than asked when it is. Progress is reported
through a callback and a sweep can be cancelled between blocks.
"""

from __future__ import annotations

import csv
import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import sympy

from systems.expressions import as_expr
from systems.integrators import STEPPERS, choose_method, get_stepper
from systems.simulation import stream

KEPLER_SCENES = {"kepler_cartesian": "cartesian", "planetary_motion": "polar"}
CSV_COLUMNS = (
    "method",
    "setting",
    "value",
    "wall_s",
    "steps",
    "rhs_evaluations",
    "final_error",
    "energy_error",
    "status",
)


class Cancelled(Exception):
    """Raised inside a sweep when the caller's ``cancelled()`` says so."""


@dataclass(frozen=True)
class WorkPoint:
    """One run of a sweep.

    Attributes
    ----------
    setting : str
        ``"dt"``, ``"ds"`` (fictitious-time step) or ``"tol"``.
    final_error : float
        Max-norm of the final state (q, p) minus the reference.
    energy_error : float or None
        Max over the run of |H - H0| / |H0| (None when H is not conserved).
    """

    method: str
    setting: str
    value: float
    wall_s: float
    steps: int
    rhs_evaluations: int
    final_error: float
    energy_error: float | None
    status: str

    def row(self) -> list:
        return [getattr(self, name) for name in CSV_COLUMNS]


@dataclass(frozen=True)
class WorkPrecision:
    """The result of a sweep: points of all methods, and how errors were measured."""

    title: str
    t_end: float
    reference: str
    methods: tuple[str, ...]
    points: tuple[WorkPoint, ...] = field(default_factory=tuple)
    cancelled: bool = False

    def curve(self, method: str) -> list[WorkPoint]:
        """The points of ``method`` that finished, in sweep order."""
        return [p for p in self.points if p.method == method and p.status == "ok"]

    def write_csv(self, path: str | Path) -> Path:
        from systems.files import atomic_path

        path = Path(path)
        with atomic_path(path) as temporary, temporary.open("w", newline="") as handle:
            writer = csv.writer(handle)
            writer.writerow(CSV_COLUMNS)
            for point in self.points:
                writer.writerow(point.row())
        return path


SWEEP_CANDIDATES = (
    "leapfrog",
    "yoshida4",
    "yoshida6",
    "yoshida8",
    "implicit_midpoint",
    "gauss_legendre4",
    "gauss_legendre6",
    "gauss_legendre4_tt",
    "dop853",
    "taylor",
)
"""The methods a sweep compares by default, where they apply (teaching methods and
scipy's stiff solvers only on request)."""


def default_methods(mechanics) -> list[str]:
    """The automatic choice first, then the other candidates that apply to ``mechanics``."""
    chosen, _ = choose_method(mechanics)
    names = [m for m in SWEEP_CANDIDATES if STEPPERS[m].applies_to(mechanics) is None]
    if STEPPERS["yoshida4"].applies_to(mechanics) is None:
        names.remove("gauss_legendre4_tt")  # separable: the explicit methods say enough
    return [chosen] + [m for m in names if m != chosen]


def settings_for(compiled, method: str, y0: np.ndarray, t_end: float, levels: int) -> list:
    """(setting name, values) of a sweep of ``method``: halving steps from twice the
    default step, or decade tolerances."""
    stepper = get_stepper(method)
    if stepper.setting == "tol":
        high = 1e-13 if not stepper.stiff else 1e-9
        if stepper.family.name == "taylor":  # the order grows with the tolerance's digits
            high = float(np.finfo(float).eps)
        return "tol", list(np.logspace(-3.0, math.log10(high), levels))
    base = stepper.default_setting(compiled, 0.0, y0, t_end)
    return stepper.setting, [base * 2.0 ** (1 - j) for j in range(levels)]


MAX_LEVELS = 12
"""Points per curve at most: each level halves the step, so the last of 12 takes 1024
times the steps of the default one."""
MAX_SWEEP_STEPS = 2 * 10**7
"""Steps the longest run of a sweep may take, as ``finest_step`` estimates them (the
catalogue's scenes at their own end times and six levels take at most 10**7: implicit
midpoint on the stiff spring pendulum; most under 10**6)."""
ADAPTIVE_PER_PERIOD = 100
"""Steps per fastest period assumed for DOP853 at the sweep's and the reference's
tightest tolerances (1e-13, 1e-14)."""


def finest_step(
    compiled, methods: Sequence[str], *, t_end: float, levels: int, y0: np.ndarray | None = None
) -> tuple[float, str]:
    """(step, whose): an estimate of the shortest time step of a sweep's runs, and whose
    run takes it (a method, or ``"the reference"`` for the DOP853 reference run).

    From the same default steps the sweep starts from (a few milliseconds of probing):
    the finest step of each fixed-step method (for a time-transformed one, the time step
    its fictitious step starts with); for the adaptive ones and the reference, a fastest
    period of the motion over ``ADAPTIVE_PER_PERIOD``. ``t_end`` over it is the most
    steps one run takes: what a sweep to an absurd end time or with too many levels
    would cost is known before it starts.
    """
    from systems.integrators.stepsize import default_step, time_transformed_step

    y0 = compiled.initial_state() if y0 is None else np.asarray(y0, dtype=float)
    adaptive = default_step(
        compiled, STEPPERS["rk4"], 0.0, y0, t_end, per_period=ADAPTIVE_PER_PERIOD
    )
    finest = (adaptive, "the reference")
    for method in methods:
        stepper = get_stepper(method)
        if stepper.setting == "tol":
            continue  # as the reference
        setting, values = settings_for(compiled, method, y0, t_end, levels)
        step = values[-1]
        if setting != "dt":
            base = time_transformed_step(compiled, stepper, 0.0, y0, t_end)
            step = base * values[-1] / (values[0] / 2.0)
        finest = min(finest, (step, method))
    return finest


def sweep_problem(
    compiled, methods: Sequence[str], *, t_end: float, levels: int, y0: np.ndarray | None = None
) -> str | None:
    """Why a sweep with these settings would not end in reasonable time, or None.

    ``levels`` beyond ``MAX_LEVELS``, or a run estimated (``finest_step``) at more than
    ``MAX_SWEEP_STEPS`` steps.
    """
    if not 2 <= levels <= MAX_LEVELS:
        return f"the levels must be 2 to {MAX_LEVELS}, not {levels}"
    step, whose = finest_step(compiled, methods, t_end=t_end, levels=levels, y0=y0)
    steps = t_end / step if step > 0 else math.inf
    if steps <= MAX_SWEEP_STEPS:
        return None
    whose = whose if whose == "the reference" else f"the finest run of {whose}"
    count = f"about {steps:.2g}" if math.isfinite(steps) else "more than 1e308"
    return (
        f"a sweep to t = {t_end:.6g} with {levels} levels would take {count} steps "
        f"in {whose}, more than the {MAX_SWEEP_STEPS:.0e} allowed (an end time of at most "
        f"{MAX_SWEEP_STEPS * step:.3g} would do)"
    )


# -- references -----------------------------------------------------------------------


def linear_reference(compiled, y0: np.ndarray, t_end: float) -> np.ndarray | None:
    """exp(J t) y0 when Hamilton's equations are linear with constant coefficients.

    None otherwise, and at once for a system in matrix form: its mass matrix depends on q
    or t (``mechanics.needs_matrix_form``), so its equations are not linear with constant
    coefficients (and the velocity symbols in them are not functions of (q, p) that a
    Jacobian could differentiate).
    """
    from scipy.linalg import expm

    mech = compiled.mechanics
    if mech.matrix_form is not None:
        return None
    variables = (*mech.q, *mech.p)
    rhs = sympy.Matrix([as_expr(e) for e in mech.hamilton_equations])
    J = rhs.jacobian(variables)
    if any(J[i, j].has(*variables, mech.t) for i in range(J.rows) for j in range(J.cols)):
        return None
    if any(e.subs(dict.fromkeys(variables, 0)) != 0 for e in rhs):
        return None
    values = {mech.params[name]: value for name, value in zip(
        compiled.parameter_names, compiled.parameters, strict=True)}  # fmt: skip
    A = np.array(J.xreplace(values).evalf(), dtype=float)
    return expm(A * t_end) @ y0


def kepler_period(compiled, y0: np.ndarray) -> float | None:
    """The period of a bound Kepler orbit for the catalogue's Kepler scenes, else None."""
    scene = compiled.mechanics.scene
    if scene.name not in KEPLER_SCENES:
        return None
    values = dict(zip(compiled.parameter_names, compiled.parameters, strict=True))
    m, k = values["m"], values["k"]
    E = float(compiled.hamiltonian(0.0, y0[None])[0])
    if not E < 0:
        return None
    a = -k / (2 * E)
    return 2 * math.pi * math.sqrt(m * a**3 / k)


def reference_state(compiled, y0: np.ndarray, t_end: float) -> tuple[np.ndarray, float, str]:
    """(reference final state, possibly adjusted t_end, a sentence naming the reference).

    For a Kepler scene ``t_end`` is rounded to a whole number of periods. Without an
    exact solution the reference is a DOP853 run at ``REFERENCE_TOL``, checked against
    a second at ``CHECK_TOL`` at ``CHECKPOINTS`` times: where they part (chaos), the
    horizon is cut to the last time they agree, and the sentence says why.

    Raises
    ------
    ReferenceUnavailable
        When the two runs disagree already at the first checkpoint.
    """
    period = kepler_period(compiled, y0)
    if period is not None:
        orbits = max(1, round(t_end / period))
        t_end = orbits * period
        y_ref = y0.copy()
        if KEPLER_SCENES[compiled.mechanics.scene.name] == "polar":
            y_ref[1] += 2 * math.pi * orbits
        return y_ref, t_end, f"exact: the initial state after {orbits} whole Kepler periods"
    exact = linear_reference(compiled, y0, t_end)
    if exact is not None:
        return exact, t_end, "exact: matrix exponential of the linear equations"
    # with constraints, DOP853 alone would let them drift: its projected twin instead
    method = "dop853" if compiled.constraints() is None else "constrained_dop853"
    label = "DOP853" if method == "dop853" else "constrained DOP853"
    times = t_end * np.arange(1, CHECKPOINTS + 1) / CHECKPOINTS
    reference = _states_at(compiled, method, y0, times, REFERENCE_TOL)
    check = _states_at(compiled, method, y0, times, CHECK_TOL)
    scale = np.maximum(1.0, np.max(np.abs(reference), axis=1))
    apart = np.max(np.abs(reference - check), axis=1) / scale
    agree = apart <= AGREEMENT
    if agree.all():
        return reference[-1].copy(), t_end, f"a converged {label} run (tol {REFERENCE_TOL:g})"
    last = int(np.argmin(agree)) - 1  # the last checkpoint before the first disagreement
    why = (
        f"{label} runs at tol {REFERENCE_TOL:g} and {CHECK_TOL:g} differ by "
        f"{apart[last + 1]:.2g} at t = {times[last + 1]:.4g} (chaotic or ill-conditioned "
        "motion: no run tells the final state there)"
    )
    if last < 0:
        raise ReferenceUnavailable(f"{why}; measure the energy error instead")
    return (
        reference[last].copy(),
        float(times[last]),
        f"a converged {label} run (tol {REFERENCE_TOL:g}) to t = {times[last]:.4g}, where a "
        f"second run agrees to {AGREEMENT:g}; not to {t_end:g}: {why}",
    )


REFERENCE_TOL = 1e-14
CHECK_TOL = 1e-12
"""The reference run's tolerance, and that of the run it is checked against: where they
differ by more than ``AGREEMENT`` (relative to the state's size, at least 1), the
reference does not tell the true state either."""
AGREEMENT = 1e-8
CHECKPOINTS = 40
"""Times, evenly spaced up to t_end, at which the two reference runs are compared."""


class ReferenceUnavailable(RuntimeError):
    """No reference run can be trusted at any time of the sweep."""


def _states_at(compiled, method: str, y0: np.ndarray, times: np.ndarray, tol: float) -> np.ndarray:
    """The states at ``times`` of a ``method`` run at ``tol``, each reached exactly (the
    run restarts at every time), shape (len(times), 2n)."""
    states = np.empty((len(times), len(y0)))
    t, y = 0.0, np.asarray(y0, dtype=float)
    for k, t_next in enumerate(times):
        last = None
        for block in stream(compiled, method=method, y0=y, t0=t, t_end=float(t_next), tol=tol):
            last = block
        if last is None or last.status != "ok":
            message = "" if last is None else last.message
            raise RuntimeError(f"the reference run did not reach t = {t_next:g}: {message}")
        t, y = float(t_next), last.y[-1].copy()
        states[k] = y
    return states


# -- the sweep ------------------------------------------------------------------------


TIMING_BUDGET = 0.05
MAX_REPEATS = 200


def _timed_run(compiled, method, y0, t_end, setting, value, watch_energy, cancelled):
    kwargs = {"tol": value} if setting == "tol" else {"dt": value}
    diagnostics = ("H",) if watch_energy else ()
    best, spent, repeats = math.inf, 0.0, 0
    # Repeat short runs until TIMING_BUDGET seconds are spent: the minimum is the least
    # disturbed timing, and short runs are otherwise dominated by scheduler noise.
    while spent < TIMING_BUDGET and repeats < MAX_REPEATS:
        repeats += 1
        start = time.perf_counter()
        last, worst = None, 0.0
        for block in stream(
            compiled, method=method, y0=y0, t_end=t_end, diagnostics=diagnostics,
            energy_tolerance=None, max_points=512, **kwargs,
        ):  # fmt: skip
            last = block
            if watch_energy and len(block.t):
                worst = max(worst, float(np.max(np.abs(block.diagnostics["H"] - watch_energy[0]))))
            if cancelled is not None and cancelled():
                raise Cancelled
        elapsed = time.perf_counter() - start
        best, spent = min(best, elapsed), spent + elapsed
    energy = worst / watch_energy[1] if watch_energy else None
    return last, best, energy


def sweep(
    compiled,
    methods: Sequence[str] | None = None,
    *,
    t_end: float,
    y0: np.ndarray | None = None,
    levels: int = 6,
    progress: Callable[[int, int, str], None] | None = None,
    cancelled: Callable[[], bool] | None = None,
) -> WorkPrecision:
    """Measure error against wall time for each method over a sweep of its setting.

    Parameters
    ----------
    compiled : CompiledSystem
        With ``rhs`` and ``hamiltonian`` (and ``separable`` for the explicit methods).
    methods : sequence of str, optional
        Defaults to ``default_methods``; methods the compiled system cannot run are
        skipped.
    y0 : ndarray, shape (2n,), optional
    levels : int
        Points per curve.
    progress : callable(done, total, text), optional
    cancelled : callable() -> bool, optional
        Polled between blocks; a cancelled sweep returns what it has, ``cancelled=True``.

    Returns
    -------
    WorkPrecision
    """
    mech = compiled.mechanics
    methods = list(methods) if methods else default_methods(mech)
    for name in methods:
        refusal = get_stepper(name).applies_to(mech)
        if refusal is not None:
            raise ValueError(refusal)
    runnable = [m for m in methods if STEPPERS[m].wants <= compiled.wanted]
    y0 = compiled.initial_state() if y0 is None else np.asarray(y0, dtype=float)
    try:
        y_ref, t_end, reference = reference_state(compiled, y0, t_end)
    except ReferenceUnavailable as exc:  # the energy error still says something
        y_ref, reference = None, f"none: {exc}; the final-state errors are not measured"
    watch = None
    if mech.classification.hamiltonian_conserved:
        H0 = float(compiled.hamiltonian(0.0, y0[None])[0])
        watch = (H0, abs(H0) if abs(H0) > 1e-8 else 1.0)
    plan = [(m, *settings_for(compiled, m, y0, t_end, levels)) for m in runnable]
    total = sum(len(values) for _, _, values in plan)
    done = 0
    points: list[WorkPoint] = []
    title = mech.scene.title
    try:
        for method, setting, values in plan:
            # compile (or load) the method's kernels before any timing
            for _ in stream(compiled, method=method, y0=y0, t_end=t_end * 1e-6 + 1e-12):
                pass
            for value in values:
                if progress is not None:
                    progress(done, total, f"{method} {setting}={value:.3g}")
                last, wall, energy = _timed_run(
                    compiled, method, y0, t_end, setting, value, watch, cancelled
                )
                if y_ref is None:
                    error = math.nan
                else:
                    error = float(np.max(np.abs(last.y[-1] - y_ref))) if len(last.t) else math.inf
                points.append(
                    WorkPoint(
                        method,
                        setting,
                        float(value),
                        wall,
                        int(last.steps),
                        int(last.rhs_evaluations),
                        error,
                        energy,
                        last.status,
                    )  # fmt: skip
                )
                done += 1
    except Cancelled:
        return WorkPrecision(title, t_end, reference, tuple(runnable), tuple(points), True)
    if progress is not None:
        progress(total, total, "done")
    return WorkPrecision(title, t_end, reference, tuple(runnable), tuple(points))
