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
from systems.integrators.registry import Stepper
from systems.integrators.stepsize import DEFAULT_TOL, STIFF_TOL, default_step, fictitious_step

PROBLEMS = ("non_finite", "singular", "energy_error", "stalled")
STATUS_CODES = {1: "non_finite", 2: "stalled", 3: "singular", 4: "stalled"}
MAX_EVENTS = 4096
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


# -- runners: one per family of compiled loop ---------------------------------------------


class _Outcome:
    __slots__ = ("t", "y", "code", "events", "steps", "evals")

    def __init__(self, t, y, code, events, steps, evals):
        self.t, self.y, self.code, self.events = t, y, code, events
        self.steps, self.evals = steps, evals


def _no_section() -> np.ndarray:
    return np.array([-1.0, 0.0, 0.0])


class _Fixed:
    """Composition and Gauss-Legendre loops: fixed step ``dt`` with Kahan summation."""

    def __init__(self, compiled, stepper: Stepper, y0, t0, t_end, dt, section, kahan=True):
        self.c, self.s = compiled, stepper
        self.y = np.array(y0, dtype=float)
        self.comp = np.zeros(len(self.y) + 1)
        self.t0, self.t_end, self.dt = t0, t_end, dt
        self.k = 0  # steps of size dt done; t = t0 + k dt
        self.done_last = False
        self.section = section
        self.kahan = kahan
        self.m = len(self.y)
        if stepper.family == "composition":
            self.kick, self.drift = stepper.kick_drift()
        else:
            self.A, self.b, self.cc, self.E = gauss_tableau(stepper.stages)
            self.Z = np.zeros((stepper.stages, self.m))
            self.zvalid = np.zeros(1, dtype=np.int64)
        self.tol = 1e-15
        self.maxit = 50

    @property
    def t(self) -> float:
        return self.t0 + self.k * self.dt

    def _call(self, t, dt, nsteps, stride):
        m = self.m
        cap = nsteps // stride + 1
        out_t, out_y = np.empty(cap), np.empty((cap, m))
        ev_t, ev_y = np.empty((MAX_EVENTS, 2)), np.empty((MAX_EVENTS, 2, m))
        info = np.zeros(8, dtype=np.int64)
        K = self.c.kernels
        if self.s.family == "composition":
            K.compose_run(
                t, self.y, self.comp, self.c.parameters, dt, nsteps, stride, self.kick,
                self.drift, self.kahan, self.section, out_t, out_y, ev_t, ev_y, info,
            )  # fmt: skip
        else:
            K.gauss_run(
                t, self.y, self.comp, self.c.parameters, dt, nsteps, stride, self.A, self.b,
                self.cc, self.E, self.Z, self.zvalid, self.tol, self.maxit, self.kahan,
                self.section, out_t, out_y, ev_t, ev_y, info,
            )  # fmt: skip
        n_out, n_ev = int(info[1]), int(info[3])
        return out_t[:n_out], out_y[:n_out], info, (ev_t[:n_ev], ev_y[:n_ev])

    def advance(self, nsteps: int, max_points: int) -> _Outcome:
        remaining = math.inf
        if math.isfinite(self.t_end):
            remaining = (self.t_end - self.t) / self.dt
        full = int(min(nsteps, math.floor(remaining + 1e-9)))
        stride = max(1, math.ceil(full / max(max_points - 1, 1)))
        ts, ys, evs = [], [], []
        steps = evals = code = 0
        if full > 0:
            out_t, out_y, info, ev = self._call(self.t, self.dt, full, stride)
            steps, evals, code = int(info[0]), int(info[4]), int(info[2])
            self.k += steps
            ts.append(out_t)
            ys.append(out_y)
            evs.append(ev)
        if code == 0 and full < nsteps and math.isfinite(self.t_end):
            last = self.t_end - self.t
            if last > 1e-12 * max(abs(self.t_end), self.dt):
                if self.s.family == "gauss":
                    self.zvalid[0] = 0
                out_t, out_y, info, ev = self._call(self.t, last, 1, 1)
                code = int(info[2])
                steps += int(info[0])
                evals += int(info[4])
                ts.append(out_t)
                ys.append(out_y)
                evs.append(ev)
            if code == 0:
                self.k = int(round((self.t_end - self.t0) / self.dt))
                self.done_last = True
                code = 5
        t = np.concatenate(ts) if ts else np.empty(0)
        y = np.concatenate(ys) if ys else np.empty((0, self.m))
        if code in (0, 1, 2, 5):  # the loops leave y at the last good state
            t, y = _with_last(t, y, self.t_end if code == 5 else self.t, self.y)
        events = _merge_events(evs, self.m)
        return _Outcome(t, y, code, events, steps, evals)


