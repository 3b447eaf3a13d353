"""The per-process warm-up (``warmup.warm_numba``): after it, a scene's first calls of its
functions load nothing more, and the drivers can be copied into a cold cache."""

from __future__ import annotations

import pytest

from systems.codegen import driver_module
from systems.integrators.warmup import copy_drivers

PRELOADED = """
import json
import numpy as np
import pytest

from systems.codegen import driver_module
from systems.compiled import compile_system
from systems.integrators.warmup import warm_numba
from systems.mechanics import derive
from systems.scene import load_scene

warm_numba()
drivers = driver_module()
NAMES = ("call4", "c_bilateral_rhs", "batch_scalar", "batch_vector")
before = {name: len(getattr(drivers, name).signatures) for name in NAMES}
wants = ("rhs", "hamiltonian", "velocities", "drawing")
for scene in ("double_pendulum", "cartesian_pendulum"):
    compiled = compile_system(derive(load_scene(scene)), wants)
    y0 = compiled.initial_state()
    compiled.rhs(0.0, y0)
    compiled.hamiltonian(0.0, y0[None])
    compiled.hamiltonian(np.zeros(3), np.tile(y0, (3, 1)))
    compiled.velocities(np.zeros(3), np.tile(y0, (3, 1)))
    compiled.velocities(0.0, y0[None])
    compiled.drawing(0.0, y0[None])
after = {name: len(getattr(drivers, name).signatures) for name in NAMES}
print(json.dumps({"before": before, "after": after}))
"""


def _fresh(script: str) -> dict:
    """Run ``script`` in a new process on the session's cache; its last line as JSON."""
    import json
    import os
    import subprocess
    import sys
    from pathlib import Path

    root = Path(__file__).resolve().parents[3]
    out = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, cwd=root,
        env=dict(os.environ, PYTHONPATH=str(root)), timeout=600,
    )  # fmt: skip
    assert out.returncode == 0, out.stderr
    return json.loads(out.stdout.strip().splitlines()[-1])


def test_after_the_warm_up_a_scenes_calls_load_no_loop():
    """``warm_numba`` (``preload_drivers``) loads the loops for the very types a scene's
    functions have: the rhs (a constrained scene's too), H and the velocities over one
    row and over several, and the drawing of two catalogue scenes then find them, in a
    new process."""
    report = _fresh(PRELOADED)
    assert report["after"] == report["before"], report
    assert all(count >= 1 for count in report["before"].values()), report


def test_copy_drivers_takes_the_drivers_and_nothing_else(tmp_path):
    from systems.cache_integrity import cache_root
    from systems.chaos.map_kernels import loop_module

    modules = (driver_module().__name__, loop_module().__name__)  # in the session's cache
    assert copy_drivers(cache_root(), tmp_path)
    names = sorted(p.name for p in (tmp_path / "kernels").rglob("*") if p.is_file())
    assert {name.split(".")[0] for name in names} == set(modules)
    assert not copy_drivers(tmp_path / "nothing here", tmp_path / "other")


def test_the_default_chaos_map_loops_come_from_the_cache_in_a_new_process():
    """``warm_drivers`` (the session's, as ``python main.py warm``) compiled the map loops
    of the methods maps take by default, taylor's map, the section portraits' batch and
    the orbit diagrams' taylor strobe loop: a new process loads them, compiles none."""
    script = """
import json
from systems.chaos.map_kernels import loop_module
from systems.chaos.maps import map_chunk, map_kernel
from systems.chaos.variational import load_tangent
from systems.compiled import compile_system
from systems.integrators.registry import STEPPERS
from systems.integrators.warmup import MAP_METHODS
from systems.mechanics import derive
from systems.scene import load_scene

for name, method in (("henon_heiles", "yoshida4"), ("henon_heiles", "gauss_legendre4"),
                     ("damped_pendulum", "rk4")):
    assert method in MAP_METHODS
    compiled = compile_system(derive(load_scene(name)), ("rhs", "hamiltonian", "separable"))
    tangent = load_tangent(compiled)
    map_chunk(map_kernel(tangent, method=method, t_end=0.1), compiled.initial_state()[None])
# taylor's map and the section portraits' batch: loops of the drivers' module
import pytest

from systems.codegen import driver_module
from systems.section import Section
from systems.section_orbits import section_portrait

compiled = compile_system(derive(load_scene("henon_heiles")), ("rhs", "hamiltonian"))
start = compiled.initial_state()
map_chunk(map_kernel(load_tangent(compiled), method="taylor", t_end=0.1), start[None])
energy = float(compiled.hamiltonian(0.0, start[None])[0])
section_portrait(compiled, Section(0, 0.0, 1), energy, start[None], t_end=0.1)
# the orbit diagram's default loop (taylor, each lane its own parameters)
from systems.chaos.bifurcation import orbit_diagram, strobe_kernel

driven = compile_system(derive(load_scene("driven_damped_pendulum")), ("rhs", "hamiltonian"))
parameter = driven.parameter_names[0]
value = float(driven.parameters[0])
kernel = strobe_kernel(driven, parameter, transient=0.0, samples=1)
assert kernel.method == "taylor"
orbit_diagram(kernel, [value, 1.01 * value])
loops = [getattr(loop_module(), f"{STEPPERS[m].family.kernel}_megno_parallel")
         for m in MAP_METHODS]
loops += [driver_module().taylor_batch_megno_parallel,
          driver_module().taylor_batch_section_parallel,
          driver_module().taylor_batch_strobe_parallel]
print(json.dumps({"misses": sum(sum(loop.stats.cache_misses.values()) for loop in loops),
                  "hits": sum(sum(loop.stats.cache_hits.values()) for loop in loops)}))
"""
    report = _fresh(script)
    assert report == {"misses": 0, "hits": 6}, report


