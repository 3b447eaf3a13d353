"""Equilibria right: gyroscopic normal modes, degenerate equilibria decided by higher-order
terms, and continua of equilibria reported as one set."""

import json
import math

import numpy as np
import pytest
import sympy

from systems.mechanics import derive
from systems.report import equilibria_sentences
from systems.scene import load_scene, parse_scene
from systems.textbook.equilibria import equilibria_json, search_equilibria

ROTATING = """
title = "Particle in a rotating frame"
[system]
coordinates = ["x", "y"]
parameters = { m = 1.0, W = 0.7, kx = 2.0, ky = 3.0 }
lagrangian = "m*((x_dot - W*y)**2 + (y_dot + W*x)**2)/2 - (kx*x**2 + ky*y**2)/2"
"""

ROTATING_H = """
title = "Particle in a rotating frame, by a Hamiltonian with no Lagrangian"
[system]
coordinates = ["x", "y"]
parameters = { W = 0.7, kx = 2.0, ky = 3.0, c = 0.01 }
hamiltonian = "(p_x**2 + p_y**2)/2 + W*(y*p_x - x*p_y) + (kx*x**2 + ky*y**2)/2 + c*p_x**4"
"""
# the quartic term (no Lagrangian: linearised from J Hess H) leaves the linearisation at
# the origin that of the rotating frame


def _scene(potential: str, coordinates=("x", "y")) -> str:
    kinetic = " + ".join(f"{c}_dot**2" for c in coordinates)
    return f"""
title = "U = {potential}"
[system]
coordinates = {list(coordinates)!r}
parameters = {{ m = 1.0 }}
kinetic = "m*({kinetic})/2"
potential = "{potential}"
""".replace("'", '"')


def _rotating_frame_omega_squared(W: float, kx: float, ky: float) -> np.ndarray:
    """The textbook's normal modes of ``xdd - 2W yd + (kx - W^2) x = 0``,
    ``ydd + 2W xd + (ky - W^2) y = 0`` (m = 1): with x, y ~ exp(i w t),
    ``(a - w^2)(b - w^2) - 4 W^2 w^2 = 0``, a = kx - W^2, b = ky - W^2: the roots w^2 of
    ``w^4 - (kx + ky + 2 W^2) w^2 + (kx - W^2)(ky - W^2) = 0``, ascending (complex when
    the discriminant is negative)."""
    s = kx + ky + 2 * W**2
    p = (kx - W**2) * (ky - W**2)
    root = np.sqrt(complex(s * s - 4 * p))
    return np.sort_complex(np.array([(s - root) / 2, (s + root) / 2]))


def test_the_textbook_formula_itself():
    """The formula above, checked against det(-w^2 M + i w G + K) built by hand in sympy
    and against the numbers of the issue, before the code is tested against it."""
    w, W, kx, ky = sympy.symbols("w W k_x k_y", real=True)
    M = sympy.eye(2)
    G = sympy.Matrix([[0, -2 * W], [2 * W, 0]])
    K = sympy.diag(kx - W**2, ky - W**2)
    det = sympy.expand((-(w**2) * M + sympy.I * w * G + K).det())
    expected = sympy.expand(w**4 - (kx + ky + 2 * W**2) * w**2 + (kx - W**2) * (ky - W**2))
    assert sympy.simplify(det - expected) == 0
    omega = np.sqrt(_rotating_frame_omega_squared(0.7, 2.0, 3.0).real)
    np.testing.assert_allclose(omega, [0.8489, 2.2933], atol=1e-4)
    assert np.all(_rotating_frame_omega_squared(2.0, 2.0, 3.0).real > 0)  # stable at W = 2


