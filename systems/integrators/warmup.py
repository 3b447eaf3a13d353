"""Start numba's compiler machinery before the first scene opens.

The first compiled function a process loads or compiles pays a fixed start-up of about
half a second (numba initialising its CPU target and registries). ``warm_numba`` pays it
up front; the application runs it in a background thread while its window appears
(``warm_in_background``), so that opening a scene costs only that scene's own kernels.
"""

from __future__ import annotations

import threading

import numpy as np

_warm = threading.Event()
_started = threading.Lock()
_thread: threading.Thread | None = None


def warm_numba() -> None:
    """Initialise numba's CPU target by compiling a trivial array function (no cache)."""
    if _warm.is_set():
        return
    from numba import njit

    @njit(nogil=True)
    def _touch(a):
        s = 0.0
        for i in range(a.shape[0]):
            s += a[i]
        return s

    _touch(np.zeros(2))
    _warm.set()


def numba_is_warm() -> bool:
    """True once ``warm_numba`` has finished in this process."""
    return _warm.is_set()


def warm_in_background() -> threading.Thread:
    """Run ``warm_numba`` in a daemon thread, once per process; returns that thread."""
    global _thread
    with _started:
        if _thread is None:
            _thread = threading.Thread(target=warm_numba, name="numba-warm-up", daemon=True)
            _thread.start()
        return _thread
