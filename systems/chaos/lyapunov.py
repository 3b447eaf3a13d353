"""The Lyapunov spectrum by Benettin's method and the fast indicators MEGNO, SALI, GALI.

A ``LyapunovRun`` integrates one orbit with its tangent vectors in the extended state of
``systems.chaos.variational``, by a method of the registry through its own compiled
driver (``systems.integrators.registry.make_runner``: no stepping loop is compiled for
it). Two sets of vectors ride along:

- the *spectrum* set (``exponents`` vectors, all 2n by default), re-orthonormalised by a
  QR decomposition at the end of every interval; the logarithms of the diagonal of R,
  summed and divided by the time, are the exponents (Benettin, Galgani, Giorgilli &
  Strelcyn 1980). Its first vector is only ever rescaled: it is the deviation vector of
  the maximal exponent and of MEGNO;
- the *alignment* set (``max(2, n)`` vectors), each only rescaled to unit length: SALI
  from its first two (Skokos 2001), GALI_k from all k of them (Skokos, Bountis &
  Antonopoulos 2007), the product of the singular values of the unit vectors.

**MEGNO** (Cincotta & Simó 2000), with f(s) = ln |delta(s)| of the first vector
(|delta(0)| = 1) and s the time since the start::

    Y(t) = (2/t) int_0^t s f'(s) ds = 2 f(t) - (2/t) int_0^t f(s) ds,
    <Y>(t) = (1/t) int_0^t Y(s) ds.

``megno`` is the mean <Y>. In this normalisation <Y> tends to 2 for quasi-periodic
orbits and for any motion whose deviations grow linearly (a torus with shear, a Kepler
orbit), to 0 for stable periodic orbits of an isochronous system (a harmonic
oscillator, whose deviations stay bounded), and grows like lambda t / 2 for chaotic ones.
The integrals are taken over every step of the run by the trapezoid rule with the
end-point derivatives (Hermite, fourth order), f' = (J delta . delta) / |delta|^2
evaluated by the tangent function at each step's state.

Intervals end where the steps reach a time ``tau`` after their start, ``tau`` adapted
so that the fastest vector grows, and the spectrum set spreads, by about e^``GROWTH``
in one (at most ``STEPS_PER_INTERVAL`` steps and ``max_interval``): where they end
depends only on the orbit, never on how the caller splits the run (``advance(seconds,
until)``), so the same run gives the same numbers.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np

from systems.chaos.variational import NotApplicable, Tangent, extended, load_tangent, refusal, split

GROWTH = 5.0
"""Growth (a logarithm) of the fastest tangent vector, and spread of the spectrum set's
(the largest log R_ii less the smallest), aimed at in one interval: the spectrum set's
condition number stays about e^GROWTH before each QR. With 3 and the growth alone, the
driven damped pendulum's exponents summed to -0.486 instead of tr J = -0.5 (a spread
of e^19 before each QR); with the spread held to e^5 the sum is within 5e-10, and the
intervals are long enough that their cost in Python (about 0.3 ms each) stays below
the steps'."""
STEPS_PER_INTERVAL = 1000
"""Most steps in one interval (fewer for large extended states: ``ROWS_BUDGET``)."""
ROWS_BUDGET = 2_000_000
"""Numbers of the extended states one interval keeps (every step's state, for MEGNO)."""
DEFAULT_METHOD = "dop853"
DEFAULT_TOL = 1e-12
CHAOTIC_MEGNO = 4.0
"""A mean MEGNO above this is called chaotic (``megno_verdict``): twice a regular orbit's."""
SEED = 20260
"""The random start of the tangent vectors: the same for every run."""


