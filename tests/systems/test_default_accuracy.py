"""Accurate by default, and pacing never changes the solution."""

import math
from pathlib import Path

import numpy as np
import pytest

from systems.compiled import compile_system
from systems.integrators import choose_method
from systems.mechanics import derive
from systems.scene import load_scene
from systems.simulation import Run, required_wants, stream

CATALOGUE = sorted(p.stem for p in Path("resources/scenes").glob("*.toml"))
TARGET = 1e-10


@pytest.mark.parametrize("name", CATALOGUE)
def test_every_conservative_catalogue_scene_keeps_its_energy_by_default(name):
    mechanics = derive(load_scene(name))
    if not mechanics.classification.hamiltonian_conserved:
        pytest.skip("H is not conserved: nothing to check here")
    method, _ = choose_method(mechanics)
    wants = required_wants(method, ("H",))
    compiled = compile_system(mechanics, wants)
    t_end = float(mechanics.scene.view.get("t_end", 10.0))
    blocks = list(stream(compiled, t_end=t_end, diagnostics=("H",)))
    assert blocks[-1].status == "ok", blocks[-1].message
    H = np.concatenate([b.diagnostics["H"] for b in blocks])
    H0 = float(compiled.hamiltonian(0.0, compiled.initial_state()[None])[0])
    error = np.max(np.abs(H - H0)) / (abs(H0) if abs(H0) > 1e-8 else 1.0)
    assert error <= TARGET, (name, method, blocks[-1].setting_value, error)


@pytest.mark.parametrize("method", ["yoshida8", "gauss_legendre6", "logh_yoshida6", "dop853"])
def test_stopping_at_any_times_passes_through_the_same_states(method):
    scene = "kepler_cartesian" if method.startswith("logh") else "simple_pendulum"
    mechanics = derive(load_scene(scene))
    compiled = compile_system(mechanics, required_wants(method, ("H",)))
    free = Run(compiled, method=method, t_end=5.0)
    paced = Run(compiled, method=method, t_end=5.0)
    states_free, states_paced = {}, {}
    while not free.finished:
        block = free.advance(0.01)
        states_free.update(zip(block.t.tolist(), map(tuple, block.y.tolist()), strict=True))
    until = 0.0
    while not paced.finished:
        until += 0.0371  # a frame's worth of simulated time, unrelated to the step
        block = paced.advance(0.01, until=until)
        states_paced.update(zip(block.t.tolist(), map(tuple, block.y.tolist()), strict=True))
    common = set(states_free) & set(states_paced)
    assert len(common) > 20 and max(common) == 5.0
    assert all(states_free[t] == states_paced[t] for t in common)  # bitwise


def test_the_automatic_choice_says_what_accuracy_it_aims_at():
    for name in ("simple_pendulum", "double_pendulum"):
        _, why = choose_method(derive(load_scene(name)))
        assert "1e-10" in why
    assert math.isfinite(TARGET)


USER_SCENES = sorted((Path(__file__).resolve().parents[1] / "user_systems").glob("*.toml"))


@pytest.mark.parametrize(
    "source", CATALOGUE + [str(p) for p in USER_SCENES], ids=lambda s: Path(s).stem
)
def test_the_automatic_choice_always_integrates_the_whole_system(source):
    """Never a method its own registry refuses for the scene (a splitting that drops an
    effect, a fixed step through impacts)."""
    from systems.integrators import STEPPERS
    from systems.scene import parse_scene

    path = Path(source)
    scene = load_scene(source) if not path.suffix else parse_scene(path.read_text(), source=source)
    mechanics = derive(scene)
    method, why = choose_method(mechanics)
    assert STEPPERS[method].applies_to(mechanics) is None, (method, why)
