"""Section portraits: many orbits' crossings of a Poincaré section at one energy.

The textbook picture of a two-degree autonomous system (Hénon–Heiles at E = 1/8): N
starts on the section (``systems.section.states_on_section`` solves the missing
momentum), each orbit's crossings of ``q_j = value`` with ``p_j > 0``. With the taylor
family the orbits run in SIMD batches over all cores
(``kernels.taylor_batch_section_parallel``: the steps of ``taylor_batch_parallel``, which
are a single run's), each crossing located on its lane's series of the step that crosses,
as a single run locates its own (``events.locate_crossings`` on the step's series).
Where taylor does not apply, ``fallback=True`` runs one ``simulation.Run`` an orbit with
the scene's automatic method; otherwise the refusal's reason is raised.

The energy is checked at every crossing and at each orbit's end: an orbit whose |H - H0|
(relative to max(|H0|, 1e-8)) passes ``energy_tolerance`` is not ``trusted``, and its
message says so.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from systems.section import Section, states_on_section

DEFAULT_CROSSINGS = 2000
"""The most crossings kept per orbit (an orbit stops when it has them)."""
ENERGY_TOLERANCE = 1e-8
"""An orbit whose energy moved by more than this (relative) is not trusted: taylor at its
default tolerance keeps Hénon–Heiles' to about 1e-14 over t = 1e4."""

STOPS = {
    "stalled": "its step collapsed to round-off (the orbit runs off to infinity or meets "
    "a singularity)",
    "non_finite": "its state became non-finite",
}


@dataclass
class Portrait:
    """Crossings of many orbits through one section.

    Attributes
    ----------
    section : Section
    energy : float
    starts : ndarray, shape (N, 2n)
        The orbits' starts (on the section, H = ``energy``).
    t : list of ndarray, shape (k_i,)
        Each orbit's crossing times, ascending.
    y : list of ndarray, shape (k_i, 2n)
        The states at them.
    reached : ndarray, shape (N,)
        The time each orbit stopped at (``t_end``, or earlier when it had its crossings or
        a problem stopped it).
    steps : ndarray of int, shape (N,)
    status : list of str
        ``"ok"`` (reached ``t_end``), ``"full"`` (had ``crossings``), or the problem
        (``simulation.STATUS_WORDS``).
    energy_error : ndarray, shape (N,)
        max |H - H0| / max(|H0|, 1e-8) over the crossings and the end.
    trusted : ndarray of bool, shape (N,)
        No problem and the energy error within the tolerance.
    messages : list of str
        Why an orbit is not trusted ("" where it is).
    method : str
        ``"taylor"``, or the fallback's method.
    """

    section: Section
    energy: float
    starts: np.ndarray
    t: list
    y: list
    reached: np.ndarray
    steps: np.ndarray
    status: list
    energy_error: np.ndarray
    trusted: np.ndarray
    messages: list
    method: str

    @property
    def crossings(self) -> int:
        """All orbits' crossings together."""
        return int(sum(len(t) for t in self.t))

    def summary(self) -> str:
        """One line: orbits, crossings, the worst energy error and the untrusted ones."""
        bad = int(np.count_nonzero(~self.trusted))
        worst = float(np.max(self.energy_error)) if len(self.energy_error) else 0.0
        text = (
            f"{len(self.t)} orbits, {self.crossings} crossings ({self.method}); "
            f"energy error at most {worst:.2g}"
        )
        if bad:
            first = next(m for m in self.messages if m)
            text += f"; {bad} orbit(s) not trusted: {first}"
        return text


def default_starts(compiled, section: Section, energy: float, count: int) -> np.ndarray:
    """``count`` starts on the section at ``energy``: (q_i, p_i) on the line p_i = 0,
    evenly spaced inside the allowed interval of q_i around the scene's start (the part
    of the line the energy reaches that holds the start's q_i, or the point nearest to
    0; an open region such as Hénon–Heiles' beyond its saddles is another interval);
    an angle's over one turn, [-pi, pi].
    The interval's ends, where the missing momentum vanishes, are left out.

    Returns
    -------
    ndarray, shape (count, 2n)

    Raises
    ------
    ValueError
        No point of the line reaches the energy.
    """
    from systems.angles import angle_coordinates
    from systems.section import forbidden

    name = compiled.mechanics.scene.coordinates[section.shown]
    turn = name in angle_coordinates(compiled.mechanics)
    probe = np.linspace(-np.pi, np.pi, 20_001) if turn else np.linspace(-50.0, 50.0, 200_001)
    allowed = ~forbidden(compiled, section, energy, probe, np.zeros_like(probe))
    if not allowed.any():
        raise ValueError(f"no point of the section's line p = 0 reaches the energy {energy:g}")
    centre = float(compiled.initial_state()[section.shown])
    inside = np.flatnonzero(allowed)
    k = int(np.argmin(np.abs(probe - centre)))
    if not allowed[k]:
        k = int(inside[np.argmin(np.abs(probe[inside]))])
    lo, hi = k, k
    while lo > 0 and allowed[lo - 1]:
        lo -= 1
    while hi < len(probe) - 1 and allowed[hi + 1]:
        hi += 1
    left, right = float(probe[lo]), float(probe[hi])
    q = left + (right - left) * (np.arange(count) + 0.5) / count
    Y = states_on_section(compiled, section, energy, q, np.zeros(count))
    return Y[np.all(np.isfinite(Y), axis=1)]


