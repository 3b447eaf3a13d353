"""Streaming integration: blocks of (t, state, diagnostics) for a wall-time budget each.

``stream`` runs one trajectory with any stepper of ``systems.integrators.STEPPERS`` and
yields a ``Block`` about every ``block_seconds``: the compiled loop runs as many steps as
fit the budget (calibrated from the previous block), keeps at most ``max_points`` states
(evenly spaced in steps), computes only the diagnostics asked for, and watches for
trouble: a non-finite state, an energy error past ``energy_tolerance``, an implicit solve
or a step size that gives up, a division by zero. Trouble ends the stream with a status
and a message instead of NaNs. Crossings of a Poincare section are found inside the
compiled loop and located by cubic Hermite interpolation.

``ensemble`` integrates many initial states in one parallel compiled loop.
"""

from __future__ import annotations

import math
import time
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field

import numpy as np

from systems.integrators import STEPPERS, choose_method, gauss_tableau, get_stepper
from systems.integrators.events import locate_crossings
from systems.integrators.registry import Stepper
from systems.integrators.runners import Dop853Runner, make_runner, no_section

PROBLEMS = ("non_finite", "singular", "energy_error", "stalled")
STATUS_CODES = {1: "non_finite", 2: "stalled", 3: "singular", 4: "stalled"}
FIXED_STEP_FAMILIES = ("composition", "gauss", "gauss_tt", "logh")
SINGULAR_GROWTH = 1e6
"""|dy/dt| this many times its initial size at a stop: the problem is a singularity."""


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
        Totals since the start of the stream (for time-transformed methods, steps in
        fictitious time; for composition methods, gradient evaluations count as rhs).
    method : str
    events_t : ndarray, shape (e,)
        Times of the section crossings found in this block.
    events_y : ndarray, shape (e, 2n)
        States at those crossings.
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

    @property
    def finished(self) -> bool:
        return self.status != "running"


DIAGNOSTICS = {"H": "hamiltonian", "qdot": "velocities", "points": "drawing"}


def required_wants(method: str, diagnostics: Sequence[str] = ()) -> frozenset[str]:
    """What ``compile_system`` must provide for ``method`` and the ``diagnostics``."""
    wants = set(get_stepper(method).wants) | {"rhs"}
    wants |= {DIAGNOSTICS[d] for d in diagnostics}
    return frozenset(wants)


# -- the stream -------------------------------------------------------------------------


def _rhs_size(compiled, t: float, y: np.ndarray) -> float:
    try:
        with np.errstate(all="ignore"):
            return float(np.max(np.abs(compiled.rhs(t, y))))
    except ZeroDivisionError:
        return math.inf


