"""Angle coordinates: which coordinates are angles, and angles wrapped to (-pi, pi].

A coordinate is an angle when the scene says so (``[view] angles = ["theta", ...]``) or,
without that key, when everything that defines the system is 2 pi-periodic in it: T and V,
L or H as the scene gives them, the enabled effects (dissipation, forces) and the drawing,
with the coordinate appearing in at least one of them. A coordinate that appears nowhere
but in its velocity (a cyclic one, such as the azimuth of a central force) counts only
through the drawing: ``r*cos(theta)`` makes theta an angle, ``x`` leaves x a length.

The test is cheap and bounded: a coordinate is a candidate only if it occurs inside a
trigonometric function, and candidates are checked together with one lambdified call at a
few random points (every other symbol random too), comparing ``f(q)`` with
``f(q + 2 pi)``. A 64-particle chain without trigonometric terms costs a tree walk.

Wrapping (``wrap``) and breaking a polyline where it wraps (``break_at_wraps``) are plain
numpy for the plots; ``periodic_crossings`` in ``systems.integrators.events`` uses the
same branch numbering for Poincaré sections on an angle.
"""

from __future__ import annotations

import math

import numpy as np
import sympy
from sympy.functions.elementary.trigonometric import TrigonometricFunction

TWO_PI = 2.0 * math.pi
SAMPLES = 12
"""Random points of the periodicity test (points where an expression is not finite are
dropped; at least ``MIN_FINITE`` must remain)."""
MIN_FINITE = 4
TOLERANCE = 1e-8
"""Relative difference f(q + 2 pi) vs f(q) below which they count as equal."""
_CACHE_KEY = "angles.detected"


def angle_coordinates(mechanics) -> tuple[str, ...]:
    """The scene's angle coordinates, in the scene's coordinate order.

    Parameters
    ----------
    mechanics : systems.mechanics.Mechanics
        Its ``scene`` is read: ``scene.view["angles"]`` when present (even empty: the
        author said which), else the coordinates detected as 2 pi-periodic.

    Returns
    -------
    tuple of str
        Names from ``scene.coordinates``.
    """
    scene = mechanics.scene
    declared = declared_angles(scene)
    if declared is not None:
        return declared
    cache = getattr(mechanics, "_cache", None)
    if isinstance(cache, dict) and _CACHE_KEY in cache:
        return cache[_CACHE_KEY]
    found = detect_angles(scene)
    if isinstance(cache, dict):
        cache[_CACHE_KEY] = found
    return found


def declared_angles(scene) -> tuple[str, ...] | None:
    """``[view] angles`` restricted to the scene's coordinates, or None without the key."""
    view = scene.view if isinstance(scene.view, dict) else dict(scene.view or {})
    if "angles" not in view:
        return None
    names = view.get("angles") or ()
    if isinstance(names, str):
        names = (names,)
    wanted = {str(name) for name in names}
    return tuple(q for q in scene.coordinates if q in wanted)


def angle_flags(mechanics) -> np.ndarray:
    """``flags[i]`` is True when coordinate i is an angle; shape (n,), bool."""
    angles = set(angle_coordinates(mechanics))
    return np.array([q in angles for q in mechanics.scene.coordinates], dtype=bool)


def _defining_expressions(scene) -> list[sympy.Expr]:
    """T and V, L or H as given, the enabled effects and the drawing, parsed."""
    fields = [
        "system.kinetic",
        "system.potential",
        "system.lagrangian",
        "system.hamiltonian",
    ]
    if scene.dissipation is not None and "dissipation" not in scene.disabled:
        fields.append("effects.dissipation")
    fields += [
        f"effects.forces.{q}" for q, _ in scene.forces if f"forces.{q}" not in scene.disabled
    ]
    if scene.drawing is not None:
        for name, _, _ in scene.drawing.points:
            fields += [f"drawing.points.{name}.x", f"drawing.points.{name}.y"]
    expressions = []
    for name in fields:
        try:
            expressions.append(scene.expression(name))  # already parsed (whitelist)
        except KeyError:  # a field the scene does not have (T and V given, not L)
            continue
    return expressions


