"""The Lyapunov spectrum, MEGNO, SALI and GALI on systems whose answers are known.

MEGNO convention (Cincotta & Simo): the mean <Y> tends to 2 for quasi-periodic orbits
and for any linear growth of the deviations (a Kepler orbit's shear), to 0 for a stable
periodic orbit of an isochronous system (the harmonic oscillator), and grows like
lambda t / 2 on a chaotic orbit."""

import math

import numpy as np
import pytest

from systems.chaos import lyapunov as ly
from systems.chaos.variational import NotApplicable, load_tangent
from systems.compiled import compile_system
from systems.mechanics import derive
from systems.scene import load_scene, parse_scene
from tests.systems.scenes import INVERTED_OSCILLATOR


def _compiled(scene):
    mechanics = derive(load_scene(scene) if "\n" not in scene else parse_scene(scene))
    wants = {"rhs", "hamiltonian"}
    if mechanics.separable_parts is not None:
        wants.add("separable")
    return compile_system(mechanics, wants)


@pytest.fixture(scope="module")
def henon_heiles():
    compiled = _compiled("henon_heiles")
    return compiled, load_tangent(compiled)


def _henon_heiles_start(energy, y, p_y=0.0):
    """On the section x = 0 with p_x > 0 at the given energy."""
    p_x = math.sqrt(2 * (energy - (y**2 / 2 - y**3 / 3)) - p_y**2)
    return np.array([0.0, y, p_x, p_y])


def test_the_inverted_oscillator_has_exponents_plus_and_minus_one():
    result = ly.lyapunov(_compiled(INVERTED_OSCILLATOR), t_end=2000.0)
    assert result.estimate.status == "ok"
    assert abs(result.estimate.maximal - 1.0) < 1e-3
    assert abs(result.estimate.exponents[1] + 1.0) < 1e-3
    # chaotic-like growth: <Y> ~ lambda t / 2, SALI zero (both vectors on the unstable one)
    assert abs(result.estimate.megno - 2000.0 / 2) < 1.0
    assert result.estimate.sali < 1e-12


def test_the_harmonic_oscillator_is_periodic_megno_zero():
    result = ly.lyapunov(_compiled("harmonic_oscillator"), t_end=1e4)
    estimate = result.estimate
    assert estimate.t == 1e4 and estimate.status == "ok"
    assert abs(estimate.maximal) < 1e-3
    assert abs(estimate.megno) < 0.05  # isochronous: deviations stay bounded


def test_the_kepler_problem_is_regular_megno_two():
    result = ly.lyapunov(_compiled("planetary_motion"), t_end=1e4)
    estimate = result.estimate
    assert estimate.status == "ok"
    assert 0.0 <= estimate.maximal < 1e-3  # ln(t)/t: the shear of the orbits
    assert abs(estimate.megno - 2.0) < 0.1
    assert len(estimate.exponents) == 4


def test_a_chaotic_henon_heiles_orbit_has_a_positive_exponent_and_megno_growing(henon_heiles):
    compiled, tangent = henon_heiles
    y0 = _henon_heiles_start(1 / 6, 0.0)
    result = ly.lyapunov(compiled, t_end=2000.0, y0=y0, tangent=tangent)
    estimate = result.estimate
    assert estimate.maximal > 0.05
    assert estimate.megno > 20
    # <Y> grows like lambda t / 2 (Cincotta and Simo)
    assert abs(estimate.megno - estimate.maximal * 2000 / 2) < 0.2 * estimate.megno
    history = result.history
    late = history["t"] > 500
    assert np.all(np.diff(history["megno"][late]) > 0) or history["megno"][-1] > 2 * np.interp(
        1000, history["t"], history["megno"]
    )
    assert estimate.sali < 1e-8  # the deviation vectors align


def test_a_regular_henon_heiles_orbit_has_megno_two(henon_heiles):
    compiled, tangent = henon_heiles
    for energy, y in ((1 / 6, 0.1), (1 / 12, 0.0)):
        result = ly.lyapunov(
            compiled, t_end=4000.0, y0=_henon_heiles_start(energy, y), tangent=tangent
        )
        assert abs(result.estimate.megno - 2.0) < 0.1
        assert result.estimate.maximal < 3e-3
        assert result.estimate.sali > 1e-4


