"""The Reduction tab: Routhian reduction by the cyclic coordinates, V_eff and the reduced
phase portrait."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
import sympy

from systems.display import for_display
from systems.lambdified import Lambdified, lambdify
from systems.report import one_line
from systems.textbook._numeric import NeedsClosedForm
from systems.textbook.jobs._cancel import NEVER, Cancel
from systems.textbook.jobs._run import names_of, parameters_of
from systems.textbook.routhian import Reduction, reduce, turning_points

if TYPE_CHECKING:
    from numpy.typing import ArrayLike

    from systems.compiled import CompiledSystem


@dataclass(frozen=True)
class ReductionSetup:
    """The reduction of the current system, or why there is none.

    Attributes
    ----------
    reduction : Reduction or None
    reason : str
        Why there is no reduction (no cyclic coordinate...), empty otherwise.
    state : ndarray, shape (2n,)
        The initial state.
    p_cyclic : ndarray, shape (c,)
        The conserved momenta of that state.
    cyclic_index, rest_index : tuple[int, ...]
        Indices of the cyclic and remaining coordinates in the scene's order.
    q_range, p_range : (float, float)
        Plot ranges of the first remaining coordinate and its momentum.
    expression : str
        V_eff in textbook notation.
    quadratic : Quadratic or None
        ``(q (K,), p_cyclic (c,)) -> (A, B, C)``, each (K,): H_red = A p² + B p + C in the
        first remaining momentum p (the other remaining coordinates and momenta at the
        state's values), so level sets are solved for p exactly; None if H_red is not
        quadratic in p.

    A setup pickles (the window makes it in a worker process), its numeric functions as
    their source (``systems.lambdified``).
    needs_closed_form : bool
        True when the system has cyclic coordinates but the reduction needs closed forms
        its derivation left to the numerical solver (a system in matrix form): ``reason``
        says so, and no advice about cyclic coordinates applies.
    """

    reduction: Reduction | None
    reason: str
    state: np.ndarray = field(default_factory=lambda: np.empty(0))
    p_cyclic: np.ndarray = field(default_factory=lambda: np.empty(0))
    cyclic_index: tuple[int, ...] = ()
    rest_index: tuple[int, ...] = ()
    q_range: tuple[float, float] = (0.0, 1.0)
    p_range: tuple[float, float] = (-1.0, 1.0)
    expression: str = ""
    quadratic: Quadratic | None = None
    needs_closed_form: bool = False


def reduction_setup(compiled: CompiledSystem, cancel: Cancel = NEVER) -> ReductionSetup:
    """Reduce the current system by its cyclic coordinates (symbolic work: off the GUI)."""

    mechanics = compiled.mechanics
    try:
        reduction = reduce(mechanics)
    except NeedsClosedForm as exc:
        return ReductionSetup(None, str(exc), needs_closed_form=True)
    except ValueError as exc:
        return ReductionSetup(None, str(exc))
    cancel.check()
    names = names_of(compiled)
    state = compiled.initial_state()
    n = compiled.n
    cyclic_index = tuple(names.index(c) for c in reduction.cyclic)
    rest_index = tuple(names.index(r) for r in reduction.rest)
    p_cyclic = np.array([state[n + i] for i in cyclic_index])
    i = rest_index[0]
    q_range = _view_range(mechanics.scene, names[i], state[i])
    p_range = _view_range(mechanics.scene, f"p_{names[i]}", state[n + i])
    try:
        text = one_line(for_display(reduction.effective_potential, mechanics.scene))
    except Exception:  # noqa: BLE001 - only a caption
        text = str(reduction.effective_potential)
    quadratic = _quadratic_in_momentum(compiled, reduction, state, rest_index)
    return ReductionSetup(
        reduction,
        "",
        state,
        p_cyclic,
        cyclic_index,
        rest_index,
        q_range,
        p_range,
        text,
        quadratic,
    )


def reduction_with_curves(
    compiled: CompiledSystem, cancel: Cancel = NEVER
) -> tuple[ReductionSetup, ReductionCurves | None]:
    """``reduction_setup`` and, where there is a reduction, ``reduction_curves`` at the
    state's own conserved momenta: what the Reduction tab shows first, in one job.

    The setup's reduction comes with the numeric V_eff and H_red at the compiled system's
    parameter values made (``Reduction``), so that moving the tab's sliders evaluates
    them without lambdifying anything.
    """
    setup = reduction_setup(compiled, cancel)
    if setup.reduction is None:
        return setup, None
    cancel.check()
    curves = reduction_curves(setup, parameters_of(compiled), setup.p_cyclic)
    return setup, curves


def _quadratic_in_momentum(compiled, reduction, state, rest_index):
    """H_red = A p² + B p + C in the first remaining momentum, as numeric functions."""
    mechanics = compiled.mechanics
    n = compiled.n
    values = {mechanics.params[k]: v for k, v in parameters_of(compiled).items()}
    q_sym, p_sym = reduction.rest_symbols[0], reduction.rest_momenta[0]
    held = {mechanics.t: sympy.S.Zero}
    for j, index in enumerate(rest_index[1:], start=1):
        held[reduction.rest_symbols[j]] = sympy.Float(state[index])
        held[reduction.rest_momenta[j]] = sympy.Float(state[n + index])
    H = sympy.expand(reduction.reduced_hamiltonian.xreplace(values).xreplace(held))
    try:
        poly = sympy.Poly(H, p_sym)
    except sympy.PolynomialError:
        return None
    if poly.degree() != 2:
        return None
    coefficients = [poly.coeff_monomial(p_sym**k) for k in (2, 1, 0)]
    if any(c.has(p_sym) for c in coefficients):
        return None
    args = [q_sym, *reduction.cyclic_momenta]
    return Quadratic(tuple(lambdify(args, c, modules="numpy") for c in coefficients))


class Quadratic:
    """``(q (K,), p_cyclic (c,)) -> (A, B, C)``, each (K,): the coefficients of H_red in
    the first remaining momentum (``ReductionSetup.quadratic``); picklable.

    Parameters
    ----------
    functions : tuple of three Lambdified
        A, B and C as functions of ``(q, *p_cyclic)``.
    """

    __slots__ = ("functions",)

    def __init__(self, functions: tuple[Lambdified, Lambdified, Lambdified]):
        self.functions = functions

    def __call__(self, q: np.ndarray, p_cyclic) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        q = np.asarray(q, dtype=float)
        pc = np.asarray(p_cyclic, dtype=float).ravel()
        with np.errstate(all="ignore"):
            return tuple(
                np.broadcast_to(np.asarray(f(q, *pc), dtype=float), q.shape) for f in self.functions
            )

    def __reduce__(self):
        return (Quadratic, (self.functions,))


def level_curve(
    q: np.ndarray, A: np.ndarray, B: np.ndarray, C: np.ndarray, energy: float
) -> tuple[np.ndarray, np.ndarray]:
    """The level set A p² + B p + C = E over the samples q, as closed loops or arcs.

    Both roots p = (−B ± √D)/(2A), D = B² − 4A(C − E), are joined where D crosses zero
    (the turning points, found by linear interpolation of D), so librations close up.
    Pieces are separated by NaN.
    """
    with np.errstate(all="ignore"):
        D = B * B - 4 * A * (C - energy)
    valid = np.isfinite(D) & np.isfinite(A) & (A != 0)
    inside = valid & (D >= 0)
    xs: list[np.ndarray] = []
    ys: list[np.ndarray] = []
    k, K = 0, len(q)
    while k < K:
        if not inside[k]:
            k += 1
            continue
        start = k
        while k < K and inside[k]:
            k += 1
        stop = k  # inside[start:stop]
        qq = q[start:stop]
        root = np.sqrt(D[start:stop])
        upper = (-B[start:stop] + root) / (2 * A[start:stop])
        lower = (-B[start:stop] - root) / (2 * A[start:stop])
        head_x, head_y, tail_x, tail_y = [], [], [], []
        if start > 0 and valid[start - 1]:  # a turning point between start - 1 and start
            x = _zero_between(q[start - 1], q[start], D[start - 1], D[start])
            head_x, head_y = [x], [float(-B[start] / (2 * A[start]))]
        if stop < K and valid[stop]:
            x = _zero_between(q[stop - 1], q[stop], D[stop - 1], D[stop])
            tail_x, tail_y = [x], [float(-B[stop - 1] / (2 * A[stop - 1]))]
        if head_x and tail_x:  # a closed loop between two turning points
            x = np.concatenate([head_x, qq, tail_x, qq[::-1], head_x])
            y = np.concatenate([head_y, upper, tail_y, lower[::-1], head_y])
        elif head_x:  # open to the right
            x = np.concatenate([qq[::-1], head_x, qq])
            y = np.concatenate([upper[::-1], head_y, lower])
        elif tail_x:  # open to the left
            x = np.concatenate([qq, tail_x, qq[::-1]])
            y = np.concatenate([upper, tail_y, lower[::-1]])
        else:
            x = np.concatenate([qq, [np.nan], qq])
            y = np.concatenate([upper, [np.nan], lower])
        xs += [x, [np.nan]]
        ys += [y, [np.nan]]
    if not xs:
        return np.array([]), np.array([])
    return np.concatenate(xs), np.concatenate(ys)


def _zero_between(x0: float, x1: float, f0: float, f1: float) -> float:
    if f1 == f0:
        return float(x0)
    return float(x0 - f0 * (x1 - x0) / (f1 - f0))


def _view_range(scene, name: str, value: float) -> tuple[float, float]:
    ranges = scene.view.get("ranges", {}) if isinstance(scene.view, dict) else {}
    if name in ranges:
        lo, hi = (float(v) for v in ranges[name])
        if lo < hi:
            return lo, hi
    half = max(1.0, 2.0 * abs(value))
    return value - half, value + half


@dataclass(frozen=True)
class ReductionCurves:
    """V_eff, the energy of the current state, turning points and the reduced portrait.

    Attributes
    ----------
    p_cyclic : ndarray, shape (c,)
    q, v_eff : ndarray, shape (K,)
        V_eff along the first remaining coordinate.
    energy : float
        H of the state with these conserved momenta.
    turning : ndarray
        Where V_eff = energy.
    minimum : float or None
        The sample where V_eff is least (inside the range).
    levels : ndarray
        Energies of the portrait's other level sets.
    lines : list of (x, y)
        The level sets of H_red at ``levels`` in (q, p).
    orbit : (x, y)
        The level set through the state.
    q0, p0 : float
        The state.
    """

    p_cyclic: np.ndarray
    q: np.ndarray
    v_eff: np.ndarray
    energy: float
    turning: np.ndarray
    minimum: float | None
    levels: np.ndarray
    lines: list
    orbit: tuple
    q0: float
    p0: float


def reduction_curves(
    setup: ReductionSetup, parameters: Mapping[str, float], p_cyclic: ArrayLike, size: int = 1200
) -> ReductionCurves:
    """Everything the Reduction tab draws for one value of the conserved momenta (fast)."""

    reduction = setup.reduction
    n = len(setup.state) // 2
    p_cyclic = np.asarray(p_cyclic, dtype=float).ravel()
    q_lo, q_hi = setup.q_range
    if q_lo <= 0.0 <= q_hi and q_hi > 0:
        q_lo = max(q_lo, 1e-3 * (q_hi - q_lo))  # a radius: V_eff blows up at 0
    q = np.linspace(q_lo, q_hi, size)
    q_state = setup.state[list(setup.rest_index)]
    p_state = setup.state[[n + j for j in setup.rest_index]]
    rest_values = np.repeat(q_state[None, :], len(q), axis=0)
    rest_values[:, 0] = q
    V = reduction.effective_potential_function(parameters)
    H = reduction.reduced_hamiltonian_function(parameters)
    with np.errstate(all="ignore"):
        v_eff = np.asarray(V(rest_values, p_cyclic), dtype=float)
        energy = float(H(q_state[None, :], p_state[None, :], p_cyclic)[0])
    turning = np.empty(0)
    if len(setup.rest_index) == 1:
        try:
            with np.errstate(all="ignore"):
                turning = turning_points(
                    reduction, energy, p_cyclic, q_lo, q_hi, parameters=parameters, samples=801
                )
        except (ValueError, RuntimeError):
            turning = np.empty(0)
    finite = np.isfinite(v_eff)
    minimum = None
    if finite.any():
        k = int(np.argmin(np.where(finite, v_eff, np.inf)))
        if 0 < k < len(q) - 1:
            minimum = float(q[k])
    levels = _portrait_levels(v_eff[finite], energy)
    lines: list = []
    orbit: tuple = (np.array([]), np.array([]))
    if setup.quadratic is not None:
        A, B, C = setup.quadratic(q, p_cyclic)
        lines = [level_curve(q, A, B, C, float(level)) for level in levels]
        orbit = level_curve(q, A, B, C, energy)
    return ReductionCurves(
        p_cyclic,
        q,
        v_eff,
        energy,
        np.asarray(turning),
        minimum,
        levels,
        lines,
        orbit,
        float(q_state[0]),
        float(p_state[0]),
    )


def _portrait_levels(v_eff: np.ndarray, energy: float, count: int = 11) -> np.ndarray:
    """Energies from just above the bottom of V_eff to well past the state's energy."""
    if not v_eff.size:
        return np.empty(0)
    bottom = float(np.min(v_eff))
    span = energy - bottom
    if not span > 0:
        span = max(float(np.quantile(v_eff, 0.5)) - bottom, 1e-6)
    return bottom + span * np.linspace(0.0, 2.5, count + 1)[1:]
