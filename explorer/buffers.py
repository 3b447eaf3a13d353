"""Preallocated arrays that double when full, so appending a block never copies every frame.

As in pyqtgraph's ``examples/scrollingPlots.py``: the plot is handed a view of the filled
part (``buffer.data``), and the storage grows geometrically, so appending ``k`` rows costs
O(k) amortised however long the trace becomes.
"""

from __future__ import annotations

import numpy as np


class GrowingArray:
    """Rows of a fixed shape appended in blocks.

    Parameters
    ----------
    row_shape : tuple of int
        Shape of one row: ``()`` for scalars, ``(2n,)`` for states, ``(npoints, 2)``.
    capacity : int
        Rows allocated up front.
    fill : float
        Value of rows that were reserved with ``extend_missing`` (NaN: not computed).
    """

    def __init__(self, row_shape: tuple[int, ...] = (), capacity: int = 1024, fill=np.nan):
        self.row_shape = tuple(row_shape)
        self._data = np.empty((max(int(capacity), 1), *self.row_shape))
        self._size = 0
        self.fill = fill

    def __len__(self) -> int:
        return self._size

    @property
    def capacity(self) -> int:
        return len(self._data)

    @property
    def data(self) -> np.ndarray:
        """The filled rows, a view (no copy): shape ``(len(self), *row_shape)``."""
        return self._data[: self._size]

    def _reserve(self, extra: int) -> None:
        needed = self._size + extra
        if needed <= len(self._data):
            return
        capacity = len(self._data)
        while capacity < needed:
            capacity *= 2
        grown = np.empty((capacity, *self.row_shape))
        grown[: self._size] = self._data[: self._size]
        self._data = grown

    def extend(self, rows: np.ndarray) -> None:
        """Append rows of shape ``(k, *row_shape)``."""
        rows = np.asarray(rows, dtype=float).reshape((-1, *self.row_shape))
        self._reserve(len(rows))
        self._data[self._size : self._size + len(rows)] = rows
        self._size += len(rows)

    def extend_missing(self, count: int) -> None:
        """Append ``count`` rows of ``fill`` (values that were not computed)."""
        self._reserve(count)
        self._data[self._size : self._size + count] = self.fill
        self._size += count

    def clear(self) -> None:
        self._size = 0