@pytest.mark.parametrize(
    "method, dt", [("dop853", None), ("yoshida8", 0.05), ("gauss_legendre4", 0.05)]
)
def test_a_hamiltonian_spectrum_comes_in_pairs_summing_to_zero(henon_heiles, method, dt):
    compiled, tangent = henon_heiles
    result = ly.lyapunov(
        compiled, t_end=2000.0, y0=_henon_heiles_start(1 / 6, 0.0), tangent=tangent,
        method=method, dt=dt,
    )  # fmt: skip
    exponents = result.estimate.exponents
    assert exponents[0] > 0.05
    np.testing.assert_allclose(exponents + exponents[::-1], 0.0, atol=2e-4)
    assert abs(np.sum(exponents)) < 1e-6
    if method != "dop853":  # a symplectic tangent map keeps det = 1 to round-off
        assert abs(np.sum(exponents)) < 1e-10


def test_the_double_pendulum_spectrum_comes_in_pairs():
    result = ly.lyapunov(_compiled("double_pendulum"), t_end=2000.0)
    exponents = result.estimate.exponents
    assert exponents[0] > 1.0  # the catalogue start is chaotic
    np.testing.assert_allclose(exponents + exponents[::-1], 0.0, atol=1e-3)  # ~0.6/t
    assert abs(np.sum(exponents)) < 1e-6


def test_a_chain_in_matrix_form_has_a_spectrum_in_pairs():
    from systems.families import pendulum_chain

    compiled = compile_system(derive(parse_scene(pendulum_chain(5))), ("rhs", "hamiltonian"))
    estimate = ly.lyapunov(compiled, t_end=300.0).estimate
    assert estimate.status == "ok" and len(estimate.exponents) == 10
    assert abs(np.sum(estimate.exponents)) < 1e-8  # det of the tangent map: 1
    np.testing.assert_allclose(estimate.exponents + estimate.exponents[::-1], 0.0, atol=0.02)


def test_damping_makes_the_exponents_sum_to_the_mean_divergence():
    """Liouville: the sum of all 2n exponents is the time average of tr J, -b/m for the
    catalogue's damped pendulum (R = b l^2 theta_dot^2 / 2); the effect is included."""
    compiled = _compiled("damped_pendulum")
    result = ly.lyapunov(compiled, t_end=200.0)
    b, m = compiled.parameters[compiled.parameter_names.index("b")], 1.0
    assert abs(np.sum(result.estimate.exponents) + b / m) < 1e-8
    assert result.estimate.maximal < 0.0  # a stable focus: both -b/(2m)
    np.testing.assert_allclose(result.estimate.exponents, -b / (2 * m), atol=0.02)


def test_the_driven_damped_pendulum_is_chaotic_and_contracts():
    compiled = _compiled("driven_damped_pendulum")
    result = ly.lyapunov(compiled, t_end=2000.0)
    exponents = result.estimate.exponents
    assert exponents[0] > 0.05  # A = 1.5: the chaotic attractor
    assert abs(np.sum(exponents) + 0.5) < 1e-8  # tr J = -b


def test_the_running_estimates_do_not_depend_on_how_the_run_is_split(henon_heiles):
    compiled, tangent = henon_heiles
    y0 = _henon_heiles_start(1 / 6, 0.0)
    whole = ly.LyapunovRun(tangent, y0=y0, t_end=300.0)
    whole.run()
    pieces = ly.LyapunovRun(tangent, y0=y0, t_end=300.0)
    blocks = 0
    while not pieces.done:
        pieces.advance(seconds=0.0)  # one interval a call
        blocks += 1
    assert blocks == pieces.intervals > 5
    assert np.array_equal(whole.estimate.exponents, pieces.estimate.exponents)
    assert whole.estimate.megno == pieces.estimate.megno
    assert whole.history.t == pieces.history.t


def test_gali_of_a_regular_orbit_with_three_degrees_of_freedom_stays_away_from_zero():
    scene = """
title = "Three oscillators, weakly coupled"
[system]
coordinates = ["x", "y", "z"]
hamiltonian = "(p_x**2 + p_y**2 + p_z**2)/2 + (x**2 + 2*y**2 + 3*z**2)/2 + 0.01*x*y*z"
[initial]
x = 0.1
y = 0.1
z = 0.1
p_x = 0.0
p_y = 0.0
p_z = 0.0
"""
    result = ly.lyapunov(_compiled(scene), t_end=1000.0)
    estimate = result.estimate
    assert estimate.gali_order == 3 and len(estimate.exponents) == 6
    assert estimate.gali > 1e-3
    assert abs(estimate.megno - 2.0) < 0.3 or abs(estimate.megno) < 0.3


