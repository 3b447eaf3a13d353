"""Compile a scene's kernels with numba in another process, then hand them over.

A system compiled with ``interpreted_start`` streams at once from its plain-Python twin
(``systems.interpreted``). Numba then has to compile the real kernels, one to two seconds
of mostly Python work. In a thread of the same process that work and the interpreted
stream fight for the GIL (numba's many short calls into LLVM each wait for the GIL), and
the compile took 8 to 14 s instead of 1.5. So ``compile_in_background`` compiles in a
child process, ``python -m systems.native_build``, which writes numba's on-disk cache;
this process then only loads the machine code from it (tens of milliseconds) and calls
``hand_over``. A scene whose kernels are already in the cache skips the child.

One child at a time: a newer request replaces any that has not started yet.
"""

from __future__ import annotations

import atexit
import contextlib
import dataclasses
import os
import pickle
import subprocess
import sys
import threading
from pathlib import Path

import numpy as np

from systems.cache_integrity import verify_numba_caches
from systems.codegen import cache_dir

ROOT = Path(__file__).resolve().parent.parent
CHILD_TIMEOUT = 300.0
LOAD_SWITCH_INTERVAL = 2e-4
"""Seconds between the interpreter's GIL hand-offs while numba loads machine code beside a
running thread (Python's default is 5e-3). Loading makes thousands of short calls that
each wait for the GIL; beside the interpreted stream a double pendulum's load took 9.3 s
at the default and 1.3 s at 2e-4 (0.4 s alone)."""


@dataclasses.dataclass
class _Job:
    compiled: object
    method: str
    diagnostics: tuple[str, ...]
    y0: np.ndarray | None
    done: threading.Event = dataclasses.field(default_factory=threading.Event)
    cancelled: bool = False  # nobody waits for it: no child, nothing loaded here


class _NativeBuilder:
    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._pending: list[_Job] = []
        self._thread: threading.Thread | None = None
        self._child: subprocess.Popen | None = None
        self._current: _Job | None = None

    def submit(self, job: _Job) -> None:
        with self._lock:
            for stale in self._pending:
                stale.done.set()  # replaced before it started: it stays interpreted
            self._pending = [job]
            if self._thread is None or not self._thread.is_alive():
                self._thread = threading.Thread(
                    target=self._work, name="numba-native-build", daemon=True
                )
                self._thread.start()

    def _work(self) -> None:
        while True:
            with self._lock:
                if not self._pending:
                    self._thread = None
                    self._current = None
                    return
                job = self._current = self._pending.pop(0)
            try:
                self._build(job)
            except Exception as exc:  # noqa: BLE001 - the interpreted kernels keep working
                job.compiled.kernels.error = exc
            finally:
                job.done.set()

    def _build(self, job: _Job) -> None:
        compiled = job.compiled
        if not job.cancelled and not cached(compiled, job.method):
            self._run_child(job)  # if it fails, numba compiles here below instead
        if job.cancelled:  # its child was killed: nothing is compiled in this process
            return
        _load(compiled, job.method, job.diagnostics, job.y0)

    def _run_child(self, job: _Job) -> None:
        compiled = job.compiled
        payload = pickle.dumps(
            {
                "mechanics": dataclasses.replace(compiled.mechanics, _cache={}),
                "wanted": sorted(compiled.wanted),
                "parameters": compiled.parameters.tolist(),
                "method": job.method,
                "diagnostics": list(job.diagnostics),
                "y0": None if job.y0 is None else np.asarray(job.y0, dtype=float).tolist(),
                "module": compiled.kernels.native.__name__,
            }
        )
        env = dict(os.environ)
        env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(ROOT), env.get("PYTHONPATH")]))
        env["PHASE_EXPLORER_CACHE"] = str(cache_dir().parent)  # this process's, or its stand-in
        try:
            child = subprocess.Popen(
                [sys.executable, "-m", "systems.native_build"],
                stdin=subprocess.PIPE,
                stdout=subprocess.PIPE,
                stderr=subprocess.PIPE,
                env=env,
                cwd=str(ROOT),
            )
        except OSError:
            return  # no child: numba compiles in this process instead
        self._child = child
        if job.cancelled:  # cancelled while it was starting
            child.kill()
        try:
            _, stderr = child.communicate(payload, timeout=CHILD_TIMEOUT)
        except subprocess.TimeoutExpired:
            child.kill()
            _, stderr = child.communicate()
        finally:
            self._child = None
        for line in stderr.decode(errors="replace").splitlines():
            if line.startswith("phase-explorer: "):  # a cache entry the child rebuilt
                print(line, file=sys.stderr, flush=True)

    def stop_child(self) -> None:
        child = self._child
        if child is not None and child.poll() is None:
            child.kill()

    def cancel(self) -> None:
        """Drop the pending jobs and end the current one: its child is killed and nothing
        is compiled in this process instead. A load of numba's code already under way in
        this process (tens of ms) goes on: numba cut short stays broken."""
        with self._lock:
            for job in self._pending:
                job.cancelled = True
                job.done.set()
            self._pending = []
            if self._current is not None:
                self._current.cancelled = True
        self.stop_child()


