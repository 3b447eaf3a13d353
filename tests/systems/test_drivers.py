"""The stepping loops are compiled once per installation: a new scene compiles only its
own functions, and a fresh process loads the loops from numba's cache.

The test session compiles the loops once before any test (``tests/conftest.py`` runs
``warm_drivers``, as ``python main.py warm`` does after an installation).
"""

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from systems.codegen import driver_module
from systems.compiled import compile_system
from systems.integrators.registry import FAMILIES, STEPPERS
from systems.mechanics import derive
from systems.scene import parse_scene
from systems.simulation import run_to_end

ROOT = Path(__file__).resolve().parents[2]


def _scene(n: int, stiffness: float) -> str:
    """A chain of ``n`` springs no other test writes (a scene numba has never seen)."""
    names = [f"u{i}" for i in range(n)]
    springs = " + ".join(f"({a} - {b})**2" for a, b in zip(names, names[1:], strict=False))
    return f"""
[system]
coordinates = {json.dumps(names)}
parameters = {{ k = {stiffness} }}
kinetic = "{" + ".join(f"{q}_dot**2/2" for q in names)}"
potential = "k*({springs} + {names[0]}**2)/2 + {names[-1]}**4/4"
[initial]
{names[0]} = 0.3
"""


def _loops():
    drivers = driver_module()
    return [
        getattr(drivers, family.run_kernel)
        for family in FAMILIES.values()
        if family.run_kernel is not None
    ]


def _misses() -> int:
    return sum(sum(loop.stats.cache_misses.values()) for loop in _loops())


def _signatures() -> int:
    return sum(len(loop.signatures) for loop in _loops())


METHODS = ["rk4", "leapfrog", "yoshida8", "gauss_legendre6", "gauss_legendre4_tt", "dop853"]


def _run_all(compiled) -> None:
    for method in METHODS:
        tol = {"tol": 1e-8} if STEPPERS[method].setting == "tol" else {"dt": 0.01}
        _, last = run_to_end(compiled, method=method, t_end=0.2, energy_tolerance=None, **tol)
        assert last.status == "ok", (method, last.message)


def test_a_new_scene_compiles_no_driver():
    wants = ("rhs", "hamiltonian", "separable", "velocities")
    first = compile_system(derive(parse_scene(_scene(3, 1.25))), wants)
    _run_all(first)  # every loop these methods use is loaded (from the session's cache)
    misses, signatures = _misses(), _signatures()
    second = compile_system(derive(parse_scene(_scene(5, 2.5))), wants)
    _run_all(second)
    second.hamiltonian(0.0, second.initial_state()[None])
    assert _misses() == misses  # nothing compiled for the second scene
    assert _signatures() == signatures  # nor loaded: the same machine code serves both


def test_a_fresh_process_loads_the_loops_from_numbas_cache(tmp_path):
    """A new process with the session's cache (where the loops were compiled) finds them
    there: cache hits, no miss."""
    script = """
import json
from systems.codegen import driver_module
from systems.compiled import compile_system
from systems.mechanics import derive
from systems.scene import load_scene
from systems.simulation import run_to_end

compiled = compile_system(derive(load_scene("simple_pendulum")), ("rhs", "hamiltonian"))
_, last = run_to_end(compiled, method="dop853", t_end=1.0)
loop = driver_module().dop853_run
print(json.dumps({
    "status": last.status,
    "hits": sum(loop.stats.cache_hits.values()),
    "misses": sum(loop.stats.cache_misses.values()),
}))
"""
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    out = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, env=env, cwd=ROOT,
        timeout=600,
    )  # fmt: skip
    assert out.returncode == 0, out.stderr
    report = json.loads(out.stdout.strip().splitlines()[-1])
    assert report == {"status": "ok", "hits": 1, "misses": 0}


@pytest.mark.parametrize("method", ["rk4", "yoshida6", "gauss_legendre4", "dop853"])
def test_ensembles_take_the_scenes_functions_too(method):
    from systems.simulation import ensemble

    compiled = compile_system(
        derive(parse_scene(_scene(2, 1.0))), ("rhs", "hamiltonian", "separable")
    )
    if not STEPPERS[method].family.ensemble:
        with pytest.raises(ValueError, match="ensembles run fixed-step methods"):
            ensemble(compiled, compiled.initial_state()[None], method=method, t_end=1, dt=0.1)
        return
    Y0 = compiled.initial_state()[None] * np.array([[1.0], [0.5]])
    t, Y, status = ensemble(compiled, Y0, method=method, t_end=2.0, dt=1e-3, samples=4)
    assert not status.any()
    for row, y0 in zip(Y, Y0, strict=True):  # each row is the single run from its start
        _, last = run_to_end(
            compiled, method=method, y0=y0, t_end=2.0, dt=1e-3, energy_tolerance=None
        )
        np.testing.assert_allclose(row[-1], last.y[-1], rtol=0, atol=1e-12)


def test_entry_points_are_keyed_by_what_numba_types():
    """``entry_point`` remembers its answer by a fingerprint of the arguments: arguments
    numba types alike share one, a layout, dtype, writeability or tuple shape numba types
    apart gets its own (the one ``typeof`` gives)."""
    from numba import typeof
    from numba.core.typing.typeof import Purpose

    from systems.codegen import _fingerprint, entry_point

    drivers = driver_module()
    v = np.zeros(4)
    frozen = np.zeros(4)
    frozen.flags.writeable = False
    kinds = [
        (v, 1.0),
        (np.ones(4), 2.0),
        (np.zeros(8)[::2], 1.0),
        (np.zeros(4, dtype=np.float32), 1.0),
        (frozen, 1.0),
        (v, 1),
        ((v, v), 1.0),
        ((v, (v, 1.0)), 1.0),
    ]
    for a in kinds:
        for b in kinds:
            same_type = tuple(typeof(x, Purpose.argument) for x in a) == tuple(
                typeof(x, Purpose.argument) for x in b
            )
            assert (_fingerprint(a) == _fingerprint(b)) == same_type, (a, b)
    compiled = compile_system(derive(parse_scene(_scene(2, 1.5))), ("rhs",))
    fn = compiled.functions(("rhs",))[0]
    P = compiled.parameters
    first = entry_point(drivers.call4, (fn, 0.0, v, P, np.zeros(4)))
    again = entry_point(drivers.call4, (fn, 0.5, np.ones(4), P, v))
    assert first is again
    out = np.zeros(4)
    again(fn, 0.0, np.array([0.3, 0.0, 0.0, 0.0]), P, out)
    assert np.allclose(out, compiled.rhs(0.0, np.array([0.3, 0.0, 0.0, 0.0])))


CONSTRAINED_LOOPS = ("cdop853_run", "cerk_run", "cdop853_step", "cerk_step", "c_rhs",
                     "c_project", "c_project_bilateral", "c_contacts", "c_switch")  # fmt: skip


def test_the_constrained_loops_allocate_nothing():
    """Their helpers take their scratch from the family's work (``c_scratch``): each
    ``c_rhs`` allocated its saddle-point system, and every loop that called one was
    compiled with reference counting (18-39% of its speed, 9% of its code)."""
    from systems.codegen import _numba_can_skip_nrt, jit_wrappers, template_source

    if not _numba_can_skip_nrt():
        pytest.skip("this numba compiles every function with reference counting")
    options = {line.split(" = ")[0]: line for line in jit_wrappers(template_source()).splitlines()}
    assert all("_nrt=False" in options[name] for name in CONSTRAINED_LOOPS)
    # what Python calls allocates the scratch itself
    assert "_nrt=False" not in options["c_multipliers"]