@pytest.mark.parametrize("text", [ROTATING, ROTATING_H], ids=["lagrangian", "hamiltonian"])
def test_rotating_frame_normal_modes_include_the_gyroscopic_terms(text):
    mech = derive(parse_scene(text))
    assert (mech.lagrangian is None) == (text is ROTATING_H)
    (eq,) = search_equilibria(mech).equilibria
    assert eq.q == {"x": 0.0, "y": 0.0} and eq.stable and eq.kind == "minimum"
    np.testing.assert_allclose(eq.frequencies, [0.8489, 2.2933], atol=1e-4)
    exact = np.sqrt(_rotating_frame_omega_squared(0.7, 2.0, 3.0).real)
    np.testing.assert_allclose(eq.frequencies, exact, rtol=1e-10)
    # without the gyroscopic terms it would be sqrt(kx - W^2), sqrt(ky - W^2) (the old answer)
    np.testing.assert_allclose(eq.omega_squared, [2 - 0.49, 3 - 0.49], rtol=1e-12)
    assert not np.allclose(eq.frequencies, np.sqrt(eq.omega_squared), rtol=1e-2)
    if mech.lagrangian is None:  # H_qp
        np.testing.assert_allclose(eq.gyroscopic, [[0, -0.7], [0.7, 0]], atol=1e-12)
    else:
        np.testing.assert_allclose(eq.gyroscopic, [[0, -1.4], [1.4, 0]], atol=1e-12)
        # every complex mode shape solves (-w^2 M + i w G + K) v = 0
        K = np.diag([2 - 0.49, 3 - 0.49])
        for w, v in zip(eq.frequencies, eq.modes.T, strict=True):
            residual = (-(w**2) * np.eye(2) + 1j * w * eq.gyroscopic + K) @ v
            assert np.linalg.norm(residual) < 1e-10 * np.linalg.norm(v)
            assert abs(v[0]) > 0.1 and abs(v[1]) > 0.1  # x and y move together...
            assert abs(v[1] / v[0]).real == pytest.approx(abs(v[1] / v[0]))
            assert abs((v[1] / v[0]).real) < 1e-10  # ... a quarter period apart


@pytest.mark.parametrize("text", [ROTATING, ROTATING_H], ids=["lagrangian", "hamiltonian"])
@pytest.mark.parametrize("W", [0.7, 1.0, 1.3, 1.45, 1.55, 1.7, 1.8, 2.0, 3.0])
def test_gyroscopic_stabilization_and_the_instability_band(text, W):
    """Stable below sqrt(kx), unstable (a growing mode) between sqrt(kx) and sqrt(ky),
    stable again above sqrt(ky) although U then has a maximum."""
    mech = derive(parse_scene(text))
    (eq,) = search_equilibria(mech, parameters={"W": W}).equilibria
    omega_squared = _rotating_frame_omega_squared(W, 2.0, 3.0)
    band = math.sqrt(2.0) < W < math.sqrt(3.0)
    assert eq.stable == (not band)
    if band:
        assert eq.kind == "saddle" and eq.verdict == "unstable: linear"
        assert eq.frequencies == []
        (negative,) = [w2.real for w2 in omega_squared if w2.real < 0]
        assert eq.growth_rates == pytest.approx([math.sqrt(-negative)], rel=1e-9)
    else:
        np.testing.assert_allclose(eq.frequencies, np.sqrt(omega_squared.real), rtol=1e-9)
        assert eq.growth_rates == []
        np.testing.assert_allclose(np.abs(eq.eigenvalues.real), 0.0, atol=1e-9)
    if W > math.sqrt(3.0):
        assert eq.kind == "maximum" and eq.verdict == "stable: gyroscopic"
        assert "gyroscopic stabilization" in eq.decided_by


def test_the_old_answer_for_w_2_was_unstable_and_is_now_stable_in_every_output():
    mech = derive(parse_scene(ROTATING.replace("W = 0.7", "W = 2.0")))
    (data,) = equilibria_json(mech)
    assert data["stable"] and data["kind"] == "maximum"
    np.testing.assert_allclose(data["frequencies"], [0.394603, 3.583893], atol=1e-6)
    json.dumps(data)  # plain data
    (line,), _ = equilibria_sentences(mech, digits=4)
    assert (
        line
        == "x = 0, y = 0: stable by gyroscopic stabilization (U has a maximum), ω = 0.3946, 3.584"
    )
    (line,), _ = equilibria_sentences(derive(parse_scene(ROTATING)), digits=4)
    assert line == "x = 0, y = 0: stable, ω = 0.8489, 2.293 (with the gyroscopic terms)"


PENNING = """
title = "Charge in a magnetic field over a potential hill (a Penning trap's plane)"
[system]
coordinates = ["x", "y"]
parameters = { m = 1.0, e = 1.0, B = 3.0, k = 2.0 }
lagrangian = "m*(x_dot**2 + y_dot**2)/2 + e*B*(x*y_dot - y*x_dot)/2 + k*(x**2 + y**2)/2"
"""


