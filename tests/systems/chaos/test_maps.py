"""Chaos maps (``systems.chaos.maps``): the Hénon–Heiles chaotic fraction grows with the
energy, the compiled loop's MEGNO agrees with the orbit's own, and a map does not depend
on how it is cut into chunks."""

import math

import numpy as np
import pytest

from systems.chaos import maps
from systems.chaos.lyapunov import LyapunovRun
from systems.chaos.variational import NotApplicable, load_tangent
from systems.compiled import compile_system
from systems.mechanics import derive
from systems.scene import load_scene
from systems.section import Section, state_on_section, states_on_section

SECTION = Section(0, 0.0, 1)  # Hénon–Heiles' x = 0, plotted in (y, p_y)


@pytest.fixture(scope="module")
def henon_heiles():
    compiled = compile_system(
        derive(load_scene("henon_heiles")), ("rhs", "hamiltonian", "separable")
    )
    return compiled, load_tangent(compiled)


def _map(compiled, tangent, energy, size=24, t_end=500.0, **options):
    kernel = maps.map_kernel(tangent, t_end=t_end)
    box = maps.section_box(compiled, SECTION, energy)
    return maps.chaos_map(
        kernel, maps.section_grid(compiled, SECTION, energy, size, size, box), **options
    )


def test_the_chaotic_fraction_grows_with_the_energy(henon_heiles):
    # Hénon & Heiles (1964): nearly all regular at E = 1/12, about half at 1/8, little
    # left at 1/6
    fractions = {}
    for energy in (1 / 12, 1 / 8, 1 / 6):
        result = _map(*henon_heiles, energy)
        assert result.complete
        valid = result.grid.valid.reshape(result.status.shape)
        stopped = int((result.status[valid] != 0).sum())
        # at E = 1/6, the escape energy, an orbit may leave through a saddle and diverge
        assert stopped == 0 if energy < 1 / 6 else stopped < 0.02 * valid.sum(), stopped
        fractions[energy] = (result.chaotic_fraction("megno"), result.chaotic_fraction("lyapunov"))
    for indicator in (0, 1):
        low, middle, high = (fractions[e][indicator] for e in (1 / 12, 1 / 8, 1 / 6))
        assert low < middle < high, fractions
    assert fractions[1 / 12][0] < 0.1
    assert 0.3 < fractions[1 / 8][0] < 0.7
    assert fractions[1 / 6][0] > 0.8


def test_every_start_is_on_the_section_at_the_energy(henon_heiles):
    compiled, _ = henon_heiles
    box = maps.section_box(compiled, SECTION, 1 / 8)
    grid = maps.section_grid(compiled, SECTION, 1 / 8, 30, 20, box)
    assert grid.starts.shape == (600, 4) and grid.names == ("y", "p_y")
    good = grid.starts[grid.valid]
    assert 0.2 * 600 < len(good) < 600  # the box holds the allowed region and more
    H = compiled.hamiltonian(0.0, good)
    assert np.abs(H - 1 / 8).max() < 1e-13
    assert (good[:, 0] == 0.0).all() and (good[:, 2] > 0).all()  # x = 0, p_x > 0
    # the allowed region's edge is inside the box, on every side
    edges = grid.valid.reshape(20, 30)
    assert not (edges[0].any() or edges[-1].any() or edges[:, 0].any() or edges[:, -1].any())
    # the window's click: the same state
    y, p_y = good[7, 1], good[7, 3]
    assert np.array_equal(state_on_section(compiled, SECTION, 1 / 8, y, p_y), good[7])
    assert state_on_section(compiled, SECTION, 1 / 8, 0.0, 0.6) is None  # p_y^2 / 2 > E
    assert np.isnan(states_on_section(compiled, SECTION, 1 / 8, [0.0], [0.6])).all()


def test_the_loop_agrees_with_the_lyapunov_run(henon_heiles):
    compiled, tangent = henon_heiles
    regular = state_on_section(compiled, SECTION, 1 / 6, 0.1, 0.0)
    chaotic = np.array([0.0, 0.0, math.sqrt(1 / 3), 0.0])  # E = 1/6
    kernel = maps.map_kernel(tangent, t_end=2000.0, dt=0.05)
    values, status = maps.map_chunk(kernel, np.stack([regular, chaotic]))
    assert (status == 0).all()
    run = LyapunovRun(tangent, y0=chaotic, t_end=2000.0)
    reference = run.run()
    # a regular orbit: <Y> near 2, the exponent's estimate near ln(t) / t
    assert abs(values[0, 0] - 2.0) < 0.1 and values[0, 1] < 3 * math.log(2000) / 2000
    # a chaotic one: the same exponent as Benettin's (both to t = 2000), <Y> ~ lambda t / 2
    assert abs(values[1, 1] - reference.maximal) < 0.15 * reference.maximal
    assert values[1, 0] > 20 and abs(values[1, 0] - values[1, 1] * 1000) < 0.3 * values[1, 0]


