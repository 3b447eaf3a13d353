"""Chaos maps with taylor (``systems.chaos.taylor_map``): the variational system and
MEGNO's integral in the Taylor series, orbits in SIMD batches, against fixed-step maps."""

import numba
import numpy as np
import pytest

from systems.chaos import maps
from systems.chaos.taylor_map import megno_decomposition
from systems.chaos.variational import NotApplicable, load_tangent
from systems.compiled import compile_system
from systems.mechanics import derive
from systems.scene import load_scene
from systems.section import Section, states_on_section
from systems.taylor.coefficients import evaluate

SECTION = Section(0, 0.0, 1)


@pytest.fixture(scope="module")
def henon_heiles():
    compiled = compile_system(
        derive(load_scene("henon_heiles")), ("rhs", "hamiltonian", "separable")
    )
    return compiled, load_tangent(compiled)


def _grid(compiled, size, energy=1 / 8):
    box = maps.section_box(compiled, SECTION, energy)
    return maps.section_grid(compiled, SECTION, energy, size, size, box)


def test_the_extended_system_is_the_tangent_flow_and_megnos_integrand(henon_heiles):
    """The decomposition's right-hand side at a state: f, J delta (the compiled tangent
    function's, from ``variational``) and (t - t0) s (delta . J delta) / |delta|^2."""
    compiled, tangent = henon_heiles
    d = megno_decomposition(compiled.mechanics)
    rng = np.random.default_rng(3)
    y, delta = rng.normal(size=4) * 0.3, rng.normal(size=4)
    t, scale, t0 = 7.0, 0.01, 2.0
    P = np.concatenate([compiled.parameters, [scale, t0]])
    value = evaluate(d, t, np.concatenate([y, delta, [0.5]]), P)
    n = compiled.n
    flow = tangent.rhs(t, np.concatenate([y[:n], delta[:n], y[n:], delta[n:]]))
    f, Jd = (
        np.concatenate([flow[:n], flow[2 * n : 3 * n]]),
        np.concatenate([flow[n : 2 * n], flow[3 * n :]]),
    )
    assert np.allclose(value[:4], f, rtol=1e-14, atol=1e-15)
    assert np.allclose(value[4:8], Jd, rtol=1e-14, atol=1e-15)
    expected = (t - t0) * scale * (delta @ Jd) / (delta @ delta)
    assert value[8] == pytest.approx(expected, rel=1e-13)


def test_regular_orbits_megno_and_exponent_agree_with_a_fine_fixed_step_map(henon_heiles):
    """Regular orbits of E = 1/8 to t = 500: <Y>, Y(t) and the exponent's estimate from
    the taylor loop (adaptive steps, Gauss-Legendre over each step's series) against
    yoshida4 at dt = 0.005 (trapezoid sums over fixed steps): an independent
    integration and quadrature; and the orbits' energy kept to round-off."""
    compiled, tangent = henon_heiles
    starts = states_on_section(compiled, SECTION, 1 / 8, [0.1, -0.35, 0.3, 0.55], [0.0] * 4)
    taylor = maps.map_kernel(tangent, t_end=500.0, method="taylor")
    fine = maps.map_kernel(tangent, t_end=500.0, method="yoshida4", dt=0.005)
    final = np.empty_like(starts)
    values, status = maps.map_chunk(taylor, starts, final=final)
    reference, _ = maps.map_chunk(fine, starts)
    assert not status.any() and taylor.t == 500.0
    assert (values[:, 0] < 2.5).all(), values  # regular
    # measured: 6.6e-9, 3.0e-8, 2.4e-11 (at dt = 0.02: 2.4e-7, 7.2e-6, 6.2e-9: the
    # fixed-step sums converge to the taylor values)
    assert np.abs(values[:, 0] - reference[:, 0]).max() < 1e-7
    assert np.abs(values[:, 2] - reference[:, 2]).max() < 1e-6
    assert np.abs(values[:, 1] - reference[:, 1]).max() < 1e-9
    H = compiled.hamiltonian(0.0, final)
    assert np.abs(H - 1 / 8).max() < 1e-13


def test_the_map_classifies_as_a_fine_fixed_step_map_does(henon_heiles):
    """A 14 x 14 map at E = 1/8 to t = 500: the taylor map's regular/chaotic verdicts
    are those of yoshida4 at dt = 0.02 but for a few boundary cells (sticky orbits near
    <Y> = 4), and the default map's (dt 0.14) but for a few more; no cell is far off
    (above 6 in one, under 3 in the other)."""
    compiled, tangent = henon_heiles
    grid = _grid(compiled, 14)
    taylor = maps.chaos_map(maps.map_kernel(tangent, method="taylor"), grid)
    fine = maps.chaos_map(maps.map_kernel(tangent, method="yoshida4", dt=0.02), grid)
    default = maps.chaos_map(maps.map_kernel(tangent), grid)
    assert taylor.method == "taylor" and taylor.t_end == 500.0
    done = (taylor.status == 0) & (fine.status == 0)
    assert done.sum() == grid.valid.sum() > 100
    for other, few in ((fine, 0.02), (default, 0.06)):
        a, b = taylor.megno[done], other.megno[done]
        assert np.mean((a > 4) != (b > 4)) <= few, np.mean((a > 4) != (b > 4))
        assert not (((a > 6) & (b < 3)) | ((a < 3) & (b > 6))).any()
    assert 0.3 < taylor.chaotic_fraction() < 0.7


def test_the_same_numbers_on_one_and_two_threads_and_in_any_chunks(henon_heiles):
    compiled, tangent = henon_heiles
    grid = _grid(compiled, 9)
    kernel = maps.map_kernel(tangent, t_end=200.0, method="taylor")
    before = numba.get_num_threads()
    try:
        numba.set_num_threads(1)
        one = maps.chaos_map(kernel, grid)
        numba.set_num_threads(min(2, numba.config.NUMBA_NUM_THREADS))
        two = maps.chaos_map(kernel, grid, chunk=5)
    finally:
        numba.set_num_threads(before)
    for name in ("megno", "lyapunov", "megno_now", "status"):
        assert np.array_equal(getattr(one, name), getattr(two, name), equal_nan=True), name
    assert np.isfinite(one.megno[grid.valid.reshape(one.megno.shape)]).all()


def test_taylor_maps_refuse_with_reasons(henon_heiles):
    _, tangent = henon_heiles
    with pytest.raises(NotApplicable, match="tolerance, not a step"):
        maps.map_kernel(tangent, method="taylor", dt=0.1)
    with pytest.raises(NotApplicable, match="not a tolerance"):
        maps.map_kernel(tangent, method="yoshida4", tol=1e-10)
    chain = compile_system(derive(load_scene("pendulum_chain")), ("rhs", "hamiltonian"))
    with pytest.raises(NotApplicable, match="matrix form"):
        maps.map_kernel(load_tangent(chain), method="taylor")
