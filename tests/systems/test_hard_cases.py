"""The hard cases of issue 3: long runs, singular potentials, chaos, stiffness, blow-ups.

Case 7 (convergence orders) lives in ``tests/systems/integrators/test_steppers.py``.
Every case runs through ``systems.simulation.stream`` on catalogue scenes, with the
automatic method choice unless the case names a method.
"""

import math

import numpy as np
import pytest
from scipy.special import ellipj, ellipk

from systems.compiled import compile_system
from systems.mechanics import derive
from systems.scene import load_scene
from systems.simulation import PROBLEMS, stream

WANTS = ("rhs", "hamiltonian", "velocities", "separable")


def compiled(name, wants=WANTS):
    return compile_system(derive(load_scene(name)), wants)


def collect(blocks, diagnostic=None):
    t = np.concatenate([b.t for b in blocks])
    y = np.concatenate([b.y for b in blocks])
    if diagnostic is None:
        return t, y
    return t, y, np.concatenate([b.diagnostics[diagnostic] for b in blocks])


def kepler_at_apocentre(e, a=1.0):
    """(x, y, p_x, p_y) at apocentre of an orbit with k = m = 1; period 2 pi a^1.5."""
    return np.array([a * (1 + e), 0.0, 0.0, math.sqrt((1 - e) / (a * (1 + e)))])


@pytest.fixture(scope="module")
def kepler():
    return compiled("kepler_cartesian")


@pytest.fixture(scope="module")
def pendulum():
    return compiled("simple_pendulum")


@pytest.mark.slow
def test_1_kepler_energy_error_bounded_with_symplectic_but_drifting_with_rk(kepler):
    # e = 0.9, 1000 orbits, 4th-order symplectic (fixed-step triple jump): the maximum
    # energy error over 10, 100 and 1000 orbits is the same; DOP853 drifts linearly.
    P = 2 * math.pi
    y0 = kepler_at_apocentre(0.9)
    H0 = kepler.hamiltonian(0.0, y0[None])[0]
    blocks = list(
        stream(kepler, method="yoshida4", y0=y0, dt=P / 8000, t_end=1000 * P, diagnostics=("H",))
    )
    assert blocks[-1].status == "ok"
    t, _, H = collect(blocks, "H")
    err = np.abs(H / H0 - 1)
    e10, e100, e1000 = (err[t <= k * P].max() for k in (10, 100, 1000))
    assert e1000 < 1e-5
    assert e1000 < 1.2 * e10 and e100 < 1.2 * e10
    blocks = list(
        stream(kepler, method="dop853", y0=y0, tol=1e-8, t_end=1000 * P, diagnostics=("H",))
    )
    t, _, H = collect(blocks, "H")
    err = np.abs(H / H0 - 1)
    d10, d1000 = (err[t <= k * P].max() for k in (10, 1000))
    assert d1000 > 30 * d10  # linear drift: about 100x over 100x the time


@pytest.mark.parametrize("e", [0.99, 0.999])
def test_2_very_eccentric_kepler_orbits_stay_bound(kepler, e):
    P = 2 * math.pi
    y0 = kepler_at_apocentre(e)
    H0 = kepler.hamiltonian(0.0, y0[None])[0]
    blocks = list(stream(kepler, y0=y0, t_end=100 * P, diagnostics=("H",)))
    assert blocks[-1].method.startswith("logh")  # the automatic choice
    assert blocks[-1].status == "ok" and blocks[-1].t[-1] == 100 * P
    t, y, H = collect(blocks, "H")
    assert np.abs(H / H0 - 1).max() <= 1e-10
    assert np.all(H < 0)  # bound
    r = np.hypot(y[:, 0], y[:, 1])
    assert r.max() <= (1 + e) * (1 + 1e-9)
    # after whole periods the planet is back at apocentre, up to the phase error of the
    # default step (about 30 steps an orbit)
    np.testing.assert_allclose(y[-1], y0, atol=1e-4)