def test_the_harmonic_oscillator_is_periodic_and_isochronous():
    compiled = compile_system(
        derive(load_scene("harmonic_oscillator")), ("rhs", "hamiltonian", "separable")
    )
    kernel = maps.map_kernel(load_tangent(compiled), t_end=1000.0)
    values, status = maps.map_chunk(kernel, np.array([[1.0, 0.0], [0.3, -2.0]]))
    assert (status == 0).all()
    assert np.abs(values[:, 0]).max() < 0.05  # MEGNO -> 0: deviations stay bounded
    assert np.abs(values[:, 1]).max() < 5e-3


def test_the_map_does_not_depend_on_its_chunks_or_threads(henon_heiles):
    import numba

    compiled, tangent = henon_heiles
    whole = _map(compiled, tangent, 1 / 8, size=10, t_end=100.0)
    reports = []
    cut = _map(compiled, tangent, 1 / 8, size=10, t_end=100.0, chunk=7,
               progress=lambda done, total: reports.append((done, total)))  # fmt: skip
    threads = numba.get_num_threads()
    numba.set_num_threads(1)
    try:
        serial = _map(compiled, tangent, 1 / 8, size=10, t_end=100.0, chunk=1000)
    finally:
        numba.set_num_threads(threads)
    for other in (cut, serial):
        assert np.array_equal(whole.megno, other.megno, equal_nan=True)
        assert np.array_equal(whole.lyapunov, other.lyapunov, equal_nan=True)
    orbits = int(whole.grid.valid.sum())
    assert reports[-1] == (orbits, orbits) and len(reports) == math.ceil(orbits / 7)


def test_the_final_states_are_the_orbits_at_the_end(henon_heiles):
    compiled, tangent = henon_heiles
    starts = states_on_section(compiled, SECTION, 1 / 8, np.array([0.1, -0.2]), np.zeros(2))
    whole = maps.map_kernel(tangent, t_end=20.0, dt=0.1)
    half = maps.map_kernel(tangent, t_end=10.0, dt=0.1)
    final, middle, again = (np.full_like(starts, np.nan) for _ in range(3))
    assert (maps.map_chunk(whole, starts, final=final)[1] == 0).all()
    maps.map_chunk(half, starts, final=middle)
    maps.map_chunk(half, middle, final=again)  # the orbit goes on from where it was
    assert np.abs(final - again).max() < 1e-12 and np.abs(final - starts).min() > 1e-3
    assert np.abs(compiled.hamiltonian(0.0, final) - 1 / 8).max() < 1e-5


def test_chunks_grow_with_the_threads(monkeypatch):
    import numba

    monkeypatch.setattr(numba, "get_num_threads", lambda: 2)
    assert maps.chunk_rows(256, 64) == 256
    monkeypatch.setattr(numba, "get_num_threads", lambda: 16)
    assert maps.chunk_rows(256, 64) == 1024


def test_a_cancelled_map_stops_between_chunks(henon_heiles):
    compiled, tangent = henon_heiles
    calls = []

    def cancelled():
        calls.append(1)
        return len(calls) > 2

    result = _map(compiled, tangent, 1 / 8, size=10, t_end=50.0, chunk=5, cancelled=cancelled)
    assert not result.complete
    assert int((result.status == 0).sum()) == 10  # two chunks of five
    assert np.isnan(result.megno[result.status == -1]).all()


def test_a_grid_over_two_variables_keeps_the_rest_of_the_start(henon_heiles):
    compiled, _ = henon_heiles
    y0 = compiled.initial_state()
    grid = maps.variable_grid(compiled, ("x", "p_y"), 3, 2, ((-0.1, 0.1), (0.2, 0.4)), y0)
    assert grid.starts.shape == (6, 4) and grid.valid.all()
    assert np.allclose(grid.starts[:, 0], [-0.1, 0, 0.1] * 2)
    assert np.allclose(grid.starts[:, 3], [0.2] * 3 + [0.4] * 3)
    assert (grid.starts[:, 1] == y0[1]).all() and (grid.starts[:, 2] == y0[2]).all()
    with pytest.raises(ValueError, match="two different state variables"):
        maps.variable_grid(compiled, ("x", "z"), 3, 2, ((0, 1), (0, 1)), y0)


def test_methods_without_a_loop_are_refused_with_the_reason(henon_heiles):
    _, tangent = henon_heiles
    with pytest.raises(NotApplicable, match="fixed-step methods in one compiled loop"):
        maps.map_kernel(tangent, method="dop853")
    with pytest.raises(NotApplicable, match="end time must be finite"):
        maps.map_kernel(tangent, t_end=math.inf)


def test_an_implicit_method_maps_to_a_shorter_time_by_default():
    assert maps.default_t_end("yoshida4") == maps.default_t_end("rk4") == 500.0
    assert maps.default_t_end("gauss_legendre4") == maps.default_t_end("gauss_legendre6") == 100.0
    mechanics = derive(load_scene("double_pendulum"))  # a non-separable H
    kernel = maps.map_kernel(load_tangent(compile_system(mechanics, ("rhs", "hamiltonian"))))
    assert (kernel.method, kernel.t) == ("gauss_legendre4", pytest.approx(100.0))
