"""The automatic choice, measured on the compiled system: the cheapest method that keeps H.

``choice.choose_method`` decides from the classification alone. Where it picks a
fixed-step symplectic method for a conservative system (``yoshida8``,
``gauss_legendre6``, ``logh_yoshida6``), the cost of that method at its default step is
not known from the classification: on the catalogue it ranges from a fair price to a
hundred times what adaptive DOP853 needs for the same energy error (a chain's fastest
mode sets the fixed step for the whole run). So both are run here, briefly, on the
compiled system, and the cheaper one that keeps the relative energy error within
``ENERGY_TARGET`` over the run is chosen.

Cost is counted, never timed (a shared machine's clock would make the choice change from
run to run): right-hand-side evaluations (or gradient pairs, for a splitting) per unit
of simulated time, times ``PER_EVALUATION``, the work per evaluation besides the
system's own (measured once by ``benchmarks/throughput.py``). The same scene and start
always get the same choice.

Over the scene's run a symplectic method's energy error stays bounded and DOP853's grows
about linearly; DOP853's pilot error is extrapolated linearly to the whole run, so it is
chosen only where its drift stays within the target by the end.

Then ``taylor`` is priced against the winner (and against the classification's own
``dop853`` on a conservative system): pilots at each of ``TAYLOR_TOLERANCES``, its error
extrapolated as DOP853's, each step priced at ``taylor_equivalents`` evaluations (a
count from the decomposition's nodes and the order, its weights fitted once to timings
by ``benchmarks/taylor_cost.py``). A tolerance other than the default that wins reaches
the run through ``chosen_tolerance``.

Where H is not conserved (damping, driving, time-dependent constraints: the
classification's ``dop853``) there is no energy to measure accuracy by: ``_by_state``
compares the pilots' states with a tight reference (taylor at machine epsilon, checked
by a second run of it on shorter steps) at checkpoints where the two agree, and prices
taylor against DOP853 at the same error per unit time.
"""

from __future__ import annotations

import math
import threading
import weakref

import numpy as np

from systems.integrators.registry import get_stepper
from systems.integrators.stepsize import (
    AIM_GROWTH,
    DEFAULT_TOL,
    ENERGY_TARGET,
    default_step,
    pilot_run,
)

CANDIDATES = ("yoshida8", "gauss_legendre6", "logh_yoshida6")
"""The classification's choices that are measured against ``dop853``."""
ALTERNATIVE = "dop853"
TAYLOR = "taylor"
"""Priced against the winner of the above (and against the classification's own
``dop853`` on a conservative system)."""
TAYLOR_TOLERANCES = (float(np.finfo(float).eps), 1e-14, 1e-13, 1e-12, 1e-11, 1e-10)
"""The tolerances taylor is priced at (orders 20, 18, 16, 15, 14, 13): the step count
hardly depends on the tolerance (the order does), so the cheapest is the one whose
coefficient function is fastest: order 20 (the default, machine epsilon) has the
unrolled form, the others the looped one (``systems.taylor.compiled``)."""
LOOSER_GAIN = 0.8
"""A looser tolerance replaces the tightest that keeps the target (machine epsilon, as
a rule) only when priced at most this fraction of it, and then the cheapest such does
(the price is a model; the timings it was fitted to varied by up to 1.5x)."""

PILOT_STEPS = 4000
"""Steps of each pilot run at most: a few ms to a few tens of ms with compiled kernels."""

PER_EVALUATION = {"gauss": 2.0}
"""Work per evaluation relative to an explicit Runge-Kutta stage, by kernel family: a
collocation iteration sums s x s stage products besides each evaluation (1.0 where not
listed)."""

MARGIN = 0.5
"""DOP853 qualifies when its extrapolated error is within this fraction of the target."""

_memory: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()
_tolerances: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()
"""Per compiled system: {(t0, y0, parameters, horizon): tol} where the choice took taylor
at a tolerance other than its default (``chosen_tolerance``)."""
_lock = threading.Lock()