def section_period(compiled, section: Section) -> float:
    """2 pi where the section cuts an angle coordinate (crossed at value + 2 pi j), else 0."""
    from systems.angles import TWO_PI, angle_coordinates

    name = compiled.mechanics.scene.coordinates[section.coordinate]
    return TWO_PI if name in angle_coordinates(compiled.mechanics) else 0.0


def section_portrait(
    compiled,
    section: Section,
    energy: float,
    starts,
    *,
    t_end: float,
    crossings: int = DEFAULT_CROSSINGS,
    tol: float | None = None,
    fallback: bool = False,
    energy_tolerance: float = ENERGY_TOLERANCE,
    cancelled: Callable[[], bool] | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> Portrait | None:
    """Integrate orbits from the section and return every crossing of each.

    Parameters
    ----------
    compiled : CompiledSystem
        A conserved Hamiltonian of two (or more) degrees of freedom, compiled with
        ``hamiltonian``.
    section : Section
    energy : float
    starts : int or array_like, shape (N, 2) or (N, 2n)
        N points (q_i, p_i) of the section (the missing momentum solved at ``energy``;
        points no momentum reaches are left out), full states, or a count
        (``default_starts``).
    t_end : float
        Each orbit runs from t = 0 to this, or until it has ``crossings``.
    crossings : int
    tol : float, optional
        The taylor family's tolerance (default machine epsilon).
    fallback : bool
        Where taylor does not apply, run one ``Run`` an orbit with the scene's automatic
        method instead of raising.
    energy_tolerance : float
    cancelled : callable, optional
        Asked between chunks of orbits (taylor: one batch of lanes a thread; the
        fallback: one orbit); True stops the portrait and None is returned. With it or
        ``progress`` the batch loop runs chunk by chunk (each orbit's crossings are the
        same: every lane steps on its own), otherwise all orbits in one call.
    progress : callable, optional
        ``progress(done, total)`` after each chunk, in orbits.

    Returns
    -------
    Portrait or None
        None only when ``cancelled`` stopped it.

    Raises
    ------
    ValueError
        No conserved energy, no start on the section, or taylor refused (its reason)
        without ``fallback``.
    """
    from systems.integrators.registry import get_stepper

    c = compiled.mechanics.classification
    if not c.hamiltonian_conserved or "hamiltonian" not in compiled.wanted:
        raise ValueError("a section portrait needs a conserved energy (an autonomous H)")
    if not (math.isfinite(t_end) and t_end > 0):
        raise ValueError(f"t_end must be a positive time, not {t_end!r}")
    if crossings < 1:
        raise ValueError(f"crossings must be at least 1, not {crossings}")
    Y0 = _starts(compiled, section, energy, starts)
    stepper = get_stepper("taylor")
    reason = stepper.applies_to(compiled.mechanics)
    if reason is not None and not fallback:
        raise ValueError(f"section portraits in batch run taylor: {reason}")
    if reason is not None:
        runs = _single_runs(compiled, section, Y0, t_end, crossings, cancelled, progress)
        if runs is None:
            return None
        t, y, reached, steps, status, method = runs
    else:
        batch = _batch(compiled, section, Y0, t_end, crossings, tol, cancelled, progress)
        if batch is None:
            return None
        t, y, reached, steps, status = batch
        method = "taylor"
    H0 = compiled.hamiltonian(0.0, Y0)
    errors = np.zeros(len(Y0))
    trusted = np.ones(len(Y0), dtype=bool)
    messages = [""] * len(Y0)
    for r in range(len(Y0)):
        scale = max(abs(H0[r]), 1e-8)
        rows = y[r] if len(y[r]) else Y0[r : r + 1]
        with np.errstate(all="ignore"):
            H = compiled.hamiltonian(0.0, rows)
        errors[r] = float(np.max(np.abs(H - H0[r]))) / scale if np.all(np.isfinite(H)) else np.inf
        if status[r] not in ("ok", "full"):
            trusted[r] = False
            why = STOPS.get(status[r], status[r])
            messages[r] = f"orbit {r} stopped at t = {reached[r]:.6g}: {why}"
        elif not errors[r] <= energy_tolerance:
            trusted[r] = False
            messages[r] = (
                f"orbit {r}: the energy error reached {errors[r]:.3g} "
                f"(tolerance {energy_tolerance:g}): its crossings cannot be trusted"
            )
    return Portrait(
        section=section, energy=float(energy), starts=Y0, t=t, y=y, reached=reached,
        steps=steps, status=status, energy_error=errors, trusted=trusted,
        messages=messages, method=method,
    )  # fmt: skip


def _starts(compiled, section: Section, energy: float, starts) -> np.ndarray:
    n = compiled.n
    if isinstance(starts, int | np.integer):
        Y0 = default_starts(compiled, section, energy, int(starts))
    else:
        points = np.atleast_2d(np.asarray(starts, dtype=float))
        if points.shape[1] == 2 * n and n != 1:
            Y0 = points
        elif points.shape[1] == 2:
            Y0 = states_on_section(compiled, section, energy, points[:, 0], points[:, 1])
            Y0 = Y0[np.all(np.isfinite(Y0), axis=1)]
        else:
            raise ValueError(f"starts must be (N, 2) points or (N, {2 * n}) states")
    if not len(Y0):
        raise ValueError(f"no start of the section reaches the energy {energy:g}")
    return np.ascontiguousarray(Y0)


def _batch(
    compiled, section: Section, Y0: np.ndarray, t_end: float, crossings: int, tol,
    cancelled=None, progress=None,
):  # fmt: skip
    """The orbits in SIMD batches: ``kernels.taylor_batch_section_parallel``, in one call,
    or (with ``cancelled`` or ``progress``) a chunk of one batch a thread at a time."""
    import numba

    from systems.codegen import driver_module
    from systems.integrators.codes import Clock, Status
    from systems.integrators.registry import get_stepper
    from systems.simulation import STATUS_WORDS

    stepper = get_stepper("taylor")
    family = stepper.family
    value = float(np.finfo(float).eps) if tol is None else float(tol)
    problem = stepper.setting_error(tol=value)
    if problem:
        raise ValueError(problem)
    runner = family.runner(compiled, stepper, Y0[0], 0.0, t_end, value, None)
    clock = runner.clock.copy()
    clock[Clock.T_PAUSE] = math.inf
    N, m = Y0.shape
    Y = Y0.copy()
    ev_t = np.full((N, crossings), np.nan)
    ev_y = np.full((N, crossings, m), np.nan)
    events = np.zeros(N, dtype=np.int64)
    status = np.zeros(N, dtype=np.int64)
    steps = np.zeros(N, dtype=np.int64)
    reached = np.zeros(N)
    fb = compiled.functions(("taylor_batch",))[0]
    lanes = compiled.taylor().batch()[1]
    cut = np.array(
        [section.coordinate, section.value, 1.0, section_period(compiled, section)], dtype=float
    )
    loop = driver_module().taylor_batch_section_parallel
    watched = cancelled is not None or progress is not None
    chunk = lanes * max(1, numba.get_num_threads()) if watched else N
    for lo in range(0, N, chunk):
        if cancelled is not None and cancelled():
            return None
        part = slice(lo, min(N, lo + chunk))
        loop(
            fb, Y[part], clock, compiled.parameters, runner.coef, cut, lanes, ev_t[part],
            ev_y[part], events[part], status[part], steps[part], reached[part],
        )  # fmt: skip
        if progress is not None:
            progress(part.stop, N)
    words = []
    for code in status:
        if code == int(Status.END):
            words.append("ok")
        elif code == int(Status.RUNNING):
            words.append("full")
        else:
            words.append(STATUS_WORDS.get(Status(int(code)), "failed"))
    t = [ev_t[r, : events[r]].copy() for r in range(N)]
    y = [ev_y[r, : events[r]].copy() for r in range(N)]
    return t, y, reached, steps, words


def _single_runs(
    compiled, section: Section, Y0: np.ndarray, t_end: float, crossings: int,
    cancelled=None, progress=None,
):  # fmt: skip
    """One ``Run`` an orbit with the scene's automatic method (taylor refused); None when
    ``cancelled`` says so before an orbit."""
    from systems.simulation import Run

    N = len(Y0)
    t, y, status = [], [], []
    reached = np.zeros(N)
    steps = np.zeros(N, dtype=np.int64)
    method = ""
    for r in range(N):
        if cancelled is not None and cancelled():
            return None
        run = Run(
            compiled, y0=Y0[r], t_end=t_end, section=(section.coordinate, section.value, 1),
            max_points=4,
        )  # fmt: skip
        method = run.method
        times: list = []
        states: list = []
        word = "ok"
        while not run.finished:
            block = run.advance(0.05)
            times.extend(block.events_t)
            states.extend(block.events_y)
            if block.status not in ("running", "ok"):
                word = block.status
            if len(times) >= crossings:
                word = "full"
                break
        t.append(np.array(times[:crossings]))
        y.append(np.array(states[:crossings]).reshape(-1, len(Y0[r])))
        reached[r] = run.t
        steps[r] = run.steps
        status.append(word)
        if progress is not None:
            progress(r + 1, N)
    return t, y, reached, steps, status, method
