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
"""

from __future__ import annotations

import math

import numpy as np

from explorer.buffers import GrowingArray

ENVELOPE_BINS = 8192
"""Bins per time since the start, at least, that a block's bins are cut to."""
CAPACITY = 2 * ENVELOPE_BINS
"""Bins one trajectory's envelope keeps at most (pairs are merged beyond)."""
MIN_EXPONENT = -60
INDEX, TIME, H_LOW, H_HIGH, ERROR_LOW, ERROR_HIGH, GAP = range(7)
COLUMNS = 7


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


def _merge_groups(rows: np.ndarray) -> np.ndarray:
    """Rows with equal consecutive ``INDEX`` merged into one: the first's time and gap,
    the lowest lows and highest highs."""
    if len(rows) < 2:
        return rows
    starts = np.concatenate([[0], np.flatnonzero(rows[1:, INDEX] != rows[:-1, INDEX]) + 1])
    if len(starts) == len(rows):
        return rows
    out = rows[starts].copy()
    for column in (H_LOW, ERROR_LOW):
        out[:, column] = np.minimum.reduceat(rows[:, column], starts)
    for column in (H_HIGH, ERROR_HIGH):
        out[:, column] = np.maximum.reduceat(rows[:, column], starts)
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

    def __init__(self, capacity: int = CAPACITY):
        self.capacity = max(int(capacity), 4)
        self.exponent: int | None = None
        self.rows = GrowingArray((COLUMNS,), capacity=256)
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
        rows = np.asarray(rows, dtype=float).reshape(-1, COLUMNS)
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
            last[H_LOW] = min(last[H_LOW], rows[0, H_LOW])
            last[ERROR_LOW] = min(last[ERROR_LOW], rows[0, ERROR_LOW])
            last[H_HIGH] = max(last[H_HIGH], rows[0, H_HIGH])
            last[ERROR_HIGH] = max(last[ERROR_HIGH], rows[0, ERROR_HIGH])
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

    def polyline(self, error: bool, scale: float = 1.0, floor: float = 0.0):
        """What to draw, as pyqtgraph's 'peak' downsampling does: each bin a vertical
        from its lowest to its highest value at its first time, a NaN row before a bin
        that follows a gap.

        Parameters
        ----------
        error : bool
            ``|H - H0| / scale`` (at least ``floor``), else H.

        Returns
        -------
        x, y : ndarray, shape (2 b + gaps,)
        """
        bins = self.rows.data
        low, high = (ERROR_LOW, ERROR_HIGH) if error else (H_LOW, H_HIGH)
        values = np.stack([bins[:, low], bins[:, high]], axis=1)
        if error:
            values = np.maximum(values / scale, floor)
        x = np.repeat(bins[:, TIME], 2)
        y = values.ravel()
        gaps = np.flatnonzero(bins[:, GAP] > 0)
        gaps = gaps[gaps > 0]
        if len(gaps):
            x = np.insert(x, 2 * gaps, x[2 * gaps])
            y = np.insert(y, 2 * gaps, np.nan)
        return x, y