@pytest.mark.parametrize("B", [2.0, 2.8, 2.9, 3.0, 5.0])
def test_a_magnetic_field_holds_a_charge_on_a_potential_hill(B):
    """x, y ~ exp(i w t): w = ±wc/2 ± sqrt(wc^2/4 - k/m), wc = eB/m: real (stable) once
    wc^2 > 4k/m, although U = -k r^2/2 has a maximum."""
    (eq,) = search_equilibria(derive(parse_scene(PENNING)), parameters={"B": B}).equilibria
    assert eq.kind == "maximum"
    inside = B**2 / 4 - 2.0
    if inside > 0:
        expected = sorted([B / 2 - math.sqrt(inside), B / 2 + math.sqrt(inside)])
        assert eq.stable and eq.frequencies == pytest.approx(expected, rel=1e-9)
    else:  # w = ±B/2 ± i sqrt(-inside): growth at sqrt(-inside)
        assert not eq.stable
        assert eq.growth_rates == pytest.approx([math.sqrt(-inside)], rel=1e-9)  # one spiral


# -- degenerate equilibria ----------------------------------------------------------------


@pytest.mark.parametrize("symbolic", [True, False])
@pytest.mark.parametrize(
    ("potential", "stable", "verdict", "order"),
    [
        ("x**4/4", True, "stable: rises", 4),
        ("x**6", True, "stable: rises", 6),
        ("x**3", False, "unstable: odd", 3),
        ("-x**4", False, "unstable: falls", 4),
    ],
)
def test_degenerate_equilibria_are_decided_by_higher_order_terms(
    potential, stable, verdict, order, symbolic
):
    mech = derive(parse_scene(_scene(potential, ("x",))))
    (eq,) = search_equilibria(mech, symbolic=symbolic).equilibria
    assert eq.q["x"] == pytest.approx(0.0, abs=1e-6)
    assert eq.kind == "degenerate" and eq.stable is stable
    assert eq.verdict == verdict and eq.order == order
    assert "the linearisation is degenerate" in eq.decided_by
    assert f"power {order}" in eq.decided_by
    assert eq.frequencies == []  # no linear oscillation: the period depends on the amplitude
    data = eq.as_json()
    assert data["kind"] == "degenerate" and data["order"] == order
    assert data["stable"] is stable and "degenerate" in data["decided_by"]


@pytest.mark.parametrize(
    ("potential", "stable"),
    [
        # along y = 0 both rise as x^4/4, but U must be followed where dU/dy = 0
        ("x**4/4 + y**2/2 + x**2*y", False),  # y = -x^2: U = -x^4/4
        ("x**4/4 + y**2/2 + x**2*y/2", True),  # y = -x^2/2: U = x^4/8
    ],
)
def test_degenerate_direction_is_followed_with_the_others_relaxed(potential, stable):
    result = search_equilibria(derive(parse_scene(_scene(potential))))
    (eq,) = result.equilibria  # not dozens of near-roots around the slow Newton limit
    assert eq.q == pytest.approx({"x": 0.0, "y": 0.0}, abs=1e-6)
    assert eq.kind == "degenerate" and eq.stable is stable and eq.order == 4
    if stable:
        assert eq.frequencies == pytest.approx([1.0], rel=1e-9)  # the y mode


# -- continua -----------------------------------------------------------------------------

HAT = "(x**2 + y**2 - 1)**2/4"


@pytest.mark.parametrize(
    "options",
    [{}, {"symbolic": False}, {"box": {"x": (-2.0, 2.0), "y": (-2.0, 2.0)}}],
    ids=["default", "numeric", "box"],
)
def test_mexican_hat_is_one_circle_of_equilibria(options):
    mech = derive(parse_scene(_scene(HAT)))
    result = search_equilibria(mech, **options)
    sets = [e for e in result.equilibria if e.continuum is not None]
    points = [e for e in result.equilibria if e.continuum is None]
    assert len(sets) == 1 and len(points) == 1  # the circle, and the top of the hat
    (ring,) = sets
    assert ring.kind == "continuum" and ring.stable
    assert ring.frequencies == pytest.approx([math.sqrt(2.0)], abs=1e-6)  # radial
    assert ring.q == pytest.approx({"x": 1.0, "y": 0.0}, abs=1e-9)
    circle = ring.continuum
    assert circle.dimension == 1 and circle.closed
    assert circle.description == "the circle x² + y² = 1"
    assert circle.found > 100  # the scan's points, each an "equilibrium" before
    r = np.hypot(circle.points[:, 0], circle.points[:, 1])
    np.testing.assert_allclose(r, 1.0, atol=1e-9)
    angles = np.sort(np.arctan2(circle.points[:, 1], circle.points[:, 0]))
    assert np.max(np.diff(np.r_[angles, angles[0] + 2 * math.pi])) < 0.2  # all the way round
    assert "neutral along it" in ring.decided_by
    (top,) = points
    assert top.q == pytest.approx({"x": 0.0, "y": 0.0}, abs=1e-9) and top.kind == "maximum"
    assert not top.stable


