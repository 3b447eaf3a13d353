"""Named codes shared by the compiled kernels and Python: statuses and array slots.

The kernels are numba templates (``systems.integrators.kernels``) that see these names as
module constants: ``systems.codegen`` writes one line ``STATUS_NON_FINITE = 1`` (and
likewise ``CLOCK_*``, ``INFO_*``) per member into each generated module, so this file is
the only place the numbers are written down.
"""

from __future__ import annotations

from enum import IntEnum


class Status(IntEnum):
    """What a step or a driver call ended with."""

    RUNNING = 0
    """Fine: the call used its step budget or reached its pause time."""
    NON_FINITE = 1
    """The state became NaN or infinite; it was rolled back to the last finite one."""
    NOT_CONVERGED = 2
    """An implicit solve did not converge."""
    BAD_TRANSFORM = 3
    """A time transformation broke down (log-H needs V < 0 and T - E > 0)."""
    STEP_COLLAPSED = 4
    """An adaptive step size fell to round-off level."""
    END = 5
    """The end time was reached."""
    OVERSHOT = 6
    """The next step would pass the end time: rolled back, the caller lands on it."""
    REJECTED = 7
    """An adaptive step was rejected and will be retried smaller (never leaves a driver)."""


class Clock(IntEnum):
    """Slots of the ``clock`` array (float64) a run carries between driver calls."""

    T = 0
    """The current time."""
    H = 1
    """The step: dt, a fictitious-time ds, or an adaptive method's next trial step."""
    T0 = 2
    """Fixed steps: the time at step count 0 (t = T0 + K H, no accumulated round-off)."""
    K = 3
    """Fixed steps: the number of steps since T0."""
    TC = 4
    """Kahan compensation of T for methods that accumulate it."""
    T_END = 5
    """Never passed: a step beyond it is rolled back (``Status.OVERSHOT``)."""
    T_PAUSE = 6
    """The driver returns after the first step that reaches it (the solution is unchanged)."""


CLOCK_SIZE = len(Clock)


class Info(IntEnum):
    """Slots of the ``info`` array (int64) a driver call returns its counts in."""

    STEPS = 0
    OUTPUTS = 1
    STATUS = 2
    EVENTS = 3
    EVALUATIONS = 4
    SAMPLED = 5


INFO_SIZE = len(Info)


def constants_source() -> str:
    """Module-level constant lines for the generated kernel module."""
    lines = []
    for enum in (Status, Clock, Info):
        prefix = enum.__name__.upper()
        lines += [f"{prefix}_{member.name} = {int(member)}" for member in enum]
    return "\n".join(lines) + "\n"