def method_refusal(mechanics, method: str) -> str | None:
    """None when ``method`` can integrate the variational equations of ``mechanics``,
    else why not (the system's own refusal first)."""
    from systems.integrators.registry import STEPPERS

    reason = refusal(mechanics)
    if reason:
        return reason
    stepper = STEPPERS.get(method)
    if stepper is None:
        return f"unknown method {method!r}; choose from {', '.join(lyapunov_methods())}"
    family = stepper.family
    if family.kernel is None:
        return (
            f"{method} is one of scipy's stiff solvers, which are not run on the "
            "variational equations; use dop853 (the default), rk4, gauss_legendre6 or a "
            "yoshida composition"
        )
    if family.time_transformed:
        return (
            f"{method} steps in a fictitious time set by the state's own motion, which "
            "the tangent vectors would change; use dop853 (the default), gauss_legendre6 "
            "or a yoshida composition"
        )
    if not _carries_tangents(family):
        return (
            f"{method} steps with functions of its own ({', '.join(family.functions)}) "
            "that have no tangent counterpart: the Taylor series of the variational "
            "equations are not written; use dop853 (the default), gauss_legendre6 or a "
            "yoshida composition"
        )
    return stepper.applies_to(mechanics)


def _carries_tangents(family) -> bool:
    """Whether every system function ``family`` steps with has a tangent counterpart."""
    from systems.chaos.variational import TANGENT_NAMES

    return family.constrained or all(name in TANGENT_NAMES for name in family.functions)


def lyapunov_methods() -> tuple[str, ...]:
    """The methods that can carry tangent vectors (for some system)."""
    from systems.integrators.registry import STEPPERS

    return tuple(
        name
        for name, s in STEPPERS.items()
        if s.family.kernel is not None and not s.family.time_transformed
        and not s.family.constrained and _carries_tangents(s.family)
    )  # fmt: skip


@dataclass(frozen=True)
class Estimate:
    """The running estimates at the end of an interval.

    Attributes
    ----------
    t : float
        The time reached.
    exponents : ndarray, shape (k,)
        The Lyapunov exponents so far, largest first.
    megno : float
        The mean MEGNO <Y>(t) (2: quasi-periodic, 0: periodic and isochronous, growing
        like lambda t / 2: chaotic).
    megno_now : float
        Y(t) itself.
    sali : float
        The smaller alignment index of the first two unit deviation vectors.
    gali : float
        GALI_k of the alignment set (k = ``gali_order``).
    gali_order : int
    status : str
        ``"running"``, ``"ok"`` (the end time reached) or a problem of
        ``systems.simulation.PROBLEMS``.
    message : str
    intervals, steps, evaluations : int
        Since the start.
    """

    t: float
    exponents: np.ndarray
    megno: float
    megno_now: float
    sali: float
    gali: float
    gali_order: int
    status: str = "running"
    message: str = ""
    intervals: int = 0
    steps: int = 0
    evaluations: int = 0

    @property
    def maximal(self) -> float:
        return float(self.exponents[0])


HISTORY_POINTS = 8192
"""Estimates a ``History`` keeps at most: beyond, every other one is dropped (the last
always kept), so an endless run's plots cost the same however long it runs."""


@dataclass
class History:
    """The estimates at the end of each interval, for plots: ``t`` (N,), ``maximal``
    (N,), ``megno`` (N,), ``sali`` (N,), ``gali`` (N,); N at most ``HISTORY_POINTS``
    (thinned evenly in index past it)."""

    t: list = field(default_factory=list)
    maximal: list = field(default_factory=list)
    megno: list = field(default_factory=list)
    sali: list = field(default_factory=list)
    gali: list = field(default_factory=list)

    def append(self, estimate: Estimate) -> None:
        self.t.append(estimate.t)
        self.maximal.append(estimate.maximal)
        self.megno.append(estimate.megno)
        self.sali.append(estimate.sali)
        self.gali.append(estimate.gali)
        if len(self.t) > HISTORY_POINTS:
            for name in ("t", "maximal", "megno", "sali", "gali"):
                values = getattr(self, name)
                setattr(self, name, values[-1::-2][::-1])

    def arrays(self) -> dict[str, np.ndarray]:
        return {name: np.asarray(getattr(self, name), dtype=float) for name in
                ("t", "maximal", "megno", "sali", "gali")}  # fmt: skip