class _LogH:
    """Logarithmic-Hamiltonian leapfrog compositions in fictitious time ``ds``."""

    def __init__(self, compiled, stepper: Stepper, y0, t0, t_end, ds, section, kahan=True):
        self.c, self.s = compiled, stepper
        self.kahan = kahan
        self.y = np.array(y0, dtype=float)
        self.m = len(self.y)
        self.comp = np.zeros(self.m + 1)
        self.tq = np.array([float(t0)])
        self.t_end, self.ds, self.section = t_end, ds, section
        self.kick, self.drift = stepper.kick_drift()
        self.energy = float(compiled.kernels.hamiltonian(float(t0), self.y, compiled.parameters))

    @property
    def t(self) -> float:
        return float(self.tq[0])

    def advance(self, nsteps: int, max_points: int) -> _Outcome:
        m = self.m
        stride = max(1, math.ceil(nsteps / max(max_points - 1, 1)))
        cap = nsteps // stride + 1
        out_t, out_y = np.empty(cap), np.empty((cap, m))
        ev_t, ev_y = np.empty((MAX_EVENTS, 2)), np.empty((MAX_EVENTS, 2, m))
        info = np.zeros(8, dtype=np.int64)
        t_end = self.t_end if math.isfinite(self.t_end) else 1e300
        self.c.kernels.logh_run(
            self.tq, self.y, self.comp, self.c.parameters, self.ds, nsteps, stride, self.kick,
            self.drift, self.energy, t_end, self.kahan, self.section, out_t, out_y, ev_t, ev_y,
            info,
        )  # fmt: skip
        code, steps, evals = int(info[2]), int(info[0]), int(info[4])
        n_out, n_ev = int(info[1]), int(info[3])
        t, y = out_t[:n_out], out_y[:n_out]
        evs = [(ev_t[:n_ev], ev_y[:n_ev])]
        if code == 5:
            evals += self._finish(evs)
        if code in (0, 1, 3, 5):
            t, y = _with_last(t, y, self.t, self.y)
        return _Outcome(t, y, code, _merge_events(evs, m), steps, evals)

    def _finish(self, evs) -> int:
        """Land on ``t_end``: the same composition in ordinary time, 8th order substeps."""
        remaining = self.t_end - self.t
        if remaining <= 0.0:
            return 0
        n = self.c.n
        P = self.c.parameters
        u = -self.c.kernels.potential(self.t, self.y[:n].copy(), P)
        dt_here = self.ds / max(u, 1e-300)
        nsub = max(1, math.ceil(2.0 * remaining / dt_here))
        kick, drift = STEPPERS["yoshida8"].kick_drift()
        info = np.zeros(8, dtype=np.int64)
        ev_t, ev_y = np.empty((16, 2)), np.empty((16, 2, self.m))
        self.c.kernels.compose_run(
            self.t, self.y, self.comp, P, remaining / nsub, nsub, nsub, kick, drift, True,
            self.section, np.empty(1), np.empty((1, self.m)), ev_t, ev_y, info,
        )  # fmt: skip
        evs.append((ev_t[: info[3]], ev_y[: info[3]]))
        self.tq[0] = self.t_end
        return int(info[4])