def measured_choice(
    compiled,
    method: str,
    reason: str,
    t0: float,
    y0: np.ndarray,
    t_end: float,
    *,
    taylor: bool = True,
) -> tuple[str, str]:
    """``(method, reason)``: the classification's choice, or ``dop853`` or ``taylor``
    where it is cheaper at the energy target (where H is not conserved: at the same
    error of the state, ``_by_state``).

    Parameters
    ----------
    compiled
        The compiled system; it must have ``rhs`` and ``hamiltonian`` (only ``rhs``
        where H is not conserved), and what ``method`` needs.
    method, reason
        ``choice.choose_method``'s answer.
    t0, y0
        The start, y0 of shape (2n,).
    t_end
        The run's end. An endless run (the window's) keeps ``method``: over unbounded
        time a symplectic method's energy error stays bounded, DOP853's and taylor's do
        not.
    taylor
        Whether ``taylor`` is priced too (False: the choice without it, for comparing;
        where H is not conserved that is the classification's ``dop853``, no pilot run).

    Remembered per compiled system and start, and on disk per scene (the derivation
    cache), so a scene opened again does not run the pilots again.
    """
    c = compiled.mechanics.classification
    conserved = c.conservative and c.hamiltonian_conserved
    by_state = method == ALTERNATIVE and not conserved  # damped, driven, rheonomic
    if by_state and not taylor:
        return method, reason
    if method not in CANDIDATES and not (method == ALTERNATIVE and conserved) and not by_state:
        return method, reason
    wanted = getattr(compiled, "wanted", frozenset())
    if not ({"rhs"} if by_state else {"rhs", "hamiltonian"}) <= set(wanted):
        return method, reason
    horizon = t_end - t0
    if math.isinf(horizon) and method == ALTERNATIVE:
        return method, reason
    if math.isinf(horizon):
        return method, reason + (
            "; kept for an endless run, where its energy error stays bounded and an "
            "adaptive method's grows without end"
        )
    if not horizon > 0.0:
        return method, reason
    y0 = np.asarray(y0, dtype=float)
    parameters = np.asarray(getattr(compiled, "parameters", ()), dtype=float)
    key = (method, t0, y0.tobytes(), parameters.tobytes(), horizon, taylor)
    with _lock:
        try:
            memory = _memory.setdefault(compiled, {})
        except TypeError:
            memory = {}
        if key in memory:
            return memory[key]
    chosen, why = _remembered(
        compiled, key, lambda: _measure(compiled, method, reason, t0, y0, horizon, taylor)
    )
    if chosen.startswith(f"{TAYLOR} tol="):  # taylor at a tolerance of its own
        _remember_tolerance(compiled, t0, y0, horizon, float(chosen.split("=", 1)[1]))
        chosen = TAYLOR
    with _lock:
        memory[key] = (chosen, why)
    return chosen, why


def _remembered(compiled, key, compute) -> tuple[str, str]:
    """``compute()``, through the derivation cache of the scene (keyed by the start,
    the parameters, the horizon and this code)."""
    import hashlib
    import sys

    from systems import derivation_cache
    from systems.integrators import kernels, registry, stepsize
    from systems.taylor import compiled as taylor_compiled

    start = hashlib.sha256(repr(key).encode()).hexdigest()[:16]
    tag = f"measured choice {start} " + derivation_cache.code_hash(
        sys.modules[__name__], stepsize, registry, kernels, taylor_compiled
    )
    scene = compiled.mechanics.scene
    text = derivation_cache.remembered(scene, tag, lambda: "\n".join(compute()))
    chosen, why = text.split("\n", 1)
    return chosen, why


def _measure(compiled, method, reason, t0, y0, horizon, taylor=True) -> tuple[str, str]:
    c = compiled.mechanics.classification
    if method == ALTERNATIVE and not (c.conservative and c.hamiltonian_conserved):
        return _by_state(compiled, method, reason, t0, y0, horizon)
    if method == ALTERNATIVE:  # the classification's own DOP853 (rule 3), priced for taylor
        chosen, why, cost = method, reason, _rate_of(compiled, method, t0, y0, horizon)
    else:
        chosen, why, cost = _fixed_or_dop853(compiled, method, reason, t0, y0, horizon)
    if not taylor:
        return chosen, why
    return _with_taylor(compiled, chosen, why, cost, t0, y0, horizon)


