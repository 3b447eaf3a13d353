"""What a drawing of a scene's particles shows when the scene draws nothing itself.

A scene given by ``[particles]`` without ``[drawing]`` links is drawn from its
transformation equations r_i(q, t) and its holonomic constraints:

- its bodies, the particles with a mass (not zero) that a coordinate moves, as discs;
  every other point (a massless pivot, a fixed particle, a support) small and grey;
- a rod between two particles whose distance the transformation keeps (|r_i - r_j| the
  same at every q and t: the double pendulum's second rod) or a holonomic constraint
  fixes (Phi a function of |r_i - r_j|, or of |r_i| for the origin: the Cartesian
  pendulum's x**2 + y**2 - l**2);
- a rod to a support: the part c(t) of r_i that no coordinate moves (the sum of the terms
  of each component free of q) when |r_i - c| is the same at every q and t, c drawn as a
  support point (``origin`` when c = 0; a particle already there when one is).

Decided at random states (values in [0.3, 1.7] for the coordinates, t and the
parameters), to 1e-9 relative, as ``systems.particles`` decides that r depends on t.
"""

from __future__ import annotations

import random
from dataclasses import dataclass

import numpy as np
import sympy

MAX_PAIRS = 780
"""Pairs of points looked at, at most (40 particles): beyond, only the supports."""
TRIALS = 6
TOLERANCE = 1e-9


@dataclass(frozen=True)
class Sketch:
    """How to draw a scene's particles.

    Attributes
    ----------
    bodies : tuple of str
        The particles drawn as discs: a mass that is not zero, moved by a coordinate.
    masses : tuple of sympy.Expr
        Their masses, in the parameters (discs sized by them).
    links : tuple of (str, str)
        Rods between point names: particles, ``origin`` and the supports.
    supports : tuple of (str, sympy.Expr, sympy.Expr)
        Support points that are not particles: a name and x, y in t and the parameters.
    """

    bodies: tuple[str, ...] = ()
    masses: tuple[sympy.Expr, ...] = ()
    links: tuple[tuple[str, str], ...] = ()
    supports: tuple[tuple[str, sympy.Expr, sympy.Expr], ...] = ()


def sketch(scene) -> Sketch:
    """The bodies, rods and supports of ``scene``'s particles (empty without particles).

    The rods and supports are found whatever the scene's ``[drawing]`` says; the window
    draws them only where the drawing has no links of its own.
    """
    if not scene.particles:
        return Sketch()
    symbols = scene.symbols
    q = tuple(symbols[name] for name in scene.coordinates)
    t = symbols["t"]
    names = [p.name for p in scene.particles]
    positions = [
        tuple(scene.expression(f"particles.{p.name}.position[{i}]") for i in range(len(p.position)))
        for p in scene.particles
    ]
    masses = [scene.expression(f"particles.{p.name}.mass") for p in scene.particles]
    moved = [any(c.has(*q) for c in r) for r in positions]
    free = sorted(
        set().union(*(c.free_symbols for r in positions for c in r)) | set(q) | {t}, key=str
    )
    states = _states(free)
    motion = set(q) | {t}

    bodies = tuple(
        (name, mass)
        for name, mass, m in zip(names, masses, moved, strict=True)
        if m and not _is_zero(mass)
    )
    links: list[tuple[str, str]] = []
    supports: list[tuple[str, sympy.Expr, sympy.Expr]] = []
    # rods to supports: r = c(t) + u(q, t) with |u| constant
    for name, r, m in zip(names, positions, moved, strict=True):
        if not m:
            continue
        fixed = tuple(c.as_independent(*q, as_Add=True)[0] for c in r)
        arm = sum(((c - f) ** 2 for c, f in zip(r, fixed, strict=True)), sympy.S.Zero)
        if not _constant(arm, free, states, motion):
            continue
        if all(f == 0 for f in fixed):
            links.append(("origin", name))
            continue
        there = [
            other
            for other, s, o in zip(names, positions, moved, strict=True)
            if not o
            and len(s) == len(fixed)
            and all(sympy.simplify(a - b) == 0 for a, b in zip(s, fixed, strict=True))
        ]
        if there:
            links.append((there[0], name))
            continue
        known = [s for s in supports if (s[1], s[2]) == (fixed[0], fixed[1])]
        if known:
            links.append((known[0][0], name))
            continue
        support = _free_name(f"support{len(supports) + 1}" if supports else "support", names)
        supports.append((support, fixed[0], fixed[1]))
        links.append((support, name))
    # rods between particles: a distance the transformation keeps or a constraint fixes
    pairs = [(i, j) for i in range(len(names)) for j in range(i + 1, len(names))]
    pairs = [(i, j) for i, j in pairs if moved[i] or moved[j]][:MAX_PAIRS]
    squares = {
        (i, j): sum(
            ((a - b) ** 2 for a, b in zip(positions[i], positions[j], strict=False)), sympy.S.Zero
        )
        for i, j in pairs
    }
    tied = _constraint_ties(scene, q, free, states, squares, positions, moved)
    drawn = set(links)
    for (i, j), square in squares.items():
        link = (names[i], names[j])
        if link in drawn or (link[1], link[0]) in drawn:
            continue
        if (i, j) in tied or _constant(square, free, states, motion):
            links.append(link)
    for i in tied.get("origin", ()):
        if ("origin", names[i]) not in links:
            links.append(("origin", names[i]))
    return Sketch(
        bodies=tuple(name for name, _ in bodies),
        masses=tuple(mass for _, mass in bodies),
        links=tuple(links),
        supports=tuple(supports),
    )


