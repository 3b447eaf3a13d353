# ruff: noqa: F821
"""The compiled loops of chaos maps and orbit diagrams: many orbits at once, rows spread
over cores. ``DRIVER_megno_parallel``: each orbit with one tangent vector and MEGNO's
running sums kept inside the loop (``systems.chaos.maps``); ``DRIVER_strobe_parallel``:
each orbit with parameters of its own, its state kept once per period of the drive
(``systems.chaos.bifurcation``).

Templates like ``systems.integrators.kernels``' drivers: each is
instantiated once per fixed-step family of the registry (``DRIVER_`` -> ``X_``, ``STEP``
-> ``X_step``, ``WORK`` -> ``X_work``; every function below the marker is a template,
named ``DRIVER_*``) and appended to the drivers' templates in a module
of its own (``systems.codegen.build_module``), so the family's step is the one the
drivers use, unchanged, and numba compiles the loop once per installation (per version
of the templates) and caches it. Everything after the marker line goes into the module.

Per row the extended state is ``(q, dq, p, dp)``, shape (4n,) (``variational.extended``
with one vector). With f(s) = ln |delta(s)| - ln |delta(0)| and s the time since the
start, every step adds, by the trapezoid rule over the fixed step h,

    A += h (f_prev + f) / 2,     Y = 2 f - 2 A / s,     B += h (Y_prev + Y) / 2,

so that at the end <Y> = B / t (MEGNO's mean, Cincotta & Simó's normalisation) and the
maximal exponent's estimate is f / t. The vector is rescaled to unit length (its Kahan
terms zeroed) whenever its length leaves [1e-100, 1e100]; the logarithms are summed.
"""

import functools
import math
import sys

import numpy as np
from numba import prange


@functools.cache
def _loop_source() -> str:
    """The templates below the marker instantiated for each fixed-step family with an
    ensemble loop."""
    import inspect
    import re

    from systems.codegen import TEMPLATE_MARKER
    from systems.integrators.registry import FAMILIES

    _, _, body = inspect.getsource(sys.modules[__name__]).partition(TEMPLATE_MARKER)
    parts = []
    for family in FAMILIES.values():
        if family.ensemble and family.kernel:
            kernel = family.kernel
            instance = body.replace("DRIVER_", f"{kernel}_")
            instance = re.sub(r"\bSTEP\(", f"{kernel}_step(", instance)
            parts.append(re.sub(r"\bWORK\(", f"{kernel}_work(", instance))
    return "\n\n".join(parts)


@functools.cache
def loop_module():
    """The module of the loops (``_loop_source``) after the drivers' templates (each loop
    compiled on first use, or by ``python main.py warm``, then loaded from numba's
    cache)."""
    from systems.codegen import build_module

    return build_module(_loop_source(), with_templates=True)


def loop_module_name() -> str:
    """The name of ``loop_module``'s file in the cache, without building the module."""
    from systems.codegen import module_name

    return module_name(_loop_source(), with_templates=True)


# --- kernels ---


def DRIVER_fixed_step(fns, y, comp, clock, P, coef, work):
    """One step of the family (tried again while it says rejected): ``STATUS_RUNNING``,
    ``STATUS_NON_FINITE`` for a state that is not finite, or the step's own problem."""
    while True:
        code, used = STEP(fns, y, comp, clock, P, coef, work)
        if code != STATUS_REJECTED:
            break
    if code == STATUS_RUNNING and not _finite(y):
        return STATUS_NON_FINITE
    return code


def DRIVER_tangent_length(y, n):
    """|delta| of the one tangent vector of the extended state ``y`` = (q, dq, p, dp)."""
    norm = 0.0
    for i in range(n):
        norm += y[n + i] * y[n + i] + y[3 * n + i] * y[3 * n + i]
    return math.sqrt(norm)


def DRIVER_megno_parallel(fns, Y, clock0, P, coef, limits, out, status):
    """Rows of extended states ``Y`` (N, 4n) advanced ``limits[0]`` fixed steps in place,
    rows spread over cores; ``out`` (N, 3) gets <Y>, f(t)/t and Y(t) per row, ``status``
    (N,) ``STATUS_RUNNING`` or what stopped the row (its numbers then are up to there)."""
    nsteps = limits[0]
    N = Y.shape[0]
    m = Y.shape[1]
    n = m // 4
    h = clock0[CLOCK_H]
    for r in prange(N):
        y = Y[r]
        comp = np.zeros(m)
        clock = clock0.copy()
        work = WORK(coef, m)
        status[r] = STATUS_RUNNING
        logs = -math.log(DRIVER_tangent_length(y, n))  # f(0) = 0
        f_prev = 0.0
        y_prev = 0.0
        a = 0.0
        b = 0.0
        f = 0.0
        megno_now = 0.0
        steps = 0
        while steps < nsteps:
            code = DRIVER_fixed_step(fns, y, comp, clock, P, coef, work)
            if code != STATUS_RUNNING:
                status[r] = code
                break
            steps += 1
            length = DRIVER_tangent_length(y, n)
            f = logs + math.log(length)
            if length > 1e100 or length < 1e-100:
                for i in range(n):
                    y[n + i] /= length
                    y[3 * n + i] /= length
                    comp[n + i] = 0.0
                    comp[3 * n + i] = 0.0
                logs += math.log(length)
                work[-1][0] = 0.0  # the family's carried-over values are stale
            s = steps * h
            a += 0.5 * h * (f_prev + f)
            megno_now = 2.0 * f - 2.0 * a / s
            b += 0.5 * h * (y_prev + megno_now)
            f_prev = f
            y_prev = megno_now
        s = steps * h
        if s > 0.0:
            out[r, 0] = b / s
            out[r, 1] = f / s
        else:
            out[r, 0] = math.nan
            out[r, 1] = math.nan
        out[r, 2] = megno_now


def DRIVER_strobe_parallel(fns, Y, clock0, H, P, coef, limits, out, status):
    """Rows of states ``Y`` (N, m), row r with its own step ``H[r]`` and parameters
    ``P[r]`` (N, k), advanced in place from the clock ``clock0``; with ``limits =
    (transient, per_period, samples)`` the state after ``(transient + 1 + j) *
    per_period`` steps (whole periods of
    the drive when ``H[r]`` is the period over ``per_period``) goes to ``out[r, j]``
    (N, samples, m), j < samples; ``status`` (N,) as ``DRIVER_megno_parallel``'s."""
    transient, per_period, samples = limits
    N = Y.shape[0]
    m = Y.shape[1]
    for r in prange(N):
        y = Y[r]
        comp = np.zeros(m)
        clock = clock0.copy()
        clock[CLOCK_H] = H[r]
        params = P[r]
        work = WORK(coef, m)
        status[r] = STATUS_RUNNING
        steps = 0
        total = (transient + samples) * per_period
        while steps < total:
            code = DRIVER_fixed_step(fns, y, comp, clock, params, coef, work)
            if code != STATUS_RUNNING:
                status[r] = code
                break
            steps += 1
            if steps % per_period == 0 and steps >= (transient + 1) * per_period:
                j = steps // per_period - transient - 1
                for k in range(m):
                    out[r, j, k] = y[k]