def test_mexican_hat_in_json_and_sentences():
    mech = derive(parse_scene(_scene(HAT)))
    data = equilibria_json(mech)
    assert len(data) == 2
    ring = next(e for e in data if "set" in e)
    assert ring["set"] == {
        "dimension": 1,
        "description": "the circle x² + y² = 1",
        "equation": "x**2 + y**2 = 1",
        "closed": True,
        "neutral_along": True,
    }
    assert ring["stable"] and ring["frequencies"] == [pytest.approx(math.sqrt(2), abs=1e-9)]
    lines, _ = equilibria_sentences(mech, digits=4)
    assert lines == [
        "the circle x² + y² = 1 (through x = 1, y = 0): a curve of equilibria, neutral along "
        "it; stable across it, ω = 1.414",
        "x = 0, y = 0: unstable (maximum)",
    ]


def test_a_continuum_through_angles_closes_on_the_torus():
    """U = -cos(a - b): the diagonal a = b (stable across) and a = b + pi (unstable), each
    a closed curve on the torus, not a hundred points."""
    result = search_equilibria(derive(parse_scene(_scene("-cos(a - b)", ("a", "b")))))
    assert result.periodic == ("a", "b")
    low, high = result.equilibria
    assert low.kind == high.kind == "continuum"
    assert low.continuum.closed and high.continuum.closed
    assert low.stable and low.frequencies == pytest.approx([math.sqrt(2.0)], rel=1e-9)
    assert not high.stable and high.growth_rates == pytest.approx([math.sqrt(2.0)], rel=1e-9)
    assert low.q == pytest.approx({"a": 0.0, "b": 0.0}, abs=1e-9)
    d = np.mod(high.continuum.points[:, 0] - high.continuum.points[:, 1], 2 * math.pi)
    np.testing.assert_allclose(d, math.pi, atol=1e-9)
    assert "along (1, 1)" in low.continuum.description


def test_a_surface_of_equilibria_is_one_set():
    result = search_equilibria(
        derive(parse_scene(_scene("(x**2 + y**2 + z**2 - 1)**2/4", ("x", "y", "z"))))
    )
    sets = [e for e in result.equilibria if e.continuum is not None]
    (sphere,) = sets
    assert sphere.continuum.dimension == 2
    assert sphere.continuum.description == "the surface x**2 + y**2 + z**2 = 1"
    assert sphere.frequencies == pytest.approx([math.sqrt(2.0)], abs=1e-6)
    assert sphere.q == pytest.approx({"x": 1.0, "y": 0.0, "z": 0.0}, abs=1e-9)
    np.testing.assert_allclose(np.linalg.norm(sphere.continuum.points, axis=1), 1.0, atol=1e-9)
    assert sphere.continuum.found > 100


def test_a_circle_with_a_transverse_spring_is_described_with_the_fixed_coordinate():
    result = search_equilibria(
        derive(parse_scene(_scene("(x**2 + y**2 - 1)**2/4 + z**2/2", ("x", "y", "z"))))
    )
    (ring,) = [e for e in result.equilibria if e.continuum is not None]
    assert ring.continuum.description == "the circle x² + y² = 1 at z = 0"
    assert ring.frequencies == pytest.approx([1.0, math.sqrt(2.0)], abs=1e-6)


# -- the catalogue ------------------------------------------------------------------------


@pytest.mark.parametrize(
    "name",
    [
        "simple_pendulum",
        "double_pendulum",
        "bead_on_rotating_hoop",
        "henon_heiles",
        "spherical_pendulum",
        "coupled_oscillators",
        "stiff_spring_pendulum",
    ],
)
def test_catalogue_equilibria_are_unchanged_where_there_are_no_gyroscopic_terms(name):
    """Without velocity-linear terms or degenerate points the new analysis must give what
    K v = w^2 M v gives: stable exactly at the minima of U, with w = sqrt(w^2)."""
    result = search_equilibria(derive(load_scene(name)))
    assert result.equilibria
    for eq in result.equilibria:
        assert not np.any(eq.gyroscopic)
        assert eq.kind in ("minimum", "saddle", "maximum")
        assert eq.stable == (eq.kind == "minimum")
        if eq.stable:
            np.testing.assert_allclose(eq.frequencies, np.sqrt(eq.omega_squared), rtol=1e-12)
        else:
            rates = np.sqrt(-eq.omega_squared[eq.omega_squared < 0])
            np.testing.assert_allclose(sorted(eq.growth_rates), sorted(rates), rtol=1e-9)