def test_3_pendulum_started_next_to_the_top_keeps_swinging(pendulum):
    y0 = np.array([math.pi - 1e-6, 0.0])
    blocks = list(stream(pendulum, y0=y0, t_end=1e5))
    assert blocks[-1].status == "ok" and blocks[-1].t[-1] == 1e5
    t, y = collect(blocks)
    assert np.abs(y[:, 0]).max() < math.pi
    # it swings (theta changes sign about twice a period, period about 20 s), not creeps
    assert np.count_nonzero(np.diff(np.sign(y[:, 0]))) > 5000


def test_4_pendulum_near_the_separatrix_against_jacobi_elliptic_functions(pendulum):
    g, l = 9.81, 1.0
    w = math.sqrt(g / l)
    k = 0.999
    m = k * k
    K = ellipk(m)
    period = 4 * K / w
    y0 = np.array([2 * math.asin(k), 0.0])
    blocks = list(
        stream(pendulum, y0=y0, t_end=200 * period, diagnostics=("H",), section=(0, 0.0, 1))
    )
    assert blocks[-1].status == "ok"
    t, y, H = collect(blocks, "H")
    err = np.abs(H / H[0] - 1)
    assert err.max() < 1e-4
    assert err.max() < 1.5 * err[t < 20 * period].max()  # bounded, not growing
    # exact: sin(theta/2) = k cd(w t | m); upward zero crossings at w t = 3K + 4K j
    sn, cn, dn, _ = ellipj(w * t[t < 2 * period], m)
    exact = 2 * np.arcsin(k * cn / dn)
    assert np.abs(y[t < 2 * period, 0] - exact).max() < 1e-2
    crossings = np.concatenate([b.events_t for b in blocks])
    assert len(crossings) == 200
    j = np.arange(len(crossings))
    phase = crossings - (3 * K + 4 * K * j) / w
    # accurate by default: after 200 periods the crossings are still at the exact times
    # (a symplectic method's phase error grows linearly; at the default step it stays tiny)
    assert np.abs(phase).max() < 1e-7 * period


@pytest.mark.slow
def test_5_henon_heiles_energy_bounded():
    system = compiled("henon_heiles")
    y0 = np.array([0.1, 0.0, 0.0, 0.5])
    blocks = list(stream(system, y0=y0, t_end=5e4, diagnostics=("H",)))
    assert blocks[-1].status == "ok"
    t, _, H = collect(blocks, "H")
    err = np.abs(H / H[0] - 1)
    assert err.max() < 1e-4
    assert err.max() < 1.5 * err[t < 5e3].max()


@pytest.mark.slow
def test_6_double_pendulum_energy_bounded_and_time_reversible():
    system = compiled("double_pendulum", ("rhs", "hamiltonian"))
    blocks = list(stream(system, t_end=1e4, diagnostics=("H",)))
    assert blocks[-1].method.startswith("gauss_legendre")
    assert blocks[-1].status == "ok"
    t, _, H = collect(blocks, "H")
    err = np.abs(H / H[0] - 1)
    assert err.max() < 1e-3
    # bounded, not growing; below 1e-10 only round-off is left, which grows like sqrt(t)
    assert err.max() < max(1.5 * err[t < 1e3].max(), 1e-10)
    # forward, flip the momenta, forward again, flip: back at the start. Chaos amplifies
    # round-off by about e^(lambda t), so the round trip is checked over t = 10
    # (a few Lyapunov times), not 1e4, where no finite precision could return.
    y0 = system.initial_state()
    there = list(stream(system, method="gauss_legendre4", y0=y0, t_end=10.0, dt=0.01))[-1]
    flipped = there.y[-1] * [1, 1, -1, -1]
    back = list(stream(system, method="gauss_legendre4", y0=flipped, t_end=10.0, dt=0.01))[-1]
    assert np.abs(back.y[-1] * [1, 1, -1, -1] - y0).max() < 1e-8
    assert np.abs(there.y[-1] - y0).max() > 0.1  # it did go somewhere


