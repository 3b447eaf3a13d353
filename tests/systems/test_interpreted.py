"""The plain-Python twins of the kernels agree with numba's, and hand over to them."""

import math

import numpy as np
import pytest

from systems.compiled import compile_system
from systems.interpreted import KernelHandover
from systems.mechanics import derive
from systems.scene import load_scene
from systems.simulation import compile_natively, ensemble, required_wants, stream
from tests.systems.scenes import DRIVEN_DAMPED, PENDULUM, PLANETARY, scene

CASES = [
    ("simple_pendulum", "yoshida4", 3.0),
    ("double_pendulum", "gauss_legendre4", 0.5),
    ("kepler_cartesian", "logh_yoshida6", 3.0),
    ("driven_damped_pendulum", "dop853", 2.0),
    ("spherical_pendulum", "implicit_midpoint", 0.5),
]


def _pair(mechanics, method, diagnostics=("H",)):
    wants = required_wants(method, diagnostics)
    native = compile_system(mechanics, wants)
    interpreted = compile_system(mechanics, wants, interpreted_start=True)
    return native, interpreted


def _final(compiled, method, t_end, **kwargs):
    blocks = list(stream(compiled, method=method, t_end=t_end, **kwargs))
    return blocks[-1]


@pytest.mark.parametrize("name, method, t_end", CASES)
def test_interpreted_stream_matches_numba_to_round_off(name, method, t_end):
    mechanics = derive(load_scene(name))
    native, interpreted = _pair(mechanics, method)
    a = _final(native, method, t_end, diagnostics=("H",))
    b = _final(interpreted, method, t_end, diagnostics=("H",))
    assert not interpreted.handed_over
    assert a.status == b.status == "ok"
    assert a.steps == b.steps  # the same step sizes (block boundaries depend on timing)
    np.testing.assert_allclose(b.y[-1], a.y[-1], rtol=1e-11, atol=1e-12)
    assert b.diagnostics["H"][-1] == pytest.approx(a.diagnostics["H"][-1], rel=1e-12)


def test_hand_over_mid_stream_continues_the_same_trajectory():
    mechanics = derive(load_scene("double_pendulum"))
    native, interpreted = _pair(mechanics, "gauss_legendre4")
    reference = _final(native, "gauss_legendre4", 2.0, block_seconds=0.005)
    blocks = stream(interpreted, method="gauss_legendre4", t_end=2.0, block_seconds=0.005)
    first = next(blocks)
    assert first.status == "running" and not interpreted.handed_over
    compile_natively(interpreted, "gauss_legendre4", ("H",))
    assert interpreted.handed_over
    rest = list(blocks)
    assert rest[-1].status == "ok"
    assert rest[-1].steps == reference.steps
    np.testing.assert_allclose(rest[-1].y[-1], reference.y[-1], rtol=1e-11, atol=1e-12)


def test_vectorised_batches_match_numba():
    mechanics = derive(scene(PENDULUM))
    wants = ("rhs", "hamiltonian", "velocities", "drawing", "momenta")
    native = compile_system(mechanics, wants)
    interpreted = compile_system(mechanics, wants, interpreted_start=True)
    rng = np.random.default_rng(3)
    Y = rng.uniform(-2, 2, (50, 2))
    t = rng.uniform(0, 1, 50)
    for function in ("hamiltonian", "velocities", "drawing"):
        expected = getattr(native, function)(t, Y)
        got = getattr(interpreted, function)(t, Y)
        np.testing.assert_allclose(got, expected, rtol=1e-13, atol=1e-14, err_msg=function)
    np.testing.assert_allclose(
        interpreted.momenta(t, Y[:, :1], Y[:, 1:]), native.momenta(t, Y[:, :1], Y[:, 1:])
    )
    assert not interpreted.handed_over


def test_a_division_by_zero_is_not_finite_as_in_numba():
    """Kernels use numba's numpy error model: 1/0 is inf, never an exception in a loop."""
    mechanics = derive(scene(PLANETARY))
    native, interpreted = _pair(mechanics, "dop853")
    at_origin = np.array([[0.0, 0.3, 0.1, 1.0]])
    results = []
    for compiled in (native, interpreted):
        with np.errstate(all="ignore"):
            H = compiled.hamiltonian(0.0, at_origin)
            rhs = compiled.rhs(0.0, at_origin[0])
        assert not np.isfinite(H[0]) and not np.all(np.isfinite(rhs))
        results.append((H, rhs))
    np.testing.assert_array_equal(results[0][0], results[1][0])
    np.testing.assert_array_equal(results[0][1], results[1][1])


ROOT_WELL = """
title = "Square-root well"
[system]
coordinates = ["x"]
parameters = { k = 1.0 }
kinetic = "x_dot**2/2"
potential = "-k*sqrt(x)"
[initial]
x = 1.0
"""


def test_a_domain_error_gives_numbas_nan_and_leaves_the_arrays_as_numba_would():
    """Python's math.sqrt(-1) raises where numba returns nan: the call goes to numba."""
    mechanics = derive(scene(ROOT_WELL))
    native, interpreted = _pair(mechanics, "dop853")
    Y = np.array([[1.0, 0.5], [-1.0, 0.5]])
    with np.errstate(all="ignore"):
        expected = native.hamiltonian(0.0, Y)
        got = interpreted.hamiltonian(0.0, Y)
        assert math.isnan(expected[1]) and math.isnan(got[1])
        np.testing.assert_array_equal(np.isnan(got), np.isnan(expected))
        assert got[0] == expected[0]
        np.testing.assert_array_equal(
            np.isnan(interpreted.rhs(0.0, Y[1])), np.isnan(native.rhs(0.0, Y[1]))
        )
    assert not interpreted.handed_over


def test_ensembles_and_native_views_never_run_the_interpreter():
    mechanics = derive(scene(PENDULUM))
    wants = required_wants("yoshida4")
    native, interpreted = _pair(mechanics, "yoshida4", ())
    assert isinstance(interpreted.kernels, KernelHandover)
    assert interpreted.native().kernels is interpreted.kernels.native
    assert native.native() is native and native.handed_over
    Y0 = np.array([[0.5, 0.0], [1.0, 0.2], [2.0, -0.1]])
    a = ensemble(native, Y0, method="yoshida4", t_end=5.0, dt=0.01)
    b = ensemble(interpreted, Y0, method="yoshida4", t_end=5.0, dt=0.01)
    np.testing.assert_array_equal(a[1], b[1])
    assert not interpreted.handed_over
    assert wants <= interpreted.wanted


def test_with_parameters_keeps_the_hand_over_and_the_new_values():
    mechanics = derive(scene(DRIVEN_DAMPED))
    native, interpreted = _pair(mechanics, "dop853")
    name = native.parameter_names[0]
    value = float(native.parameters[0]) * 1.5
    a = _final(native.with_parameters({name: value}), "dop853", 1.0)
    b = _final(interpreted.with_parameters({name: value}), "dop853", 1.0)
    np.testing.assert_allclose(b.y[-1], a.y[-1], rtol=1e-11, atol=1e-12)
    y = native.initial_state()
    changed = interpreted.with_parameters({name: value})
    compile_natively(changed, "dop853")
    assert interpreted.handed_over  # one set of kernels, whatever the parameter values
    np.testing.assert_allclose(changed.momenta_from_velocities(0.0, y[:1], y[1:]), y[1:])