def _constraint_ties(scene, q, free, states, squares, positions, moved) -> dict:
    """The pairs (i, j), and under ``"origin"`` the particles i, whose distance a
    holonomic constraint fixes: its gradient in q parallel to that of the distance's
    square at every state (Phi = f(|r_i - r_j|**2))."""
    found: dict = {}
    if not scene.holonomic_constraints or not q:
        return found
    constraints = [
        scene.expression(f"constraints.holonomic[{k}]")
        for k in range(len(scene.holonomic_constraints))
    ]
    candidates = dict(squares)
    for i, r in enumerate(positions):
        if moved[i]:
            candidates[("origin", i)] = sum((c**2 for c in r), sympy.S.Zero)
    for key, square in candidates.items():
        grad_d = [sympy.diff(square, x) for x in q]
        for phi in constraints:
            if not phi.free_symbols & set(q):
                continue
            grad_phi = [sympy.diff(phi, x) for x in q]
            if _parallel(grad_d, grad_phi, free, states):
                if key[0] == "origin":
                    found.setdefault("origin", []).append(key[1])
                else:
                    found[key] = True
                break
    return found


def _states(free) -> np.ndarray:
    rng = random.Random(20250125)
    return np.array([[rng.uniform(0.3, 1.7) for _ in free] for _ in range(TRIALS)])


def _values(expr, free, states) -> np.ndarray | None:
    function = sympy.lambdify(free, expr, modules="numpy")
    with np.errstate(all="ignore"):
        try:
            values = np.array([complex(function(*row)) for row in states])
        except (TypeError, ValueError, ZeroDivisionError, OverflowError):
            return None
    if not np.all(np.isfinite(values)) or np.any(np.abs(values.imag) > 1e-12):
        return None
    return values.real


def _constant(expr: sympy.Expr, free, states, motion: set) -> bool:
    """True if ``expr`` is the same, and not zero, at every coordinate and time (the
    parameters as they are at one state): its derivatives in q and t vanish."""
    if expr == 0:
        return False
    value = _values(expr, free, states)
    if value is None or np.max(np.abs(value)) <= 1e-12:
        return False
    for s in expr.free_symbols & motion:
        rate = _values(sympy.diff(expr, s), free, states)
        if rate is None or np.max(np.abs(rate)) > TOLERANCE * np.max(np.abs(value)):
            return False
    return True


def _parallel(u, v, free, states) -> bool:
    """True if the vectors of expressions ``u`` and ``v`` are parallel and not zero at
    every state."""
    a = [_values(e, free, states) for e in u]
    b = [_values(e, free, states) for e in v]
    if any(x is None for x in a + b):
        return False
    a, b = np.array(a), np.array(b)  # (n, trials)
    aa, bb, ab = (a * a).sum(0), (b * b).sum(0), (a * b).sum(0)
    if np.any(aa <= 1e-24) or np.any(bb <= 1e-24):
        return False
    return bool(np.all(aa * bb - ab * ab <= TOLERANCE * aa * bb))


def _is_zero(mass) -> bool:
    return mass == 0


def _free_name(name: str, taken) -> str:
    while name in taken:
        name += "_"
    return name
