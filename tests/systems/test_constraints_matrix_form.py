"""Constraints on systems in matrix form: more than four coupled coordinates whose mass
matrix the kernels solve numerically (``Mechanics.matrix_form``).

The saddle-point system needs M and F, which matrix form has; what changes is that the
velocities are solved from M qdot = p - a at every evaluation, in the kernels and in
``constraints.Numeric``. The reference is the same constrained system with the
Legendre transform in closed form: a three-link chain, derived twice, once forced into
matrix form.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from systems import mechanics as mechanics_module
from systems.compiled import compile_system
from systems.mechanics import derive
from systems.scene import parse_scene
from systems.simulation import required_wants, stream

WANTS = required_wants("constrained_dop853", ("H",)) | {"velocities"}


def _chain(links: int) -> str:
    """A chain of ``links`` equal pendulums whose end slides on the vertical through the
    pivot (x of the last bob = 0): a closed loop, scleronomic and conservative."""
    names = [f"a{i}" for i in range(1, links + 1)]
    xs, ys, kinetic, potential = [], [], [], []
    for i in range(links):
        x = " + ".join(f"l*sin({a})" for a in names[: i + 1])
        y = " + ".join(f"-l*cos({a})" for a in names[: i + 1])
        vx = " + ".join(f"l*cos({a})*{a}_dot" for a in names[: i + 1])
        vy = " + ".join(f"l*sin({a})*{a}_dot" for a in names[: i + 1])
        xs.append(x)
        ys.append(y)
        kinetic.append(f"m*(({vx})**2 + ({vy})**2)/2")
        potential.append(f"m*g*({y})")
    start = [0.6, -0.3] + [0.0] * (links - 3)
    rest = " + ".join(f"sin({v})" for v in start)
    initial = "\n".join(f"{a} = {v}" for a, v in zip(names, start, strict=False))
    return f"""
title = "closed chain"
[system]
coordinates = {names!r}
parameters = {{ m = 1.0, g = 9.81, l = 1.0 }}
kinetic = "{" + ".join(kinetic)}"
potential = "{" + ".join(potential)}"
[constraints]
holonomic = ["{xs[-1]}"]
[initial]
{initial}
{names[-1]} = "-asin({rest})"
"""


def _run(compiled, t_end: float):
    blocks = list(
        stream(compiled, method="constrained_dop853", t_end=t_end, tol=1e-11, max_points=100_000)
    )
    assert blocks[-1].status == "ok", blocks[-1].message
    return np.concatenate([b.t for b in blocks]), np.concatenate([b.y for b in blocks])


def _compiled(text: str):
    mechanics = derive(parse_scene(text))
    return compile_system(mechanics, WANTS)


@pytest.fixture(scope="module")
def three_links_both_ways():
    """The three-link loop in closed form, and forced into matrix form."""
    text = _chain(3)
    closed = _compiled(text)
    with pytest.MonkeyPatch.context() as patch:
        patch.setenv("PHASE_EXPLORER_DERIVATION_CACHE", "0")
        patch.setattr(mechanics_module, "SYMBOLIC_INVERSE_LIMIT", 2)
        solved = _compiled(text)
    return closed, solved


def test_the_three_link_loop_in_matrix_form_is_the_loop_in_closed_form(three_links_both_ways):
    closed, solved = three_links_both_ways
    assert closed.mechanics.matrix_form is None
    assert solved.mechanics.matrix_form is not None
    t1, y1 = _run(closed, 1.5)
    t2, y2 = _run(solved, 1.5)
    assert t1[-1] == t2[-1] == 1.5
    # the same equations: the same motion to the tolerance of the steps
    assert np.max(np.abs(y1[-1] - y2[-1])) < 1e-8
    numeric = solved.constraints()
    assert numeric.violation(t2, y2) <= 1e-10
    lam1 = closed.constraints().multipliers(t1[-1], y1[-1])
    lam2 = numeric.multipliers(t2[-1], y2[-1])
    assert lam2 == pytest.approx(lam1, rel=1e-7)


def test_numeric_velocities_of_a_system_in_matrix_form_solve_the_mass_matrix(
    three_links_both_ways,
):
    closed, solved = three_links_both_ways
    rng = np.random.default_rng(3)
    Y = rng.uniform(-1.0, 1.0, (20, 6))
    expected = closed.constraints().qdot(0.0, Y)
    assert solved.constraints().qdot(0.0, Y) == pytest.approx(expected, rel=1e-12, abs=1e-12)
    assert solved.velocities(0.0, Y) == pytest.approx(expected, rel=1e-12, abs=1e-12)


def test_a_five_link_loop_derives_and_runs_on_its_constraint():
    """Five coupled angles: matrix form by itself. Energy is conserved (scleronomic,
    conservative) and the end stays on its vertical."""
    compiled = _compiled(_chain(5))
    mechanics = compiled.mechanics
    assert mechanics.matrix_form is not None
    from systems import constraints

    assert constraints.degrees_of_freedom(mechanics) == 4
    t, y = _run(compiled, 0.5)
    numeric = compiled.constraints()
    assert numeric.violation(t, y) <= 1e-10
    H = compiled.hamiltonian(t, y)
    assert np.max(np.abs(H - H[0])) <= 1e-8 * max(1.0, abs(H[0]))
    # the end bob's x along the run (the constraint itself), and its tension is finite
    x_end = sum(np.sin(y[:, i]) for i in range(5))
    assert np.max(np.abs(x_end)) <= 1e-10
    lam = numeric.multipliers(t, y)
    assert np.all(np.isfinite(lam)) and math.isfinite(float(np.max(np.abs(lam))))
