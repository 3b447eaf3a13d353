"""The tangent functions: J(y) times any number of vectors, the system's own values, and
the tangent map of each family that carries them (the derivative of its numerical flow)."""

import numpy as np
import pytest

from systems.chaos import variational as va
from systems.compiled import compile_system
from systems.integrators.registry import STEPPERS, make_runner
from systems.mechanics import derive
from systems.scene import load_scene, parse_scene

SCENES = ("henon_heiles", "planetary_motion", "double_pendulum", "driven_damped_pendulum")


def _compiled(name):
    mechanics = derive(load_scene(name))
    wants = {"rhs", "hamiltonian"}
    if mechanics.separable_parts is not None:
        wants.add("separable")
    return compile_system(mechanics, wants)


def _jacobian_by_differences(compiled, t, y, eps=1e-6):
    columns = []
    for i in range(len(y)):
        e = np.zeros(len(y))
        e[i] = eps
        columns.append((compiled.rhs(t, y + e) - compiled.rhs(t, y - e)) / (2 * eps))
    return np.array(columns).T


@pytest.mark.parametrize("name", SCENES)
def test_the_jacobian_is_that_of_hamiltons_equations_effects_included(name):
    compiled = _compiled(name)
    tangent = va.load_tangent(compiled)
    y = compiled.initial_state() + np.linspace(0.01, 0.03, 2 * compiled.n)
    J = tangent.jacobian(0.7, y)
    assert J.shape == (2 * compiled.n, 2 * compiled.n)
    scale = max(1.0, np.abs(J).max())
    assert np.abs(J - _jacobian_by_differences(compiled, 0.7, y)).max() < 1e-7 * scale


@pytest.mark.parametrize("k", [1, 2, 3, 7])
def test_one_function_serves_any_number_of_vectors_in_the_extended_layout(k):
    compiled = _compiled("double_pendulum")
    tangent = va.load_tangent(compiled)
    rng = np.random.default_rng(1)
    y = compiled.initial_state() + 0.1
    V = rng.standard_normal((4, k))
    Y = va.extended(y, V)
    assert Y.shape == (4 * (1 + k),)
    y_back, V_back = va.split(Y, 2)
    assert np.array_equal(y_back, y) and np.array_equal(V_back, V)
    f, JV = va.split(tangent.rhs(0.0, Y), 2)
    assert np.array_equal(f, compiled.rhs(0.0, y))  # the system's own rhs, bit for bit
    np.testing.assert_allclose(JV, tangent.jacobian(0.0, y) @ V, rtol=1e-13, atol=1e-14)


