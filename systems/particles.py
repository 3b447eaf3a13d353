"""Particles: T and the gravitational V from the bodies' positions r_i(q, t).

A scene may describe its bodies instead of its kinetic energy (``[particles]`` in
``docs/scenes.md``). Each particle has a constant mass and a position with 2 or 3
Cartesian components in the coordinates, ``t`` and the parameters: the transformation
equations r_i = r_i(q, t). From them

    v_i = dr_i/dt = sum_j (dr_i/dq_j) q_dot_j + dr_i/dt|_explicit,
    T = sum_i m_i |v_i|**2 / 2 = T2 + T1 + T0,

with T2 = q_dot.M.q_dot/2 (M_jk = sum_i m_i dr_i/dq_j . dr_i/dq_k), T1 = b.q_dot
(b_j = sum_i m_i dr_i/dq_j . dr_i/dt) and T0 = sum_i m_i |dr_i/dt|**2 / 2; T1 and T0 are
zero unless some r_i depends on t explicitly (a rheonomic transformation). A uniform
gravitational field g adds V = -sum_i m_i g . r_i.

This module only handles sympy expressions already parsed by ``systems.scene`` (which
reads the table and reports errors by field); it never sees user text.
"""

from __future__ import annotations

import random
from collections.abc import Sequence
from dataclasses import dataclass

import sympy

from systems.calculus import numeric_evaluator
from systems.display import combine_trig, expanded_terms
from systems.expressions import as_expr

TRIGSIMP_OPS = 80
"""Entries of M, b and T0 with at most this many operations (after the cheap trig
combination) are also tried with ``sympy.trigsimp``: a spherical pendulum's
cos²θ cos²φ + sin²θ + cos²θ sin²φ needs it, and on small entries it costs milliseconds."""

EXPAND_TERMS = 400
"""Entries whose expansion has at most this many terms are expanded before the cheap
trig combination (the terms of a product of sums must meet to combine)."""


@dataclass(frozen=True)
class Particle:
    """A point mass of a scene, as the text the user wrote.

    Attributes
    ----------
    name : str
        The particle's name, also the name of its point in the drawing.
    mass : str
        An expression in the parameters.
    position : tuple of str
        2 or 3 Cartesian components, expressions in the coordinates, ``t`` and the
        parameters (x to the right, y up, z towards the viewer).
    """

    name: str
    mass: str
    position: tuple[str, ...]


@dataclass(frozen=True, eq=False)
class Transformation:
    """The transformation equations of a scene's particles and what follows from them.

    Attributes
    ----------
    names : tuple of str
        The particles, in the scene's order.
    masses : tuple of sympy.Expr
    positions : tuple of tuple of sympy.Expr
        r_i(q, t), 2 or 3 components each.
    velocities : tuple of tuple of sympy.Expr
        v_i = dr_i/dt (total derivative) in (q, q_dot, t).
    mass_matrix : sympy.Matrix, shape (n, n)
        M_jk = sum_i m_i dr_i/dq_j . dr_i/dq_k.
    kinetic_parts : tuple of three sympy.Expr
        (T2, T1, T0): quadratic, linear and free of the velocities.
    kinetic : sympy.Expr
        T = T2 + T1 + T0.
    potential : sympy.Expr
        The gravitational V = -sum_i m_i g . r_i (zero without gravity).
    depends_on_time : bool
        True exactly when some r_i depends on t explicitly (dr_i/dt|_explicit is not
        identically zero): the transformation is rheonomic.
    """

    names: tuple[str, ...]
    masses: tuple[sympy.Expr, ...]
    positions: tuple[tuple[sympy.Expr, ...], ...]
    velocities: tuple[tuple[sympy.Expr, ...], ...]
    mass_matrix: sympy.Matrix
    kinetic_parts: tuple[sympy.Expr, sympy.Expr, sympy.Expr]
    kinetic: sympy.Expr
    potential: sympy.Expr
    depends_on_time: bool


def gravity_vector(gravity: sympy.Expr | tuple[sympy.Expr, ...], dimension: int) -> tuple:
    """The field vector g: a scalar g means (0, -g) or (0, -g, 0), along -y.

    Parameters
    ----------
    gravity : sympy.Expr or tuple of sympy.Expr
        The scene's ``gravity``: a magnitude, or the vector itself.
    dimension : int
        2 or 3, the number of components of the positions.

    Raises
    ------
    ValueError
        If a vector does not have ``dimension`` components.
    """
    if isinstance(gravity, tuple):
        if len(gravity) != dimension:
            raise ValueError(f"has {len(gravity)} components, but the positions have {dimension}")
        return gravity
    return (sympy.S.Zero, -gravity) + (sympy.S.Zero,) * (dimension - 2)


def depends_on_time(positions: Sequence[Sequence[sympy.Expr]], t: sympy.Symbol) -> bool:
    """True if some component of ``positions`` depends on ``t`` explicitly.

    A component that mentions t but whose partial derivative in t vanishes identically
    (``sin(t)**2 + cos(t)**2``) does not count: the test is on dr/dt, exactly (sympy) or
    at random real values of all symbols.
    """
    rng = random.Random(20261123)
    for position in positions:
        for component in position:
            if not component.has(t):
                continue
            rate = sympy.diff(component, t)
            if not _vanishes(rate, rng):
                return True
    return False