def _rate_of(compiled, method, t0, y0, horizon):
    """A function giving ``method``'s priced evaluations per unit time (None: unknown),
    by a pilot run only when asked."""

    def price() -> float | None:
        own = _pilot(compiled, method, t0, y0, horizon)
        if own is None:
            return None
        return own[0] * PER_EVALUATION.get(get_stepper(method).family.kernel, 1.0)

    return price


def _fixed_or_dop853(compiled, method, reason, t0, y0, horizon):
    """``(method, why, price)``: the classification's fixed-step method or ``dop853``,
    whichever is cheaper and keeps the target; ``price()`` its evaluations per unit
    time."""
    other = _pilot(compiled, ALTERNATIVE, t0, y0, horizon)
    if other is None:
        return method, reason, _rate_of(compiled, method, t0, y0, horizon)
    other_rate, other_error = other
    if other_error > MARGIN * ENERGY_TARGET:
        return (
            method,
            reason
            + (
                f"; measured: DOP853 at tolerance {DEFAULT_TOL:g} would let the energy error "
                f"reach {other_error:.1e} over t = {horizon:g}"
            ),
            _rate_of(compiled, method, t0, y0, horizon),
        )
    stepper = get_stepper(method)
    factor = PER_EVALUATION.get(stepper.family.kernel, 1.0)
    # the fixed step's cost at the longest step the aim may give (a short pilot at the
    # step before aiming): where even that is dearer, no aiming pilots are needed
    if stepper.setting == "dt":
        quick = _pilot(compiled, method, t0, y0, horizon, steps=QUICK_STEPS, aim=False)
        if quick is not None:
            least = quick[0] * factor / AIM_GROWTH[1]
            if other_rate < least:
                chosen, why = _dop853(method, horizon, other_rate, other_error, least, "at best")
                return chosen, why, lambda: other_rate
    own = _pilot(compiled, method, t0, y0, horizon)
    if own is None:
        return method, reason, lambda: None
    own_cost = own[0] * factor
    if other_rate >= own_cost:
        return (
            method,
            reason
            + (
                f"; measured: {own_cost * horizon:.3g} evaluations over t = {horizon:g} "
                f"against DOP853's {other_rate * horizon:.3g}"
            ),
            lambda: own_cost,
        )
    chosen, why = _dop853(method, horizon, other_rate, other_error, own_cost, "at its default step")
    return chosen, why, lambda: other_rate


def _dop853(method, horizon, rate, error, own_cost, how) -> tuple[str, str]:
    return ALTERNATIVE, (
        f"measured on this system over t = {horizon:g}: adaptive 8th-order Runge-Kutta "
        f"(tolerance {DEFAULT_TOL:g}) keeps the relative energy error to {error:.1e} "
        f"with {rate * horizon:.3g} evaluations, where {method} {how} needs "
        f"{own_cost * horizon:.3g}"
    )


def _with_taylor(compiled, chosen, why, price, t0, y0, horizon) -> tuple[str, str]:
    """``taylor`` at the tightest tolerance of ``TAYLOR_TOLERANCES`` whose pilot keeps
    the energy target, or a looser one priced well below it (``LOOSER_GAIN``; the price
    is ``taylor_equivalents`` a step), where it applies and
    that cost is below ``chosen``'s (``price()``, evaluations per unit time); else
    ``(chosen, why)``, with taylor's price added where it was measured. A chosen
    tolerance is remembered for the run (``chosen_tolerance``); the text's first line
    then says it (``"taylor tol=1e-13"``)."""
    from systems.taylor.compiled import decomposition_of

    if get_stepper(TAYLOR).applies_to(compiled.mechanics) is not None:
        return chosen, why
    decomposition = None
    priced = []  # (cost per unit time, tol, order, each, steps per unit time, error)
    worst_error = 0.0
    for tol in TAYLOR_TOLERANCES:
        pilot = _pilot(compiled, TAYLOR, t0, y0, horizon, tol=tol)
        if pilot is None:  # a failed run (a singular state): this tolerance is out
            continue
        steps_rate, error = pilot
        if error > MARGIN * ENERGY_TARGET:
            worst_error = max(worst_error, error)
            continue
        decomposition = decomposition or decomposition_of(compiled.mechanics)
        order = taylor_order(tol)
        each = taylor_equivalents(decomposition, order)
        priced.append((steps_rate * each, tol, order, each, steps_rate, error))
    best = priced[0] if priced else None  # the tightest that keeps the target
    looser = [p for p in priced[1:] if best and p[0] <= LOOSER_GAIN * best[0]]
    if looser:
        best = min(looser, key=lambda p: p[0])
    if best is None and not worst_error:
        return chosen, why  # no pilot ran to its end
    if best is None:
        return chosen, why + (
            f"; taylor would let the energy error reach {worst_error:.1e} over t = {horizon:g}"
        )
    cost, tol, order, each, steps_rate, error = best
    theirs = price()
    if theirs is None or cost >= theirs:
        against = "" if theirs is None else f" against {theirs * horizon:.3g}"
        return chosen, why + (
            f"; taylor (order {order}) priced at {cost * horizon:.3g} evaluations{against}"
        )
    eps = tol == TAYLOR_TOLERANCES[0]
    tolerance = f"tolerance {tol:.1e}" + (", machine epsilon" if eps else "")
    return TAYLOR if eps else f"{TAYLOR} tol={tol!r}", (
        f"measured on this system over t = {horizon:g}: Taylor series of order {order} "
        f"({tolerance}) keep the relative energy error to {error:.1e} in "
        f"{steps_rate * horizon:.3g} steps, priced at {each:.3g} right-hand-side "
        f"evaluations each ({cost * horizon:.3g} in all), where {chosen} needs "
        f"{theirs * horizon:.3g}"
    )