def test_the_gradients_of_a_separable_hamiltonian_carry_the_hessians():
    compiled = _compiled("henon_heiles")
    tangent = va.load_tangent(compiled)
    assert set(tangent.code.names) == {
        "tangent_rhs", "tangent_grad_kinetic", "tangent_grad_potential",
    }  # fmt: skip
    x, y = 0.2, -0.3
    V = np.array([[1.0, 0.0], [0.0, 1.0], [2.0, 3.0], [5.0, 7.0]])
    Y = va.extended(np.array([x, y, 0.4, 0.1]), V)
    grad_kinetic, grad_potential = tangent.functions(("grad_kinetic", "grad_potential"))
    from systems.codegen import driver_module, entry_point

    out = np.empty(len(Y) // 2)
    call = entry_point(driver_module().call4, (grad_potential, 0.0, Y, tangent.parameters, out))
    call(grad_potential, 0.0, Y, tangent.parameters, out)
    # V = (x^2 + y^2)/2 + x^2 y - y^3/3: V_q and V_qq dq for dq = (1, 0), (0, 1)
    hessian = np.array([[1 + 2 * y, 2 * x], [2 * x, 1 - 2 * y]])
    np.testing.assert_allclose(out[:2], [x + 2 * x * y, y + x**2 - y**2], rtol=1e-15)
    np.testing.assert_allclose(out[2:4], hessian[:, 0], rtol=1e-15)
    np.testing.assert_allclose(out[4:6], hessian[:, 1], rtol=1e-15)
    call = entry_point(driver_module().call3, (grad_kinetic, Y, tangent.parameters, out))
    call(grad_kinetic, Y, tangent.parameters, out)
    assert np.array_equal(out, [0.4, 0.1, 2.0, 5.0, 3.0, 7.0])  # T = |p|^2/2: T_pp dp = dp


def _differences(compiled, stepper, y0, setting, t_end, steps, eps=1e-6, t0=0.0):
    """Central differences of the end states of runs from y0 +- eps e_i at t0."""
    columns = []
    for i in range(len(y0)):
        ends = []
        for sign in (1, -1):
            start = y0.copy()
            start[i] += sign * eps
            runner = make_runner(compiled, stepper, start, t0, t_end, setting, None)
            runner.advance(steps, 2)
            ends.append(runner.y.copy())
        columns.append((ends[0] - ends[1]) / (2 * eps))
    return np.array(columns).T


@pytest.mark.parametrize(
    "method, dt", [("yoshida8", 0.05), ("leapfrog", 0.01), ("gauss_legendre6", 0.1), ("rk4", 0.02)]
)
def test_each_fixed_step_family_carries_the_tangent_map_of_its_own_scheme(method, dt):
    """The vectors carried by a method are the derivative of that method's numerical flow
    (central differences of two runs from nearby starts by the same method and steps),
    not merely of the exact flow: a splitting steps the tangent with its own drifts and
    kicks, Gauss-Legendre with its own collocation."""
    compiled = _compiled("henon_heiles")
    tangent = va.load_tangent(compiled)
    stepper = STEPPERS[method]
    y0 = np.array([0.0, 0.1, 0.45, 0.1])
    extended_run = make_runner(tangent, stepper, va.extended(y0, np.eye(4)), 0.0, 1e3, dt, None)
    assert extended_run.advance(200, 2).steps == 200
    y_end, V_end = va.split(extended_run.y, 2)
    plain = make_runner(compiled, stepper, y0, 0.0, 1e3, dt, None)
    plain.advance(200, 2)
    if stepper.family.name == "gauss":  # iterated until the vectors converge too
        np.testing.assert_allclose(y_end, plain.y, rtol=0, atol=1e-14)
    else:  # explicit: the orbit is the plain run's, bit for bit
        assert np.array_equal(y_end, plain.y)
    expected = _differences(compiled, stepper, y0, dt, 1e3, 200)
    np.testing.assert_allclose(V_end, expected, atol=2e-8 * np.abs(V_end).max())


def test_dop853_carries_the_derivative_of_the_flow():
    compiled = _compiled("henon_heiles")
    tangent = va.load_tangent(compiled)
    stepper = STEPPERS["dop853"]
    y0 = np.array([0.0, 0.1, 0.45, 0.1])
    run = make_runner(tangent, stepper, va.extended(y0, np.eye(4)), 0.0, 20.0, 1e-13, None)
    run.advance(10**6, 2)
    assert run.t == 20.0
    _, V_end = va.split(run.y, 2)
    expected = _differences(compiled, stepper, y0, 1e-14, 20.0, 10**6)
    np.testing.assert_allclose(V_end, expected, atol=1e-7 * np.abs(V_end).max())


def test_a_free_particle_has_a_zero_hessian_of_v_written_as_zeros():
    scene = parse_scene(
        'title = "free"\n[system]\ncoordinates = ["x"]\nhamiltonian = "p_x**2/2"\n'
        "[initial]\nx = 0.0\np_x = 1.0\n"
    )
    compiled = compile_system(derive(scene), ("rhs", "hamiltonian", "separable"))
    tangent = va.load_tangent(compiled)
    Y = va.extended(np.array([0.0, 1.0]), np.array([[1.0, 2.0], [3.0, 4.0]]))
    # dq' = dp, dp' = 0 whatever the output held before
    assert np.array_equal(tangent.rhs(0.0, Y), [1.0, 3.0, 4.0, 0.0, 0.0, 0.0])


def test_constraints_are_refused_with_the_reason():
    constrained = derive(load_scene("cartesian_pendulum"))
    assert "[constraints]" in va.refusal(constrained)
    with pytest.raises(va.NotApplicable, match="constraints"):
        va.tangent_code(constrained)
    assert va.refusal(derive(load_scene("fpu_chain"))) is None  # diagonal M: closed form


def test_a_system_in_matrix_form_solves_for_the_vectors_velocities():
    """Five links: M(q) is not inverted symbolically; the tangent solves M dqdot =
    dp - R dq for each vector, with the drivers' solver."""
    from systems.families import pendulum_chain

    compiled = compile_system(derive(parse_scene(pendulum_chain(5))), ("rhs", "hamiltonian"))
    assert compiled.mechanics.matrix_form is not None
    tangent = va.load_tangent(compiled)
    y = compiled.initial_state() + np.linspace(0.05, 0.3, 10)
    J = tangent.jacobian(0.3, y)
    expected = _jacobian_by_differences(compiled, 0.3, y)
    assert np.abs(J - expected).max() < 1e-8 * np.abs(J).max()
    f, _ = va.split(tangent.rhs(0.3, va.extended(y, np.eye(10))), 5)
    np.testing.assert_allclose(f, compiled.rhs(0.3, y), rtol=1e-13, atol=1e-13)


@pytest.mark.parametrize(
    "name, method, dt",
    [("mathieu_oscillator", "yoshida6", 0.01), ("kapitza_pendulum", "gauss_legendre4", 0.001),
     ("bead_on_rotating_hoop", "rk4", 0.01)],
)  # fmt: skip
def test_driven_and_rheonomic_systems_from_a_later_start(name, method, dt):
    """t in V (a splitting's kicks take it), a shaken support, a rotating wire."""
    compiled = _compiled(name)
    stepper = STEPPERS[method]
    if stepper.needs_separable:
        compiled = compile_system(compiled.mechanics, {"rhs", "hamiltonian", "separable"})
    tangent = va.load_tangent(compiled)
    y0 = compiled.initial_state() + 0.05
    m = len(y0)
    run = make_runner(tangent, stepper, va.extended(y0, np.eye(m)), 0.3, 1e3, dt, None)
    run.advance(300, 2)
    _, V_end = va.split(run.y, m // 2)
    expected = _differences(compiled, stepper, y0, dt, 1e3, 300, t0=0.3)
    np.testing.assert_allclose(V_end, expected, atol=1e-8 * np.abs(V_end).max())
