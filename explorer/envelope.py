"""Min/max envelopes of H over every step, in time bins: what the energy plots draw.

The worker hands the store a bounded number of states a second; H at those states alone
is a sparse sample of a quantity that changes at every step (an energy error is
round-off at the step's scale), and a line through sparse samples is a sawtooth that
hides the extremes. So the worker evaluates H at every step of every block (before the
states are thinned) and sums it up per time bin: bin ``j`` of exponent ``e`` holds the
steps with ``j <= (t - t0) / 2**e < j + 1``, their first time, the lowest and highest H
and the lowest and highest ``|H - H0|`` (``H0`` at the orbit's start). The bins of a block
are at most ``1 / ENVELOPE_BINS`` of the time since the start wide, so the whole history
drawn across a plot's width keeps several bins per pixel column.

``Envelope`` keeps bins of one exponent; a piece of finer bins is merged into it (the
grids are nested: powers of two from the same ``t0``), a coarser one makes it coarsen
first. Past ``capacity`` bins, pairs of neighbouring bins are merged (the exponent goes
up by one), so memory stays bounded however long the run, and every step's value stays
inside its bin's range. A bin whose ``gap`` is set follows steps that were not summed
up (H was not wanted while its plot was hidden): the plot draws a break before it.

The conserved momenta are summed up the same way (``summarize_series``, an ``Envelope``
of ``quantities`` columns: each bin the lowest and highest value of every conserved
momentum and Noether charge, ``conserved_quantities``), so that their plot at full speed
shows every step too. An envelope's row is its index, first time, the lowest and highest
of each quantity in turn, and the gap flag last: H's is the envelope of two quantities,
H and ``|H - H0|``.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from explorer.buffers import GrowingArray

ENVELOPE_BINS = 8192
"""Bins per time since the start, at least, that a block's bins are cut to."""
CAPACITY = 2 * ENVELOPE_BINS
"""Bins one trajectory's envelope keeps at most (pairs are merged beyond)."""
MIN_EXPONENT = -60
INDEX, TIME, H_LOW, H_HIGH, ERROR_LOW, ERROR_HIGH, GAP = range(7)
COLUMNS = 7


MOMENTA = "momenta"
"""The diagnostic that asks the worker for the conserved momenta's envelope."""


def conserved_quantities(compiled) -> list[tuple[str, Callable]]:
    """The conserved momenta the conserved view draws, in its order: each cyclic
    coordinate's ``p_q`` (a state component), then each Noether charge
    (``systems.symmetries.charge_functions``); each as ``f(t, Y) -> (k,)`` for times
    (k,) and states (k, 2n). Called on the GUI thread (the charges' functions are made
    there by sympy once per system)."""
    from systems.symmetries import charge_functions

    mechanics = compiled.mechanics
    coordinates = list(mechanics.scene.coordinates)
    n = len(coordinates)
    found: list[tuple[str, Callable]] = []
    for name in mechanics.conserved:
        if name.startswith("p_") and name[2:] in coordinates:
            column = n + coordinates.index(name[2:])
            found.append((name, lambda t, Y, column=column: Y[:, column]))
    for name, function in charge_functions(mechanics).items():
        found.append((name, lambda t, Y, f=function: f(t, Y, compiled.parameters)))
    return found


def bin_exponent(span: float) -> int:
    """The exponent of bins at most ``span / ENVELOPE_BINS`` wide (``span`` > 0)."""
    if not span > 0 or not math.isfinite(span):
        return MIN_EXPONENT
    return max(math.floor(math.log2(span / ENVELOPE_BINS)), MIN_EXPONENT)


def summarize(t: np.ndarray, H: np.ndarray, t0: float, H0: float, exponent: int) -> np.ndarray:
    """Bins of the steps (t, H), rows of ``COLUMNS`` (no gap set); non-finite H left out.

    Parameters
    ----------
    t, H : ndarray, shape (k,)
        Times (nondecreasing) and H of the steps.
    t0, H0 : float
        The orbit's start and H there.
    exponent : int
        Bins are ``2**exponent`` wide, counted from ``t0``.

    Returns
    -------
    ndarray, shape (b, COLUMNS)
    """
    t = np.asarray(t, dtype=float)
    H = np.asarray(H, dtype=float)
    good = np.isfinite(H) & np.isfinite(t)
    t, H = t[good], H[good]
    if not len(t):
        return np.empty((0, COLUMNS))
    index = np.floor(np.ldexp(t - t0, -exponent))
    starts = np.concatenate([[0], np.flatnonzero(index[1:] != index[:-1]) + 1])
    error = np.abs(H - H0)
    out = np.empty((len(starts), COLUMNS))
    out[:, INDEX] = index[starts]
    out[:, TIME] = t[starts]
    out[:, H_LOW] = np.minimum.reduceat(H, starts)
    out[:, H_HIGH] = np.maximum.reduceat(H, starts)
    out[:, ERROR_LOW] = np.minimum.reduceat(error, starts)
    out[:, ERROR_HIGH] = np.maximum.reduceat(error, starts)
    out[:, GAP] = 0.0
    return out