def test_gali_of_a_chaotic_orbit_with_three_degrees_of_freedom_falls_to_round_off():
    p_x = math.sqrt(2 * 0.15 - 0.01 + 2 * 0.001 / 6)  # E = 0.15
    scene = f"""
title = "Henon-Heiles in three dimensions"
[system]
coordinates = ["x", "y", "z"]
hamiltonian = "(p_x**2 + p_y**2 + p_z**2)/2 + (x**2 + y**2 + z**2)/2 + x**2*y - y**3/3 + 0.5*x**2*z - z**3/6"
[initial]
x = 0.0
y = 0.0
z = 0.1
p_x = {p_x!r}
p_y = 0.0
p_z = 0.0
"""  # noqa: E501
    estimate = ly.lyapunov(_compiled(scene), t_end=2000.0).estimate
    assert estimate.gali_order == 3 and estimate.status == "ok"
    assert estimate.maximal > 0.01 and estimate.megno > 8
    assert estimate.gali < 1e-15  # GALI_3 ~ exp(-(2 l1 - l2 - l3) t): the vectors align
    np.testing.assert_allclose(estimate.exponents + estimate.exponents[::-1], 0.0, atol=1e-3)


def test_fewer_exponents_give_the_largest_ones(henon_heiles):
    compiled, tangent = henon_heiles
    y0 = _henon_heiles_start(1 / 6, 0.0)
    # fixed steps: the same orbit whatever the vectors (DOP853's error norm takes them in)
    options = {"t_end": 500.0, "y0": y0, "tangent": tangent, "method": "yoshida8", "dt": 0.05}
    full = ly.lyapunov(compiled, **options)
    one = ly.lyapunov(compiled, exponents=1, **options)
    assert len(one.estimate.exponents) == 1
    assert abs(one.estimate.maximal - full.estimate.maximal) < 1e-9
    assert abs(one.estimate.megno - full.estimate.megno) < 1e-6


def test_methods_and_settings_that_cannot_carry_vectors_are_refused_with_the_reason():
    mechanics = derive(load_scene("henon_heiles"))
    assert "fictitious time" in ly.method_refusal(mechanics, "logh_yoshida6")
    assert "fictitious time" in ly.method_refusal(mechanics, "gauss_legendre6_tt")
    assert "scipy" in ly.method_refusal(mechanics, "radau")
    assert "no tangent counterpart" in ly.method_refusal(mechanics, "taylor")
    assert "taylor" not in ly.lyapunov_methods()
    assert "unknown method" in ly.method_refusal(mechanics, "nope")
    assert ly.method_refusal(mechanics, "yoshida8") is None
    pendulum = derive(load_scene("double_pendulum"))
    assert "separable" in ly.method_refusal(pendulum, "yoshida8")
    assert "[constraints]" in ly.method_refusal(derive(load_scene("cartesian_pendulum")), "dop853")
    assert ly.method_refusal(derive(load_scene("pendulum_chain")), "gauss_legendre6") is None
    tangent = load_tangent(_compiled("henon_heiles"))
    with pytest.raises(NotApplicable, match="exponents"):
        ly.LyapunovRun(tangent, exponents=5, t_end=10.0)
    with pytest.raises(NotApplicable, match="tol"):
        ly.LyapunovRun(tangent, method="yoshida8", tol=1e-9, t_end=10.0)
    for name in ly.lyapunov_methods():
        assert name not in ("radau", "bdf", "lsoda", "constrained_dop853")


def test_the_history_of_an_endless_run_stays_bounded():
    history = ly.History()
    for i in range(3 * ly.HISTORY_POINTS):
        history.append(ly.Estimate(float(i), np.array([1.0 / (i + 1)]), 2.0, 2.0, 0.5, 0.5, 2))
    arrays = history.arrays()
    assert ly.HISTORY_POINTS // 2 <= len(arrays["t"]) <= ly.HISTORY_POINTS
    assert arrays["t"][-1] == 3 * ly.HISTORY_POINTS - 1  # the latest is always there
    assert np.all(np.diff(arrays["t"]) > 0) and len({len(a) for a in arrays.values()}) == 1