STATE_CHECKPOINTS = 12
"""Where H is not conserved the pilots' states are compared at t0 + horizon 2^-j, j =
11..0: the run's length and shorter stretches down to 1/2048 of it, so that motion that
amplifies small differences (chaos) still leaves stretches where a tight reference can
be trusted (as the work-precision sweep shortens its horizon: ``systems.workprecision``)."""
RATE_CHECKPOINTS = 4
"""The error per unit time is the largest over the last this many checkpoints where the
references agree (the last 1/8 of the stretch and on): at the earlier ones a few units
of round-off, over a short time, would be extrapolated up to 2048 times."""
REFERENCE_SHARE = 0.1
"""A checkpoint counts only where the two tight references agree to this fraction of the
error allowed there (the target's share of the run up to it), and every one before it."""
CHECK_STEP = 0.5
"""The check reference is taylor at machine epsilon with steps of at most this fraction of
the reference's mean step: another path through the same motion."""


def _by_state(compiled, method, reason, t0, y0, horizon) -> tuple[str, str]:
    """``taylor`` or the classification's ``dop853`` where H is not conserved (damping,
    driving, time-dependent constraints): whichever is cheaper among those whose state
    keeps the accuracy target.

    Without an energy to measure accuracy by, the error is that of the state: pilots to
    ``STATE_CHECKPOINTS`` times (``PILOT_STEPS`` steps at most, DOP853's budget setting
    the stretch) are compared with a tight reference, taylor at machine epsilon, which is
    checked against a second run of it with shorter steps (``CHECK_STEP``). The error at
    each checkpoint where the references agree (``REFERENCE_SHARE``), relative to the
    state's size (at least 1), over the time to it, is the error per unit time; its
    largest over the last ``RATE_CHECKPOINTS`` of them, times the horizon, must stay
    within ``MARGIN`` x ``ENERGY_TARGET`` or DOP853's own (taylor is never less accurate
    than the choice it replaces). Machine epsilon's error is the references' gap. Priced
    as ``_with_taylor`` prices: the tightest tolerance that keeps the target, or a looser
    one at most ``LOOSER_GAIN`` of it, each step at ``taylor_equivalents`` evaluations,
    DOP853 at its counted ones.
    """
    from systems.taylor.compiled import decomposition_of

    refusal = get_stepper(TAYLOR).applies_to(compiled.mechanics)
    if refusal is not None:
        return method, f"{reason}; taylor is not priced: {refusal}"
    times = t0 + horizon * 2.0 ** -np.arange(STATE_CHECKPOINTS - 1, -1, -1, dtype=float)
    theirs = _states_at(compiled, method, t0, y0, times, tol=DEFAULT_TOL)
    if theirs is None:
        return method, reason
    eps = TAYLOR_TOLERANCES[0]
    times = times[: len(theirs[0])]
    reference = _states_at(compiled, TAYLOR, t0, y0, times, tol=eps)
    if reference is None:
        return method, reason
    h = CHECK_STEP * reference[3] / max(reference[2], 1)
    check = _states_at(compiled, TAYLOR, t0, y0, times, tol=eps, max_step=h)
    if check is None or len(check[0]) < len(reference[0]):
        return method, reason
    times = times[: len(reference[0])]
    ref = reference[0]
    scale = np.maximum(1.0, np.max(np.abs(ref), axis=1))
    elapsed = times - t0
    target = MARGIN * ENERGY_TARGET

    def errors(states: np.ndarray) -> np.ndarray:
        return np.max(np.abs(states[: len(ref)] - ref), axis=1) / scale

    gap = errors(check[0])
    trusted = int(np.argmin(np.append(gap <= REFERENCE_SHARE * target * elapsed / horizon, False)))
    if trusted == 0:
        return method, reason + (
            f"; taylor is not priced: two tight references differ by {gap[0]:.1e} of the "
            f"state by t = {times[0] - t0:.3g}, more than a tenth of the error the target "
            "allows there, so no error can be measured"
        )

    last = slice(max(0, trusted - RATE_CHECKPOINTS), trusted)

    def over_run(error: np.ndarray) -> float:  # the error per unit time, over the horizon
        return float(np.max(error[last] / elapsed[last]) * horizon)

    their_error = over_run(errors(theirs[0]))
    their_rate = theirs[1] / theirs[3]
    accuracy = max(target, their_error)
    decomposition = decomposition_of(compiled.mechanics)
    priced = []  # (cost per unit time, tol, order, each, steps per unit time, error)
    worst_error = 0.0
    for tol in TAYLOR_TOLERANCES:
        pilot = check if tol == eps else _states_at(compiled, TAYLOR, t0, y0, times, tol=tol)
        if pilot is None or len(pilot[0]) < trusted:
            continue
        run = reference if tol == eps else pilot  # the eps pilot: the reference itself
        error = over_run(gap if tol == eps else errors(pilot[0]))
        if error > accuracy:
            worst_error = max(worst_error, error)
            continue
        order = taylor_order(tol)
        each = taylor_equivalents(decomposition, order)
        steps_rate = run[2] / run[3]
        priced.append((steps_rate * each, tol, order, each, steps_rate, error))
    best = priced[0] if priced else None
    looser = [p for p in priced[1:] if best and p[0] <= LOOSER_GAIN * best[0]]
    if looser:
        best = min(looser, key=lambda p: p[0])
    measured = (
        f"the state's error against a tight reference, relative to its size, per unit "
        f"time up to t = {times[trusted - 1] - t0:.3g}, times {horizon:g}"
    )
    if best is None:
        return method, reason + (
            f"; taylor would let the state's error reach {worst_error:.1e} over t = "
            f"{horizon:g} ({measured}), where {method} keeps it to {their_error:.1e}"
        )
    cost, tol, order, each, steps_rate, error = best
    if cost >= their_rate:
        return method, reason + (
            f"; measured over t = {horizon:g}: taylor (order {order}) priced at "
            f"{cost * horizon:.3g} evaluations against {their_rate * horizon:.3g}"
        )
    tolerance = f"tolerance {tol:.1e}" + (", machine epsilon" if tol == eps else "")
    return TAYLOR if tol == eps else f"{TAYLOR} tol={tol!r}", (
        f"measured on this system over t = {horizon:g}, by {measured} (no energy to "
        f"measure accuracy by): Taylor series of order {order} ({tolerance}) keep it to "
        f"{error:.1e} in {steps_rate * horizon:.3g} steps, priced at {each:.3g} "
        f"right-hand-side evaluations each ({cost * horizon:.3g} in all), where {method} "
        f"(tolerance {DEFAULT_TOL:g}) needs {their_rate * horizon:.3g} for {their_error:.1e}"
    )


