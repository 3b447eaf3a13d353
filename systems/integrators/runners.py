"""Runners: one per family of compiled loop, each advancing a trajectory by a budget.

A runner owns the state between calls (the Kahan compensation, the Gauss-Legendre stage
guesses, the adaptive step) and returns an ``Outcome``: the states kept (at most
``max_points``), the loop's status code, the section crossings bracketed by steps, and
counters. ``systems.simulation.stream`` turns outcomes into ``Block``s.
"""

from __future__ import annotations

import math

import numpy as np

from systems.integrators.registry import STEPPERS, Stepper, gauss_tableau
from systems.integrators.stepsize import DEFAULT_TOL, STIFF_TOL, default_step, fictitious_step

MAX_EVENTS = 4096


class Outcome:
    __slots__ = ("t", "y", "code", "events", "steps", "evals")

    def __init__(self, t, y, code, events, steps, evals):
        self.t, self.y, self.code, self.events = t, y, code, events
        self.steps, self.evals = steps, evals


def no_section() -> None:
    """The ``ev_spec`` of a run without a section: the loops compile without event code."""
    return None


class FixedRunner:
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

    def advance(self, nsteps: int, max_points: int) -> Outcome:
        full = int(nsteps)
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
        return Outcome(t, y, code, events, steps, evals)


class LogHRunner:
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

    def advance(self, nsteps: int, max_points: int) -> Outcome:
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
        return Outcome(t, y, code, _merge_events(evs, m), steps, evals)

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


class GaussTTRunner:
    """Gauss-Legendre on the Sundman-transformed system (``gauss_tt_run``).

    ``ds`` is the fictitious step; g = (|f(y0)| / |f(y)|)^(3/4), so steps start at
    ``ds`` in t and shrink like r^1.5 near a 1/r singularity. The last partial step to
    ``t_end`` is made by ordinary Gauss-Legendre substeps.
    """

    POWER = 0.75

    def __init__(self, compiled, stepper: Stepper, y0, t0, t_end, ds, section):
        self.c, self.s = compiled, stepper
        self.y = np.array(y0, dtype=float)
        self.m = len(self.y)
        self.comp = np.zeros(self.m + 1)
        self.tq = np.array([float(t0)])
        self.t_end, self.ds, self.section = t_end, ds, section
        self.A, self.b, self.cc, self.E = gauss_tableau(stepper.stages)
        self.Z = np.zeros((stepper.stages, self.m))
        self.T = np.zeros(stepper.stages)
        self.zvalid = np.zeros(1, dtype=np.int64)
        f0 = float(np.linalg.norm(compiled.rhs(t0, self.y)))
        self.fscale = f0 if f0 > 0.0 else 1.0

    @property
    def t(self) -> float:
        return float(self.tq[0])

    def advance(self, nsteps: int, max_points: int) -> Outcome:
        m = self.m
        stride = max(1, math.ceil(nsteps / max(max_points - 1, 1)))
        cap = nsteps // stride + 1
        out_t, out_y = np.empty(cap), np.empty((cap, m))
        ev_t, ev_y = np.empty((MAX_EVENTS, 2)), np.empty((MAX_EVENTS, 2, m))
        info = np.zeros(8, dtype=np.int64)
        t_end = self.t_end if math.isfinite(self.t_end) else 1e300
        self.c.kernels.gauss_tt_run(
            self.tq, self.y, self.comp, self.c.parameters, self.ds, nsteps, stride, self.A,
            self.b, self.cc, self.E, self.Z, self.T, self.zvalid, self.fscale, self.POWER,
            t_end, 1e-15, 50, self.section, out_t, out_y, ev_t, ev_y, info,
        )  # fmt: skip
        code, steps, evals = int(info[2]), int(info[0]), int(info[4])
        n_out, n_ev = int(info[1]), int(info[3])
        t, y = out_t[:n_out], out_y[:n_out]
        evs = [(ev_t[:n_ev], ev_y[:n_ev])]
        if code == 5:
            evals += self._finish(evs)
        if code in (0, 1, 2, 5):
            t, y = _with_last(t, y, self.t, self.y)
        return Outcome(t, y, code, _merge_events(evs, m), steps, evals)

    def _finish(self, evs) -> int:
        """Land on ``t_end`` with ordinary Gauss-Legendre substeps of the local step."""
        remaining = self.t_end - self.t
        if remaining <= 0.0:
            return 0
        f = self.c.rhs(self.t, self.y)
        norm = float(np.linalg.norm(f))
        g = min((self.fscale / norm) ** self.POWER, 1e3) if norm > 0 else 1.0
        nsub = max(1, math.ceil(2.0 * remaining / (self.ds * g)))
        info = np.zeros(8, dtype=np.int64)
        Z, zvalid = np.zeros_like(self.Z), np.zeros(1, dtype=np.int64)
        ev_t, ev_y = np.empty((16, 2)), np.empty((16, 2, self.m))
        self.c.kernels.gauss_run(
            self.t, self.y, self.comp, self.c.parameters, remaining / nsub, nsub, nsub, self.A,
            self.b, self.cc, self.E, Z, zvalid, 1e-15, 50, True, self.section, np.empty(1),
            np.empty((1, self.m)), ev_t, ev_y, info,
        )  # fmt: skip
        evs.append((ev_t[: info[3]], ev_y[: info[3]]))
        self.tq[0] = self.t_end
        return int(info[4])


