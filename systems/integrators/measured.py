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
"""

from __future__ import annotations

import math
import threading
import weakref

import numpy as np

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

PILOT_STEPS = 4000
"""Steps of each pilot run at most: a few ms to a few tens of ms with compiled kernels."""

PER_EVALUATION = {"gauss": 2.0}
"""Work per evaluation relative to an explicit Runge-Kutta stage, by kernel family: a
collocation iteration sums s x s stage products besides each evaluation (1.0 where not
listed)."""

MARGIN = 0.5
"""DOP853 qualifies when its extrapolated error is within this fraction of the target."""

_memory: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()
_lock = threading.Lock()


def measured_choice(
    compiled, method: str, reason: str, t0: float, y0: np.ndarray, t_end: float
) -> tuple[str, str]:
    """``(method, reason)``: the classification's choice, or ``dop853`` where it is cheaper.

    Parameters
    ----------
    compiled
        The compiled system; it must have ``rhs`` and ``hamiltonian`` (and what
        ``method`` needs).
    method, reason
        ``choice.choose_method``'s answer.
    t0, y0
        The start, y0 of shape (2n,).
    t_end
        The run's end. An endless run (the window's) keeps ``method``: over unbounded
        time a symplectic method's energy error stays bounded, DOP853's does not.

    Remembered per compiled system and start, and on disk per scene (the derivation
    cache), so a scene opened again does not run the pilots again.
    """
    if method not in CANDIDATES:
        return method, reason
    wanted = getattr(compiled, "wanted", frozenset())
    if not {"rhs", "hamiltonian"} <= set(wanted):
        return method, reason
    horizon = t_end - t0
    if math.isinf(horizon):
        return method, reason + (
            "; kept for an endless run, where its energy error stays bounded and an "
            "adaptive method's grows without end"
        )
    if not horizon > 0.0:
        return method, reason
    y0 = np.asarray(y0, dtype=float)
    parameters = np.asarray(getattr(compiled, "parameters", ()), dtype=float)
    key = (method, t0, y0.tobytes(), parameters.tobytes(), horizon)
    with _lock:
        try:
            memory = _memory.setdefault(compiled, {})
        except TypeError:
            memory = {}
        if key in memory:
            return memory[key]
    answer = _remembered(compiled, key, lambda: _measure(compiled, method, reason, t0, y0, horizon))
    with _lock:
        memory[key] = answer
    return answer


def _remembered(compiled, key, compute) -> tuple[str, str]:
    """``compute()``, through the derivation cache of the scene (keyed by the start,
    the parameters, the horizon and this code)."""
    import hashlib
    import sys

    from systems import derivation_cache
    from systems.integrators import kernels, registry, stepsize

    start = hashlib.sha256(repr(key).encode()).hexdigest()[:16]
    tag = f"measured choice {start} " + derivation_cache.code_hash(
        sys.modules[__name__], stepsize, registry, kernels
    )
    scene = compiled.mechanics.scene
    text = derivation_cache.remembered(scene, tag, lambda: "\n".join(compute()))
    chosen, why = text.split("\n", 1)
    return chosen, why


def _measure(compiled, method, reason, t0, y0, horizon) -> tuple[str, str]:
    from systems.integrators.registry import get_stepper

    other = _pilot(compiled, ALTERNATIVE, t0, y0, horizon)
    if other is None:
        return method, reason
    other_rate, other_error = other
    if other_error > MARGIN * ENERGY_TARGET:
        return method, reason + (
            f"; measured: DOP853 at tolerance {DEFAULT_TOL:g} would let the energy error "
            f"reach {other_error:.1e} over t = {horizon:g}"
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
                return _dop853(method, horizon, other_rate, other_error, least, "at best")
    own = _pilot(compiled, method, t0, y0, horizon)
    if own is None:
        return method, reason
    own_cost = own[0] * factor
    if other_rate >= own_cost:
        return method, reason + (
            f"; measured: {own_cost * horizon:.3g} evaluations over t = {horizon:g} against "
            f"DOP853's {other_rate * horizon:.3g}"
        )
    return _dop853(method, horizon, other_rate, other_error, own_cost, "at its default step")


def _dop853(method, horizon, rate, error, own_cost, how) -> tuple[str, str]:
    return ALTERNATIVE, (
        f"measured on this system over t = {horizon:g}: adaptive 8th-order Runge-Kutta "
        f"(tolerance {DEFAULT_TOL:g}) keeps the relative energy error to {error:.1e} "
        f"with {rate * horizon:.3g} evaluations, where {method} {how} needs "
        f"{own_cost * horizon:.3g}"
    )


QUICK_STEPS = 200
"""Steps of the pilot that prices a fixed step before any aiming."""


def _pilot(
    compiled, method, t0, y0, horizon, steps: int = PILOT_STEPS, aim: bool = True
) -> tuple[float, float] | None:
    """(evaluations per unit time, relative energy error over ``horizon``) of ``method``
    at its default setting (``aim=False``: a fixed step before ``stepsize.aimed_step``),
    from a run of ``steps`` steps at most; None where the method does not apply or the
    pilot fails. DOP853's error is extrapolated linearly from the pilot's stretch to the
    whole horizon; a fixed-step symplectic method's bounded error is taken as measured."""
    from systems.integrators.registry import get_stepper

    stepper = get_stepper(method)
    if stepper.applies_to(compiled.mechanics) is not None:
        return None
    end = t0 + horizon
    setting = {}
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
