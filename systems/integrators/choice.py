"""The automatic choice of a stepper from a system's classification.

Rules, first match wins:

0. holonomic constraints (``[constraints]``) -> ``constrained_dop853``, the only adaptive
   method that projects onto them;
1. stiff (see ``stiffness_ratio``): with decaying fast modes -> ``radau``; with purely
   oscillatory fast modes in a conservative system (a stiff spring) ->
   ``gauss_legendre6`` with a step that resolves the fastest mode, since an L-stable
   method must resolve an excited oscillation too, at far higher cost per step;
2. not conservative (dissipation, driving forces, explicitly time-dependent potential)
   or H not conserved -> ``dop853``;
3. autonomous with a singular attractive potential (a coordinate expression in a
   denominator of V, e.g. -k/r, and V < 0 at the initial state): separable ->
   ``logh_yoshida6``; not separable (Kepler in polar coordinates) -> ``dop853``, whose
   adaptive steps follow close approaches that a fixed step cannot;
4. separable -> ``yoshida8``;
5. otherwise (conservative, H = H(q, p) not separable) -> ``gauss_legendre6``.

Conservative choices are high order because the default step (``stepsize``) aims at a
relative energy error of ``stepsize.ENERGY_TARGET`` (1e-10) over a scene's run, which
low orders reach only at many times the cost.

Rules 3 to 5 are then measured on the compiled system against ``dop853``, and the
winner against ``taylor``, and rule 2's ``dop853`` against ``taylor`` by the error of
the state (``systems.integrators.measured``), where a system is built for the window or
``run``: a finite run only (the window's endless one keeps the rule's method).
"""

from __future__ import annotations

import math
import weakref

import numpy as np
import sympy

from systems import matrix_solve
from systems.expressions import as_expr
from systems.integrators.stepsize import DEFAULT_TOL, ENERGY_TARGET, jacobian

STIFF_RATIO = 100.0
"""Stiff when the fastest rate of the linearisation exceeds the slowest by this factor."""


def initial_point(mechanics) -> tuple[dict, np.ndarray]:
    """Parameter values (symbol -> float) and the scene's initial (q, p), shape (2n,)."""
    scene = mechanics.scene
    params = {mechanics.params[name]: float(value) for name, value in scene.parameters}
    values = scene.initial_values
    q = [values.get(name, 0.0) for name in scene.coordinates]
    qdot = [values.get(name, 0.0) for name in scene.velocity_names]
    p = []
    subs = {**params, mechanics.t: 0.0}
    subs |= dict(zip(mechanics.q, q, strict=True)) | dict(zip(mechanics.qdot, qdot, strict=True))
    for i, name in enumerate(scene.momentum_names):
        if name in values:
            p.append(values[name])
        elif mechanics.momenta is not None:
            p.append(_number(mechanics.momenta[i], subs))
        else:
            p.append(0.0)
    return params, np.array(q + p, dtype=float)


def _number(expr, subs: dict) -> float:
    expr = as_expr(expr)
    if isinstance(expr, sympy.Basic):
        expr = expr.xreplace(subs)
    return float(expr)


def _eigenvalues(mechanics) -> np.ndarray:
    """Eigenvalues of the Jacobian of Hamilton's equations at the start (complex).

    For a system in matrix form the velocities in Hamilton's equations are solved from
    ``M(q, t) qdot = p - a(q, t)`` at every state (``matrix_solve.state_function``).
    """
    try:
        return _EIGENVALUES[mechanics]
    except (KeyError, TypeError):
        pass
    params, y0 = initial_point(mechanics)
    f = matrix_solve.state_function(mechanics, mechanics.hamilton_equations, params)
    J = jacobian(lambda y: f(0.0, y), y0)
    eigenvalues = np.array([]) if J is None else np.linalg.eigvals(J)
    try:
        _EIGENVALUES[mechanics] = eigenvalues
    except TypeError:  # not weak-referenceable
        pass
    return eigenvalues


_EIGENVALUES: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()
"""``_eigenvalues`` per Mechanics: ``stiffness_ratio`` and the choice both ask."""


