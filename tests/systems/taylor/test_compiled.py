"""The compiled coefficient function (LLVM IR written from the decomposition) against the
numpy reference evaluator, on catalogue scenes and a scene with every function."""

import numpy as np
import pytest

from systems.compiled import compile_system
from systems.taylor.coefficients import taylor_coefficients
from systems.taylor.compiled import (
    NAME,
    UNROLL_BUDGET,
    UNROLLED,
    decomposition_of,
    load_taylor,
    taylor_code,
    unrolled_terms,
)
from systems.taylor.decompose import NotDecomposable
from tests.systems.taylor.test_systems import _mechanics

SCENES = (
    "harmonic_oscillator",
    "kepler_cartesian",
    "planetary_motion",
    "double_pendulum",
    "henon_heiles",
    "fpu_chain",
    "driven_damped_pendulum",
    "every_function",
)


@pytest.mark.parametrize("name", SCENES)
def test_the_coefficients_are_the_reference_evaluators(name):
    mechanics = _mechanics(name)
    d = decomposition_of(mechanics)
    kernels = load_taylor(mechanics)
    assert kernels.width == d.m + len(d.nodes)
    compiled = compile_system(mechanics, ("rhs",))
    P = compiled.parameters * 1.1
    y0 = compiled.initial_state()
    y0 = y0 + np.random.default_rng(7).uniform(-0.1, 0.1, y0.shape)
    # one function, the order read from the array's shape: the default order unrolled
    # (below a budget of products), the others looped
    for order in (UNROLLED, 7, 1, UNROLLED + 3):
        got = kernels.coefficients(0.4, y0, P, order)
        want = taylor_coefficients(d, 0.4, y0, P, order, nodes=True)
        assert got.shape == want.shape
        # the state's to order N; the varying nodes' to N - 1 (order N of a node is not
        # needed) where the looped form ran (the unrolled one, of the default order, keeps
        # them in registers); the constant nodes' at order 0 only
        varying = [d.m + i for i, node in enumerate(d.nodes) if not node.constant]
        if order == UNROLLED and unrolled_terms(d, order) <= UNROLL_BUDGET:
            varying = []
        constant = [d.m + i for i, node in enumerate(d.nodes) if node.constant]
        # relative to each column's largest: the state's to 4e-15 (measured: 1.7e-15, the
        # double pendulum's order 20, where the unrolled form multiplies by reciprocals,
        # sums pairwise and a square's pairs once; 1.0e-15 looped), the nodes' (sums of
        # up to 20 rounded products, in another order than numpy's) to 1e-14
        parts = [
            (got[:, : d.m], want[:, : d.m], 4e-15),
            (got[:order, varying], want[:order, varying], 1e-14),
            (got[:1, constant], want[:1, constant], 1e-15),
        ]
        for a, b, tolerance in parts:
            if b.size:
                column = np.abs(b).max(axis=0)
                assert np.all(np.abs(a - b) <= tolerance * column), (name, order)


def test_the_ir_is_remembered_per_scene(tmp_path, monkeypatch):
    monkeypatch.setenv("PHASE_EXPLORER_CACHE", str(tmp_path))
    mechanics = _mechanics("double_pendulum")
    first = taylor_code(mechanics)
    second = taylor_code(mechanics)
    assert second.text == first.text
    assert f"@{NAME}(" in first.text or f'@"{NAME}"(' in first.text
    d = decomposition_of(mechanics)
    assert (first.m, first.width) == (d.m, d.m + len(d.nodes))
    stored = list(tmp_path.rglob("*.txt"))
    assert any(first.text.encode() in path.read_bytes() for path in stored)


def test_a_system_in_matrix_form_is_refused_with_the_reason():
    mechanics = _mechanics("pendulum_chain")
    with pytest.raises(NotDecomposable, match="matrix form"):
        taylor_code(mechanics)


FALL = """
[system]
coordinates = ["x"]
parameters = { F = 0.5 }
hamiltonian = "p_x**2/2 - F*x"
[initial]
x = 1.0
p_x = -2.0
"""


def test_a_parameter_as_an_equation_and_a_polynomial_solution():
    # dx/dt = p, dp/dt = F (a parameter read, no node): x = 1 - 2t + F t^2/2
    from systems.mechanics import derive
    from systems.scene import parse_scene
    from systems.simulation import stream

    mechanics = derive(parse_scene(FALL))
    kernels = load_taylor(mechanics)
    for order in (UNROLLED, 5):
        got = kernels.coefficients(0.0, np.array([1.0, -2.0]), np.array([0.5]), order)
        want = np.zeros((order + 1, 2))
        want[:3, 0] = [1.0, -2.0, 0.25]
        want[:2, 1] = [-2.0, 0.5]
        np.testing.assert_array_equal(got[:, :2], want)
    # every coefficient beyond the second is zero: one step to the end, exact
    compiled = compile_system(mechanics, ("rhs",))
    blocks = list(stream(compiled, method="taylor", t_end=10.0, energy_tolerance=None))
    assert blocks[-1].status == "ok" and blocks[-1].steps == 1
    np.testing.assert_allclose(blocks[-1].y[-1], [1.0 - 20.0 + 25.0, -2.0 + 5.0], rtol=1e-15)