@pytest.mark.slow
def test_8_round_off_grows_like_sqrt_t_with_compensated_summation(kepler):
    # The log-H stepper's energy error on Kepler is round-off only (its truncation error
    # leaves the energy exact), so it shows Brouwer's law. The RMS error over the second
    # half of [0, k orbits], averaged over 6 nearby orbits, against k = 10 .. 1e4.
    P = 2 * math.pi * 2**1.5  # the catalogue orbit: a = 2
    ks = np.array([10, 30, 100, 300, 1000, 3000, 10000])

    def mean_square(compensated):
        total = np.zeros(len(ks))
        for r in range(6):
            y0 = kepler.initial_state() * [1, 1, 1, 1 + 0.01 * r]
            blocks = list(
                stream(kepler, y0=y0, t_end=1e4 * P, diagnostics=("H",), compensated=compensated)
            )
            assert blocks[-1].status == "ok"
            t, _, H = collect(blocks, "H")
            err = np.abs(H / H[0] - 1)
            total += [np.mean(err[(t > k * P / 2) & (t <= k * P)] ** 2) for k in ks]
        return np.sqrt(total / 6)

    rms = mean_square(True)
    slope = np.polyfit(np.log(ks), np.log(rms), 1)[0]
    assert slope <= 0.6
    assert rms[-1] < 1e-13
    assert mean_square(False)[-1] > 2 * rms[-1]  # the compensation is what does it


def test_9_stiff_spring_pendulum_neither_stalls_nor_explodes():
    system = compiled("stiff_spring_pendulum", ("rhs", "hamiltonian"))
    blocks = list(stream(system, t_end=10.0, diagnostics=("H",)))
    assert blocks[-1].status == "ok" and blocks[-1].t[-1] == 10.0
    t, y, H = collect(blocks, "H")
    assert np.all(np.isfinite(y))
    assert np.abs(H / H[0] - 1).max() < 1e-6
    assert np.abs(y[:, 0] - 1.0).max() < 1e-4  # the stiff rod keeps its length
    assert np.abs(y[:, 1]).max() < 1.0 + 1e-6  # the swing keeps its amplitude


def test_10_spherical_pendulum_through_the_pole_gives_no_nans():
    system = compiled("spherical_pendulum", ("rhs", "hamiltonian"))
    # a tiny azimuthal momentum: the bob passes about 3e-4 rad from the pole, where phi
    # turns at 1e4 rad/s
    blocks = list(stream(system, y0=[1.0, 0.0, 0.0, 1e-3], t_end=20.0))
    _, y = collect(blocks)
    assert np.all(np.isfinite(y))
    last = blocks[-1]
    # the fixed step cannot follow phi there: the run stops and says why (an energy error
    # or an implicit solve that fails, with how fast the motion gets)
    assert last.status in PROBLEMS
    assert last.message and str(round(last.t[-1], 2))[:3] in last.message
    # the adaptive method the message points to gets through
    through = list(stream(system, method="dop853", y0=[1.0, 0.0, 0.0, 1e-3], t_end=2.0))
    assert through[-1].status == "ok"
    assert np.all(np.isfinite(np.concatenate([b.y for b in through])))


@pytest.mark.parametrize("method", [None, "dop853", "radau"])
def test_10_radial_kepler_fall_stops_at_the_singularity(method):
    system = compiled("planetary_motion", ("rhs", "hamiltonian"))
    # at rest at r = 1: it falls into r = 0 at t = pi / (2 sqrt 2)
    blocks = list(stream(system, method=method, y0=[1.0, 0.0, 0.0, 0.0], t_end=5.0))
    _, y = collect(blocks)
    assert np.all(np.isfinite(y))
    last = blocks[-1]
    assert last.status == "singular"
    assert "singular near t = 1.11" in last.message
    assert last.t[-1] <= math.pi / (2 * math.sqrt(2)) + 1e-6


def test_10_a_start_on_the_singularity_is_refused_with_a_status():
    system = compiled("planetary_motion", ("rhs", "hamiltonian"))
    blocks = list(stream(system, y0=[0.0, 0.0, 0.0, 0.0], t_end=1.0))
    assert len(blocks) == 1
    assert blocks[0].status == "singular" and "initial state" in blocks[0].message
    assert np.all(np.isfinite(blocks[0].y))