def transformation(
    names: Sequence[str],
    masses: Sequence[sympy.Expr],
    positions: Sequence[Sequence[sympy.Expr]],
    gravity: sympy.Expr | tuple[sympy.Expr, ...] | None,
    q: tuple[sympy.Symbol, ...],
    qdot: tuple[sympy.Symbol, ...],
    t: sympy.Symbol,
) -> Transformation:
    """Build T = T2 + T1 + T0 and the gravitational V from the particles.

    Parameters
    ----------
    names : sequence of str
        The particles' names.
    masses : sequence of sympy.Expr
        Their masses, in the parameters.
    positions : sequence of sequences of sympy.Expr
        r_i(q, t), all with the same number of components (2 or 3).
    gravity : sympy.Expr, tuple of sympy.Expr, or None
        The uniform field: a magnitude along -y, or the vector; None for none.
    q, qdot, t
        The scene's coordinate, velocity and time symbols.

    Returns
    -------
    Transformation
        Each entry of M and b, and T0, is simplified (sines and cosines combined).
    """
    positions = tuple(tuple(as_expr(c) for c in r) for r in positions)
    masses = tuple(as_expr(m) for m in masses)
    n = len(q)
    # columns[i][j]: dr_i/dq_j; rates[i]: the explicit dr_i/dt
    columns = [[[sympy.diff(c, x) for c in r] for x in q] for r in positions]
    rates = [[sympy.diff(c, t) for c in r] for r in positions]
    velocities = tuple(
        tuple(
            _simplified(sum((cols[j][a] * qdot[j] for j in range(n)), sympy.S.Zero) + rate[a])
            for a in range(len(rate))
        )
        for cols, rate in zip(columns, rates, strict=True)
    )

    def weighted(pairs) -> sympy.Expr:
        """sum_i m_i u_i . w_i over the particles, for the (u_i, w_i) of ``pairs``."""
        total = sympy.S.Zero
        for m, (u, w) in zip(masses, pairs, strict=True):
            total += m * sum((a * b for a, b in zip(u, w, strict=True)), sympy.S.Zero)
        return total

    M = sympy.zeros(n, n)
    for j in range(n):
        for k in range(j, n):
            M[j, k] = M[k, j] = _simplified(weighted((c[j], c[k]) for c in columns))
    b = [
        _simplified(weighted((c[j], r) for c, r in zip(columns, rates, strict=True)))
        for j in range(n)
    ]
    T0 = _simplified(weighted((r, r) for r in rates) / 2)
    T2 = sum((M[j, j] * qdot[j] ** 2 / 2 for j in range(n)), sympy.S.Zero)
    T2 += sum(
        (M[j, k] * qdot[j] * qdot[k] for j in range(n) for k in range(j + 1, n)), sympy.S.Zero
    )
    T2 = _shortest([T2, sympy.factor_terms(T2)])
    T1 = sum((b[j] * qdot[j] for j in range(n)), sympy.S.Zero)
    V = sympy.S.Zero
    if gravity is not None:
        for m, r in zip(masses, positions, strict=True):
            g = gravity_vector(gravity, len(r))
            V -= m * sum((gc * rc for gc, rc in zip(g, r, strict=True)), sympy.S.Zero)
        V = _simplified(V)
    return Transformation(
        names=tuple(names),
        masses=masses,
        positions=positions,
        velocities=velocities,
        mass_matrix=M,
        kinetic_parts=(T2, T1, T0),
        kinetic=T2 + T1 + T0,
        potential=V,
        depends_on_time=depends_on_time(positions, t),
    )


def _simplified(expr: sympy.Expr) -> sympy.Expr:
    """The shortest of ``expr``, its sines and cosines combined (after expanding when that
    is small) and, for a small result, ``sympy.trigsimp`` of it; common factors pulled out.

    Every candidate equals ``expr`` identically: these are sympy's exact rewritings.
    """
    expr = as_expr(expr)
    if expr.is_Atom:
        return expr
    candidates = [expr, sympy.factor_terms(combine_trig(expr))]
    if expanded_terms(expr) <= EXPAND_TERMS:
        combined = combine_trig(sympy.expand(expr))
        candidates.append(sympy.factor_terms(combined))
        if _trig_products(combined) and combined.count_ops() <= TRIGSIMP_OPS:
            candidates.append(sympy.factor_terms(sympy.trigsimp(combined)))
    return _shortest(candidates)


def _trig_products(expr: sympy.Expr) -> bool:
    """True if a term of ``expr`` multiplies two or more sines or cosines (a square counts
    twice): what ``combine_trig`` may have left for ``trigsimp``. A pendulum chain's
    entries are single cosines by then, and trigsimp on each cost seconds for ten links."""
    for term in sympy.Add.make_args(expr):
        count = 0
        for factor in sympy.Mul.make_args(term):
            base, power = factor.as_base_exp()
            if isinstance(base, sympy.sin | sympy.cos):
                count += int(power) if power.is_Integer and power > 0 else 1
        if count >= 2:
            return True
    return False


def _shortest(candidates: list[sympy.Expr]) -> sympy.Expr:
    return min(candidates, key=lambda e: (len(str(e)), e.count_ops()))


def _vanishes(expr: sympy.Expr, rng: random.Random) -> bool:
    """True if ``expr`` is zero identically: exactly, or at five random real states
    (values in [0.3, 1.7]) to 1e-9 relative to the size of its terms."""
    if expr == 0:
        return True
    evaluate = numeric_evaluator(expr)
    terms = sympy.Add.make_args(sympy.expand(expr)) if expr.count_ops() < 200 else (expr,)
    sizes = [numeric_evaluator(term) for term in terms]
    free = sorted(expr.free_symbols, key=str)
    for _ in range(5):
        values = {s: rng.uniform(0.3, 1.7) for s in free}
        try:
            value = evaluate(values)
            scale = max([1.0] + [abs(size(values)) for size in sizes])
        except (TypeError, ValueError, ZeroDivisionError, RuntimeError):
            return False
        if not abs(value) <= 1e-9 * scale:
            return False
    return True
