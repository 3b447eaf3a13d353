"""Chaos maps with the taylor family: MEGNO on the variational system, in SIMD batches.

The extended system (``megno_decomposition``, decomposed by ``systems.taylor.decompose``
beside Hamilton's equations, written by ``systems.taylor.compiled``'s batch writer):

    y' = f(y, t),    delta' = J(y, t) delta,    W' = (t - t0) s (delta . delta') / |delta|^2

with J = df/dy from the symbolic Jacobian (``calculus.Calculus.gradient``, as
``variational`` forms it), state ``(q, p, dq, dp, W)`` of size 4n + 1, and two
parameters after the scene's: ``s`` = 1 / (t_end - t0) and ``t0``. W is MEGNO's
integral as an extra state variable (heyoka's way: the indicator is part of the Taylor
system, so its series and the step control include it): MEGNO's Y(t) = 2 W / (s (t -
t0)), and its mean <Y> = (1 / (t - t0)) int Y dt is summed step by step on W's series
(``kernels.taylor_batch_megno_parallel``: Gauss-Legendre over each step; a state
variable ``int Y dt`` would need ``1 / (t - t0)`` in the series, infinite at the start).
The scale ``s`` keeps W of order one (W grows like lambda t^2 / 2 on a chaotic orbit),
so it does not loosen the step control of the orbit's own variables, which are measured
against max(1, |y|).

Each orbit takes its own adaptive steps (Jorba–Zou's order and step at the tolerance,
machine epsilon by default) in batches of SIMD lanes over all cores; a row's numbers
depend on its start only (not on the chunk, the batch or the threads).
"""

from __future__ import annotations

import functools
import math

import numpy as np
import sympy

from systems.chaos.variational import NotApplicable

SCALE = "megno_scale"
START = "megno_t0"


def megno_decomposition(mechanics):
    """The Taylor decomposition of the extended system (see the module) of
    ``mechanics``: variables ``(q, p, dq, dp, W)``, parameters the scene's then
    ``megno_scale`` and ``megno_t0``, time ``mechanics.t``.

    Raises
    ------
    NotApplicable
        Where Hamilton's equations do not decompose (``decompose.refusal`` or the
        decomposition's reason).
    """
    from systems import calculus
    from systems.expressions import as_expr
    from systems.taylor.decompose import NotDecomposable, decompose, refusal

    reason = refusal(mechanics)
    if reason:
        raise NotApplicable(f"taylor needs Hamilton's equations as elementary operations: {reason}")
    scene = mechanics.scene
    n = mechanics.n
    state = (*mechanics.q, *mechanics.p)
    f = [as_expr(e) for e in mechanics.hamilton_equations]
    delta = sympy.symbols(f"megno_d0:{2 * n}", real=True)
    w = sympy.Symbol("megno_w", real=True)
    scale, start = sympy.Symbol(SCALE, real=True), sympy.Symbol(START, real=True)
    calc = calculus.Calculus(scene.symbols.values())
    tangent = []
    for row in f:
        gradient = calc.gradient(row, state)
        tangent.append(sympy.Add(*(g * d for g, d in zip(gradient, delta, strict=True) if g != 0)))
    dot = sympy.Add(*(d * e for d, e in zip(delta, tangent, strict=True)))
    norm = sympy.Add(*(d * d for d in delta))
    megno = (mechanics.t - start) * scale * dot / norm
    parameters = [mechanics.params[name] for name, _ in scene.parameters]
    try:
        return decompose(
            [*f, *tangent, megno], (*state, *delta, w), [*parameters, scale, start], mechanics.t
        )
    except NotDecomposable as exc:
        reason = f"taylor needs Hamilton's equations as elementary operations: {exc}"
        raise NotApplicable(reason) from exc


UNROLL_BUDGET = 8000
"""The extended system is written unrolled at order 20 up to this many products
(``compiled.unrolled_terms``), beyond the scene's own budget (3000): Hénon–Heiles'
extended system has 3670, and looped its batch step cost 1.5 us a lane against 0.09 for
the orbit alone."""


def write_megno_batch_ir(decomposition, B: int) -> str:
    """``compiled.write_taylor_batch_ir`` with this module's ``UNROLL_BUDGET``."""
    from systems.taylor import compiled

    return compiled.write_taylor_batch_ir(decomposition, B, UNROLL_BUDGET)


@functools.cache
def _compiled_batch(text: str):
    from systems.taylor.compiled import BATCH_NAME, _kernels

    kernels = _kernels(text, BATCH_NAME)
    return kernels, kernels.functions[BATCH_NAME]


class TaylorMegno:
    """The batch coefficient function of a system's extended MEGNO system, compiled.

    Attributes
    ----------
    function
        ``taylor_batch`` of the extended system (the value the loop takes).
    lanes : int
    width : int
        Columns of its ``out`` (4n + 1 variables and the nodes).
    """

    def __init__(self, mechanics):
        from systems.taylor.compiled import lanes

        self.mechanics = mechanics
        self.lanes = lanes()
        text = write_megno_batch_ir(megno_decomposition(mechanics), self.lanes)
        self.width = int(text.split("width=", 1)[1].split()[0])
        self.m = 4 * mechanics.n + 1
        self._kernels, self.function = _compiled_batch(text)


def megno_coef(width: int, tol: float) -> tuple:
    """The loop's ``coef``, as ``runners.TaylorRunner`` makes it: (width, Kahan, order,
    longest step, heyoka's factor)."""
    from systems.taylor.coefficients import jorba_zou

    order = max(2, jorba_zou(tol))
    factor = math.exp(-0.7 / (order - 1)) / math.e**2
    return (int(width), True, int(order), math.inf, float(factor))


def taylor_megno_rows(
    megno: TaylorMegno,
    parameters: np.ndarray,
    starts: np.ndarray,
    vector: np.ndarray,
    t0: float,
    t_end: float,
    tol: float,
    *,
    final: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """The indicators of the orbits from ``starts`` (N, 2n), each with the tangent
    vector ``vector`` (2n,), from ``t0`` to ``t_end``: ``(values (N, 3), status (N,))``
    as ``maps.map_chunk`` returns them (<Y>, the exponent's estimate, Y(t); status 0
    for a row that reached the end)."""
    from systems.codegen import driver_module
    from systems.integrators.codes import CLOCK_SIZE, Clock, Status

    starts = np.asarray(starts, dtype=float)
    N, m2 = starts.shape
    Y = np.zeros((N, 2 * m2 + 1))
    Y[:, :m2] = starts
    Y[:, m2 : 2 * m2] = vector
    clock = np.zeros(CLOCK_SIZE)
    clock[Clock.T] = clock[Clock.T0] = t0
    clock[Clock.T_END] = t_end
    clock[Clock.T_PAUSE] = math.inf
    P = np.concatenate([np.asarray(parameters, dtype=float), [1.0 / (t_end - t0), t0]])
    values = np.full((N, 3), np.nan)
    status = np.zeros(N, dtype=np.int64)
    steps = np.zeros(N, dtype=np.int64)
    if N:
        coef = megno_coef(megno.width, tol)
        loop = driver_module().taylor_batch_megno_parallel
        loop(megno.function, Y, clock, P, coef, megno.lanes, values, status, steps)
    status[status == int(Status.END)] = int(Status.RUNNING)
    if final is not None:
        final[:] = Y[:, :m2]
    return values, status


def refusal(mechanics) -> str | None:
    """Why a taylor map cannot run ``mechanics`` (None if it can)."""
    from systems.integrators.registry import STEPPERS

    return STEPPERS["taylor"].applies_to(mechanics)
