"""Poincaré sections of two-degree autonomous systems: q_j = c crossed with p_j > 0.

Shared by the window (``explorer.poincare``) and the chaos maps (``systems.chaos.maps``).

The crossings themselves come from the engine (``stream(..., section=...)`` locates them
inside each step by cubic Hermite interpolation). A click on the section at energy E
solves H(q, p) = E for the missing momentum p_j > 0; H of a natural system is quadratic
in p_j, so three evaluations of H give the quadratic and its roots.

Without ``[view] section`` the cut is an angle if there is one (a cyclic angle first: it
keeps turning, so every orbit crosses it), else the first coordinate, at 0. A cut on an
angle is crossed at ``value + 2 pi j`` (``systems.simulation`` finds those crossings).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Section:
    """The surface q_j = value, crossed in the direction p_j > 0; plotted in (q_i, p_i)."""

    coordinate: int
    value: float
    shown: int

    @classmethod
    def from_scene(
        cls, scene, angles: tuple[str, ...] = (), cyclic: tuple[str, ...] = ()
    ) -> Section:
        """The scene's ``[view] section``, or a default cut (see the module).

        Parameters
        ----------
        scene : systems.scene.Scene
            Of two (or more) coordinates.
        angles, cyclic : tuple of str
            The scene's angle coordinates and cyclic coordinates.
        """
        n = len(scene.coordinates)
        table = dict(scene.view.get("section", {}) or {})
        preferred = [q for q in scene.coordinates if q in angles and q in cyclic]
        preferred += [q for q in scene.coordinates if q in angles]
        name = table.get("coordinate", (preferred or list(scene.coordinates))[0])
        j = scene.coordinates.index(name) if name in scene.coordinates else 0
        shown = next(i for i in range(n) if i != j)
        return cls(j, float(table.get("value", 0.0)), shown)


def _quadratic_in_pj(compiled, section: Section, q_i, p_i):
    """Coefficients (a, b, c) of H = a p_j^2 + b p_j + c on the section, per (q_i, p_i)."""
    n = compiled.n
    q_i = np.atleast_1d(np.asarray(q_i, dtype=float))
    p_i = np.atleast_1d(np.asarray(p_i, dtype=float))
    states = np.zeros((3, len(q_i), 2 * n))
    states[:, :, section.shown] = q_i
    states[:, :, n + section.shown] = p_i
    states[:, :, section.coordinate] = section.value
    for row, pj in enumerate((-1.0, 0.0, 1.0)):
        states[row, :, n + section.coordinate] = pj
    with np.errstate(all="ignore"):  # H not finite (r = 0): the callers leave such points out
        H = compiled.hamiltonian(0.0, states.reshape(-1, 2 * n)).reshape(3, -1)
        a = 0.5 * (H[0] + H[2]) - H[1]
        b = 0.5 * (H[2] - H[0])
    return a, b, H[1]


def forbidden(compiled, section: Section, energy: float, q_i, p_i) -> np.ndarray:
    """True where no p_j reaches ``energy``: the energetically forbidden part of the plane.

    Points where H is not finite (a singular line such as r = 0) are forbidden too: no
    state can be put there.
    """
    a, b, c = _quadratic_in_pj(compiled, section, q_i, p_i)
    with np.errstate(all="ignore"):
        minimum = np.where(a > 0, c - b * b / (4 * a), -np.inf)
    finite = np.isfinite(a) & np.isfinite(b) & np.isfinite(c)
    return ~(finite & (minimum <= energy))


def state_on_section(compiled, section: Section, energy: float, q_i: float, p_i: float):
    """The state on the section at (q_i, p_i) with H = ``energy`` and p_j > 0, or None."""
    y = states_on_section(compiled, section, energy, [q_i], [p_i])[0]
    return None if np.isnan(y[0]) else y


def states_on_section(compiled, section: Section, energy: float, q_i, p_i) -> np.ndarray:
    """The states on the section at the points (q_i, p_i) with H = ``energy``, p_j > 0.

    Parameters
    ----------
    q_i, p_i : array_like, shape (N,)

    Returns
    -------
    ndarray, shape (N, 2n)
        A row of NaN where no p_j > 0 reaches ``energy`` (or H is not finite there).
    """
    a, b, c = _quadratic_in_pj(compiled, section, q_i, p_i)
    with np.errstate(all="ignore"):
        disc = b * b - 4 * a * (c - energy)
        p_j = (-b + np.sqrt(disc)) / (2 * a)
    good = np.isfinite(a) & np.isfinite(b) & np.isfinite(c) & (a > 0) & (disc >= 0) & (p_j > 0)
    n = compiled.n
    Y = np.zeros((len(a), 2 * n))
    Y[:, section.shown] = np.atleast_1d(np.asarray(q_i, dtype=float))
    Y[:, n + section.shown] = np.atleast_1d(np.asarray(p_i, dtype=float))
    Y[:, section.coordinate] = section.value
    Y[:, n + section.coordinate] = np.where(good, p_j, 0.0)
    Y = Y[good]
    j = n + section.coordinate
    for _ in range(3):  # polish, in case H is not exactly quadratic in p_j
        if not len(Y):
            break
        h = 1e-7 * np.maximum(1.0, np.abs(Y[:, j]))
        plus, minus = Y.copy(), Y.copy()
        plus[:, j] += h
        minus[:, j] -= h
        with np.errstate(all="ignore"):
            H = compiled.hamiltonian(0.0, np.concatenate([Y, plus, minus])).reshape(3, -1)
            slope = (H[1] - H[2]) / (2 * h)
            usable = (slope != 0) & np.isfinite(slope)
            Y[usable, j] -= (H[0, usable] - energy) / slope[usable]
    out = np.full((len(good), 2 * n), np.nan)
    out[good] = Y
    return out
