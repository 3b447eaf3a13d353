"""Unilateral constraints g(q, t) >= 0: impacts, resting contact and release.

The bouncing ball (``resources/scenes/bouncing_ball.toml``): x, y with T = m (x_dot**2 +
y_dot**2)/2, V = m g y and the floor y >= 0, dropped from height h with a horizontal
speed. In free fall it reaches the floor after t_1 = sqrt(2 h / g) with speed
v_0 = sqrt(2 g h); Newton's law of restitution sends it back up at e v_0, and after the
k-th impact at e**k v_0. Between impacts k and k + 1 it flies for 2 e**k v_0 / g and rises
to (e**k v_0)**2 / (2 g): apex heights fall by e**2 per bounce and the times between
impacts by e. The impacts end at t_1 + (2 e v_0 / g) / (1 - e) (a Zeno sequence); then
the ball slides along the floor at its horizontal speed, and the floor pushes it up with
m g. The force of a constraint is -grad(g) lambda (the convention of holonomic ones, see
``systems.constraints``), so lambda = -m g there: a unilateral multiplier is <= 0.

The gas molecule (``gas_in_box.toml``): a free particle between the walls x >= 0,
a - x >= 0, y >= 0, b - y >= 0 with elastic impacts (no restitution parameter: e = 1).
Each wall reverses one velocity component, so the motion is the free motion folded into
the box.

A particle on top of a sphere (here a circle, x**2 + y**2 - R**2 >= 0, gravity along
-y), started on it at angle theta_0 from the top with a small speed v_0 along it: energy
conservation gives v**2 = v_0**2 + 2 g R (cos(theta_0) - cos(theta)), and the surface
pushes with m (g cos(theta) - v**2 / R), which vanishes at
cos(theta) = (2 cos(theta_0) + v_0**2 / (g R)) / 3, near 2/3: there it leaves.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from systems import constraints
from systems.compiled import compile_system
from systems.integrators import STEPPERS
from systems.mechanics import DerivationError, derive
from systems.report import derivation_json, readable
from systems.scene import load_scene, parse_scene
from systems.simulation import Run, Sampler, required_wants, stream

G, M, H0, VX = 9.81, 1.0, 1.0, 0.8  # the bouncing ball's g, m, height and x_dot
T1 = math.sqrt(2 * H0 / G)
V0 = math.sqrt(2 * G * H0)


# What ``run`` compiles (``explorer.commands.run_cmd.prepare``), so that the command's
# tests reuse the ball's kernels: numba takes about 15 s for a constrained scene's.
WANTS = required_wants("constrained_dop853") | {"hamiltonian", "velocities"}


def _compiled(scene):
    """The scene's system, with what ``run`` compiles."""
    return compile_system(derive(scene), WANTS)


@pytest.fixture(scope="module")
def ball():
    return _compiled(load_scene("bouncing_ball"))


def _trajectory(compiled, **options):
    options.setdefault("method", "constrained_dop853")
    blocks = list(stream(compiled, max_points=1_000_000, **options))
    assert blocks[-1].status == "ok", blocks[-1].message
    return np.concatenate([b.t for b in blocks]), np.concatenate([b.y for b in blocks])


def _arriving(t):
    """The rows that arrive at an event (an impact, a contact): the run keeps the state
    before the event and the state after it, at the same time."""
    arriving = np.zeros(len(t), dtype=bool)
    arriving[:-1] = t[1:] == t[:-1]
    return arriving


def _impacts(t, y, floor=1e-12):
    """The states right after each impact on the floor (y = 0, moving up): (t_k, v_k)."""
    after = np.flatnonzero((np.abs(y[:, 1]) <= floor) & (y[:, 3] > 0.0))
    return t[after], y[after, 3] / M, after


# -- the bouncing ball -------------------------------------------------------------------------