class _Dop853:
    """Compiled adaptive DOP853; every accepted step is kept, then thinned."""

    def __init__(self, compiled, stepper, y0, t0, t_end, tol, section):
        from scipy.integrate._ivp import dop853_coefficients as dc

        self.c = compiled
        self.y = np.array(y0, dtype=float)
        self.m = len(self.y)
        self.state = np.array([float(t0), 0.0, 0.0])
        self.t_end = t_end
        self.rtol, self.atol = tol, tol * 1e-2
        self.coef = (
            np.ascontiguousarray(dc.A[:12, :12]),
            dc.B.copy(),
            np.ascontiguousarray(dc.C[:12]),
            dc.E3.copy(),
            dc.E5.copy(),
        )
        self.section = section
        f0 = compiled.rhs(t0, self.y)
        scale = self.atol + self.rtol * np.abs(self.y)
        d0, d1 = np.linalg.norm(self.y / scale), np.linalg.norm(f0 / scale)
        h = 1e-6 if d0 < 1e-5 or d1 < 1e-5 else 0.01 * d0 / d1
        if math.isfinite(t_end):
            h = min(h, t_end - t0)
        self.state[1] = h

    @property
    def t(self) -> float:
        return float(self.state[0])

    def advance(self, nsteps: int, max_points: int) -> _Outcome:
        m = self.m
        out_t, out_y = np.empty(nsteps), np.empty((nsteps, m))
        ev_t, ev_y = np.empty((MAX_EVENTS, 2)), np.empty((MAX_EVENTS, 2, m))
        info = np.zeros(8, dtype=np.int64)
        t_end = self.t_end if math.isfinite(self.t_end) else 1e300
        A, B, C, E3, E5 = self.coef
        self.c.kernels.dop853_run(
            self.state, self.y, self.c.parameters, t_end, self.rtol, self.atol, nsteps, A, B,
            C, E3, E5, self.section, out_t, out_y, ev_t, ev_y, info,
        )  # fmt: skip
        n_out, n_ev = int(info[1]), int(info[3])
        t, y = _thin(out_t[:n_out], out_y[:n_out], max_points)
        code = int(info[2])
        return _Outcome(
            t, y, code, _merge_events([(ev_t[:n_ev], ev_y[:n_ev])], m), int(info[0]), int(info[4])
        )


class _Scipy:
    """scipy's Radau, BDF or LSODA stepping on the compiled rhs (for stiff systems)."""

    def __init__(self, compiled, stepper, y0, t0, t_end, tol, section):
        from scipy.integrate import BDF, LSODA, Radau

        cls = {"radau": Radau, "bdf": BDF, "lsoda": LSODA}[stepper.name]
        self.c = compiled
        self.m = len(y0)
        self.evals = 0
        rhs, P, K = np.empty(self.m), compiled.parameters, compiled.kernels

        def fun(t, y):
            self.evals += 1
            out = np.empty(self.m)
            K.rhs(float(t), np.ascontiguousarray(y, dtype=float), P, out)
            return out

        del rhs
        bound = t_end if math.isfinite(t_end) else 1e300
        self.solver = cls(fun, t0, np.array(y0, dtype=float), bound, rtol=tol, atol=tol * 1e-2)
        self.section = section
        self.t_end = t_end

    @property
    def t(self) -> float:
        return float(self.solver.t)

    @property
    def y(self) -> np.ndarray:
        return self.solver.y

    def advance(self, nsteps: int, max_points: int) -> _Outcome:
        ts, ys, evs = [], [], []
        steps, code = 0, 0
        index, value, direction = int(self.section[0]), self.section[1], self.section[2]
        evals0 = self.evals
        for _ in range(nsteps):
            t_old, y_old = self.solver.t, self.solver.y.copy()
            message = self.solver.step()
            if self.solver.status == "failed":
                code = 4
                break
            steps += 1
            y = self.solver.y
            if not np.all(np.isfinite(y)):
                code = 1
                break
            ts.append(self.solver.t)
            ys.append(y.copy())
            if index >= 0 and _crosses(y_old[index] - value, y[index] - value, direction):
                evs.append((np.array([[t_old, self.solver.t]]), np.stack([y_old, y])[None]))
            if self.solver.status == "finished":
                code = 5
                break
        del message
        t = np.array(ts)
        y = np.array(ys).reshape(len(ts), self.m)
        t, y = _thin(t, y, max_points)
        return _Outcome(t, y, code, _merge_events(evs, self.m), steps, self.evals - evals0)


def _crosses(before: float, after: float, direction: float) -> bool:
    return (direction >= 0 and before < 0.0 <= after) or (direction <= 0 and before > 0.0 >= after)


def _with_last(t: np.ndarray, y: np.ndarray, t_last: float, y_last: np.ndarray):
    """Make sure the latest state ends the block (a stride may have skipped it)."""
    if len(t) and t[-1] == t_last:
        y = y.copy()
        y[-1] = y_last
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