def stream(
    compiled,
    *,
    method: str | None = None,
    y0: np.ndarray | None = None,
    t0: float = 0.0,
    t_end: float = math.inf,
    dt: float | None = None,
    tol: float | None = None,
    diagnostics: Sequence[str] = (),
    block_seconds: float = 0.03,
    max_points: int = 4096,
    section: tuple[int, float, int] | None = None,
    energy_tolerance: float = 1e-2,
    compensated: bool = True,
) -> Iterator[Block]:
    """Integrate ``compiled`` and yield ``Block``s, each after about ``block_seconds``.

    Parameters
    ----------
    compiled : CompiledSystem
        Must provide ``required_wants(method, diagnostics)``.
    method : str or None
        A key of ``STEPPERS``; None chooses automatically (``choose_method``).
    y0 : ndarray, shape (2n,), optional
        Initial ``(q, p)``; the scene's initial state by default.
    dt, tol
        Fixed step (fictitious-time step for log-H methods) or tolerance of adaptive
        methods; defaults from the time scales at ``y0``.
    diagnostics : sequence of {"H", "qdot", "points"}
    section : (index, value, direction), optional
        Record crossings of ``y[index] = value`` (direction +1 upward, -1 downward,
        0 both) in ``Block.events_t``/``events_y``.
    energy_tolerance : float
        Stop with ``"energy_error"`` when H (if conserved and compiled) drifts by more than
        this, relative to |H(y0)| (absolute when |H(y0)| < 1e-8).
    compensated : bool
        Kahan-compensated summation of the state in fixed-step and log-H loops, so
        round-off grows like sqrt(t) (Brouwer's law). Off only for comparisons.

    Yields
    ------
    Block
        The last one has status ``"ok"`` (at ``t_end``) or a problem; an endless run
        (``t_end = inf``) yields until the caller stops iterating.
    """
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
    y0 = compiled.initial_state(t0) if y0 is None else np.array(y0, dtype=float)
    if t_end <= t0:
        raise ValueError("t_end must be after t0")
    sec = no_section() if section is None else np.array(section, dtype=float)
    f_start = _rhs_size(compiled, t0, y0)
    if not np.isfinite(f_start) or not np.all(np.isfinite(y0)):
        yield Block(
            np.array([t0]), y0[None, :], {}, "singular",
            f"the equations of motion are singular at the initial state (|dy/dt| = "
            f"{f_start:.3g}): a collision, r = 0 or a coordinate singularity; move it",
            0, 1, method,
        )  # fmt: skip
        return
    runner = make_runner(compiled, stepper, y0, t0, t_end, dt, tol, sec, compensated)
    c = compiled.mechanics.classification
    watch_energy = c.hamiltonian_conserved and "hamiltonian" in compiled.wanted
    H0 = float(compiled.hamiltonian(t0, y0[None, :])[0]) if watch_energy else 0.0
    H_scale = abs(H0) if abs(H0) > 1e-8 else 1.0
    f0 = max(f_start, 1e-300)

    nsteps = 16 if stepper.family != "scipy" else 4
    steps = evals = 0
    good = (t0, y0.copy())  # the last state handed out: a division may stop mid-step
    while True:
        start = time.perf_counter()
        try:
            out = runner.advance(nsteps, max_points)
        except ZeroDivisionError as exc:
            t_good, y_good = good
            yield Block(
                np.array([t_good]), y_good[None, :], {}, "singular",
                _division(exc) + f"; the last good state is at t = {t_good:.6g}",
                steps, evals, method,
            )  # fmt: skip
            return
        elapsed = time.perf_counter() - start
        steps += out.steps
        evals += out.evals
        status, message = "running", ""
        if out.code == 5:
            status = "ok"
        elif out.code in STATUS_CODES:
            status, message = STATUS_CODES[out.code], _explain(out.code, stepper, runner)
        t, y = out.t, out.y
        diag = _diagnostics(compiled, diagnostics, t, y)
        if watch_energy and status in ("running", "ok") and len(t):
            H = diag["H"] if "H" in diag else compiled.hamiltonian(t[-1], y[-1:])
            worst = float(np.max(np.abs(H - H0))) / H_scale
            if not worst <= energy_tolerance:
                status = "energy_error"
                message = (
                    f"the energy error reached {worst:.3g} (tolerance {energy_tolerance:g}) by "
                    f"t = {t[-1]:.6g}; reduce the step or tolerance"
                )
        if status in PROBLEMS and status != "singular" and len(t):
            status, message = _diagnose(compiled, runner, t[-1], y[-1], f0, status, message)
        ev_t, ev_y = np.empty(0), np.empty((0, len(y0)))
        if section is not None and len(out.events[0]):
            ev_t, ev_y = locate_crossings(
                compiled, out.events[0], out.events[1], int(section[0]), float(section[1]),
                dense=stepper.family == "dop853",
            )  # fmt: skip
        yield Block(
            t=t,
            y=y,
            diagnostics=diag,
            status=status,
            message=message,
            steps=steps,
            rhs_evaluations=evals,
            method=method,
            events_t=ev_t,
            events_y=ev_y,
        )
        if status != "running":
            return
        if len(t):
            good = (float(t[-1]), np.array(y[-1]))
        if out.steps > 0:
            rate = elapsed / out.steps
            target = block_seconds / max(rate, 1e-12)
            nsteps = int(min(max(target, nsteps / 4, 1), nsteps * 8, 1e9))


def _diagnose(compiled, runner, t: float, y: np.ndarray, f0: float, status: str, message: str):
    """Tell a singularity from a step that is merely too long, after a stop at (t, y).

    A short accurate adaptive run from the last good state over the next few steps shows
    whether |dy/dt| runs away (or the adaptive step collapses too): then the problem is a
    singularity of the equations (a collision, r = 0, a coordinate pole), named as such.
    Otherwise the message says how fast the motion gets there.
    """
    size = _rhs_size(compiled, t, y)
    peak, collapsed, t_stop = size, False, t
    horizon = 4.0 * getattr(runner, "dt", 0.0)
    if math.isfinite(size) and horizon > 0.0 and "rhs" in compiled.wanted:
        probe = Dop853Runner(compiled, STEPPERS["dop853"], y, t, t + horizon, 1e-8, no_section())
        try:
            out = probe.advance(20000, 20000)
        except ZeroDivisionError:
            out = None
        collapsed = out is None or out.code in (1, 4)
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