class LyapunovRun:
    """One orbit and its tangent vectors, from ``t0`` to ``t_end`` (inf: endless).

    Parameters
    ----------
    tangent : Tangent
        The system's tangent functions (``variational.load_tangent``).
    method : str
        A method of ``lyapunov_methods()`` that applies to the system.
    y0 : ndarray, shape (2n,), optional
        The start (default: the scene's initial state).
    dt, tol : float, optional
        The step of a fixed-step method, the tolerance of DOP853 (default 1e-12).
    exponents : int, optional
        How many exponents (largest first): 1 to 2n, default 2n.
    max_interval : float
        The longest interval between two QR decompositions (and estimates): the window
        follows the main orbit with intervals of a few ``time_scale``.

    Raises
    ------
    NotApplicable
        For a system or method the variational equations are not integrated by, and
        for settings out of range, with the reason.
    """

    def __init__(
        self,
        tangent: Tangent,
        *,
        method: str = DEFAULT_METHOD,
        y0: np.ndarray | None = None,
        t0: float = 0.0,
        t_end: float = math.inf,
        dt: float | None = None,
        tol: float | None = None,
        exponents: int | None = None,
        max_interval: float = math.inf,
    ):
        from systems.integrators.registry import STEPPERS, make_runner

        reason = method_refusal(tangent.mechanics, method)
        if reason:
            raise NotApplicable(reason)
        self.stepper = stepper = STEPPERS[method]
        compiled = tangent.compiled
        n = self.n = compiled.n
        dimension = 2 * n
        k_s = dimension if exponents is None else int(exponents)
        if not 1 <= k_s <= dimension:
            raise NotApplicable(
                f"the number of exponents must be from 1 to {dimension} (2n), not {exponents}"
            )
        wrong = stepper.setting_error(dt, tol, (t0, t_end))
        if wrong:
            raise NotApplicable(wrong)
        y0 = compiled.initial_state(t0) if y0 is None else np.asarray(y0, dtype=float)
        self.t0, self.t_end = float(t0), float(t_end)
        self.y0 = np.array(y0, dtype=float)
        self.k_s, self.k_g = k_s, max(2, n)
        rng = np.random.default_rng(SEED)
        basis, _ = np.linalg.qr(rng.standard_normal((dimension, dimension)))
        alignment = rng.standard_normal((dimension, self.k_g))
        alignment /= np.linalg.norm(alignment, axis=0)
        V0 = np.hstack([basis[:, :k_s], alignment])
        if stepper.setting == "tol":
            value = DEFAULT_TOL if tol is None else tol
        else:
            value = dt if dt is not None else stepper.default_setting(compiled, t0, y0, t_end)
        self.setting, self.setting_value = stepper.setting, float(value)
        self.tangent = tangent
        self.runner = make_runner(tangent, stepper, extended(y0, V0), t0, t_end, value, None)
        self.logs = np.zeros(k_s)  # sums of ln R_ii
        self.steps = self.evaluations = self.intervals = 0
        rate = _fastest_rate(tangent, t0, y0)
        # 1 / the largest |eigenvalue| of J at the start: the fastest motion's time
        self.time_scale = 1.0 / rate if rate > 0 else 1.0
        self.max_interval = float(max_interval)
        self.tau = min(GROWTH * self.time_scale, self.max_interval)
        if math.isfinite(t_end):
            self.tau = min(self.tau, (t_end - t0) / 4)
        self.rows = max(16, min(STEPS_PER_INTERVAL, ROWS_BUDGET // len(self.runner.y)))
        # MEGNO: the last row's time, f, f', Y, Y', and the integrals of f and Y so far
        start = self._first_vector(self.runner.y[None])
        self._last = (self.t0, 0.0, self._rate_of_growth(np.array([t0]), start)[0])
        self._last_y = (0.0, self._last[2])
        self._integrals = [0.0, 0.0]
        self.status, self.message = "running", ""
        self._alignment_indices(alignment)
        self.estimate = self._estimate()
        self.history = History()

    @property
    def t(self) -> float:
        return self.runner.t

    def energy_error(self) -> float | None:
        """|H - H0| / |H0| of the orbit now (|H - H0| where H0 = 0), or None where H is
        not conserved or was not compiled: how well the orbit itself was kept."""
        compiled = self.tangent.compiled
        if "hamiltonian" not in compiled.wanted:
            return None
        if not compiled.mechanics.classification.hamiltonian_conserved:
            return None
        y, _ = split(self.runner.y, self.n)
        H0, H = compiled.hamiltonian(np.array([self.t0, self.t]), np.stack([self.y0, y]))
        return float(abs(H - H0) / abs(H0) if H0 != 0 else abs(H - H0))

    @property
    def done(self) -> bool:
        return self.status != "running"

    def advance(self, seconds: float = 0.03, until: float = math.inf) -> Estimate:
        """Whole intervals for about ``seconds`` of computing (at least one), ending
        after the first that reaches ``until``; returns the estimate at the end of the
        last. The intervals depend on neither."""
        start = time.perf_counter()
        while not self.done:
            self._interval()
            if time.perf_counter() - start >= seconds or self.t >= until:
                break
        return self.estimate

    def run(self) -> Estimate:
        """To the end time (or the first problem); returns the last estimate."""
        if not math.isfinite(self.t_end):
            raise ValueError("an endless run has no end: use advance()")
        while not self.done:
            self._interval()
        return self.estimate

    # -- one interval --------------------------------------------------------------------

    def _interval(self) -> None:
        from systems.integrators.codes import Status
        from systems.simulation import STATUS_WORDS, _explain

        runner = self.runner
        until = self.t + self.tau
        outcome = runner.advance(self.rows, self.rows + 1, until=until)
        self.steps += outcome.steps
        self.evaluations += outcome.evals
        t, Y = outcome.t, outcome.y
        if outcome.steps:
            self._megno(t, Y)
            self._renormalise()
            self.intervals += 1
        if outcome.code == Status.END:
            self.status = "ok"
        elif outcome.code not in (Status.RUNNING, Status.OVERSHOT):
            self.status = STATUS_WORDS.get(outcome.code, "stalled")
            self.message = _explain(outcome.code, self.stepper, runner)
        self.estimate = self._estimate()
        if outcome.steps:
            self.history.append(self.estimate)

    def _first_vector(self, Y: np.ndarray) -> np.ndarray:
        """The extended states of the orbit and its first vector alone, (q, dq_1, p,
        dp_1), of the rows ``Y`` (N, m); returns (N, 4n)."""
        n, half = self.n, Y.shape[1] // 2
        return np.concatenate([Y[:, : 2 * n], Y[:, half : half + 2 * n]], axis=1)

    def _rate_of_growth(self, t: np.ndarray, one: np.ndarray) -> np.ndarray:
        """f' = (J v . v) / |v|^2 of the first vector at the rows ``(t, one)`` of
        ``_first_vector``."""
        n = self.n
        rates = self.tangent.rhs_rows(np.broadcast_to(t, (len(one),)), one)
        v = np.concatenate([one[:, n : 2 * n], one[:, 3 * n :]], axis=1)
        Jv = np.concatenate([rates[:, n : 2 * n], rates[:, 3 * n :]], axis=1)
        return np.einsum("ij,ij->i", Jv, v) / np.einsum("ij,ij->i", v, v)

    def _megno(self, t: np.ndarray, Y: np.ndarray) -> None:
        """Carry the MEGNO integrals over the rows of one interval."""
        n = self.n
        one = self._first_vector(Y)
        squares = np.einsum("ij,ij->i", one[:, n : 2 * n], one[:, n : 2 * n])
        squares += np.einsum("ij,ij->i", one[:, 3 * n :], one[:, 3 * n :])
        f = self.logs[0] + 0.5 * np.log(squares)
        df = self._rate_of_growth(t, one)
        t_prev, f_prev, df_prev = self._last
        h = np.diff(np.concatenate([[t_prev], t]))
        first = _hermite(h, np.concatenate([[f_prev], f]), np.concatenate([[df_prev], df]))
        integral_f = self._integrals[0] + np.cumsum(first)
        s = t - self.t0
        with np.errstate(divide="ignore", invalid="ignore"):
            Yn = np.where(s > 0, 2 * f - 2 * integral_f / s, 0.0)
            dY = np.where(s > 0, 2 * df - 2 * f / s + 2 * integral_f / s**2, df)
        Ys = np.concatenate([[self._last_y[0]], Yn])
        dYs = np.concatenate([[self._last_y[1]], dY])
        integral_y = self._integrals[1] + np.sum(_hermite(h, Ys, dYs))
        self._integrals = [float(integral_f[-1]), float(integral_y)]
        self._last = (float(t[-1]), float(f[-1]), float(df[-1]))
        self._last_y = (float(Yn[-1]), float(dY[-1]))

    def _renormalise(self) -> None:
        """QR of the spectrum set, unit length for the alignment set (SALI and GALI
        measured on it); the logarithms of R's diagonal summed; the next interval's
        length from the growth."""
        runner = self.runner
        y, V = split(runner.y, self.n)
        spectrum, alignment = V[:, : self.k_s], V[:, self.k_s :]
        Q, R = np.linalg.qr(spectrum)
        diagonal = np.diag(R)
        logs = np.log(np.abs(diagonal))
        self.logs += logs
        Q = Q * np.sign(diagonal)
        norms = np.sqrt(np.einsum("ij,ij->j", alignment, alignment))
        # the fastest growth, and the spread of the spectrum set: the error of a step
        # goes with the largest vector, the volumes the smaller exponents come from
        # with the smallest
        growth = max(float(np.max(np.log(norms))), float(logs[0]), float(np.ptp(logs)))
        alignment = alignment / norms
        self._alignment_indices(alignment)
        runner.y[:] = extended(y, np.hstack([Q, alignment]))
        half = len(runner.y) // 2
        runner.comp[self.n : half] = 0.0  # the Kahan terms of the vectors rescaled
        runner.comp[half + self.n :] = 0.0
        runner.work[-1][0] = 0.0  # nothing carried over (a derivative, stage guesses)
        factor = GROWTH / growth if growth > 0 else 2.0
        self.tau = min(self.tau * min(2.0, max(0.5, factor)), self.max_interval)

    def _alignment_indices(self, unit: np.ndarray) -> None:
        """SALI of the first two unit vectors of ``unit`` (2n, k), GALI_k of all."""
        a, b = unit[:, 0], unit[:, 1]
        self._sali = float(min(np.sqrt(np.dot(a + b, a + b)), np.sqrt(np.dot(a - b, a - b))))
        self._gali = float(np.prod(np.linalg.svd(unit, compute_uv=False)))

    def _estimate(self) -> Estimate:
        elapsed = self.t - self.t0
        if elapsed > 0:
            exponents = np.sort(self.logs / elapsed)[::-1]
        else:
            exponents = np.zeros(self.k_s)
        sali, gali = self._sali, self._gali
        megno = self._integrals[1] / elapsed if elapsed > 0 else 0.0
        return Estimate(
            t=self.t, exponents=exponents, megno=float(megno), megno_now=self._last_y[0],
            sali=sali, gali=gali, gali_order=self.k_g, status=self.status,
            message=self.message, intervals=self.intervals, steps=self.steps,
            evaluations=self.evaluations,
        )  # fmt: skip


def megno_verdict(megno: float) -> str:
    """What the mean MEGNO says of an orbit, in words: ``"periodic"`` (|<Y>| < 0.5: an
    isochronous periodic orbit), ``"regular"`` (within 0.5 of 2: quasi-periodic, or
    deviations growing linearly), ``"chaotic"`` (above ``CHAOTIC_MEGNO``), otherwise
    ``"undecided"`` (a longer run decides)."""
    if not math.isfinite(megno):
        return "undecided"
    if abs(megno) < 0.5:
        return "periodic"
    if abs(megno - 2.0) < 0.5:
        return "regular"
    if megno > CHAOTIC_MEGNO:
        return "chaotic"
    return "undecided"


def _hermite(h: np.ndarray, f: np.ndarray, df: np.ndarray) -> np.ndarray:
    """The integral of f over each interval of lengths ``h`` (N,) between the values
    ``f`` (N + 1,) with derivatives ``df``: the trapezoid rule with its end-point
    correction h^2/12 (f'_a - f'_b), exact for cubics."""
    return h / 2 * (f[:-1] + f[1:]) + h**2 / 12 * (df[:-1] - df[1:])


def _fastest_rate(tangent: Tangent, t0: float, y0: np.ndarray) -> float:
    """The largest |eigenvalue| of J at the start (a time scale for the first interval)."""
    J = tangent.jacobian(t0, y0)
    if not np.all(np.isfinite(J)):
        return 0.0
    return float(np.max(np.abs(np.linalg.eigvals(J))))


@dataclass(frozen=True)
class Spectrum:
    """The result of ``lyapunov``: the final ``estimate``, the ``history`` of the running
    estimates (``History.arrays()``), the method and its setting, and timings."""

    estimate: Estimate
    history: dict
    method: str
    setting: str
    setting_value: float
    t0: float
    t_end: float
    compile_s: float
    wall_s: float
    energy_error: float | None = None

    def as_json(self) -> dict:
        e = self.estimate
        exponents = [float(x) for x in e.exponents]
        return {
            "exponents": exponents,
            "max": exponents[0],
            "sum": float(np.sum(e.exponents)),
            "megno": e.megno,
            "megno_now": e.megno_now,
            "verdict": megno_verdict(e.megno),
            "sali": e.sali,
            "gali": e.gali,
            "gali_order": e.gali_order,
            "t_end": e.t,
            "t0": self.t0,
            "status": e.status,
            "message": e.message,
            "method": self.method,
            self.setting: self.setting_value,
            "steps": e.steps,
            "evaluations": e.evaluations,
            "intervals": e.intervals,
            "energy_error": self.energy_error,
            "megno_convention": "Cincotta-Simo: <Y> -> 2 quasi-periodic, 0 periodic "
            "(isochronous), ~ max*t/2 chaotic",
            "compile_s": self.compile_s,
            "wall_s": self.wall_s,
        }


def lyapunov(
    compiled,
    *,
    t_end: float,
    method: str = DEFAULT_METHOD,
    y0: np.ndarray | None = None,
    dt: float | None = None,
    tol: float | None = None,
    exponents: int | None = None,
    tangent: Tangent | None = None,
) -> Spectrum:
    """The Lyapunov spectrum and the fast indicators of the orbit from ``y0`` (default:
    the scene's start) to ``t_end``, integrated by ``method`` (``LyapunovRun``).

    Raises
    ------
    NotApplicable
        With the reason, for a system, method or setting that does not apply.
    """
    start = time.perf_counter()
    tangent = load_tangent(compiled) if tangent is None else tangent
    compile_s = time.perf_counter() - start
    run = LyapunovRun(
        tangent, method=method, y0=y0, t_end=t_end, dt=dt, tol=tol, exponents=exponents
    )
    estimate = run.run()
    return Spectrum(
        estimate=estimate, history=run.history.arrays(), method=method,
        setting=run.setting, setting_value=run.setting_value, t0=run.t0, t_end=t_end,
        compile_s=compile_s, wall_s=time.perf_counter() - start,
        energy_error=run.energy_error(),
    )  # fmt: skip


__all__ = [
    "Estimate", "LyapunovRun", "NotApplicable", "Spectrum", "lyapunov", "megno_verdict",
    "method_refusal",
]  # fmt: skip