def test_bounces_follow_the_exact_free_fall(ball):
    """Measured: the first 30 impact times agree with the exact ones to 2e-13, the rebound
    speeds to 3e-12 (relative), the ratios of the apex heights and of the times between
    impacts to 3e-12 and 9e-13; y never goes below 0 (51 impacts, then rest)."""
    e = 0.8
    t, y = _trajectory(ball, t_end=6.0)
    tk, vk, _ = _impacts(t, y)
    assert len(tk) >= 40
    k = np.arange(1, 31)
    speeds = e**k * V0
    times = T1 + np.concatenate([[0.0], np.cumsum(2 * e ** k[:-1] * V0 / G)])
    assert np.max(np.abs(tk[:30] - times)) <= 1e-10
    assert np.max(np.abs(vk[:30] / speeds - 1.0)) <= 1e-9
    # apex heights (e**k v_0)**2 / (2 g) fall by e**2; the times between impacts by e
    apex = vk[:30] ** 2 / (2 * G)
    assert np.max(np.abs(apex[1:] / apex[:-1] - e**2)) <= 1e-9
    gaps = np.diff(tk[:30])
    assert np.max(np.abs(gaps[1:] / gaps[:-1] - e)) <= 1e-8
    assert tk[0] == pytest.approx(T1, abs=1e-12)
    assert y[:, 1].min() >= -1e-10
    assert np.all(np.diff(t) >= 0.0)
    # the horizontal motion goes on untouched by the floor
    assert np.max(np.abs(y[:, 0] - (-2.0 + VX * t))) <= 1e-10
    assert np.max(np.abs(y[:, 2] - M * VX)) <= 1e-12


def test_a_drawn_run_shows_every_flight(ball):
    """After the second bounce DOP853 integrates a flight (a parabola) exactly, so its
    error control would cross each one in a single step, impact to impact, and a drawing
    of the states kept would show the ball lying on the floor from t = 1.2 s. With the
    window's bound on the steps (``max_step="drawing"``) every flight of the first
    fifteen has states, its highest within 0.1 % of the drop height of its exact apex
    (measured: 0.02 %), and the impacts stay exact."""
    e = 0.8
    t, y = _trajectory(ball, t_end=4.0, max_step="drawing")
    tk, vk, _ = _impacts(t, y)
    k = np.arange(1, 16)
    times = T1 + np.concatenate([[0.0], np.cumsum(2 * e ** k[:-1] * V0 / G)])
    assert np.max(np.abs(tk[:15] - times)) <= 1e-10
    for i in range(14):
        flight = (t > tk[i]) & (t < tk[i + 1])
        apex = (e ** (i + 1) * V0) ** 2 / (2 * G)
        assert flight.any(), i
        assert y[flight, 1].max() == pytest.approx(apex, abs=1e-3 * H0), i
    # without the bound, the flights after the second are single steps
    t, y = _trajectory(ball, t_end=4.0)
    tk, _, _ = _impacts(t, y)
    assert not ((t > tk[3]) & (t < tk[4])).any()


def test_both_sides_of_each_impact_are_kept_whatever_the_stride(ball):
    """Each impact leaves two rows at its time: the ball arriving (y = 0, moving down)
    and leaving (e times as fast, up). A run that keeps only some of its steps (a
    stride, as the window asks for while a block keeps few states) still keeps both,
    so no drawing joins the arrival to a state after the bounce."""
    for max_points in (1_000_000, 6):
        blocks = list(stream(ball, method="constrained_dop853", t_end=3.0, max_points=max_points))
        t = np.concatenate([b.t for b in blocks])
        y = np.concatenate([b.y for b in blocks])
        arrive = np.flatnonzero(t[1:] == t[:-1])
        assert len(arrive) == 6, max_points  # impacts at 0.45, 1.17, 1.75, 2.21, 2.58, 2.88
        leave = arrive + 1
        assert np.all(np.abs(y[arrive, 1]) <= 1e-12) and np.all(y[leave, 1] == y[arrive, 1])
        assert np.allclose(y[leave, 3], -0.8 * y[arrive, 3], rtol=1e-12)
        if max_points == 6:
            assert len(t) < 60  # the stride left most steps out, not the impacts


