"""Numba compiles a newly opened scene in a child process, then the kernels hand over."""

import sys
import threading
import time
import uuid

import numpy as np
import pytest

from systems import native_build
from systems.compiled import compile_system
from systems.integrators import FAMILIES
from systems.mechanics import derive
from systems.scene import parse_scene
from systems.simulation import required_wants, stream

HAND_OVER_SECONDS = 240.0


def _new_pendulum():
    """A pendulum whose kernel module nobody compiled yet (a fresh parameter name)."""
    tag = "u" + uuid.uuid4().hex[:10]
    text = f"""
title = "Pendulum {tag}"
[system]
coordinates = ["theta"]
parameters = {{ m = 1.0, g = 9.81, l = 1.0, {tag} = 0.0 }}
kinetic = "m*l**2*theta_dot**2/2"
potential = "-m*g*l*cos(theta) + {tag}*theta"
[initial]
theta = 1.0
"""
    return derive(parse_scene(text, source="test.toml"))


def _run_while_compiling(compiled, done):
    """Stream until the kernels hand over; returns the blocks seen before and after."""
    blocks = stream(compiled, method="yoshida4", t_end=1e6, block_seconds=0.01)
    before = [next(blocks)]
    assert done.wait(HAND_OVER_SECONDS), "numba never handed over"
    after = [next(blocks) for _ in range(3)]
    return before, after


def test_a_new_scene_streams_at_once_and_hands_over_after_the_child_compiled():
    mechanics = _new_pendulum()
    wants = required_wants("yoshida4", ("H",))
    compiled = compile_system(mechanics, wants, interpreted_start=True)
    assert not native_build.cached(compiled, "yoshida4")
    done = native_build.compile_in_background(compiled, "yoshida4", ("H",))
    before, after = _run_while_compiling(compiled, done)
    assert compiled.handed_over and compiled.kernels.error is None
    assert native_build.cached(compiled, "yoshida4")  # the child wrote numba's cache
    assert before[0].status == after[-1].status == "running"
    assert after[-1].steps > before[0].steps
    reference = compile_system(mechanics, wants)
    final = list(stream(reference, method="yoshida4", t_end=1.0))[-1]
    again = list(stream(compiled, method="yoshida4", t_end=1.0))[-1]
    np.testing.assert_array_equal(again.y[-1], final.y[-1])


def test_without_a_child_numba_compiles_in_this_process(monkeypatch):
    monkeypatch.setattr(sys, "executable", "/nonexistent/python")
    compiled = compile_system(_new_pendulum(), required_wants("yoshida4"), interpreted_start=True)
    done = native_build.compile_in_background(compiled, "yoshida4")
    _run_while_compiling(compiled, done)
    assert compiled.handed_over and compiled.kernels.error is None


def test_a_cached_scene_hands_over_before_returning():
    from systems.integrators.warmup import warm_numba

    warm_numba()
    mechanics = _new_pendulum()
    wants = required_wants("yoshida4")
    first = compile_system(mechanics, wants)
    list(stream(first, method="yoshida4", t_end=1e-3))  # numba compiles and caches it
    compiled = compile_system(mechanics, wants, interpreted_start=True)
    assert native_build.cached(compiled, "yoshida4")
    done = native_build.compile_in_background(compiled, "yoshida4")
    assert done.is_set() and compiled.handed_over


def test_a_newer_request_replaces_one_still_waiting():
    builder = native_build._NativeBuilder()
    started, release = [], threading.Event()

    def build(job):
        started.append(job)
        release.wait(10)

    builder._build = build
    jobs = [native_build._Job(compiled=None, method="yoshida4", diagnostics=(), y0=None)
            for _ in range(3)]  # fmt: skip
    builder.submit(jobs[0])
    deadline = time.monotonic() + 10
    while not started and time.monotonic() < deadline:
        time.sleep(0.01)
    builder.submit(jobs[1])
    builder.submit(jobs[2])
    assert jobs[1].done.is_set()  # replaced before it started: it stays interpreted
    release.set()
    assert jobs[2].done.wait(10)
    assert started == [jobs[0], jobs[2]]


def test_the_cache_probe_names_real_loops():
    compiled = compile_system(_new_pendulum(), ("rhs", "hamiltonian", "separable"))
    for family in FAMILIES.values():
        if family.kernel is not None:
            assert callable(getattr(compiled.kernels, family.run_kernel)), family.name
            assert callable(getattr(compiled.kernels, f"{family.kernel}_work")), family.name


def test_loads_shorten_the_gil_hand_offs_and_restore_them_after():
    """numba's loads beside the interpreted stream wait for the GIL thousands of times:
    while any load runs the interval is ``LOAD_SWITCH_INTERVAL``, and the one before comes
    back when the last load ends (also when a load fails)."""

    before = sys.getswitchinterval()
    try:
        sys.setswitchinterval(0.005)
        with native_build._quick_gil_hand_offs():
            assert sys.getswitchinterval() == pytest.approx(native_build.LOAD_SWITCH_INTERVAL)
            with pytest.raises(RuntimeError), native_build._quick_gil_hand_offs():
                raise RuntimeError("a load that fails")
            assert sys.getswitchinterval() == pytest.approx(native_build.LOAD_SWITCH_INTERVAL)
        assert sys.getswitchinterval() == pytest.approx(0.005)
    finally:
        sys.setswitchinterval(before)
