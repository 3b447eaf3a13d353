"""Systems of more than four coordinates (issue 12): lattices and particles in Cartesian
coordinates (M diagonal) and pendulum chains (M full, solved numerically in the kernels)
derive for any size and run right."""

from __future__ import annotations

import numpy as np
import pytest
import sympy
from sympy.physics import mechanics as sm

from systems.compiled import compile_system
from systems.families import fpu_chain, pendulum_chain
from systems.mechanics import derive
from systems.scene import load_scene, parse_scene
from systems.simulation import Run, Sampler


def trajectory(text: str, t_end: float, samples: int = 20) -> np.ndarray:
    mechanics = derive(parse_scene(text))
    compiled = compile_system(mechanics, ["rhs", "hamiltonian", "separable"])
    run = Run(compiled, method="yoshida8", t_end=t_end, diagnostics=("H",))
    rows = list(Sampler(run, np.linspace(0.0, t_end, samples + 1)))
    assert run.finished and run.t == pytest.approx(t_end)
    return np.array([y for _, y in rows]), mechanics


def test_an_fpu_chain_from_t_and_v_and_from_h_gives_the_same_trajectory():
    from_tv, mechanics_tv = trajectory(fpu_chain(12, form="tv"), 20.0)
    from_h, mechanics_h = trajectory(fpu_chain(12, form="h"), 20.0)
    assert mechanics_tv.classification.separable and mechanics_h.classification.separable
    assert mechanics_h.momenta is not None  # the Legendre transform inverted, at n = 12
    np.testing.assert_allclose(from_tv, from_h, atol=1e-11)
    assert np.max(np.abs(from_tv[-1] - from_tv[0])) > 0.1  # it moved


def test_the_figure_eight_returns_after_one_period_and_stays_for_a_hundred():
    """Chenciner-Montgomery initial conditions to Simo's 8 digits: back to about 1e-7 after
    one period; after 100 the drift along the orbit (from the 8-digit period) stays small
    and the energy error at round-off."""
    mechanics = derive(load_scene("figure_eight"))
    compiled = compile_system(mechanics, ["rhs", "hamiltonian", "separable"])
    period = 6.32591398
    run = Run(compiled, method="yoshida8", t_end=100 * period, dt=period / 2000)
    y0 = run.y0.copy()
    rows = list(Sampler(run, [period, 100 * period]))  # the start, then these times
    assert [t for t, _ in rows[1:]] == pytest.approx([period, 100 * period])
    assert np.max(np.abs(rows[1][1] - y0)) < 1e-6
    assert np.max(np.abs(rows[-1][1] - y0)) < 1e-4
    energies = compiled.hamiltonian(0.0, np.array([y for _, y in rows]))
    assert np.max(np.abs(energies - run.H0)) <= 1e-12 * abs(run.H0)


def lagranges_method_chain(n: int):
    """M(q) and F(q, qdot) of an n-link chain (unit masses and rods, g = 9.81) formed by
    sympy.physics.mechanics' LagrangesMethod, as numpy functions of (q, qdot)."""
    q = sm.dynamicsymbols(f"q1:{n + 1}")
    qd = [sm.dynamicsymbols(f"q{i}", 1) for i in range(1, n + 1)]
    frame, origin = sm.ReferenceFrame("N"), sm.Point("O")
    origin.set_vel(frame, 0)
    particles, joint = [], origin
    for i in range(n):
        joint = joint.locatenew(f"P{i}", sympy.sin(q[i]) * frame.x - sympy.cos(q[i]) * frame.y)
        joint.set_vel(frame, joint.pos_from(origin).dt(frame))
        particle = sm.Particle(f"m{i}", joint, 1)
        particle.potential_energy = 9.81 * joint.pos_from(origin).dot(frame.y)
        particles.append(particle)
    method = sm.LagrangesMethod(sm.Lagrangian(frame, *particles), q)
    method.form_lagranges_equations()
    x = sympy.symbols(f"x0:{n}")
    v = sympy.symbols(f"v0:{n}")
    plain = dict(zip(qd, v, strict=True)) | dict(zip(q, x, strict=True))
    mass = sympy.lambdify((x, v), method.mass_matrix.xreplace(plain), "numpy")
    forcing = sympy.lambdify((x, v), method.forcing.xreplace(plain), "numpy")
    return mass, forcing


@pytest.mark.parametrize("n", [5, 8])
def test_chain_accelerations_agree_with_lagranges_method(n):
    """M qddot = F of our derivation against sympy.physics.mechanics at random states."""
    mechanics = derive(parse_scene(pendulum_chain(n)))
    assert mechanics.matrix_form is not None  # no symbolic inverse at this size
    parameters = {mechanics.params[k]: v for k, v in mechanics.scene.parameters}
    ours_m = sympy.lambdify(
        (mechanics.q, mechanics.qdot), mechanics.mass_matrix.xreplace(parameters), "numpy"
    )
    ours_f = sympy.lambdify(
        (mechanics.q, mechanics.qdot), mechanics.forcing.xreplace(parameters), "numpy"
    )
    their_m, their_f = lagranges_method_chain(n)
    rng = np.random.default_rng(n)
    for _ in range(5):
        q, qdot = rng.uniform(-2, 2, n), rng.uniform(-2, 2, n)
        ours = np.linalg.solve(np.array(ours_m(q, qdot), float), np.ravel(ours_f(q, qdot)))
        theirs = np.linalg.solve(np.array(their_m(q, qdot), float), np.ravel(their_f(q, qdot)))
        assert np.max(np.abs(ours - theirs)) <= 1e-10 * np.max(np.abs(theirs))


def test_a_chain_in_matrix_form_has_the_closed_forms_equations():
    """Forced into matrix form, a 3-link chain's kernels give the closed form's Hamilton's
    equations and H: the Cholesky solve inside the kernels is the Legendre transform."""
    import systems.mechanics

    text = pendulum_chain(3, drawing=False)
    closed = derive(parse_scene(text))
    assert closed.matrix_form is None
    saved = systems.mechanics.SYMBOLIC_INVERSE_LIMIT
    systems.mechanics.SYMBOLIC_INVERSE_LIMIT = 1
    try:
        matrix = systems.mechanics._derive(parse_scene(text))  # not from the cache
    finally:
        systems.mechanics.SYMBOLIC_INVERSE_LIMIT = saved
    assert matrix.matrix_form is not None
    wants = ["rhs", "hamiltonian", "velocities"]
    # the reference as plain Python (no compile); the matrix form's as numba compiles it
    kernels = [compile_system(closed, wants), compile_system(matrix, wants)]
    rng = np.random.default_rng(3)
    for _ in range(5):
        y = rng.uniform(-2, 2, 6)
        rates = [k.rhs(0.0, y) for k in kernels]
        np.testing.assert_allclose(rates[1], rates[0], rtol=1e-12, atol=1e-12)
        energies = [k.hamiltonian(0.0, y[None])[0] for k in kernels]
        assert energies[1] == pytest.approx(energies[0], rel=1e-13)
        speeds = [k.velocities(0.0, y[None])[0] for k in kernels]
        np.testing.assert_allclose(speeds[1], speeds[0], rtol=1e-12, atol=1e-12)
