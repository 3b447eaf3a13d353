"""The Legendre transform of square-root Lagrangians in closed form.

A Lagrangian ``L = kappa(q, t) sqrt(B) + a(q, t).qdot + L0(q, t)`` whose radicand is
quadratic in the velocities with no linear part, ``B = B0(q, t) + qdot.G(q, t).qdot``
(a relativistic particle, ``-m c**2 sqrt(1 - v**2/c**2) - V``, in any coordinates;
``-f(x) sqrt(1 - x_dot**2)``), is inverted by solving for the "speed" ``w = qdot.G.qdot``
first: with ``pi = p - a`` the momenta are ``pi = kappa G qdot/sqrt(B)``, so
``P2 = pi.G^-1.pi = kappa**2 w/(B0 + w)`` gives ``w``, and then

    qdot = G^-1 pi |kappa| sqrt(B0) / (kappa sqrt(kappa**2 - P2)),
    H = -sign(kappa) sqrt(B0) sqrt(kappa**2 - P2) - L0,

the textbook ``sqrt(p**2 c**2 + m**2 c**4) + V``. ``sympy.solve`` on the momenta took
seconds for a two-dimensional relativistic oscillator and returned an H that treated x
and y differently. The energy in the velocities is ``-kappa B0/sqrt(B) - L0``
(``m c**2/sqrt(1 - v**2/c**2) + V``).

``|kappa|`` needs the signs of the parameters: the transform is formed with the
parameters that are positive in the scene taken as positive (as the textbook takes m and
c), so it holds for positive values of them; the caller checks the inverse at random
states.
"""

from __future__ import annotations

from dataclasses import dataclass

import sympy

from systems.display import EXPANSION_LIMIT, expanded_terms


@dataclass(frozen=True)
class SquareRootTransform:
    """The closed-form Legendre transform of a square-root Lagrangian.

    Attributes
    ----------
    velocities : tuple of sympy.Expr
        qdot_i(q, p, t).
    hamiltonian : sympy.Expr
        H(q, p, t).
    energy : sympy.Expr
        The same H in (q, qdot, t): ``-kappa B0/sqrt(B) - L0``.
    force : tuple of sympy.Expr
        ``-dH/dq_i`` in (q, p, t) (``dL/dq_i`` at ``qdot(q, p)``), the sign of kappa held
        constant.
    """

    velocities: tuple[sympy.Expr, ...]
    hamiltonian: sympy.Expr
    energy: sympy.Expr
    force: tuple[sympy.Expr, ...]