def detect_angles(scene) -> tuple[str, ...]:
    """The coordinates in which every defining expression is 2 pi-periodic (see module).

    Parameters
    ----------
    scene : systems.scene.Scene

    Returns
    -------
    tuple of str
        In the scene's coordinate order.
    """
    expressions = _defining_expressions(scene)
    if not expressions:
        return ()
    symbols = scene.symbols
    inside_trig: set[sympy.Symbol] = set()
    present: set[sympy.Symbol] = set()
    for expr in expressions:
        present |= expr.free_symbols
        for atom in expr.atoms(TrigonometricFunction):
            inside_trig |= atom.free_symbols
    candidates = [
        q for q in scene.coordinates if symbols[q] in inside_trig and symbols[q] in present
    ]
    if not candidates:
        return ()
    arguments = sorted(present, key=lambda s: s.name)
    try:
        function = sympy.lambdify(arguments, expressions, modules="numpy", cse=False)
    except Exception:  # noqa: BLE001 - an expression numpy cannot evaluate: no angles
        return ()
    rng = np.random.default_rng(20240610)
    coordinates = set(scene.coordinates)
    parameters = {name for name, _ in scene.parameters}
    base = []
    for symbol in arguments:
        if symbol.name in coordinates:
            base.append(rng.uniform(-3.0, 3.0, SAMPLES))
        elif symbol.name in parameters:
            base.append(rng.uniform(0.5, 2.0, SAMPLES))  # lengths and masses are positive
        elif symbol.name == "t":
            base.append(rng.uniform(0.0, 10.0, SAMPLES))
        else:  # velocities and momenta
            base.append(rng.uniform(-2.0, 2.0, SAMPLES))
    # one call: the base points, then each candidate shifted by 2 pi
    columns = []
    for k, symbol in enumerate(arguments):
        blocks = [base[k]]
        for q in candidates:
            blocks.append(base[k] + TWO_PI if symbol.name == q else base[k])
        columns.append(np.concatenate(blocks))
    with np.errstate(all="ignore"):
        try:
            raw = function(*columns)
        except Exception:  # noqa: BLE001 - a numpy failure on exotic input: no angles
            return ()
    values = np.empty((len(expressions), SAMPLES * (1 + len(candidates))))
    for i, value in enumerate(raw):
        values[i] = np.broadcast_to(np.asarray(value, dtype=float), values.shape[1:])
    values = values.reshape(len(expressions), 1 + len(candidates), SAMPLES)
    reference = values[:, 0, :]
    angles = []
    for j, q in enumerate(candidates):
        shifted = values[:, 1 + j, :]
        finite = np.isfinite(reference).all(axis=0) & np.isfinite(shifted).all(axis=0)
        if finite.sum() < MIN_FINITE:
            continue
        a, b = reference[:, finite], shifted[:, finite]
        scale = np.maximum(1.0, np.maximum(np.abs(a), np.abs(b)))
        if np.all(np.abs(a - b) <= TOLERANCE * scale):
            angles.append(q)
    return tuple(angles)


def wrap(x):
    """Angles wrapped to (-pi, pi]; same shape as ``x`` (a float for a scalar)."""
    wrapped = math.pi - np.mod(math.pi - np.asarray(x, dtype=float), TWO_PI)
    return float(wrapped) if np.ndim(wrapped) == 0 else wrapped


def branch(x) -> np.ndarray:
    """The integer k with ``x = wrap(x) + 2 pi k``, as floats; same shape as ``x``."""
    x = np.asarray(x, dtype=float)
    return np.ceil((x - math.pi) / TWO_PI)


def break_at_wraps(columns, angles) -> tuple[np.ndarray, ...]:
    """A polyline with its angle columns wrapped to (-pi, pi], broken where one wraps.

    Where consecutive points lie on neighbouring branches of one angle the segment is cut
    at the edge: the line runs to +pi (or -pi) with the other columns linearly
    interpolated, a NaN point breaks it, and it resumes at the opposite edge, so no chord
    crosses the plot. Points further apart than one turn, or where two angles wrap in the
    same step, are only separated by the NaN.

    Parameters
    ----------
    columns : sequence of ndarray, each shape (k,)
        The polyline's coordinates, angles unwrapped.
    angles : sequence of bool
        Which columns are angles.

    Returns
    -------
    tuple of ndarray, each shape (k + extra,)
        The wrapped columns, with three extra points per edge crossing (one per other
        break).
    """
    columns = [np.asarray(c, dtype=float) for c in columns]
    flags = [bool(a) for a in angles]
    shown = [wrap(c) if a and c.size else c.copy() for c, a in zip(columns, flags, strict=True)]
    branches = [branch(c) for c, a in zip(columns, flags, strict=True) if a]
    if not branches or len(columns[0]) < 2:
        return tuple(np.atleast_1d(c) for c in shown)
    steps = np.stack([np.diff(k) for k in branches])  # (angles, k - 1)
    with np.errstate(invalid="ignore"):
        jumps = np.flatnonzero((steps != 0).any(axis=0))
    if not len(jumps):
        return tuple(shown)
    which = [i for i, a in enumerate(flags) if a]
    pieces: list[list[np.ndarray]] = [[] for _ in columns]
    start = 0
    for i in jumps:
        for c, piece in zip(shown, pieces, strict=True):
            piece.append(c[start : i + 1])
        changed = np.flatnonzero(steps[:, i] != 0)
        ends = [c[i : i + 2] for c in columns]
        edge_crossing = (
            len(changed) == 1
            and abs(steps[changed[0], i]) == 1
            and all(np.isfinite(e).all() for e in ends)
        )
        if edge_crossing:
            col = which[changed[0]]
            k0 = branches[changed[0]][i]
            edge = math.pi if steps[changed[0], i] > 0 else -math.pi
            a, b = ends[col]
            fraction = (edge + TWO_PI * k0 - a) / (b - a) if b != a else 0.5
            for j, (piece, (u, v)) in enumerate(zip(pieces, ends, strict=True)):
                at = u + fraction * (v - u)
                if j == col:
                    piece.append(np.array([edge, np.nan, -edge]))
                else:
                    at = wrap(at) if flags[j] else at
                    piece.append(np.array([at, np.nan, at]))
        else:
            for piece in pieces:
                piece.append(np.array([np.nan]))
        start = i + 1
    for c, piece in zip(shown, pieces, strict=True):
        piece.append(c[start:])
    return tuple(np.concatenate(piece) for piece in pieces)