def stiffness_ratio(mechanics) -> float:
    """Fastest over slowest nonzero rate |lambda| of the linearised flow at the start.

    The eigenvalues of the Jacobian of Hamilton's equations (with the effects) at the
    initial state give the time scales 1/|lambda| of the motion. A step sized for the
    slow motion, dt ~ 1/|lambda|_min, puts the fast modes at |lambda|_max dt = this
    ratio: beyond ``STIFF_RATIO`` an explicit or fixed-point-iterated implicit method is
    unstable or stalls there, and an L-stable implicit method is the right tool.
    Returns 1.0 when the ratio cannot be formed (no motion, a singular start).
    """
    return _ratio(_eigenvalues(mechanics), _scene_t_end(mechanics))


def _scene_t_end(mechanics) -> float:
    """The length of the scene's run ([view] t_end; 10 when it gives none)."""
    return float(mechanics.scene.view.get("t_end", 10.0))


def _ratio(eigenvalues: np.ndarray, t_end: float = math.inf) -> float:
    """Fastest over slowest rate that matters over a run of length ``t_end``.

    A rate slower than one cycle per run does not limit any step, and symmetries
    (translations, a conserved momentum) give zero eigenvalues that finite differences
    return as small nonzero ones (a Jordan block's by the square root of round-off): so
    the slowest rate counted is at least 2 pi / t_end.
    """
    rates = np.abs(eigenvalues)
    if rates.size == 0:
        return 1.0
    fast = rates.max()
    slow_rates = rates[rates > 1e-9 * max(fast, 1e-300)]
    if fast == 0.0 or slow_rates.size == 0:
        return 1.0
    floor = 2.0 * math.pi / t_end if math.isfinite(t_end) and t_end > 0 else 0.0
    return float(fast / max(slow_rates.min(), floor))


def singular_terms(expr) -> list[sympy.Expr]:
    """Denominators of ``expr`` that contain a coordinate symbol (1/r, 1/sqrt(x^2+y^2))."""
    found = []
    for node in sympy.preorder_traversal(as_expr(expr)):
        if isinstance(node, sympy.Pow) and node.exp.is_negative:
            if any(isinstance(s, sympy.Symbol) for s in node.base.free_symbols):
                found.append(node.base)
    return found


def _potential(mechanics):
    """V(q, t): the separable part, the scene's potential, -L0 for a system in matrix
    form (whose H holds velocities: H at p = 0 would not be V), or H at p = 0."""
    if mechanics.separable_parts is not None:
        return mechanics.separable_parts[1]
    if mechanics.potential is not None:
        return mechanics.potential
    if mechanics.matrix_form is not None:
        return -as_expr(mechanics.matrix_form.rest)
    return as_expr(mechanics.hamiltonian).xreplace(dict.fromkeys(mechanics.p, sympy.S.Zero))


def potential_at_start(mechanics) -> float | None:
    """V at the scene's initial state (``_potential``), or None where it is not a number."""
    params, y0 = initial_point(mechanics)
    n = mechanics.n
    subs = {**params, mechanics.t: 0.0} | dict(zip(mechanics.q, y0[:n], strict=True))
    try:
        value = _number(_potential(mechanics), subs)
    except (TypeError, ValueError, ZeroDivisionError):
        return None
    return value if np.isfinite(value) else None


def _singular_attractive(mechanics) -> bool:
    """V has a coordinate expression in a denominator and is negative at the start."""
    V = _potential(mechanics)
    coords = set(mechanics.q)
    if not any(b.free_symbols & coords for b in singular_terms(V)):
        return False
    value = potential_at_start(mechanics)
    return value is not None and value < 0.0


def choose_method(mechanics) -> tuple[str, str]:
    """Pick a stepper for ``mechanics`` (from ``systems.mechanics.derive``).

    Returns
    -------
    name : str
        A key of ``STEPPERS``.
    reason : str
        One line saying why.

    The choice is remembered on ``mechanics`` (a stream started without a method for
    every frame pays for it once).
    """
    cache = getattr(mechanics, "_cache", None)
    if isinstance(cache, dict) and "method_choice" in cache:
        return cache["method_choice"]
    choice = _remembered_choice(mechanics)
    if isinstance(cache, dict):
        cache["method_choice"] = choice
    return choice