def locate_crossings(
    compiled, brackets_t: np.ndarray, brackets_y: np.ndarray, index: int, value: float
) -> tuple[np.ndarray, np.ndarray]:
    """Crossings of ``y[index] = value`` inside bracketing steps, by cubic Hermite.

    Parameters
    ----------
    brackets_t : ndarray, shape (e, 2)
        Times before and after each crossing step.
    brackets_y : ndarray, shape (e, 2, 2n)
        States before and after.

    Returns
    -------
    t : ndarray, shape (e,)
    y : ndarray, shape (e, 2n)
        The Hermite interpolant (from the states and rhs at both ends, error O(h^4)) at
        the root of its ``index`` component, found by safeguarded Newton/bisection.
    """
    e = len(brackets_t)
    m = brackets_y.shape[-1] if e else 0
    ts, ys = np.empty(e), np.empty((e, m))
    for i in range(e):
        t0, t1 = brackets_t[i]
        y0, y1 = brackets_y[i]
        h = t1 - t0
        f0 = compiled.rhs(t0, y0) * h
        f1 = compiled.rhs(t1, y1) * h

        def at(s, y0=y0, y1=y1, f0=f0, f1=f1):
            h00 = 2 * s**3 - 3 * s**2 + 1
            h10 = s**3 - 2 * s**2 + s
            h01 = -2 * s**3 + 3 * s**2
            h11 = s**3 - s**2
            return h00 * y0 + h10 * f0 + h01 * y1 + h11 * f1

        lo, hi = 0.0, 1.0
        g_lo = y0[index] - value
        s = g_lo / (g_lo - (y1[index] - value)) if y1[index] != y0[index] else 0.5
        for _ in range(60):
            g = at(s)[index] - value
            if g == 0.0:
                break
            if (g < 0) == (g_lo < 0):
                lo, g_lo = s, g
            else:
                hi = s
            if hi - lo < 1e-15:
                break
            s = 0.5 * (lo + hi)
        ts[i] = t0 + s * h
        ys[i] = at(s)
    return ts, ys


# -- the stream -------------------------------------------------------------------------


def _make_runner(compiled, stepper, y0, t0, t_end, dt, tol, section, compensated=True):
    family = stepper.family
    if family in ("composition", "gauss"):
        if dt is None:
            dt = default_step(compiled, stepper, t0, y0, t_end)
        return _Fixed(compiled, stepper, y0, t0, t_end, dt, section, compensated)
    if family == "logh":
        ds = dt if dt is not None else fictitious_step(compiled, stepper, t0, y0, t_end)
        return _LogH(compiled, stepper, y0, t0, t_end, ds, section, compensated)
    if family == "dop853":
        tol = DEFAULT_TOL if tol is None else tol
        return _Dop853(compiled, stepper, y0, t0, t_end, tol, section)
    # implicit stiff solvers: a tolerance loose enough to step over resolved-away fast modes
    tol = STIFF_TOL if tol is None else tol
    return _Scipy(compiled, stepper, y0, t0, t_end, max(tol, 1e-12), section)


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
    sec = _no_section() if section is None else np.array(section, dtype=float)
    runner = _make_runner(compiled, stepper, y0, t0, t_end, dt, tol, sec, compensated)
    c = compiled.mechanics.classification
    watch_energy = c.hamiltonian_conserved and "hamiltonian" in compiled.wanted
    H0 = float(compiled.hamiltonian(t0, y0[None, :])[0]) if watch_energy else 0.0
    H_scale = abs(H0) if abs(H0) > 1e-8 else 1.0
    f0 = max(_rhs_size(compiled, t0, y0), 1e-300)

    nsteps = 16 if stepper.family != "scipy" else 4
    steps = evals = 0
    while True:
        start = time.perf_counter()
        try:
            out = runner.advance(nsteps, max_points)
        except ZeroDivisionError as exc:
            yield _stopped(compiled, method, runner, steps, evals, "singular", _division(exc))
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
                compiled, out.events[0], out.events[1], int(section[0]), float(section[1])
            )
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
        probe = _Dop853(compiled, STEPPERS["dop853"], y, t, t + horizon, 1e-8, _no_section())
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


def _stopped(compiled, method, runner, steps, evals, status, message) -> Block:
    y = np.array(runner.y, dtype=float)[None, :]
    t = np.array([runner.t])
    if not np.all(np.isfinite(y)):
        y = np.empty((0, y.shape[1]))
        t = np.empty(0)
    return Block(t, y, {}, status, message, steps, evals, method)


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
    K, P = compiled.kernels, compiled.parameters
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
