"""Unbounded motion: a coordinate that grows by orders of magnitude, and how fast.

A ``GrowthWatch`` follows a run's coordinates block by block and records when each first
passed 10, 100, 1000, ... times its start scale (the larger of its start value, the
largest start coordinate and 1; angles are not watched: they wind). Exponential growth
crosses the decades at even intervals (e^(lambda t): one every ln 10 / lambda), a power
law at ever longer ones (t^a: each a factor 10^(1/a) longer), a blow-up in finite time at
ever shorter ones. A coordinate ``UNBOUNDED_GROWTH`` times its start scale whose last
decades came at intervals that do not lengthen (the last at most ``STEADY`` times the
earliest of the last three) is moving off to infinity, if the equations agree: an
accurate run from there over one decade's time grows too (``Run`` checks; a method
unstable at its step grows at even intervals as well, but the motion it misses does
not). ``Run`` stops it as
``"unbounded"`` while its guard is on, and a run that overflows or trips the energy guard
after such growth is reported as unbounded too, not as a step too long or a singularity
(a bead on a rotating wire, r = cosh(w t), tripped the guard at t = 14 on round-off of
its huge kinetic and potential energies).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

UNBOUNDED_GROWTH = 1e6
"""A coordinate this many times its start scale, grown steadily: the run stops."""
GROWN_AT_STOP = 1e3
"""A run stopped otherwise (overflow, energy guard) after growth by this much: unbounded."""
MAX_DECADES = 308
"""Decades recorded at most: 10.0 ** 309 is past the largest double (Python raises
OverflowError there; a state of 1e308 times its scale had crashed the watch)."""
STEADY = 2.0
"""The last of the last three decade intervals at most this times the first: steady."""


@dataclass(frozen=True)
class Growth:
    """A coordinate that grew without bound.

    Attributes
    ----------
    name : str
    value : float
        Its value where the verdict was reached.
    t : float
    start : float
        The scale it is measured against (its start value, at least 1).
    rate : float
        lambda of e^(lambda t) over the last decades (inf: faster than the states show).
    index : int
        The coordinate's place in the state.
    """

    name: str
    value: float
    t: float
    start: float
    rate: float
    index: int = 0

    def sentence(self) -> str:
        """``"r grew to 1e+06 by t = 14.5 (from 1), like e^(1 t): the motion is unbounded"``"""
        like = (
            f"like e^({self.rate:.3g} t)"
            if math.isfinite(self.rate)
            else "faster than the states show"
        )
        return (
            f"{self.name} grew to {self.value:.3g} by t = {self.t:.6g} (from a scale of "
            f"{self.start:.3g}), {like}: the motion is unbounded"
        )

    def as_dict(self) -> dict:
        return {
            "coordinate": self.name,
            "value": self.value,
            "t": self.t,
            "start_scale": self.start,
            "rate": self.rate if math.isfinite(self.rate) else None,
        }


class GrowthWatch:
    """The decades each watched coordinate has passed, from the blocks of one run.

    Parameters
    ----------
    names : sequence of str
        The coordinates, in state order (the state is ``(q, p)``).
    y0 : ndarray, shape (2n,)
    angles : sequence of bool, optional
        Coordinates not to watch.
    """

    def __init__(self, names, y0: np.ndarray, angles=None):
        n = len(names)
        q0 = np.abs(np.asarray(y0, dtype=float)[:n])
        q0 = np.where(np.isfinite(q0), q0, 0.0)
        floor = max(float(q0.max(initial=0.0)), 1.0)
        self.names = tuple(names)
        self.scale = np.maximum(q0, floor)
        flags = np.zeros(n, bool) if angles is None else np.asarray(angles, bool)
        self.watched = [i for i in range(n) if not flags[i]]
        self.crossed: list[list[float]] = [[] for _ in range(n)]

    def update(self, t: np.ndarray, y: np.ndarray, at_least: float = UNBOUNDED_GROWTH):
        """Record the decades passed in a block; the first row where a coordinate is
        ``at_least`` times its scale, grown steadily, as (row, ``Growth``), else None."""
        found = None
        if not len(t) or not self.watched:
            return None
        watched = self.watched
        # fmax passes NaN by (a row of NaN cannot hide a decade another row passed)
        tops = np.fmax.reduce(np.abs(y[:, watched]), axis=0) / self.scale[watched]
        for i, top in zip(watched, tops.tolist(), strict=True):
            crossed = self.crossed[i]
            if not top >= 10.0 ** (len(crossed) + 1):  # no new decade (or not finite)
                continue
            size = np.abs(y[:, i]) / self.scale[i]
            size = np.where(np.isfinite(size), size, 0.0)
            top = float(size.max())
            while len(crossed) < MAX_DECADES and top >= 10.0 ** (len(crossed) + 1):
                level = 10.0 ** (len(crossed) + 1)
                row = int(np.argmax(size >= level))
                crossed.append(float(t[row]))
                if level >= at_least and (found is None or row < found[0]):
                    growth = self._verdict(i, float(y[row, i]), float(t[row]))
                    if growth is not None:
                        found = (row, growth)
        return found

    def grown(self, t: float, y: np.ndarray, at_least: float = GROWN_AT_STOP) -> Growth | None:
        """The coordinate grown steadily by ``at_least`` or more at the state ``(t, y)``
        (the one grown most), else None."""
        best = None
        for i in self.watched:
            if len(self.crossed[i]) < math.log10(at_least) - 1e-9:
                continue
            growth = self._verdict(i, float(y[i]), t)
            if growth is not None and (best is None or len(self.crossed[i]) > best[0]):
                best = (len(self.crossed[i]), growth)
        return None if best is None else best[1]

    def _verdict(self, i: int, value: float, t: float) -> Growth | None:
        times = self.crossed[i][-4:]
        if len(times) < 3:
            return None
        gaps = np.diff(times)
        first, last = float(gaps[0]), float(gaps[-1])
        if last > STEADY * first:
            return None  # the decades come ever more slowly: a power law, not unbounded yet
        span = times[-1] - times[0]
        rate = len(gaps) * math.log(10.0) / span if span > 0 else math.inf
        return Growth(self.names[i], value, t, float(self.scale[i]), rate, i)