class Dop853Runner:
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

    def advance(self, nsteps: int, max_points: int) -> Outcome:
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
        if not len(t) or t[-1] != self.t:  # a call that only found t_end still reports
            t, y = _with_last(t, y, self.t, self.y)
        return Outcome(
            t, y, code, _merge_events([(ev_t[:n_ev], ev_y[:n_ev])], m), int(info[0]), int(info[4])
        )


class ScipyRunner:
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

    def advance(self, nsteps: int, max_points: int) -> Outcome:
        ts, ys, evs = [], [], []
        steps, code = 0, 0
        index, value, direction = -1, 0.0, 0.0
        if self.section is not None:
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
        if code != 1 and (not len(t) or t[-1] != self.t):
            t, y = _with_last(t, y, self.t, self.y)
        return Outcome(t, y, code, _merge_events(evs, self.m), steps, self.evals - evals0)


def _crosses(before: float, after: float, direction: float) -> bool:
    return (direction >= 0 and before < 0.0 <= after) or (direction <= 0 and before > 0.0 >= after)


def _with_last(t: np.ndarray, y: np.ndarray, t_last: float, y_last: np.ndarray):
    """Make sure the latest state ends the block (a stride may have skipped it).

    The loop's time (t0 + i dt + dt) and the runner's (t0 + k dt) may differ in the last
    bits: the same instant, which must not appear twice.
    """
    if len(t) and math.isclose(t[-1], t_last, rel_tol=1e-12, abs_tol=1e-300):
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


def make_runner(compiled, stepper, y0, t0, t_end, dt, tol, section, compensated=True):
    family = stepper.family
    if family in ("composition", "gauss"):
        if dt is None:
            dt = default_step(compiled, stepper, t0, y0, t_end)
        return FixedRunner(compiled, stepper, y0, t0, t_end, dt, section, compensated)
    if family == "logh":
        ds = dt if dt is not None else fictitious_step(compiled, stepper, t0, y0, t_end)
        return LogHRunner(compiled, stepper, y0, t0, t_end, ds, section, compensated)
    if family == "gauss_tt":
        if dt is None:
            dt = default_step(compiled, stepper, t0, y0, t_end, probe=False)
        return GaussTTRunner(compiled, stepper, y0, t0, t_end, dt, section)
    if family == "dop853":
        tol = DEFAULT_TOL if tol is None else tol
        return Dop853Runner(compiled, stepper, y0, t0, t_end, tol, section)
    # implicit stiff solvers: a tolerance loose enough to step over resolved-away fast modes
    tol = STIFF_TOL if tol is None else tol
    return ScipyRunner(compiled, stepper, y0, t0, t_end, max(tol, 1e-12), section)