def _states_at(
    compiled, method: str, t0: float, y0: np.ndarray, times: np.ndarray, **setting
) -> tuple[np.ndarray, int, int, float] | None:
    """(states at the first k of ``times`` (k, 2n), right-hand-side evaluations, steps,
    time covered) of a run of ``method`` from ``(t0, y0)`` (y0 of shape (2n,)) to
    ``times[-1]`` (ascending, shape (K,)) at ``setting``, ``PILOT_STEPS`` steps at most
    (the states after its budget are not reached); None where the run fails or reaches
    none of them."""
    from systems.simulation import Run, Sampler

    try:
        run = Run(
            compiled, method=method, y0=y0, t0=t0, t_end=float(times[-1]), max_points=2,
            energy_tolerance=None, max_steps=PILOT_STEPS, **setting,
        )  # fmt: skip
    except (ValueError, ArithmeticError):
        return None
    if run.runner is None:
        return None
    sampler = Sampler(run, np.asarray(times, dtype=float))
    t, y = zip(*sampler.chunks(), strict=True)
    t, y = np.concatenate(t[1:] or [np.empty(0)]), np.concatenate(y[1:] or [np.empty((0, len(y0)))])
    last = sampler.last
    if last is None or last.status not in ("ok", "budget"):
        return None
    k = 0
    while k < len(times) and k < len(t) and t[k] == times[k]:
        k += 1
    covered = run.t - t0
    if k == 0 or not covered > 0.0 or not np.all(np.isfinite(y[:k])):
        return None
    return y[:k], last.rhs_evaluations, last.steps, covered


