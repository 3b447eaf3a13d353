"""Start numba's compiler machinery before the first scene opens.

The first compiled function a process loads or compiles pays a fixed start-up of about
half a second (numba initialising its CPU target and registries). ``warm_numba`` pays it
up front, e.g. in a background thread while the application's window appears, so that
opening the first scene costs only that scene's own kernels.
"""

from __future__ import annotations

import numpy as np


def warm_numba() -> None:
    """Initialise numba's CPU target by compiling a trivial array function (no cache)."""
    from numba import njit

    @njit(nogil=True)
    def _touch(a):
        s = 0.0
        for i in range(a.shape[0]):
            s += a[i]
        return s

    _touch(np.zeros(2))
