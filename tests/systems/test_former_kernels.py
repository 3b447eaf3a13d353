"""The stepping loops compiled once, calling a scene's functions through pointers (LLVM
IR or numba), reproduce the former kernels bit for bit: the final states and step
counts below were written by the kernels as they were before (the stepper templates
inlined with each scene's functions and compiled per scene, commit 772c117), for every
family on the catalogue's scenes, ensembles included.

Bitwise, not approximately: every operation and its order are unchanged, and neither
backend lets LLVM contract or reorder floating-point operations.
"""

import json
from pathlib import Path

import numpy as np
import pytest

from systems.compiled import compile_system
from systems.integrators import STEPPERS
from systems.mechanics import derive
from systems.scene import load_scene
from systems.simulation import ensemble, required_wants, run_to_end

FORMER = json.loads((Path(__file__).parent / "former_kernels.json").read_text())
RUNS = sorted(key for key in FORMER if not key.endswith("/ensemble"))


def _setting(method: str) -> dict:
    return {"tol": 1e-9} if STEPPERS[method].setting == "tol" else {"dt": 0.01}


@pytest.mark.parametrize("key", RUNS)
def test_a_run_ends_where_the_former_kernels_ended(key):
    scene, method = key.split("/")
    mechanics = derive(load_scene(scene))
    compiled = compile_system(mechanics, required_wants(method, ("H",)))
    _, last = run_to_end(
        compiled, method=method, t_end=3.0, energy_tolerance=None, **_setting(method)
    )
    status, steps, final = FORMER[key]
    assert (last.status, last.steps) == (status, steps)
    assert [float(v).hex() for v in last.y[-1]] == final


@pytest.mark.parametrize("key", sorted(key for key in FORMER if key.endswith("/ensemble")))
def test_an_ensemble_ends_where_the_former_kernels_ended(key):
    scene, method, _ = key.split("/")
    compiled = compile_system(derive(load_scene(scene)), required_wants(method, ("H",)))
    Y0 = np.array([compiled.initial_state(), 0.5 * compiled.initial_state()])
    _, Y, status = ensemble(compiled, Y0, method=method, t_end=2.0, dt=0.01, samples=3)
    assert not status.any()
    assert [float(v).hex() for v in Y[:, -1].ravel()] == FORMER[key]
