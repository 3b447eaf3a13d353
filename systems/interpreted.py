"""Kernels that run as plain Python until numba has compiled them.

Numba compiles a scene's kernel module in one to two seconds the first time it is opened.
So that the first block does not wait for it, ``KernelHandover`` runs the *same source*
as plain Python meanwhile, and switches to numba's machine code once ``hand_over`` is
called (by ``systems.simulation.compile_natively``, usually from a background thread):

- a *scalar twin*: the generated module executed with ``njit`` as the identity, so every
  stepper template runs unchanged, about 100 times slower than compiled;
- a *vector twin*: the system functions executed with numpy in place of ``math``, so the
  ``*_batch`` functions (energy on a level-set grid, drawing points of a block) evaluate
  whole arrays at once.

Whatever the interpreter would do differently from numba (a float exception, a domain
error, a non-finite batch value) is never returned: the arrays the call received are
restored and the call is repeated by the numba kernel itself, compiling it on the spot if
need be. Results before the hand-over therefore agree with numba's to round-off.
"""

from __future__ import annotations

import math
import threading
from pathlib import Path
from types import ModuleType

import numpy as np

from systems.codegen import execute, kernel_prefix

NUMBA_IMPORT = "from numba import njit, prange\n"
MATH_IMPORT = "import math\n"
SCALAR_PRELUDE = "def njit(**options):\n    return lambda function: function\n\n\nprange = range\n"
VECTOR_BATCH = """
def hamiltonian_batch(ts, Y, P, out):
    out[:] = hamiltonian(ts, Y.T, P)


def velocities_batch(ts, Y, P, out):
    velocities(ts, Y.T, P, out.T)


def momenta_batch(ts, Q, Qdot, P, out):
    momenta(ts, Q.T, Qdot.T, P, out.T)


def drawing_batch(ts, Y, P, out):
    drawing(ts, Y.T, P, out.transpose(1, 2, 0))
"""
_NUMPY_NAMES = {
    "asin": "arcsin",
    "acos": "arccos",
    "atan": "arctan",
    "atan2": "arctan2",
    "asinh": "arcsinh",
    "acosh": "arccosh",
    "atanh": "arctanh",
    "fabs": "abs",
    "pow": "power",
}


class _VectorMath:
    """``math`` with numpy's element-wise functions (``math.erf`` and the like vectorised)."""

    pi, e, tau, inf, nan = math.pi, math.e, math.tau, math.inf, math.nan

    def __getattr__(self, name: str):
        function = getattr(np, _NUMPY_NAMES.get(name, name), None)
        if function is None:
            function = np.vectorize(getattr(math, name), otypes=[float])
        setattr(self, name, function)
        return function


def _execute(source: str, name: str, path: str, prefix: str = "") -> ModuleType:
    module = ModuleType(name)
    module.__file__ = path
    execute(source, path, module.__dict__, prefix)
    return module


def scalar_twin(native: ModuleType) -> ModuleType:
    """The generated module ``native`` executed as plain Python (``njit`` is the identity)."""
    path = native.__file__
    # the source that was verified and run (systems.codegen), never the file read again
    source = getattr(native, "__phase_explorer_source__", None) or Path(path).read_text()
    if NUMBA_IMPORT not in source:
        raise RuntimeError(f"{path} does not import numba as systems.codegen writes it")
    source = source.replace(NUMBA_IMPORT, SCALAR_PRELUDE, 1)
    prefix = kernel_prefix().replace(NUMBA_IMPORT, SCALAR_PRELUDE, 1)
    module = _execute(source, native.__name__ + "_scalar", path, prefix)
    if hasattr(module, "solve_augmented"):
        # the velocity solve of a system in matrix form: LAPACK instead of the kernels'
        # loops, which in plain Python cost milliseconds a call for ten coordinates
        module.solve_augmented = _solve_augmented_numpy
    return module


def _solve_augmented_numpy(W: np.ndarray, n: int) -> None:
    """``systems.matrix_solve.solve_augmented`` by numpy (same result to round-off)."""
    W[:, n] = np.linalg.solve(W[:, :n], W[:, n])


def vector_twin(native: ModuleType, system_source: str) -> ModuleType:
    """The system functions of ``system_source`` on arrays, with vectorised batch functions.

    Parameters
    ----------
    native : module
        The numba module (for its name and file, shown in tracebacks).
    system_source : str
        The printed system functions alone (no stepper templates).
    """
    source = "import numpy as np\n\n" + system_source + "\n" + VECTOR_BATCH
    module = _execute(source, native.__name__ + "_vector", native.__file__)
    module.math = _VectorMath()
    return module


def _arrays(args) -> list[tuple[np.ndarray, np.ndarray]]:
    return [(a, a.copy()) for a in args if isinstance(a, np.ndarray) and a.flags.writeable]


def _restore(saved) -> None:
    for array, copy in saved:
        array[...] = copy


class KernelHandover:
    """A kernel module that is plain Python until ``hand_over``, numba's afterwards.

    Attribute access returns the function to call now: numba's dispatcher once handed
    over; before that, a guarded plain-Python function (batch functions vectorised).

    Parameters
    ----------
    native : module
        The numba module from ``systems.codegen.build_module``.
    system_source : str
        The printed system functions (for the vector twin).
    """

    def __init__(self, native: ModuleType, system_source: str):
        self.native = native
        self._system_source = system_source
        self._twins: tuple[ModuleType, ModuleType] | None = None
        self._lock = threading.Lock()
        self._ready = threading.Event()
        self._guarded: dict[str, object] = {}
        self.error: BaseException | None = None

    def twins(self) -> tuple[ModuleType, ModuleType]:
        """The scalar and vector twins, executed on first use (tens of ms of compiling)."""
        with self._lock:
            if self._twins is None:
                native, source = self.native, self._system_source
                self._twins = (scalar_twin(native), vector_twin(native, source))
            return self._twins

    @property
    def handed_over(self) -> bool:
        return self._ready.is_set()

    def hand_over(self) -> None:
        """From now on every call goes to numba's compiled kernels."""
        self._ready.set()

    def __getattr__(self, name: str):
        if name.startswith("__"):
            raise AttributeError(name)
        if self._ready.is_set():
            return getattr(self.native, name)
        guarded = self._guarded.get(name)
        if guarded is None:
            guarded = self._guard(name)
            self._guarded[name] = guarded
        return guarded

    def _guard(self, name: str):
        scalar, vectorised = self.twins()
        python = getattr(scalar, name)
        if not callable(python):
            return python
        native = getattr(self.native, name)
        vector = getattr(vectorised, name, None) if name.endswith("_batch") else None

        def scalar_call(*args):
            saved = _arrays(args)
            try:
                with np.errstate(all="raise", under="ignore"):
                    return python(*args)
            except (ArithmeticError, ValueError, TypeError):
                _restore(saved)
                return native(*args)

        if vector is None:
            scalar_call.__name__ = name
            return scalar_call

        def batch_call(*args):
            out = args[-1]
            try:
                with np.errstate(all="ignore"):
                    vector(*args)
                if np.all(np.isfinite(out)):
                    return None
            except Exception:  # noqa: BLE001 - a form numpy cannot broadcast: go point by point
                pass
            return scalar_call(*args)

        batch_call.__name__ = name
        return batch_call
