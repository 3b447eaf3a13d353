"""Compile the drivers once per installation, and start numba before the first scene.

Every family's stepping loop (``systems.codegen.driver_module``) is the same machine code
for every scene: numba compiles it the first time it runs and keeps it in its on-disk
cache. ``warm_drivers`` runs each family once on two small systems of its own (a free
particle in an attractive 1/r field, and a pendulum in Cartesian coordinates held by a
constraint), with and without a Poincare section, as ensembles, and the batch
functions, so that afterwards no scene waits for a driver; ``python main.py warm`` and
``make run`` call it, and the test session does once.

The first compiled function a process loads pays a fixed start-up of about half a
second (numba initialising its CPU target), and the drivers' module its import (0.1 s):
``warm_in_background`` pays both in a daemon thread while the window appears, so that
a scene opened then only loads its own functions and its method's loop.
"""

from __future__ import annotations

import json
import os
import threading
import time
from pathlib import Path

import numpy as np

FREE = """
title = "Warm-up: a particle in an attractive 1/r field"
[system]
coordinates = ["x", "y"]
parameters = { k = 1.0 }
kinetic = "(x_dot**2 + y_dot**2)/2"
potential = "-k/sqrt(x**2 + y**2)"
[initial]
x = 1.0
y_dot = 1.1
[drawing]
points = { body = ["x", "y"] }
links = [["origin", "body"]]
"""

CONSTRAINED = """
title = "Warm-up: a pendulum in Cartesian coordinates"
[system]
coordinates = ["x", "y"]
parameters = { g = 9.81 }
kinetic = "(x_dot**2 + y_dot**2)/2"
potential = "g*y"
[constraints]
holonomic = ["x**2 + y**2 - 1"]
[initial]
x = 0.6
y = -0.8
"""

_warm = threading.Event()
_started = threading.Lock()
_thread: threading.Thread | None = None


def warm_drivers(progress=None, processes: int = 2) -> float:
    """Compile (or load from numba's cache) every family's driver; returns the seconds.

    ``progress(text)``, if given, is called before each piece of work this process does,
    and with the names of the pieces handed to a second process. ``processes``: with 2
    (the default, on a machine with two cores or more), ``SECOND_PART`` is compiled in a
    worker process (``systems.processes``) while this one compiles the rest: numba
    compiles on one core, and the two parts take about the same time (70 and 75 s on an
    empty cache, against 143 s in one process).
    """
    start = time.perf_counter()
    systems = _warm_systems()  # written to the caches before the second process reads them
    names = list(_tasks())
    second = [name for name in names if name in SECOND_PART]
    job = None
    if processes >= 2 and (os.cpu_count() or 1) >= 2 and second:
        from systems import processes as workers

        if progress is not None:
            progress(", ".join(second) + " (in a second process)")
        job = workers.submit(warm_part, second, what="compiling " + ", ".join(second))
        names = [name for name in names if name not in SECOND_PART]
    try:
        warm_part(names, progress, systems)
        if job is not None:
            job.result()
    finally:
        if job is not None:
            job.cancel()  # Ctrl+C or a failure here: the worker ends too
    _warm.set()
    from systems.cache_integrity import write_atomic
    from systems.codegen import prune_drivers

    prune_drivers()  # the builds of former versions of the templates
    state = _drivers_state()
    if state is not None:
        try:
            write_atomic(_stamp_path(), json.dumps(state, sort_keys=True).encode())
        except OSError:
            pass  # the next warm-up loads them all again
    return time.perf_counter() - start


def drivers_warmed() -> bool:
    """True when ``warm_drivers`` ran to its end on this cache and the files it left are
    as it left them (its stamp beside numba's files: the drivers' and the map loops'
    modules, numba's cache files of them and their sizes, numba's version). Warming
    again would then only load every loop from numba's cache (14 s of a test session's
    start); a file removed or grown since (a signature compiled later) makes it False."""
    try:
        recorded = json.loads(_stamp_path().read_text())
    except (OSError, ValueError):
        return False
    return recorded == _drivers_state()


