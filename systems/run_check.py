"""A finished run checked by a second, finer run where the energy cannot check it.

Where H is conserved a run watches its energy. Where it is not (damping, driving, an
explicitly time-dependent H), nothing in the run itself tells a good answer from a wrong
one: Euler on a damped oscillator ends 1e-2 from the exact state and an implicit method
1e-4, while the run reaches its end as if all were well. ``check_final_state`` runs the
same method again with half the step (a fixed-step method: Richardson's estimate of the
first run's error, ``gap * 2**p / (2**p - 1)``) or a tolerance a hundred times smaller
(an adaptive one: the gap itself), and compares the final states. Where the estimate
exceeds ``ACCURACY`` of the state's size, the run is ``"inaccurate"`` and says why: the
step is too long for the method, or the motion amplifies small differences (chaos), so
that no affordable setting gives its final state.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

ACCURACY = 1e-6
"""The largest estimated error of a final state, relative to the state's size (at least
1), that a checked run may have and still end ok: far looser than the 1e-10 the default
settings aim at, so that only answers wrong in their leading digits are flagged."""
FINER_TOLERANCE = 1e-2
"""An adaptive run's check runs at this times its tolerance (at least ``MIN_TOLERANCE``)."""
MIN_TOLERANCE = 1e-15


@dataclass(frozen=True)
class Check:
    """What a second run says of a first one's final state.

    Attributes
    ----------
    against : str
        The second run, in words ("euler at dt = 0.0005").
    error : float or None
        The estimated error of the first run's final state (largest over q and p); None
        where the second run did not reach the end (``message`` says why).
    scale : float
        The state's size the error is measured against (at least 1).
    accurate : bool
        ``error <= ACCURACY * scale``.
    message : str
        Why the final state is not reliable, and what to change; empty when it is.
    """

    against: str
    error: float | None
    scale: float
    accurate: bool
    message: str

    def as_dict(self) -> dict:
        return {
            "checked_against": self.against,
            "final_state_error": self.error,
            "relative_to": self.scale,
            "accurate": self.accurate,
        }


def check_final_state(
    compiled,
    method: str,
    setting: str,
    value: float,
    t0: float,
    y0: np.ndarray,
    t_end: float,
    y_end: np.ndarray,
    *,
    max_steps: int | None = None,
) -> Check:
    """Run ``method`` again from ``(t0, y0)`` to ``t_end`` with a finer ``setting``
    (``"dt"``, ``"ds"`` or ``"tol"``; ``value`` the first run's) and judge the first run's
    final state ``y_end`` (shape (2n,)) by it."""
    from systems.integrators import get_stepper
    from systems.simulation import Run

    stepper = get_stepper(method)
    adaptive = setting == "tol"
    finer = max(value * FINER_TOLERANCE, MIN_TOLERANCE) if adaptive else value / 2
    word = {"dt": "step", "ds": "step", "tol": "tolerance"}[setting]
    against = f"{method} at {setting} = {finer:.3g}"
    scale = max(1.0, float(np.max(np.abs(y0))), float(np.max(np.abs(y_end))))
    options = {"tol" if adaptive else "dt": finer}
    run = Run(
        compiled, method=method, y0=y0, t0=t0, t_end=t_end, energy_tolerance=None,
        max_steps=None if max_steps is None else 2 * max_steps, **options,
    )  # fmt: skip
    last = run.advance(math.inf)
    while not run.finished:
        last = run.advance(math.inf)
    if last.status != "ok":
        return Check(
            against, None, scale, False,
            f"the check ({against}) did not reach the end ({last.status}: {last.message}), "
            "so the final state is unchecked",
        )  # fmt: skip
    gap = float(np.max(np.abs(np.asarray(y_end, dtype=float) - last.y[-1])))
    if adaptive:
        error = gap
    else:
        p = stepper.order
        error = gap * 2**p / (2**p - 1)
    if error <= ACCURACY * scale:
        return Check(against, error, scale, True, "")
    if adaptive or error > 0.1 * scale:
        why = (
            f"the final state is not reliable: a run at a finer {word} ({against}) ends "
            f"{gap:.2g} away from it. The {word} is too coarse for {method}, or the motion "
            "amplifies small differences (chaos) so that no affordable setting fixes its "
            f"state this far ahead; shorten the run or take a finer {word} "
            f"(--{'tol' if adaptive else setting})"
        )
    else:
        why = (
            f"the final state is off by about {error:.2g} (estimated from a run at half the "
            f"{word}, {against}): {method} is too inaccurate at {setting} = {value:.3g} for "
            f"this motion; take a smaller {word} (--{setting}) or an adaptive method (dop853)"
        )
    return Check(against, error, scale, False, why)