def test_the_second_process_takes_named_pieces_and_leaves_the_first_some():
    """``SECOND_PART`` names pieces of the warm-up (a misspelt one would silently stay in
    the first process), every Taylor piece among them (one process decomposes each
    warm-up system), and leaves the other families to the first process."""
    from systems.integrators.warmup import SECOND_PART, _tasks

    names = set(_tasks())
    assert SECOND_PART <= names
    assert {name for name in names if "taylor" in name} <= SECOND_PART
    assert {"section portraits", "orbit diagrams"} <= SECOND_PART
    assert names - SECOND_PART >= {"runge_kutta", "gauss", "dop853", "chaos maps"}


def test_a_part_of_the_warm_up_runs_in_a_worker_process():
    """What ``warm_drivers`` hands to a second process crosses to a worker and runs
    there (the warm-up systems derived and compiled in the worker), from the session's
    cache."""
    from systems import processes
    from systems.integrators.warmup import warm_part

    assert processes.run(warm_part, ["orbit diagrams"], what="a piece of the warm-up") is None


def test_the_session_starts_from_a_complete_warm_up():
    """The session's cache (tests/conftest.py: the installation's copied, or its own
    ``warm_drivers``) holds the stamp a complete warm-up writes, naming numba's files."""
    import json
    from pathlib import Path

    from tests.conftest import _SHARED_CACHE

    folder = Path(_SHARED_CACHE) / "kernels"
    (stamp,) = (folder / "__pycache__").glob(f"{driver_module().__name__}.warm")
    files = json.loads(stamp.read_text())["files"]
    assert any(name.endswith(".nbi") for name in files)
    assert all((folder / name).is_file() for name in files)


def test_a_warm_up_is_done_again_only_when_its_files_changed(tmp_path, monkeypatch):
    """``drivers_warmed`` (``python main.py warm`` and the test session ask it first):
    True for the files a complete warm-up left; False without its stamp, with a numba
    file grown (a signature compiled since) or gone, or under another numba."""
    import json

    from systems.cache_integrity import cache_root, write_atomic
    from systems.integrators import warmup

    assert copy_drivers(cache_root(), tmp_path)
    monkeypatch.setenv("PHASE_EXPLORER_CACHE", str(tmp_path))
    pycache = tmp_path / "kernels" / "__pycache__"
    for stamp in pycache.glob("*.warm"):
        stamp.unlink()
    assert not warmup.drivers_warmed()

    def stamp(state) -> None:  # as the end of warm_drivers writes it
        write_atomic(warmup._stamp_path(), json.dumps(state, sort_keys=True).encode())

    complete = warmup._drivers_state()
    stamp(complete)
    assert warmup.drivers_warmed()
    stamp({**complete, "numba": "0.1"})
    assert not warmup.drivers_warmed()
    stamp(complete)
    index = next(pycache.glob(f"{driver_module().__name__}*.nbi"))
    data = index.read_bytes()
    index.write_bytes(data + b"\0")
    assert not warmup.drivers_warmed()
    index.write_bytes(data)
    assert warmup.drivers_warmed()
    next(pycache.glob(f"{driver_module().__name__}*.nbc")).unlink()
    assert not warmup.drivers_warmed()


def test_warm_on_a_warmed_cache_says_so_and_compiles_nothing(tmp_path, monkeypatch, capsys):
    import json

    from explorer.cli import main
    from systems.cache_integrity import cache_root, write_atomic
    from systems.integrators import warmup

    assert copy_drivers(cache_root(), tmp_path)
    monkeypatch.setenv("PHASE_EXPLORER_CACHE", str(tmp_path))
    state = json.dumps(warmup._drivers_state(), sort_keys=True).encode()
    write_atomic(warmup._stamp_path(), state)
    monkeypatch.setattr(warmup, "warm_drivers", lambda *a, **k: pytest.fail("warmed again"))
    assert main(["warm"]) == 0
    assert "compiled already" in capsys.readouterr().err