def summarize_series(t: np.ndarray, values: np.ndarray, t0: float, exponent: int) -> np.ndarray:
    """Bins of the steps ``t`` with ``values`` of shape (k, m) (m quantities), rows of
    ``2 + 2 m + 1`` columns (no gap set); a non-finite value is left out of its bin (a
    bin where a quantity has none holds NaN for it).

    Parameters
    ----------
    t : ndarray, shape (k,)
        Times of the steps, nondecreasing.
    values : ndarray, shape (k, m)
    t0 : float
        The orbit's start.
    exponent : int
        Bins are ``2**exponent`` wide, counted from ``t0``.
    """
    t = np.asarray(t, dtype=float)
    values = np.asarray(values, dtype=float).reshape(len(t), -1)
    good = np.isfinite(t)
    t, values = t[good], values[good]
    quantities = values.shape[1]
    if not len(t):
        return np.empty((0, 3 + 2 * quantities))
    index = np.floor(np.ldexp(t - t0, -exponent))
    starts = np.concatenate([[0], np.flatnonzero(index[1:] != index[:-1]) + 1])
    out = np.empty((len(starts), 3 + 2 * quantities))
    out[:, INDEX] = index[starts]
    out[:, TIME] = t[starts]
    with np.errstate(invalid="ignore"):
        out[:, 2:-1:2] = np.fmin.reduceat(values, starts, axis=0)
        out[:, 3:-1:2] = np.fmax.reduceat(values, starts, axis=0)
    out[:, -1] = 0.0
    return out


def _merge_groups(rows: np.ndarray) -> np.ndarray:
    """Rows with equal consecutive ``INDEX`` merged into one: the first's time and gap,
    the lowest lows and highest highs."""
    if len(rows) < 2:
        return rows
    starts = np.concatenate([[0], np.flatnonzero(rows[1:, INDEX] != rows[:-1, INDEX]) + 1])
    if len(starts) == len(rows):
        return rows
    out = rows[starts].copy()
    with np.errstate(invalid="ignore"):
        out[:, 2:-1:2] = np.fmin.reduceat(rows[:, 2:-1:2], starts, axis=0)
        out[:, 3:-1:2] = np.fmax.reduceat(rows[:, 3:-1:2], starts, axis=0)
    return out


class Envelope:
    """Bins of one exponent, in time order (see the module's docstring).

    Attributes
    ----------
    exponent : int or None
        Bins are ``2**exponent`` wide (None: no bin yet).
    revision : int
        Raised when bins were merged in pairs (every row may have changed).
    version : int
        Raised at every change (the last bin may change in place).
    """

    def __init__(self, capacity: int = CAPACITY, quantities: int = 2):
        self.capacity = max(int(capacity), 4)
        self.quantities = quantities
        self.exponent: int | None = None
        self.rows = GrowingArray((3 + 2 * quantities,), capacity=256)
        self.revision = 0
        self.version = 0

    def __len__(self) -> int:
        return len(self.rows)

    @property
    def data(self) -> np.ndarray:
        """The bins, shape (b, COLUMNS) (a view)."""
        return self.rows.data

    def add(self, exponent: int, rows: np.ndarray) -> None:
        """Merge bins of ``exponent`` (rows of ``COLUMNS``, later than those held)."""
        rows = np.asarray(rows, dtype=float).reshape(-1, 3 + 2 * self.quantities)
        if not len(rows):
            return
        if self.exponent is None:
            self.exponent = exponent
        if exponent > self.exponent:
            self._coarsen(exponent)
        rows = rows.copy()
        rows[:, INDEX] = np.floor(np.ldexp(rows[:, INDEX], exponent - self.exponent))
        rows = _merge_groups(rows)
        held = self.rows.data
        if len(held) and held[-1, INDEX] == rows[0, INDEX]:
            last = held[-1]
            with np.errstate(invalid="ignore"):
                last[2:-1:2] = np.fmin(last[2:-1:2], rows[0, 2:-1:2])
                last[3:-1:2] = np.fmax(last[3:-1:2], rows[0, 3:-1:2])
            rows = rows[1:]
        self.rows.extend(rows)
        while len(self.rows) > self.capacity:
            self._coarsen(self.exponent + 1)
        self.version += 1

    def extend(self, other: Envelope) -> None:
        """Merge the bins of ``other`` (later than those held)."""
        if other.exponent is not None:
            self.add(other.exponent, other.data)

    def _coarsen(self, exponent: int) -> None:
        rows = self.rows.data.copy()
        rows[:, INDEX] = np.floor(np.ldexp(rows[:, INDEX], self.exponent - exponent))
        self.exponent = exponent
        self.rows.clear()
        self.rows.extend(_merge_groups(rows))
        self.revision += 1

    def clear(self) -> None:
        self.rows.clear()
        self.exponent = None
        self.revision += 1
        self.version += 1

    def width(self) -> float:
        """The bins' width in time (inf with no bin)."""
        return math.inf if self.exponent is None else math.ldexp(1.0, self.exponent)

    def polyline(
        self,
        error: bool = False,
        scale: float = 1.0,
        floor: float = 0.0,
        quantity: int | None = None,
    ):
        """What to draw, as pyqtgraph's 'peak' downsampling does: each bin a vertical
        from its lowest to its highest value at its first time, a NaN row before a bin
        that follows a gap.

        Parameters
        ----------
        error : bool
            ``|H - H0| / scale`` (at least ``floor``), else H.
        quantity : int, optional
            Of an envelope of several quantities: that one's (``error`` is then ignored).

        Returns
        -------
        x, y : ndarray, shape (2 b + gaps,)
        """
        bins = self.rows.data
        if quantity is not None:
            low, high = 2 + 2 * quantity, 3 + 2 * quantity
            error = False
        else:
            low, high = (ERROR_LOW, ERROR_HIGH) if error else (H_LOW, H_HIGH)
        values = np.stack([bins[:, low], bins[:, high]], axis=1)
        if error:
            values = np.maximum(values / scale, floor)
        x = np.repeat(bins[:, TIME], 2)
        y = values.ravel()
        gaps = np.flatnonzero(bins[:, -1] > 0)
        gaps = gaps[gaps > 0]
        if len(gaps):
            x = np.insert(x, 2 * gaps, x[2 * gaps])
            y = np.insert(y, 2 * gaps, np.nan)
        return x, y