def _stamp_path() -> Path:
    from systems.codegen import cache_dir, driver_module_name

    return cache_dir() / "__pycache__" / f"{driver_module_name()}.warm"


def _drivers_state() -> dict | None:
    """The files a complete warm-up leaves, by name, with their sizes (None: a module is
    missing)."""
    import numba

    from systems.chaos.map_kernels import loop_module_name
    from systems.codegen import cache_dir, driver_module_name

    folder = cache_dir()
    files = {}
    for module in (driver_module_name(), loop_module_name()):
        try:
            files[f"{module}.py"] = (folder / f"{module}.py").stat().st_size
            for entry in (folder / "__pycache__").glob(f"{module}.*"):
                if entry.suffix != ".warm":
                    files[f"__pycache__/{entry.name}"] = entry.stat().st_size
        except OSError:
            return None
    return {"numba": numba.__version__, "files": files}


SECOND_PART = frozenset(
    {"taylor", "taylor map", "section portraits", "orbit diagrams", "constrained",
     "constrained_fixed"}
)  # fmt: skip
"""What ``warm_drivers`` hands to a second process: every piece that writes or reads the
Taylor code of a warm-up system stays in one process, which then decomposes each system
once (``systems.taylor.compiled.decomposition_of``) rather than two processes each
remembering their own; the constrained families share their constraint loops. A new
family goes with the first part."""


def _warm_systems() -> dict:
    """The two warm-up systems, compiled (``FREE`` and ``CONSTRAINED``), after the loops
    every family calls (the augmented solve, ``preload_drivers``')."""
    from systems.codegen import driver_module
    from systems.compiled import compile_system
    from systems.llvm_kernels import SOLVER_SIGNATURE
    from systems.mechanics import derive
    from systems.scene import parse_scene

    driver_module().solve_augmented.compile(SOLVER_SIGNATURE)
    preload_drivers()
    systems = {}
    for name, text in (("free", FREE), ("constrained", CONSTRAINED)):
        mechanics = derive(parse_scene(text, source=f"<warm-up {name}>"))
        wants = ["rhs", "hamiltonian", "velocities", "momenta"]
        if name == "free":
            wants += ["separable", "drawing"]
        compiled = compile_system(mechanics, wants)
        y0 = compiled.initial_state()
        compiled.hamiltonian(0.0, y0[None])
        compiled.velocities(0.0, y0[None])
        compiled.momenta(0.0, y0[None, :2], y0[None, 2:])
        if name == "free":
            compiled.drawing(0.0, y0[None])
        systems[name] = compiled
    return systems


def _tasks() -> dict:
    """The pieces of the warm-up by name, in order: each family's loops (the registry's
    family names), then the chaos maps', taylor's map, the section portraits' and the
    orbit diagrams'; each a function of the warm-up systems."""
    from systems.integrators.registry import STEPPERS

    tasks = {}
    for stepper in STEPPERS.values():
        family = stepper.family
        if family.kernel is not None and family.name not in tasks:
            tasks[family.name] = lambda systems, name=stepper.name: _warm_family(systems, name)
    tasks["chaos maps"] = lambda systems: warm_map_loops(systems["free"])
    tasks["taylor map"] = lambda systems: warm_map_loops(systems["free"], ("taylor",))
    tasks["section portraits"] = lambda systems: warm_section_portraits(systems["free"])
    tasks["orbit diagrams"] = lambda systems: warm_orbit_diagrams()
    return tasks


def warm_part(names: list[str], progress=None, systems: dict | None = None) -> None:
    """Do the pieces of the warm-up named ``names`` (keys of ``_tasks``) in this process;
    ``systems``: the warm-up systems, compiled here if not given."""
    systems = systems if systems is not None else _warm_systems()
    tasks = _tasks()
    for name in names:
        if progress is not None:
            progress(name)
        tasks[name](systems)