def taylor_order(tol: float) -> int:
    """The order the taylor family takes at ``tol`` (Jorba and Zou's, at least 2)."""
    from systems.taylor.coefficients import jorba_zou

    return max(2, jorba_zou(tol))


def chosen_tolerance(compiled, t0: float, y0: np.ndarray, t_end: float) -> float | None:
    """The tolerance the measured choice gave ``taylor`` for this run (the compiled
    system, its start ``y0`` (2n,) at ``t0`` and ``t_end``), or None where it did not
    choose taylor for it (the family's default applies: machine epsilon)."""
    parameters = np.asarray(getattr(compiled, "parameters", ()), dtype=float)
    key = (float(t0), np.asarray(y0, dtype=float).tobytes(), parameters.tobytes(), t_end - t0)
    with _lock:
        try:
            return _tolerances.get(compiled, {}).get(key)
        except TypeError:
            return None


def _remember_tolerance(compiled, t0, y0, horizon, tol: float) -> None:
    parameters = np.asarray(getattr(compiled, "parameters", ()), dtype=float)
    key = (float(t0), np.asarray(y0, dtype=float).tobytes(), parameters.tobytes(), horizon)
    with _lock:
        try:
            _tolerances.setdefault(compiled, {})[key] = tol
        except TypeError:
            pass


LINEAR_OPS = frozenset({"time", "neg", "add", "sub", "abs", "sign"})
"""Nodes whose coefficient of order k is one operation on the arguments' (no sum)."""
TRANSCENDENTAL_OPS = frozenset(
    "pow sqrt exp log sin cos sinh cosh tan tanh asin acos atan atan2".split()
)
"""Nodes whose value (order 0) is a library call rather than one arithmetic operation."""
TRANSCENDENTAL_WEIGHT = 10.0
"""A library call's value in arithmetic operations (order 0 of a node, in the
right-hand side and in the Taylor step alike)."""
EVALUATION_COST = (17.6, 0.44, 2.3)
"""A DOP853 right-hand-side evaluation: (fixed, per order-0 operation, per state
variable: the stage's combination of earlier stages and the error estimate), fitted by
``benchmarks/taylor_cost.py`` (three runs together) in nanoseconds on the calibration
machine; only the ratio to ``STEP_COST`` matters."""
STEP_COST = (180.0, 1.24, {"unrolled": 0.17, "looped": 0.44})
"""A Taylor step at order p: (fixed: the call, the norms, the step's logarithms and
exponential, Kahan's sums and the driver's bookkeeping; per order-0 operation; per
recurrence term by the coefficient function's form: ``systems.taylor.compiled``'s
unrolled form keeps the coefficients in registers, the looped form loads them in inner
loops), fitted with ``EVALUATION_COST``."""