def square_root_transform(
    L: sympy.Expr,
    q: tuple[sympy.Symbol, ...],
    qdot: tuple[sympy.Symbol, ...],
    p: tuple[sympy.Symbol, ...],
    positive: tuple[sympy.Symbol, ...] = (),
) -> SquareRootTransform | None:
    """The Legendre transform of ``L`` if it is a square-root Lagrangian, else None.

    Parameters
    ----------
    L : sympy.Expr
        The Lagrangian in (q, qdot, t).
    q, qdot, p : tuple of sympy.Symbol
        The coordinates, their velocities and momenta, in the same order.
    positive : tuple of sympy.Symbol
        Symbols (the parameters positive in the scene) taken as positive, so that
        ``sqrt(m**2 c**4)`` is ``m c**2``.

    Returns
    -------
    SquareRootTransform or None
        None unless L has exactly the form of the module's docstring (one radicand, no
        linear part in it, no velocity outside it beyond a linear term, G invertible
        symbolically: diagonal, or at most four coordinates).
    """
    assumed = {s: sympy.Dummy(s.name, positive=True) for s in positive}
    back = {d: s for s, d in assumed.items()}
    parts = _split(L.xreplace(assumed), qdot)
    if parts is None:
        return None
    kappa, radicand, other = parts
    kappa = sympy.factor_terms(kappa)  # -(1 + x**2), not -1 - x**2: sqrt(kappa**2) then simplifies
    zero = dict.fromkeys(qdot, sympy.S.Zero)
    B0 = radicand.xreplace(zero)
    gradient = [sympy.diff(radicand, v) for v in qdot]
    if any(g.xreplace(zero) != 0 for g in gradient):
        return None  # a part linear in the velocities: a moving frame, not this form
    G = sympy.Matrix([[sympy.diff(g, v) / 2 for v in qdot] for g in gradient])
    if G.has(*qdot) or B0 == 0:
        return None
    shift = [sympy.diff(other, v) for v in qdot]
    if any(a.has(*qdot) for a in shift):
        return None  # velocities outside the root beyond a linear term
    L0 = other.xreplace(zero)
    pi = [pi_ - a for pi_, a in zip(p, shift, strict=True)]
    inverse_pi = _solve(G, pi)
    if inverse_pi is None:
        return None
    P2 = sympy.Add(*[x * y for x, y in zip(pi, inverse_pi, strict=True)])
    # c**2 (m**2 c**2 + p**2) -> c sqrt(m**2 c**2 + p**2) with c positive
    root = sympy.sqrt(sympy.factor_terms(kappa**2 - P2))
    sign = kappa / sympy.sqrt(kappa**2)  # 1 or -1 where the signs are known
    if not sign.is_number:
        sign = sympy.sign(kappa)
    # sign(kappa) is constant where the transform exists (kappa = 0 makes the velocity
    # Hessian singular): held as a symbol while H is differentiated
    held = sympy.Dummy("sign")
    scale = sympy.sqrt(B0) / (held * root)
    velocities = tuple(scale * x for x in inverse_pi)
    H = -held * sympy.sqrt(B0) * root - L0
    force = tuple(-sympy.diff(H, x) for x in q)
    energy = -kappa * B0 / sympy.sqrt(radicand) - L0

    def plain(expr: sympy.Expr) -> sympy.Expr:
        return expr.xreplace({held: sign}).xreplace(back)

    return SquareRootTransform(
        tuple(map(plain, velocities)), plain(H), plain(energy), tuple(map(plain, force))
    )


def _split(L: sympy.Expr, qdot) -> tuple[sympy.Expr, sympy.Expr, sympy.Expr] | None:
    """``(kappa, B, rest)`` with ``L = kappa sqrt(B) + rest``, kappa free of the
    velocities and rest at most linear in them, read off the terms of L (its top level
    expanded); None if L is not of that form."""
    kappa, radicand, rest = sympy.S.Zero, None, []
    # nothing on the derivation path expands past EXPANSION_LIMIT terms (a long sum to a
    # high power); such an L is taken term by term as written
    if expanded_terms(L) <= EXPANSION_LIMIT:
        L = sympy.expand(L, deep=False)
    for term in sympy.Add.make_args(L):
        if not term.has(*qdot):
            rest.append(term)
            continue
        moving = [f for f in sympy.Mul.make_args(term) if f.has(*qdot)]
        if len(moving) != 1:
            return None
        (factor,) = moving
        if factor.is_Pow and factor.exp == sympy.S.Half:
            if radicand is not None and factor.base != radicand:
                return None
            radicand = factor.base
            kappa += term / factor
            continue
        if any(sympy.diff(term, v, w) != 0 for v in qdot for w in qdot):
            return None
        rest.append(term)
    if radicand is None or kappa == 0:
        return None
    return kappa, radicand, sympy.Add(*rest)


def _solve(G: sympy.Matrix, rhs: list[sympy.Expr]) -> list[sympy.Expr] | None:
    """``G^-1 rhs``: entry by entry for a diagonal G, by cofactors up to four rows."""
    from systems.mechanics import SYMBOLIC_INVERSE_LIMIT, _cofactors

    n = G.rows
    if all(G[i, j] == 0 for i in range(n) for j in range(n) if i != j):
        if any(G[i, i] == 0 for i in range(n)):
            return None
        return [rhs[i] / G[i, i] for i in range(n)]
    if n > SYMBOLIC_INVERSE_LIMIT:
        return None
    det, adjugate = _cofactors(G)
    if det == 0:
        return None
    return [sympy.Add(*[adjugate[i, j] * rhs[j] for j in range(n)]) / det for i in range(n)]