@pytest.mark.parametrize("name", ["henon_heiles", "driven_damped_pendulum", "every_function"])
def test_the_batch_function_is_the_scalar_one_lane_by_lane(name):
    """``taylor_batch`` (every value a vector of ``lanes()`` doubles; the libm functions
    called lane by lane) gives each lane's coefficients bitwise as
    ``taylor_coefficients`` at that lane's time and state, in both forms."""
    mechanics = _mechanics(name)
    kernels = load_taylor(mechanics)
    function, B = kernels.batch()
    compiled = compile_system(mechanics, ("rhs",))
    P = compiled.parameters * 1.1
    rng = np.random.default_rng(3)
    Y = compiled.initial_state()[:, None] + rng.uniform(-0.1, 0.1, (kernels.m, B))
    T = rng.uniform(0.0, 2.0, B)
    for order in (UNROLLED, 7):
        out = np.zeros((order + 1, kernels.width, B))
        kernels._batch[0].taylor_batch(T, np.ascontiguousarray(Y), P, out)
        for lane in range(B):
            want = kernels.coefficients(T[lane], Y[:, lane].copy(), P, order)
            assert np.array_equal(out[:, : kernels.m, lane], want[:, : kernels.m]), (order, lane)


@pytest.mark.parametrize("name", ["driven_damped_pendulum", "every_function"])
def test_the_sweep_function_is_the_scalar_one_at_each_lanes_parameters(name):
    """``TaylorKernels.sweep`` (an orbit diagram's batch: P (k, B), each lane its own
    parameters) gives each lane's coefficients bitwise as ``taylor_coefficients`` at
    that lane's parameters, time and state, in both forms; with lane 0's parameters
    everywhere the other lanes would differ."""
    mechanics = _mechanics(name)
    kernels = load_taylor(mechanics)
    function, B, width = kernels.sweep()
    assert width == kernels.width  # the same decomposition here
    compiled = compile_system(mechanics, ("rhs",))
    rng = np.random.default_rng(4)
    P = compiled.parameters[:, None] * rng.uniform(0.8, 1.2, (len(compiled.parameters), B))
    Y = compiled.initial_state()[:, None] + rng.uniform(-0.1, 0.1, (kernels.m, B))
    T = rng.uniform(0.0, 2.0, B)
    for order in (UNROLLED, 7):
        out = np.zeros((order + 1, kernels.width, B))
        kernels._sweep[0].taylor_batch(T, np.ascontiguousarray(Y), P.ravel(), out)
        for lane in range(B):
            want = kernels.coefficients(T[lane], Y[:, lane].copy(), P[:, lane].copy(), order)
            assert np.array_equal(out[:, : kernels.m, lane], want[:, : kernels.m]), (order, lane)
            if lane:
                other = kernels.coefficients(T[lane], Y[:, lane].copy(), P[:, 0].copy(), order)
                assert not np.array_equal(out[:, : kernels.m, lane], other[:, : kernels.m])


def test_a_conserved_variable_is_a_constant_and_quotients_share_a_reciprocal():
    """Polar Kepler: ``decompose_mechanics`` makes p_theta (its equation 0) a constant,
    so ``p_theta / (m r^2)`` and ``k / r^2`` are scalings of one node ``1 / r^2``; the
    series are those of the decomposition without ``conserve`` to round-off, and the
    compiled function's too."""
    from systems.taylor.decompose import decompose

    mechanics = _mechanics("planetary_motion")
    d = decomposition_of(mechanics)
    parameters = [mechanics.params[name] for name, _ in mechanics.scene.parameters]
    variables = (*mechanics.q, *mechanics.p)
    plain = decompose(mechanics.hamilton_equations, variables, parameters, mechanics.t)
    assert plain.conserved == () and d.conserved == (3,)
    quotients = [n for n in d.nodes if n.op == "div" and not n.constant]
    assert len(quotients) == 1 and quotients[0].args[0].kind == "num"
    assert len([n for n in plain.nodes if n.op == "div" and not n.constant]) == 2
    y0, P = np.array([1.9, 0.3, 0.01, 0.43]), np.array([1.2, 0.8])
    want = taylor_coefficients(plain, 0.0, y0, P, UNROLLED)
    scale = np.abs(want).max(axis=0)
    for got in (
        taylor_coefficients(d, 0.0, y0, P, UNROLLED),
        load_taylor(mechanics).coefficients(0.0, y0, P, UNROLLED)[:, : d.m],
    ):
        assert np.all(np.abs(got - want) <= 2e-15 * scale), np.abs(got - want).max(axis=0) / scale