def _taylor_features(decomposition) -> dict[str, int]:
    """The decomposition's node counts the cost model reads: ``m``, ``nodes`` (varying),
    ``linear``, ``scalings`` (products with a constant), ``convolutions`` (the rest),
    ``calls`` (library functions)."""
    m = decomposition.m
    found = dict(m=m, nodes=0, linear=0, scalings=0, convolutions=0, calls=0)
    for node in decomposition.nodes:
        if node.constant:
            continue
        found["nodes"] += 1
        found["calls"] += node.op in TRANSCENDENTAL_OPS
        if node.op in LINEAR_OPS:
            found["linear"] += 1
        elif node.op == "mul" and any(
            a.kind != "u" or (a.value >= m and decomposition.nodes[a.value - m].constant)
            for a in node.args
        ):
            found["scalings"] += 1
        else:
            found["convolutions"] += 1
    return found


def taylor_equivalents(decomposition, order: int) -> float:
    """What one Taylor step of ``order`` costs, in DOP853 right-hand-side evaluations.

    A deterministic count (never a timing) with weights fitted once to timings: the step
    evaluates every node at order 0 (as the right-hand side does), then for each order
    k = 1..p a convolution node sums about k + 1 products, a linear node or a scaling
    does one operation, and each state variable's series is scaled and summed by
    Horner's rule::

        terms = convolutions p (p + 3) / 2 + (linear + scalings + 2 m) p
        order0 = nodes + TRANSCENDENTAL_WEIGHT * calls
        step = STEP_COST[0] + STEP_COST[1] order0 + STEP_COST[2][form] terms
        evaluation = EVALUATION_COST[0] + EVALUATION_COST[1] order0 + EVALUATION_COST[2] m

    The form is the coefficient function's at this order: unrolled at
    ``systems.taylor.compiled.UNROLLED`` within its budget, else looped.
    Calibrated by ``benchmarks/taylor_cost.py`` (docs/internals.md: three runs on ten
    catalogue scenes; the measured ratio varied by up to 1.5x between runs).
    """
    from systems.taylor.compiled import UNROLL_BUDGET, UNROLLED, unrolled_terms

    f = _taylor_features(decomposition)
    p = int(order)
    unrolled = p == UNROLLED and unrolled_terms(decomposition, p) <= UNROLL_BUDGET
    order0 = f["nodes"] + TRANSCENDENTAL_WEIGHT * f["calls"]
    terms = f["convolutions"] * p * (p + 3) / 2 + (f["linear"] + f["scalings"] + 2 * f["m"]) * p
    fixed, per_value, per_term = STEP_COST
    step = fixed + per_value * order0 + per_term["unrolled" if unrolled else "looped"] * terms
    fixed, per_value, per_state = EVALUATION_COST
    return step / (fixed + per_value * order0 + per_state * f["m"])


QUICK_STEPS = 200
"""Steps of the pilot that prices a fixed step before any aiming."""


def _pilot(
    compiled,
    method,
    t0,
    y0,
    horizon,
    steps: int = PILOT_STEPS,
    aim: bool = True,
    tol: float | None = None,
) -> tuple[float, float] | None:
    """(evaluations per unit time, relative energy error over ``horizon``) of ``method``
    at its default setting or ``tol`` (``aim=False``: a fixed step before
    ``stepsize.aimed_step``),
    from a run of ``steps`` steps at most; None where the method does not apply or the
    pilot fails. DOP853's error is extrapolated linearly from the pilot's stretch to the
    whole horizon; a fixed-step symplectic method's bounded error is taken as measured."""
    from systems.integrators.registry import get_stepper

    stepper = get_stepper(method)
    if stepper.applies_to(compiled.mechanics) is not None:
        return None
    end = t0 + horizon
    setting = {} if tol is None else {"tol": tol}
    try:
        if stepper.setting == "dt":  # a fixed step: the pilot's stretch, not a budget stop
            dt = default_step(compiled, stepper, t0, y0, end, aim=aim)
            end = t0 + min(horizon, steps * dt)
            setting["dt"] = dt
    except (ValueError, ArithmeticError):
        return None
    outcome = pilot_run(compiled, method, t0, y0, end, steps, **setting)
    if outcome is None:
        return None
    error, evaluations, covered = outcome
    if stepper.family.adaptive:
        error *= max(1.0, horizon / covered)
    return evaluations / covered, error
