"""Runs that grow without bound say so (issue 25 item 5): the coordinate, how far, how fast.

A bead on a rotating wire (L = m/2 (r_dot^2 + w^2 r^2)) moves as r = cosh(w t). It used to
stop at t = 14 with "the energy error reached 0.0111 ... reduce the step" (round-off of
its kinetic and potential energies, 1e11 each, against H = -1/2), or with "the equations
are singular" where the numbers overflowed.
"""

from __future__ import annotations

import math
import re

import numpy as np
import pytest

from systems.compiled import compile_system
from systems.growth import UNBOUNDED_GROWTH, GrowthWatch
from systems.mechanics import derive
from systems.scene import load_scene
from systems.simulation import PROBLEMS, run_to_end
from tests.systems.scenes import scene

BEAD = """
title = "Bead on a rotating wire"
[system]
coordinates = ["r"]
parameters = { m = 1.0, w = 1.0 }
lagrangian = "m/2*(r_dot**2 + w**2*r**2)"
[initial]
r = 1.0
"""

DOUBLE_WELL = """
title = "Double well"
[system]
coordinates = ["x"]
parameters = { m = 1.0 }
kinetic = "m*x_dot**2/2"
potential = "x**4/4 - x**2/2"
[initial]
x = 1e-9
"""

FALLING = """
title = "Falling"
[system]
coordinates = ["x"]
parameters = { m = 1.0, g = 10.0 }
kinetic = "m*x_dot**2/2"
potential = "m*g*x"
[initial]
x = 0.0
x_dot = 1.0
"""

WANTED = ("rhs", "hamiltonian", "velocities", "separable")


def _compiled(text: str):
    return compile_system(derive(scene(text)), WANTED)


@pytest.fixture(scope="module")
def bead():
    return _compiled(BEAD)


@pytest.mark.parametrize(
    "options",
    [{}, {"method": "leapfrog", "dt": 0.05}, {"method": "dop853"}, {"method": "rk4", "dt": 0.1}],
)
def test_the_bead_stops_as_unbounded_naming_r_its_value_and_rate(bead, options):
    _, last = run_to_end(bead, t_end=40.0, **options)
    assert last.status == "unbounded" and "unbounded" in PROBLEMS
    assert last.message.startswith("r grew to "), last.message
    assert "the motion is unbounded" in last.message
    rate = float(re.search(r"like e\^\(([0-9.e+-]+) t\)", last.message).group(1))
    assert rate == pytest.approx(1.0, rel=0.05)  # w = 1
    # stopped where r passed a million times its start, at cosh(t) = 1e6: t = 14.5
    r = float(last.y[-1, 0])
    assert UNBOUNDED_GROWTH <= r < 1.2 * UNBOUNDED_GROWTH
    assert float(last.t[-1]) == pytest.approx(math.acosh(r), abs=0.05)
    assert "energy error" not in last.message and "singular" not in last.message


def test_the_energy_guard_off_follows_the_growth_and_the_overflow_is_named(bead):
    _, last = run_to_end(bead, t_end=40.0, energy_tolerance=None)
    assert last.status == "ok"
    assert float(last.y[-1, 0]) == pytest.approx(math.cosh(40.0), rel=1e-6)
    _, last = run_to_end(bead, t_end=2000.0, energy_tolerance=None)
    assert last.status == "unbounded", last.message  # was "singular"
    assert last.message.startswith("r grew to ") and "non-finite" in last.message


def test_round_off_of_huge_energy_terms_is_no_energy_error(bead):
    # at t = 12, T and V are 7e9 each and H = -1/2: |dH| of round-off is ~1e-6 of H
    _, last = run_to_end(bead, t_end=12.0, method="leapfrog", dt=0.02)
    assert last.status == "ok", last.message


def test_a_method_unstable_at_its_step_is_not_called_unbounded():
    compiled = compile_system(derive(load_scene("harmonic_oscillator")), WANTED)
    stiff = compiled.with_parameters({"k": 1e4})
    _, last = run_to_end(stiff, method="leapfrog", dt=0.5, t_end=1e4, energy_tolerance=math.inf)
    assert last.status in PROBLEMS and last.status != "unbounded", last.message


@pytest.mark.parametrize("text", [DOUBLE_WELL, FALLING])
def test_bounded_and_power_law_motion_runs_on(text):
    # the double well leaves its hump from 1e-9 exponentially but stays within |x| < 1.5;
    # a falling body goes as t^2: to x = -5e6 over t = 1000, no steady decades
    _, last = run_to_end(_compiled(text), t_end=1000.0)
    assert last.status == "ok", last.message


def test_growth_watch_tells_exponential_from_power_law_growth():
    t = np.linspace(0.0, 30.0, 3001)
    watch = GrowthWatch(("x",), np.array([1.0, 0.0]))
    found = watch.update(t, np.column_stack([np.exp(t), np.zeros_like(t)]))
    assert found is not None
    row, growth = found
    assert growth.name == "x" and growth.rate == pytest.approx(1.0, rel=0.05)
    assert t[row] == pytest.approx(math.log(1e6), abs=0.02)
    assert growth.as_dict()["coordinate"] == "x"
    for power in (1, 2, 3):
        watch = GrowthWatch(("x",), np.array([1.0, 0.0]))
        t = np.concatenate([[0.0], np.geomspace(1e-3, 1e7, 20001)])
        assert watch.update(t, np.column_stack([(1 + t) ** power, 0 * t])) is None


def test_growth_watch_takes_states_up_to_the_largest_double():
    """A coordinate passing 1e308 times its scale, in one block or over many: the decades
    stop at the largest double (10.0 ** 309 raised OverflowError inside the watch)."""
    t = np.linspace(0.0, 710.0, 7101)
    x = np.exp(np.minimum(t, 709.0))  # up to 8.2e307, then held
    x[-1] = np.finfo(float).max
    for blocks in (1, 71):
        watch = GrowthWatch(("x",), np.array([1.0, 0.0]))
        found = []
        for part in np.array_split(np.arange(len(t)), blocks):
            found.append(watch.update(t[part], np.column_stack([x[part], 0 * x[part]])))
        first = next(f for f in found if f is not None)
        assert first[1].rate == pytest.approx(1.0, rel=0.05)
        assert len(watch.crossed[0]) == 308


def test_growth_at_the_edge_of_the_doubles_is_growth(bead):
    """Where the last good state is within a decade of the largest double (where a run's
    last block ends decides it), the steady decades are the evidence: no probe can follow
    one more decade."""
    from systems.growth import Growth
    from systems.simulation import _grows

    y = np.array([1.7e308, 1.7e308])
    growth = Growth("r", 1.7e308, 710.4, 1.0, 1.0, 0)
    assert _grows(bead, 710.4, y, growth)