def test_energy_is_kept_between_bounces_and_lost_at_each(ball):
    t, y = _trajectory(ball, t_end=3.0)
    H = ball.hamiltonian(t, y)
    tk, vk, after = _impacts(t, y)
    # from the start to the first impact, and between impacts: constant
    starts = np.concatenate([[0], after])
    ends = np.concatenate([after, [len(t)]])
    for first, stop in zip(starts, ends, strict=True):
        piece = H[first:stop]
        assert np.ptp(piece) <= 1e-12 * H[0], (t[first], np.ptp(piece))
    # at the k-th impact the vertical kinetic energy drops by the factor e**2
    kinetic = H[after] - M * VX**2 / 2
    assert kinetic[0] == pytest.approx(0.64 * M * G * H0, rel=1e-12)
    assert len(kinetic) >= 5
    assert np.allclose(kinetic[1:] / kinetic[:-1], 0.64, rtol=1e-10)


def test_an_elastic_ball_keeps_its_energy_over_a_hundred_bounces(ball):
    """e = 1 (the restitution slider at 1): the ball bounces with period 2 t_1 for ever.
    Measured: over 100 bounces the relative energy error stays below 3e-12, the impact
    times within 6e-11 of the exact ones and the rebound speeds within 2e-12 of v_0."""
    elastic = ball.with_parameters({"restitution": 1.0})
    t_end = 200 * T1 + T1 / 2  # 100 impacts, at t_1 (2 k - 1)
    t, y = _trajectory(elastic, t_end=t_end)
    tk, vk, _ = _impacts(t, y)
    assert len(tk) == 100
    assert np.max(np.abs(tk - T1 * (2 * np.arange(1, 101) - 1))) <= 3e-10
    assert np.max(np.abs(vk / V0 - 1.0)) <= 1e-10
    H = elastic.hamiltonian(t, y)
    assert np.max(np.abs(H - H[0])) / H[0] <= 1e-10
    assert y[:, 1].min() >= -1e-10 and y[:, 1].max() <= H0 + 1e-10


