"""Which kernels a command's run uses: numba's machine code, or its plain-Python twin.

numba takes 5 to 15 s to compile a scene's kernels for one method, longer than many
runs take on the plain-Python twins (``systems.interpreted``). So ``run`` starts on the
twins, and after ``GRACE`` seconds estimates how long the rest would take on them: if
longer than ``COMPILE_SECONDS``, numba compiles the kernels there and then, and the run
goes on with the machine code from its next block. Kernels already in numba's on-disk
cache are loaded at once instead.

The compile runs in the run's own thread, not in the background: loading machine code
takes many short calls that each wait for the GIL, and beside a thread running the
twins the load of the double pendulum's took 10 s instead of 0.5 (and a child
process's compile 13 s instead of 6).
"""

from __future__ import annotations

import math
import time

import numpy as np

GRACE = 0.5
"""Seconds of a run on the plain-Python kernels before its remaining time is estimated."""

COMPILE_SECONDS = 5.0
"""Runs whose rest would take longer than this on the plain-Python kernels are compiled:
about what numba takes for a small scene's kernels of one method."""


class Kernels:
    """The kernels of one run: numba's from its cache, else the plain-Python twins until
    the run turns out long enough to be worth numba's compilation.

    Parameters
    ----------
    compiled : CompiledSystem
        From ``compile_system(..., interpreted_start=True)``.
    method : str
    diagnostics : sequence of str
        What the run computes besides the states (``systems.simulation.DIAGNOSTICS``).
    y0 : ndarray, shape (2n,)
    t0, t_end : float
        The run's span (``t_end`` inf for an endless run).
    """

    def __init__(self, compiled, method: str, diagnostics, y0, t0: float, t_end: float):
        self.compiled = compiled
        self.method = method
        self.diagnostics = tuple(diagnostics)
        self.y0 = np.asarray(y0, dtype=float)
        self.t0, self.t_end = float(t0), float(t_end)
        self._started = time.perf_counter()
        self._decided = False
        self._native_from: float | None = None
        self.compile_s = 0.0

    def start(self) -> None:
        """Load numba's kernels now if they are in its cache."""
        from systems.native_build import cached
        from systems.simulation import compile_natively

        self._started = time.perf_counter()
        if self.compiled.handed_over or cached(self.compiled, self.method):
            self.compile_s = compile_natively(self.compiled, self.method, self.diagnostics, self.y0)
            self._native_from = 0.0
            self._decided = True

    def poll(self, t: float) -> None:
        """After a sample at time ``t``: once, ``GRACE`` seconds into the run, compile
        numba's kernels if the rest of the run would take longer than ``COMPILE_SECONDS``
        on the plain-Python ones."""
        if self._decided:
            return
        elapsed = time.perf_counter() - self._started
        if elapsed < GRACE:
            return
        self._decided = True
        done = (t - self.t0) / (self.t_end - self.t0) if math.isfinite(self.t_end) else 0.0
        if done > 0.0 and elapsed * (1.0 - done) / done <= COMPILE_SECONDS:
            return
        from systems.simulation import compile_natively

        self.compile_s = compile_natively(self.compiled, self.method, self.diagnostics, self.y0)
        self._native_from = time.perf_counter() - self._started

    def description(self) -> str:
        """Which kernels ran: ``"numba"``, ``"plain Python"``, or ``"plain Python, then
        numba after 0.52 s"``."""
        if self._native_from == 0.0:
            return "numba"
        if self._native_from is None:
            return "plain Python (a short run: quicker than numba's compilation)"
        return f"plain Python, then numba after {self._native_from:.2g} s"