def _remembered_choice(mechanics) -> tuple[str, str]:
    """``_choose``, through the on-disk cache of ``systems.derivation_cache``."""
    import sys

    from systems import derivation_cache
    from systems.integrators import registry, stepsize, tableaux

    tag = "method choice " + derivation_cache.code_hash(
        sys.modules[__name__], stepsize, registry, tableaux
    )
    text = derivation_cache.remembered(mechanics.scene, tag, lambda: "\n".join(_choose(mechanics)))
    method, reason = text.split("\n", 1)
    from systems.integrators.registry import get_stepper

    if get_stepper(method).applies_to(mechanics) is not None:  # a stale or damaged cache entry
        method, reason = _choose(mechanics)
    return method, reason


def _choose(mechanics) -> tuple[str, str]:
    from systems.constraints import constrained

    if constrained(mechanics.scene):
        return "constrained_dop853", (
            "constraints: adaptive 8th-order Runge-Kutta on the equations with "
            "Lagrange multipliers, projected onto the constraints after every step "
            f"(tolerance {DEFAULT_TOL:g})"
        )
    c = mechanics.classification
    eigenvalues = _eigenvalues(mechanics)
    ratio = _ratio(eigenvalues, _scene_t_end(mechanics))
    if ratio > STIFF_RATIO:
        fast = eigenvalues[np.abs(eigenvalues) > 0.5 * np.abs(eigenvalues).max()]
        oscillatory = np.all(np.abs(fast.real) <= 0.01 * np.abs(fast))
        if oscillatory and c.conservative and c.hamiltonian_conserved:
            return "gauss_legendre6", (
                f"stiff (time scales differ by {ratio:.3g}) but the fast modes oscillate: "
                "implicit symplectic Gauss-Legendre with steps that resolve them"
            )
        return "radau", (
            f"stiff: time scales at the start differ by a factor {ratio:.3g} "
            f"(> {STIFF_RATIO:g}), so an L-stable implicit method"
        )
    if not c.conservative or not c.hamiltonian_conserved:
        what = "dissipative or driven" if not c.conservative else "H depends on time"
        return "dop853", (
            f"{what}: no energy to preserve, so adaptive 8th-order Runge-Kutta "
            f"(tolerance {DEFAULT_TOL:g})"
        )
    singular = not c.time_dependent and _singular_attractive(mechanics)
    # a force that does no work keeps H conserved, but a splitting of H leaves it out
    splits = c.separable and _splitting_applies(mechanics)
    if singular and splits:
        return "logh_yoshida6", (
            "separable with a singular attractive potential: time-transformed "
            "(logarithmic-Hamiltonian) symplectic steps shrink near the singularity"
        )
    if singular:
        return "dop853", (
            "a singular attractive potential with H not separable: adaptive 8th-order "
            "steps shrink at close approaches, where fixed steps would fail "
            f"(tolerance {DEFAULT_TOL:g})"
        )
    aim = f"steps aimed at a relative energy error of {ENERGY_TARGET:g}"
    if splits:
        return "yoshida8", f"separable H = T(p) + V(q): explicit symplectic, 8th order, {aim}"
    if c.separable:
        return "gauss_legendre6", (
            "H is separable, but a force that does no work acts besides it, which a "
            f"splitting of H would leave out: implicit Gauss-Legendre, 6th order, {aim}"
        )
    return "gauss_legendre6", (
        f"conservative but H is not separable: implicit symplectic Gauss-Legendre, 6th order, {aim}"
    )


def _splitting_applies(mechanics) -> bool:
    """Whether the splitting methods integrate the whole system (no effect they drop)."""
    from systems.integrators.registry import STEPPERS

    return STEPPERS["yoshida8"].applies_to(mechanics) is None
