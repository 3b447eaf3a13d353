"""The composition family's fused loops (``composef_*`` of ``systems.integrators.kernels``):
where the LLVM backend wrote the scene's ``compose_stages`` (a step's stages with both
gradients inline, ``systems.llvm_kernels._StagesWriter``), a single trajectory's runner
calls it once a step instead of ``grad_kinetic`` and ``grad_potential`` twice a stage.
The results must be bitwise those of the unfused loops (``compose_*``: the same system
without the function, and the numba backend's functions), with Kahan terms and without,
through pauses, sampled times and the landing step on the end time."""

from __future__ import annotations

import math

import numpy as np
import pytest

from systems.codegen import driver_module
from systems.compiled import compile_system
from systems.integrators import STEPPERS
from systems.integrators.registry import make_runner
from systems.llvm_kernels import STAGES, LLVMKernels
from systems.mechanics import derive
from systems.scene import load_scene, parse_scene
from systems.simulation import Run

COMPOSITIONS = sorted(name for name, s in STEPPERS.items() if s.family.name == "composition")
WANTS = ("rhs", "hamiltonian", "separable")

# V(q, t): a pumped, coupled pair of springs (the drifts advance the time of V)
DRIVEN = """
[system]
coordinates = ["x", "y"]
parameters = { delta = 1.0, epsilon = 0.3, c = 0.2 }
kinetic = "(x_dot**2 + 2*y_dot**2)/2"
potential = "(delta + epsilon*cos(t))*x**2/2 + y**2/2 + c*x**2*y**2 + sin(t/3)*y"
[initial]
x = 0.4
y = -0.3
x_dot = 0.2
y_dot = 0.5
"""

SCENES = ("simple_pendulum", "henon_heiles", "driven")
_compiled: dict = {}


def _system(scene: str, backend: str = "auto"):
    key = (scene, backend)
    if key not in _compiled:
        parsed = parse_scene(DRIVEN, source="<driven>") if scene == "driven" else load_scene(scene)
        _compiled[key] = compile_system(derive(parsed), WANTS, backend=backend)
    return _compiled[key]


def _dt(scene: str) -> float:
    return {"simple_pendulum": 0.01, "henon_heiles": 0.03, "driven": 0.02}[scene]


def _bits(array) -> bytes:
    return np.ascontiguousarray(array, dtype=float).tobytes()


def _script(compiled, method: str, dt: float, compensated: bool) -> list:
    """A run through everything a runner does, recorded bit for bit: strided blocks, a
    pause, sampled times (inside steps, at a step's end, left over for ``answer``), a
    step that lands on the end time."""
    stepper = STEPPERS[method]
    y0 = compiled.initial_state()
    t_end = 400.37 * dt  # not a whole number of steps: the last one is shortened
    runner = make_runner(compiled, stepper, y0, 0.0, t_end, dt, None, compensated)
    record = [runner.kernel]

    def keep(outcome):
        record.append((_bits(outcome.t), _bits(outcome.y), int(outcome.code), outcome.steps,
                       outcome.evals, outcome.sampled))  # fmt: skip
        record.append((_bits(runner.y), _bits(runner.comp), _bits(runner.clock)))

    keep(runner.advance(57, 10))
    keep(runner.advance(500, 7, until=101.5 * dt))  # pauses after the step reaching it
    times = np.array([103.25, 104.0, 110.7, 150.0001, 151.5]) * dt
    keep(runner.advance(500, 2, samples=times))
    t, y = runner.answer(np.array([runner.t - 0.3 * dt]))
    record.append((_bits(t), _bits(y)))
    keep(runner.advance(100, 5))
    times = np.array([300.1, 399.9, 400.2, 400.37]) * dt  # the last ones in the landing step
    keep(runner.advance(1000, 2, samples=times))
    assert runner.t == t_end
    return record


@pytest.mark.parametrize("scene", SCENES)
@pytest.mark.parametrize("compensated", [True, False])
def test_the_fused_loop_is_bitwise_the_unfused_one(scene, compensated):
    compiled = _system(scene)
    assert compiled.offers(STAGES)
    for method in COMPOSITIONS:
        fused = _script(compiled, method, _dt(scene), compensated)
        unfused = _script(compiled.without(STAGES), method, _dt(scene), compensated)
        assert fused[0] == "composef" and unfused[0] == "compose"
        assert fused[1:] == unfused[1:], (scene, method, compensated)


@pytest.mark.parametrize("scene", SCENES)
def test_the_fused_loop_is_bitwise_the_numba_backends(scene):
    compiled, numba = _system(scene), _system(scene, "numba")
    assert not numba.offers(STAGES)
    for method in ("leapfrog", "yoshida4", "yoshida8"):
        for compensated in (True, False):
            fused = _script(compiled, method, _dt(scene), compensated)
            other = _script(numba, method, _dt(scene), compensated)
            assert other[0] == "compose"
            assert fused[1:] == other[1:], (scene, method, compensated)


def test_a_runs_samples_are_the_same_through_the_fused_loop():
    compiled = _system("driven")
    times = np.linspace(0.013, 4.99, 37)
    results = []
    for system in (compiled, compiled.without(STAGES)):
        run = Run(system, method="yoshida6", dt=0.02, t_end=5.0, energy_tolerance=None)
        rows, last = [], None
        left = times
        while not run.finished and len(left):
            block = run.advance(0.001, samples=left)
            rows.append(block.y[: block.samples])
            left = left[block.samples :]
            last = block
        results.append((_bits(np.concatenate(rows)), _bits(last.y[-1])))
    assert results[0] == results[1]


def test_an_llvm_compiled_separable_scene_steps_with_one_call_a_step():
    compiled = _system("simple_pendulum")
    assert isinstance(compiled.kernels, LLVMKernels)
    assert STAGES in compiled.kernels.functions
    runner = make_runner(compiled, STEPPERS["yoshida4"], compiled.initial_state(), 0.0,
                         math.inf, 1e-3, None)  # fmt: skip
    drivers = driver_module()
    assert runner.kernel == "composef" and runner.loop is drivers.composef_run
    assert runner.fns == compiled.functions(("grad_potential", STAGES))
    outcome = runner.advance(10, 2)
    assert outcome.steps == 10 and outcome.evals == 1 + 10 * 3  # the first gradient, then 3 a step
    # the numba backend writes no such function: the family's own loops
    numba = _system("simple_pendulum", "numba")
    other = make_runner(numba, STEPPERS["yoshida4"], numba.initial_state(), 0.0, math.inf,
                        1e-3, None)  # fmt: skip
    assert other.kernel == "compose" and other.loop is drivers.compose_run


def test_large_gradients_keep_two_calls_a_stage():
    """``compose_stages`` only where the gradients are small (``STAGES_MAX_INSTRUCTIONS``):
    a 32-particle FPU chain's fused steps were slower than the calls, and doubled its
    compile."""
    compiled = compile_system(derive(load_scene("fpu_chain")), WANTS)
    assert isinstance(compiled.kernels, LLVMKernels)
    assert not compiled.offers(STAGES) and compiled.offers("grad_potential")
    runner = make_runner(compiled, STEPPERS["leapfrog"], compiled.initial_state(), 0.0,
                         math.inf, 1e-3, None)  # fmt: skip
    assert runner.kernel == "compose"