def test_the_ball_comes_to_rest_and_the_floor_pushes_with_m_g(ball):
    e = 0.8
    t, y = _trajectory(ball, t_end=8.0)
    zeno = T1 + 2 * e * V0 / G / (1 - e)  # where the bounces would end
    tk, _, _ = _impacts(t, y)
    # the last impact comes 5e-5 before the Zeno limit (where a rebound would rise less
    # than the contact gap, 1e-10: the contact becomes a resting one); none after it
    assert tk[-1] < zeno and zeno - tk[-1] <= 1e-4
    resting = (t > tk[-1]) & ~_arriving(t)
    assert resting.sum() >= 3
    assert np.max(np.abs(y[resting, 1])) <= 1e-12 and np.max(np.abs(y[resting, 3])) <= 1e-12
    numeric = ball.constraints()
    lam = numeric.multipliers(t, y)[:, 0]
    assert np.max(np.abs(lam[resting] + M * G)) <= 1e-12  # lambda = -m g: the floor pushes
    assert numeric.contacts(t[resting], y[resting]).all()
    flying = y[:, 1] > 1e-6
    assert np.all(lam[flying] == 0.0)  # no contact in flight
    # sliding on: x = x_0 + x_dot t, the energy that is left is m x_dot**2 / 2
    assert y[-1, 0] == pytest.approx(-2.0 + VX * 8.0, abs=1e-10)
    assert ball.hamiltonian(t[-1], y[-1:])[0] == pytest.approx(M * VX**2 / 2, abs=1e-10)
    kernel = np.empty(1)
    for row in np.flatnonzero(resting | flying)[:: max(1, len(t) // 30)]:
        ball.constrained("c_multipliers", float(t[row]), y[row], ball.parameters, kernel)
        assert kernel[0] == lam[row]


def test_a_plastic_impact_stops_the_ball_at_once(ball):
    plastic = ball.with_parameters({"restitution": 0.0})
    t, y = _trajectory(plastic, t_end=2.0)
    assert len(_impacts(t, y)[0]) == 0
    arriving = _arriving(t)
    after = (t >= T1 - 1e-12) & ~arriving
    # the step that ends on the impact, and the impact: the ball arrives at v_0, stops
    (at,) = np.flatnonzero(arriving)
    assert abs(t[at] - T1) <= 1e-12 and y[at, 3] == pytest.approx(-M * V0, rel=1e-10)
    assert np.max(np.abs(y[after, 1])) <= 1e-12 and np.max(np.abs(y[after, 3])) <= 1e-12
    assert np.max(np.abs(plastic.constraints().multipliers(t[after], y[after]) + M * G)) <= 1e-12


def test_a_start_resting_on_the_floor_stays_there(ball):
    y0 = np.array([0.0, 0.0, M * VX, 0.0])
    t, y = _trajectory(ball, y0=y0, t_end=2.0)
    assert np.max(np.abs(y[:, 1])) <= 1e-15 and np.max(np.abs(y[:, 3])) <= 1e-15
    assert y[-1, 0] == pytest.approx(2.0 * VX, abs=1e-12)


def test_the_run_reports_how_far_a_state_is_beyond_a_wall(ball):
    run = Run(ball, method="constrained_dop853", t_end=6.0)
    sampler = Sampler(run, np.linspace(0.0, 6.0, 601))
    list(sampler)
    assert sampler.last.status == "ok", sampler.last.message
    assert 0.0 <= sampler.violation <= 1e-10
    numeric = ball.constraints()
    states = np.array([[0.0, -0.01, 0.0, 0.0], [0.0, 0.5, 0.0, 0.0]])
    assert numeric.violation(0.0, states) == pytest.approx(0.01)  # max(0, -g)
    assert numeric.violation(0.0, states[1:]) == 0.0
    assert numeric.values(0.0, states)[:, 0].tolist() == [-0.01, 0.5]


def test_the_run_command_reports_the_violation(tmp_path):
    from explorer.cli import main

    out = tmp_path / "ball.csv"
    args = ["run", "bouncing_ball", "--t-end", "6", "--samples", "60", "--json"]
    assert main([*args, "--out", str(out)]) == 0
    header = out.read_text().splitlines()[0].split(",")
    assert header[-1] == "lambda_1"
    rows = np.loadtxt(out, delimiter=",", skiprows=1)
    assert rows[-1, -1] == pytest.approx(-M * G, abs=1e-12)  # at rest by t = 6


def test_the_run_json_has_the_violation(capsys):
    from explorer.cli import main

    assert main(["run", "bouncing_ball", "--t-end", "3", "--samples", "30", "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["method"] == "constrained_dop853" and data["status"] == "ok"
    assert 0.0 <= data["max_constraint_violation"] <= 1e-10


# -- the gas molecule --------------------------------------------------------------------------


def _fold(u: np.ndarray, length: float) -> np.ndarray:
    """Free motion u folded into [0, length] by mirror walls."""
    u = np.mod(u, 2 * length)
    return np.where(u > length, 2 * length - u, u)


def test_the_gas_molecule_stays_in_its_box_with_its_speeds():
    """Measured over 200 time units (270 impacts): the position follows the folded free
    motion to 3e-13, |v_x| and |v_y| do not change at all, nor does H."""
    compiled = _compiled(load_scene("gas_in_box"))
    c = compiled.mechanics.classification
    assert c.hamiltonian_conserved and c.conservative and not c.bilateral and c.simple
    t, y = _trajectory(compiled, t_end=200.0)  # H is watched (e = 1): the run would stop
    a, b = 2.0, 1.0
    assert y[:, 0].min() >= -1e-10 and y[:, 0].max() <= a + 1e-10
    assert y[:, 1].min() >= -1e-10 and y[:, 1].max() <= b + 1e-10
    assert np.max(np.abs(np.abs(y[:, 2]) - 1.3)) <= 1e-12
    assert np.max(np.abs(np.abs(y[:, 3]) - 0.7)) <= 1e-12
    assert np.max(np.abs(y[:, 0] - _fold(0.3 + 1.3 * t, a))) <= 1e-10
    assert np.max(np.abs(y[:, 1] - _fold(0.2 + 0.7 * t, b))) <= 1e-10
    H = compiled.hamiltonian(t, y)
    assert np.ptp(H) <= 1e-12 * H[0]
    # the walls' impulses: 2 m |v_x| on the side walls, once per 2 a / |v_x|
    flips = np.sum(np.diff(np.sign(y[:, 2])) != 0)
    assert flips == pytest.approx(200.0 * 1.3 / a, abs=1)


# -- release ----------------------------------------------------------------------------------

SPHERE = """
[system]
coordinates = ["x", "y"]
parameters = {{ m = 1.0, g = 9.81, R = 1.0 }}
kinetic = "m*(x_dot**2 + y_dot**2)/2"
potential = "m*g*y"
[constraints]
unilateral = ["x**2 + y**2 - R**2"]
[initial]
x = {x!r}
y = {y!r}
x_dot = {vx!r}
y_dot = {vy!r}
"""


def test_a_particle_leaves_the_sphere_where_cos_theta_is_two_thirds():
    """Measured: the release is located where cos(theta) differs from the exact value by
    2e-14, with lambda at -7e-16 there."""
    theta0, v0 = 0.01, 1e-3
    text = SPHERE.format(
        x=math.sin(theta0),
        y=math.cos(theta0),
        vx=v0 * math.cos(theta0),
        vy=-v0 * math.sin(theta0),
    )
    compiled = _compiled(parse_scene(text))
    t, y = _trajectory(compiled, t_end=3.0)
    numeric = compiled.constraints()
    contact = numeric.contacts(t, y)[:, 0]
    assert contact[0] and not contact[-1]
    released = np.flatnonzero(~contact)[0] - 1  # the last state in contact
    assert np.all(contact[: released + 1])
    x, yy, vx, vy = y[released]
    cos_theta = yy / math.hypot(x, yy)
    exact = (2 * math.cos(theta0) + v0**2 / (G * 1.0)) / 3
    assert abs(cos_theta - exact) <= 1e-9
    assert abs(cos_theta - 2 / 3) <= 1e-4  # near the textbook's 2/3 for a start at rest
    # on the sphere the multiplier is the normal force: -2 lambda R = m (g cos - v**2/R)
    lam = numeric.multipliers(t, y)[:, 0]
    on = np.arange(released + 1)
    speed2 = y[on, 2] ** 2 + y[on, 3] ** 2
    cos_on = y[on, 1] / np.hypot(y[on, 0], y[on, 1])
    assert np.allclose(-2 * lam[on], M * (G * cos_on - speed2), atol=1e-9)
    assert abs(lam[released]) <= 1e-9
    # after the release: a free parabola outside the sphere, energy kept throughout
    assert np.all(y[released + 1 :, 0] ** 2 + y[released + 1 :, 1] ** 2 >= 1.0 - 1e-12)
    H = compiled.hamiltonian(t, y)
    assert np.ptp(H) <= 1e-11 * abs(H[0])


# -- the derivation and mistakes ---------------------------------------------------------------


def test_the_derivation_shows_the_floor_and_the_restitution():
    mechanics = derive(load_scene("bouncing_ball"))
    data = derivation_json(mechanics)
    assert data["degrees_of_freedom"] == 2
    given = data["constraints"]
    assert given["unilateral"] == ["y"] and given["unilateral_gradient"] == [["0", "1"]]
    assert given["restitution"] == 0.8 and given["multipliers"] == ["lambda_1"]
    text = readable(mechanics, equilibria=False)
    assert "Unilateral constraints g(q, t) ≥ 0" in text
    assert "e = 0.8 (the parameter restitution)" in text
    assert "degrees of freedom: 2 (one per coordinate); 1 unilateral constraint" in text
    c = mechanics.classification
    assert not c.bilateral and c.holonomic and not c.rheonomic
    # e < 1 may take energy away: not conservative, H not conserved (nor watched)
    assert not c.conservative and not c.hamiltonian_conserved and not c.simple
    # the floor does not push along x: p_x is conserved, p_y is not
    assert "p_x" in mechanics.conserved and "x" in mechanics.cyclic
    assert "p_y" not in mechanics.conserved
    box = derive(load_scene("gas_in_box"))
    assert derivation_json(box)["constraints"]["restitution"] == 1.0
    # the walls push along x and y: no momentum (nor Noether's translation) is conserved
    assert box.cyclic == () and set(box.conserved) == {"H"}


def test_only_the_adaptive_constrained_method_applies():
    mechanics = derive(load_scene("bouncing_ball"))
    reason = STEPPERS["constrained_rk4"].applies_to(mechanics)
    assert reason is not None and "unilateral" in reason and "constrained_dop853" in reason
    assert STEPPERS["constrained_dop853"].applies_to(mechanics) is None
    assert "[constraints]" in STEPPERS["dop853"].applies_to(mechanics)


def test_a_restitution_outside_zero_to_one_is_refused():
    text = load_scene("bouncing_ball").to_toml().replace("restitution = 0.8", "restitution = 1.5")
    with pytest.raises(DerivationError) as caught:
        derive(parse_scene(text, source="ball.toml"))
    assert caught.value.field == "system.parameters" and "restitution" in str(caught.value)


def test_a_start_beyond_a_wall_is_refused(ball):
    with pytest.raises(DerivationError) as caught:
        Run(ball, method="constrained_dop853", y0=np.array([0.0, -0.5, 0.0, 0.0]), t_end=1.0)
    assert caught.value.field == "constraints.unilateral[0]"
    assert "beyond the unilateral constraint y >= 0" in str(caught.value)


def test_a_moving_wall_is_rheonomic_and_the_energy_tab_refuses_walls():
    text = SPHERE.format(x=0.0, y=2.0, vx=0.0, vy=0.0).replace(
        '"x**2 + y**2 - R**2"', '"y - sin(t)"'
    )
    mechanics = derive(parse_scene(text))
    c = mechanics.classification
    assert c.rheonomic and c.time_dependent and not c.hamiltonian_conserved
    from systems.textbook import jobs

    for scene in (parse_scene(text), load_scene("gas_in_box")):
        compiled = compile_system(derive(scene), ("rhs", "hamiltonian", "velocities"))
        with pytest.raises(ValueError, match="constraint moves|unilateral"):
            jobs.energy(compiled, 1.0)


def test_multiplier_columns_follow_every_kind():
    scene = load_scene("gas_in_box")
    assert constraints.multiplier_names(scene) == [f"lambda_{i}" for i in range(1, 5)]
    assert constraints.counts(scene) == {"holonomic": 0, "nonholonomic": 0, "unilateral": 4}


def test_a_pendulum_bounces_off_a_wall_keeping_its_string():
    """The Cartesian pendulum (holonomic x**2 + y**2 = l**2) with a wall x >= -l/2 and
    elastic impacts: the bob swings from theta = 1.2 to the wall (theta = -pi/6), where
    its velocity along the circle is reversed with the string kept, and swings back to
    theta = 1.2 at twice that time. The reference time to the wall comes from the polar
    simple pendulum, integrated by scipy to 1e-13."""
    from scipy.integrate import solve_ivp

    scene = load_scene("cartesian_pendulum")
    text = scene.to_toml().replace(
        'holonomic = ["x**2 + y**2 - l**2"]',
        'holonomic = ["x**2 + y**2 - l**2"]\nunilateral = ["x + l/2"]',
    )
    compiled = _compiled(parse_scene(text, source="wall.toml"))
    assert constraints.rows(compiled.mechanics).kinds == ("holonomic", "unilateral")

    def polar(t, s):
        return [s[1], -G * math.sin(s[0])]

    def wall(t, s):
        return s[0] + math.pi / 6

    wall.terminal = True
    reference = solve_ivp(polar, (0, 5), [1.2, 0.0], rtol=1e-13, atol=1e-14, events=wall)
    t_wall = float(reference.t_events[0][0])
    t, y = _trajectory(compiled, t_end=2 * t_wall)
    numeric = compiled.constraints()
    assert y[:, 0].min() >= -0.5 - 1e-10
    at_wall = np.flatnonzero(np.abs(y[:, 0] + 0.5) <= 1e-12)
    # the bob arriving and leaving, at the same time and place, its velocity reversed
    assert len(at_wall) == 2 and abs(t[at_wall[0]] - t_wall) <= 1e-9
    assert t[at_wall[1]] == t[at_wall[0]]
    arrive, leave = y[at_wall[0]], y[at_wall[1]]
    assert np.array_equal(arrive[:2], leave[:2])
    assert np.allclose(leave[2:], -arrive[2:], rtol=1e-12, atol=1e-12)
    # the string holds, before, at and after the impact; the energy is kept
    assert np.max(np.abs(numeric.values(t, y)[:, 0])) <= 1e-12
    assert np.max(np.abs(y[:, 0] * y[:, 2] + y[:, 1] * y[:, 3])) <= 1e-10
    H = compiled.hamiltonian(t, y)
    assert np.ptp(H) <= 1e-10 * abs(H[0])
    # back where it started, at rest
    assert y[-1, 0] == pytest.approx(math.sin(1.2), abs=1e-8)
    assert y[-1, 1] == pytest.approx(-math.cos(1.2), abs=1e-8)
    assert np.hypot(y[-1, 2], y[-1, 3]) <= 1e-6


def test_a_rolling_disk_bounces_off_a_wall_and_keeps_rolling():
    """The catalogue's rolling disk with a wall x >= -1 and elastic impacts: each impact
    must keep the rolling constraints (the impulse includes the ground's), so the disk
    still rolls without slipping afterwards, and with e = 1 and ideal constraints the
    kinetic energy is kept. Measured: H to 2e-14 (relative), slip 2e-16."""
    text = load_scene("rolling_disk").to_toml()
    text = text.replace("nonholonomic = [", 'unilateral = ["x + 1"]\nnonholonomic = [')
    compiled = _compiled(parse_scene(text, source="walled.toml"))
    assert constraints.rows(compiled.mechanics).kinds == (
        "nonholonomic",
        "nonholonomic",
        "unilateral",
    )
    t, y = _trajectory(compiled, t_end=60.0)
    assert y[:, 0].min() >= -1.0 - 1e-10
    assert np.sum(np.abs(y[:, 0] + 1.0) <= 1e-12) >= 2  # it reached the wall
    assert compiled.constraints().violation(t, y) <= 1e-12
    H = compiled.hamiltonian(t, y)
    assert np.ptp(H) <= 1e-11 * H[0]


# -- the Atwood machines stop at their floor and pulley (issue 25) ----------------------------


@pytest.mark.parametrize("name", ["atwood_machine", "atwood_rope"])
def test_the_atwood_machines_land_on_their_floor_and_stay(name):
    """Thrown up at 1.2 from x = 1.5 (the left mass's depth below the pulley), the machine
    accelerates at a = g (m1 - m2)/(m1 + m2) towards the heavier left mass, which lands
    on the floor h = 2.5 below the pulley at t = (1.2 + sqrt(1.2**2 + 2 a (h - 1.5)))/a
    and stops there (e = 0), the taut rope stopping the other; they used to run through
    the pulley to y = +-1000."""
    compiled = _compiled(load_scene(name))
    t, y = _trajectory(compiled, t_end=40.0, tol=1e-12)
    depth = y[:, 0] if name == "atwood_machine" else -y[:, 0]  # the left mass's
    other = 3.0 - depth if name == "atwood_machine" else -y[:, 1]
    assert depth.min() >= 0.0 and other.min() >= 0.0  # never above the pulley
    assert depth.max() <= 2.5 + 1e-12 and other.max() <= 2.5 + 1e-12  # nor below the floor
    a = G * 0.2 / 2.2
    landing = (1.2 + math.sqrt(1.2**2 + 2 * a * 1.0)) / a
    arrived = t[np.argmax(depth >= 2.5 - 1e-12)]
    assert arrived == pytest.approx(landing, abs=1e-9)
    after = t >= landing + 1e-6
    assert np.all(np.abs(depth[after] - 2.5) <= 1e-12)
    assert np.all(np.abs(y[after, compiled.n :]) <= 1e-12)  # at rest: no momentum
    assert t[-1] == 40.0