def _warm_family(systems: dict, method: str) -> None:
    """Compile (or load) the loops of ``method``'s family: with and without a section,
    the sampling loop (Sampler: run --out, export) and, where it has them, ensembles;
    a family with ``fused`` loops both those (the warm-up system is the LLVM backend's)
    and its own (a system without the fused function: the numba backend's)."""
    from systems.integrators.registry import STEPPERS
    from systems.simulation import Run, ensemble, precompile

    stepper = STEPPERS[method]
    family = stepper.family
    compiled = systems["constrained" if family.constrained else "free"]
    variants = [compiled]
    if family.fused is not None:  # its fused loops (the LLVM backend's), and its own
        variants.append(compiled.without(*set(family.fused[1]) - set(family.functions)))
    for system in variants:
        for section in (None, (1, 0.0, 1)):
            precompile(system, stepper.name, section=section)
        setting = {} if stepper.setting == "tol" else {"dt": 1e-3}
        run = Run(system, method=stepper.name, t_end=1e-2, energy_tolerance=None, **setting)
        run.advance(0.01, samples=np.array([5e-3]))
    if family.ensemble or family.adaptive_ensemble:
        Y0 = np.repeat(compiled.initial_state()[None], 2, axis=0)
        ensemble(compiled, Y0, method=stepper.name, t_end=1e-3, dt=1e-3, samples=1)


MAP_METHODS = ("yoshida4", "rk4", "gauss_legendre4")
"""The methods whose chaos-map loops the warm-up compiles: those a map or an orbit
diagram takes by default (``systems.chaos.maps.default_map_method``). Taylor's
(``chaosmap --method taylor``: a loop of the drivers, ``taylor_batch_megno_parallel``) is
a piece of its own, "taylor map". Another method's loop compiles on its first use,
about 6 s, then comes from numba's cache."""


def warm_map_loops(compiled, methods: tuple[str, ...] = MAP_METHODS) -> None:
    """Compile (or load) the chaos map's loop of each of ``methods`` with a map of one
    orbit and one step on ``compiled`` (a conservative, separable system); taylor's takes
    its own steps."""
    from systems.chaos.maps import map_chunk, map_kernel
    from systems.chaos.variational import load_tangent

    tangent = load_tangent(compiled)
    start = compiled.initial_state()[None]
    for method in methods:
        step = {} if method == "taylor" else {"dt": 1e-3}
        map_chunk(map_kernel(tangent, method=method, t_end=1e-3, **step), start)


def warm_section_portraits(compiled) -> None:
    """Compile (or load) the loop of ``systems.section_orbits.section_portrait`` (the
    taylor batch with crossings) with two orbits of ``compiled`` (two degrees of freedom,
    conserved H) for a moment."""
    from systems.section import Section
    from systems.section_orbits import section_portrait

    start = compiled.initial_state()
    energy = float(compiled.hamiltonian(0.0, start[None])[0])
    section_portrait(compiled, Section(1, 0.0, 0), energy, np.stack([start, start]), t_end=1e-3)


DRIVEN = """
title = "Warm-up: a spring pumped with period 2 pi"
[system]
coordinates = ["x"]
parameters = { delta = 1.0, epsilon = 0.3 }
kinetic = "x_dot**2/2"
potential = "(delta + epsilon*cos(t))*x**2/2"
[initial]
x = 0.1
"""


def warm_orbit_diagrams() -> None:
    """Compile (or load) the orbit diagram's default loop (``taylor_batch_strobe_parallel``:
    the first diagram had waited about 7 s for it) with two values of a driven spring's
    parameter, one period each."""
    from systems.chaos.bifurcation import strobe_chunk, strobe_kernel
    from systems.compiled import compile_system
    from systems.mechanics import derive
    from systems.scene import parse_scene

    compiled = compile_system(derive(parse_scene(DRIVEN, source="<warm-up driven>")))
    kernel = strobe_kernel(compiled, "epsilon", transient=0.0, samples=1, method="taylor")
    strobe_chunk(kernel, np.array([0.2, 0.3]), compiled.initial_state())