_switch_lock = threading.Lock()
_loading = 0


@contextlib.contextmanager
def _quick_gil_hand_offs():
    """``LOAD_SWITCH_INTERVAL`` while any load runs, the previous interval after."""
    global _loading
    with _switch_lock:
        if _loading == 0:
            _quick_gil_hand_offs.previous = sys.getswitchinterval()
            sys.setswitchinterval(min(_quick_gil_hand_offs.previous, LOAD_SWITCH_INTERVAL))
        _loading += 1
    try:
        yield
    finally:
        with _switch_lock:
            _loading -= 1
            if _loading == 0:
                sys.setswitchinterval(_quick_gil_hand_offs.previous)


def _load(compiled, method: str, diagnostics, y0) -> None:
    """numba's compile (or load from its cache) of the kernels, then the hand-over."""
    from systems.simulation import compile_natively

    with _quick_gil_hand_offs():
        compile_natively(compiled, method, diagnostics, y0)


_builder = _NativeBuilder()
atexit.register(_builder.stop_child)


def cached(compiled, method: str) -> bool:
    """True if numba's on-disk cache holds machine code for ``method``'s loop of this scene.

    Reads the cache index of the loop's dispatcher (numba's ``IndexDataCacheFile``) after
    checking the checksums of all the module's cache entries (a damaged one is deleted and
    reported, and the child compiles it again); any surprise in numba's internals counts
    as not cached, which only costs a child process.
    """
    from systems.integrators import get_stepper

    loop = get_stepper(method).family.run_kernel
    if loop is None:
        return True  # scipy's solvers: only the right-hand side is numba's, and it is small
    native = compiled.native().kernels
    try:
        sound = verify_numba_caches(native)
        return sound and bool(getattr(native, loop)._cache._cache_file._load_index())
    except Exception:  # noqa: BLE001 - private numba API; fall back to compiling in a child
        return False


def compile_in_background(
    compiled, method: str, diagnostics=(), y0: np.ndarray | None = None
) -> threading.Event:
    """Compile ``compiled``'s native kernels for ``method`` away from this process's GIL.

    Parameters
    ----------
    compiled : CompiledSystem
        From ``compile_system(..., interpreted_start=True)``; for any other system the
        kernels are compiled in a background thread of this process.
    method : str
    diagnostics : sequence of {"H", "qdot", "points"}
    y0 : ndarray, shape (2n,), optional

    A scene whose machine code is in numba's cache, once numba has started
    (``systems.integrators.warmup``), is loaded here and now instead.

    Returns
    -------
    threading.Event
        Set when the work is over: handed over, or failed (``compiled.kernels.error``),
        or replaced by a newer request before it started.
    """
    from systems.integrators.warmup import numba_is_warm

    job = _Job(compiled, method, tuple(diagnostics), y0)
    if compiled.handed_over:
        job.done.set()
    elif numba_is_warm() and cached(compiled, method):
        _load(compiled, method, job.diagnostics, y0)  # tens of ms
        job.done.set()
    else:
        _builder.submit(job)
    return job.done


def _child_main() -> int:
    from systems.compiled import compile_system
    from systems.simulation import compile_natively

    job = pickle.load(sys.stdin.buffer)
    compiled = compile_system(job["mechanics"], job["wanted"])
    if compiled.kernels.__name__ != job["module"]:
        print(f"printed {compiled.kernels.__name__}, expected {job['module']}", file=sys.stderr)
        return 3
    compiled = compiled.with_parameters(job["parameters"])
    y0 = None if job["y0"] is None else np.array(job["y0"])
    compile_natively(compiled, job["method"], job["diagnostics"], y0)
    return 0


if __name__ == "__main__":
    raise SystemExit(_child_main())