def _division(exc: Exception) -> str:
    return (
        f"a division by zero in the equations of motion ({exc}): the state reached a "
        "singularity (a collision, r = 0, or a coordinate singularity)"
    )


def _explain(code: int, stepper: Stepper, runner) -> str:
    t = runner.t
    if code == 1:
        return (
            f"the state became non-finite after t = {t:.6g}; the last finite state is "
            "shown. Reduce the step or tolerance, or check the equations"
        )
    if code == 2:
        return (
            f"the implicit {stepper.name} solve did not converge at t = {t:.6g}; reduce the "
            "step (the motion is too fast for it there)"
        )
    if code == 3:
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
    if get_stepper(method).family in FIXED_STEP_FAMILIES:
        kwargs.setdefault("dt", 1e-10)  # any step compiles the loop; skip choosing one
    for _ in stream(compiled, method=method, y0=y0, t_end=1e-9, energy_tolerance=math.inf,
                    **kwargs):  # fmt: skip
        pass
    return time.perf_counter() - start


def compile_natively(
    compiled, method: str, diagnostics: Sequence[str] = (), y0: np.ndarray | None = None, **kwargs
) -> float:
    """Compile (or load from the cache) what a stream of ``method`` calls, then hand over.

    For a system compiled with ``interpreted_start``: numba compiles the stepper's loop,
    the right-hand side and the ``diagnostics`` by a throwaway run of its native kernels;
    afterwards every call of ``compiled`` (and of running streams, from their next block
    on) goes to the machine code. For any other system this is ``precompile``. Returns the
    seconds it took. ``kwargs`` go to ``stream`` (``dt``, ``tol``).
    """
    start = time.perf_counter()
    native = compiled.native()
    y0 = native.initial_state() if y0 is None else np.asarray(y0, dtype=float)
    with np.errstate(all="ignore"):
        try:
            native.rhs(0.0, y0)
            _diagnostics(native, diagnostics, np.zeros(1), y0[None, :])
        except ArithmeticError:
            pass  # a singular initial state: stream reports it; the kernels are compiled
    precompile(native, method, y0, **kwargs)
    handover = compiled.kernels
    if not compiled.handed_over:
        handover.hand_over()
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
    dt: float,
    t0: float = 0.0,
    samples: int = 100,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Integrate many initial states at once in one parallel compiled loop.

    Parameters
    ----------
    Y0 : ndarray, shape (N, 2n)
    method : str
        A composition or Gauss-Legendre stepper.
    samples : int
        States kept per trajectory (evenly spaced).

    Returns
    -------
    t : ndarray, shape (m,)
    Y : ndarray, shape (N, m, 2n)
        Rows past a failure keep their last good values (see ``status``).
    status : ndarray of int, shape (N,)
        0 fine, 1 non-finite, 2 implicit solve failed.
    """
    stepper = get_stepper(method)
    Y = np.array(Y0, dtype=float, copy=True)
    N, m = Y.shape
    nsteps = max(1, int(round((t_end - t0) / dt)))
    stride = max(1, nsteps // samples)
    count = nsteps // stride
    out = np.full((N, count, m), np.nan)
    status = np.zeros(N, dtype=np.int64)
    K, P = compiled.native().kernels, compiled.parameters  # never the interpreter's loops
    if stepper.family == "composition":
        kick, drift = stepper.kick_drift()
        K.compose_ensemble_parallel(t0, Y, P, dt, nsteps, stride, kick, drift, out, status)
    elif stepper.family == "gauss":
        A, b, c, E = gauss_tableau(stepper.stages)
        K.gauss_ensemble_parallel(t0, Y, P, dt, nsteps, stride, A, b, c, E, 1e-15, 50, out, status)
    else:
        raise ValueError(f"ensembles run composition or Gauss-Legendre methods, not {method!r}")
    t = t0 + dt * stride * np.arange(1, count + 1)
    # rows that failed keep their last good sample instead of NaN
    for r in np.flatnonzero(status):
        good = np.flatnonzero(np.all(np.isfinite(out[r]), axis=1))
        if len(good):
            out[r, good[-1] + 1 :] = out[r, good[-1]]
    return t, out, status
