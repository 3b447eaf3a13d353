"""The per-process warm-up (``warmup.warm_numba``): after it, a scene's first calls of its
functions load nothing more, and the drivers can be copied into a cold cache."""

from __future__ import annotations

import numpy as np

from systems.codegen import driver_module
from systems.compiled import compile_system
from systems.integrators.warmup import copy_drivers, preload_drivers, warm_numba
from systems.mechanics import derive
from systems.scene import load_scene


def _loaded() -> dict[str, int]:
    drivers = driver_module()
    return {
        name: len(getattr(drivers, name).signatures)
        for name in ("call4", "batch_scalar", "batch_vector")
    }


def test_after_the_warm_up_a_scenes_calls_load_no_loop():
    """``preload_drivers`` loads the loops for the very types a scene's functions have:
    the rhs, H, the velocities and the drawing of a catalogue scene then find them."""
    warm_numba()
    preload_drivers()  # again: a process that warmed before this test's session
    before = _loaded()
    compiled = compile_system(
        derive(load_scene("double_pendulum")), ("rhs", "hamiltonian", "velocities", "drawing")
    )
    y0 = compiled.initial_state()
    compiled.rhs(0.0, y0)
    compiled.hamiltonian(0.0, y0[None])
    compiled.velocities(np.zeros(3), np.tile(y0, (3, 1)))
    compiled.drawing(0.0, y0[None])
    assert _loaded() == before


def test_copy_drivers_takes_the_drivers_and_nothing_else(tmp_path):
    from systems.cache_integrity import cache_root

    driver_module()  # written into the session's cache
    assert copy_drivers(cache_root(), tmp_path)
    names = sorted(p.name for p in (tmp_path / "kernels").rglob("*") if p.is_file())
    assert names and all(name.startswith(driver_module().__name__) for name in names)
    assert not copy_drivers(tmp_path / "nothing here", tmp_path / "other")