def copy_drivers(source: Path, target: Path) -> bool:
    """Copy the drivers' module of this source and the chaos maps' loops, with numba's
    cache files of them, from the cache directory ``source`` into the cache directory
    ``target`` (both roots as ``PHASE_EXPLORER_CACHE`` names them); nothing else (no
    scene's derivation or functions), so that ``target`` is a cold cache for scenes on an
    installation whose drivers are compiled. False where ``source`` has no such drivers
    or a copy fails (``target`` then compiles them afresh)."""
    import shutil

    from systems.chaos.map_kernels import loop_module_name
    from systems.codegen import driver_module_name

    installed, kernels = Path(source) / "kernels", Path(target) / "kernels"
    name = driver_module_name()
    if not (installed / f"{name}.py").is_file():
        return False
    try:
        (kernels / "__pycache__").mkdir(parents=True, exist_ok=True)
        for module in (name, loop_module_name()):
            if not (installed / f"{module}.py").is_file():
                continue  # compiled afresh where used
            shutil.copy2(installed / f"{module}.py", kernels / f"{module}.py")
            for entry in (installed / "__pycache__").glob(f"{module}.*"):
                if entry.is_file() and not entry.is_symlink():
                    shutil.copy2(entry, kernels / "__pycache__" / entry.name)
    except OSError:
        return False
    return True


def warm_numba() -> None:
    """Initialise numba's CPU target by compiling a trivial array function (no cache),
    import what sympy imports at its first addition and its first lambdify, then import
    the drivers' module and load the loops every scene calls whatever its method
    (``preload_drivers``)."""
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
    # sympy imports sympy.tensor.tensor, and with it sympy.combinatorics (40 ms), at the
    # first addition a process makes (Add.flatten), and its code printers at the first
    # lambdify (a constrained scene's numpy constraints, ``constraints.Numeric``: 7 ms):
    # imports paid here, not by the first scene derived or opened
    import sympy.codegen.ast  # noqa: F401
    import sympy.tensor.tensor  # noqa: F401

    preload_drivers()
    _warm.set()


def preload_drivers() -> None:
    """Import the drivers' module (``systems.codegen.driver_module``) and load from
    numba's cache the loops that call a scene's functions one at a time or over rows
    (``call4``: rhs; ``c_bilateral_rhs``: a constrained scene's; ``batch_scalar``: H;
    ``batch_vector``: the velocities and the drawing; the times of one row come
    read-only, of several writable: both), for the function types every scene's
    functions have. Once per process, the same for every scene: 0.1 s that a scene
    opened first would otherwise pay. The function values are placeholders at address
    0, typed, never called."""
    from numba.core import sigutils
    from numba.core.typing import signature

    from systems.codegen import SIGNATURES, driver_module, entry_point, function_value
    from systems.constraints import PRIMITIVES

    def placeholder(name: str):
        args, result = sigutils.normalize_signature(SIGNATURES[name])
        return function_value(0, signature(result, *args), None)

    drivers = driver_module()
    v, P, rows = np.zeros(2), np.zeros(1), np.zeros((1, 2))
    fixed = np.zeros(2)
    fixed.flags.writeable = False  # np.broadcast_to's times of a single row
    entry_point(drivers.call4, (placeholder("rhs"), 0.0, v, P, v))
    cs = (*(placeholder(name) for name in PRIMITIVES), np.zeros(4, dtype=np.int64))
    entry_point(drivers.c_bilateral_rhs, (cs, 0.0, v, P, v))
    for ts in (v, fixed):
        entry_point(drivers.batch_scalar, (placeholder("hamiltonian"), ts, rows, P, v))
        entry_point(drivers.batch_vector, (placeholder("velocities"), ts, rows, P, rows))
        drawing = (placeholder("drawing"), ts, rows, P, np.zeros((1, 1, 2)))
        entry_point(drivers.batch_vector, drawing)


def numba_is_warm() -> bool:
    """True once ``warm_numba`` or ``warm_drivers`` has finished in this process."""
    return _warm.is_set()


def warm_in_background() -> threading.Thread:
    """Run ``warm_numba`` in a daemon thread, once per process; returns that thread."""
    global _thread
    with _started:
        if _thread is None:
            _thread = threading.Thread(target=warm_numba, name="numba-warm-up", daemon=True)
            _thread.start()
        return _thread
