"""The Textbook tabs' computations on compiled systems (``systems.textbook.jobs``), and
their values crossing between processes (the window runs each in a worker)."""

from __future__ import annotations

import dataclasses
import math
import pickle

import numpy as np
import pytest
import sympy

from systems import processes
from systems.compiled import compile_system
from systems.mechanics import Mechanics, derive
from systems.scene import load_scene
from systems.textbook import jobs


def _compiled(name: str):
    return compile_system(derive(load_scene(name)), ("rhs", "hamiltonian", "velocities"))


def test_level_curve_closes_an_ellipse_at_the_turning_points():
    q = np.linspace(-2.0, 2.0, 401)
    half = np.full_like(q, 0.5)
    x, y = jobs.level_curve(q, half, np.zeros_like(q), q**2 / 2, 0.5)  # p² + q² = 1
    finite = np.isfinite(x)
    assert np.allclose(x[finite] ** 2 + y[finite] ** 2, 1.0, atol=1e-3)
    assert x[finite].min() == pytest.approx(-1.0, abs=1e-3)
    assert x[finite].max() == pytest.approx(1.0, abs=1e-3)
    assert (x[finite][0], y[finite][0]) == pytest.approx((x[finite][-1], y[finite][-1]))
    # above every value of the potential: two open branches, no turning point
    x, y = jobs.level_curve(q, half, np.zeros_like(q), q**2 / 2, 10.0)
    assert np.isnan(x).sum() >= 1 and np.nanmin(np.abs(y)) > 3.0


def test_rheonomic_energy_theorem_holds_along_the_run():
    result = jobs.energy(_compiled("variable_length_pendulum"), 5.0)
    assert result.explicit_time and result.rheonomic and not result.effects
    b = result.balance
    assert np.max(np.abs(b.rate - b.predicted)) < 1e-2 * np.max(np.abs(b.rate))


def test_action_angle_refuses_what_does_not_qualify():
    assert "one-degree" in jobs.action_angle_reason(_compiled("planetary_motion"))
    assert "effects" in jobs.action_angle_reason(_compiled("damped_pendulum"))
    hoop = _compiled("bead_on_rotating_hoop")  # its constraint moves, but H has no t
    assert jobs.action_angle_reason(hoop) == ""


def test_planetary_reduction_portrait_and_turning_points():
    compiled = _compiled("planetary_motion")
    setup = jobs.reduction_setup(compiled)
    assert setup.reduction.cyclic == ("theta",) and setup.quadratic is not None
    assert "/" in setup.expression and "**" not in setup.expression  # one line, for people
    curves = jobs.reduction_curves(setup, jobs.parameters_of(compiled), setup.p_cyclic)
    assert curves.energy == pytest.approx(-0.25)
    assert curves.turning == pytest.approx([1.0, 3.0], rel=1e-8)
    x, y = curves.orbit  # the orbit's level set: p_r² / 2 + V_eff(r) = E
    finite = np.isfinite(x)
    V = 1.5 / (2 * x[finite] ** 2) - 1 / x[finite]
    assert np.allclose(y[finite] ** 2 / 2 + V, -0.25, atol=1e-9)
    assert x[finite].min() == pytest.approx(1.0, abs=1e-3)
    assert x[finite].max() == pytest.approx(3.0, abs=1e-3)
    assert len(curves.lines) == len(curves.levels) > 5


def test_pendulum_period_matches_the_elliptic_integral():
    compiled = _compiled("simple_pendulum")
    found = jobs.equilibria(compiled)
    result = jobs.action_angle_data(compiled, found.search, count=40)
    below = np.isfinite(result.exact)
    assert below.sum() > 10
    assert np.allclose(result.period[below], result.exact[below], rtol=1e-8)
    assert result.small_period == pytest.approx(2 * math.pi / math.sqrt(9.81))


def test_a_cancelled_job_stops():
    cancel = jobs.Cancel()
    cancel.set()
    with pytest.raises(jobs.Cancelled):
        jobs.integrate(_compiled("simple_pendulum"), 10.0, cancel=cancel)


# -- values that cross between processes ------------------------------------------------------

WAIT = 120.0
"""Seconds a test waits at most for a worker (a busy machine; never a measurement)."""


def assert_same(a, b, where: str = "value") -> None:
    """``a`` and ``b`` hold the same data, field by field (NaN equal to NaN); functions
    are left to the callers, who evaluate them.

    sympy rebuilds an unpickled expression through its constructors, which evaluate
    (``m r (p/(m r²))²`` comes back as ``p²/(m r³)``): expressions need only be equal, and
    a derivation only of the same scene.
    """
    if isinstance(a, Mechanics):
        assert isinstance(b, Mechanics) and a.scene == b.scene, where
    elif dataclasses.is_dataclass(a) and not isinstance(a, type):
        assert type(a) is type(b), where
        for f in dataclasses.fields(a):
            assert_same(getattr(a, f.name), getattr(b, f.name), f"{where}.{f.name}")
    elif isinstance(a, np.ndarray):
        np.testing.assert_array_equal(a, b, err_msg=where)
    elif isinstance(a, dict):
        assert a.keys() == b.keys(), where
        for key in a:
            assert_same(a[key], b[key], f"{where}[{key!r}]")
    elif isinstance(a, list | tuple):
        assert type(a) is type(b) and len(a) == len(b), where
        for k, (x, y) in enumerate(zip(a, b, strict=True)):
            assert_same(x, y, f"{where}[{k}]")
    elif isinstance(a, sympy.Basic):
        assert a == b or sympy.simplify(a - b) == 0, where
    elif callable(a):
        assert callable(b), where
    elif isinstance(a, float) and math.isnan(a):
        assert isinstance(b, float) and math.isnan(b), where
    else:
        assert a == b, where


def _every_job() -> list[tuple[str, object, object]]:
    """``(label, compiled, value)`` for every job on systems where it has something to
    show, and where it has nothing (no reduction, no well)."""
    pendulum = _compiled("simple_pendulum")
    planetary = _compiled("planetary_motion")
    double = _compiled("double_pendulum")
    hoop = _compiled("bead_on_rotating_hoop")
    return [
        ("equilibria", pendulum, jobs.equilibria(pendulum)),
        ("equilibria, two degrees", double, jobs.equilibria(double)),
        ("equilibria, closed forms", hoop, jobs.equilibria(hoop)),
        ("principle", pendulum, jobs.principle(pendulum, 1.0, 1, 0, 0.1)),
        ("two-point", pendulum, jobs.two_point(pendulum, [0.1], [0.2], 1.0)),
        ("energy", hoop, jobs.energy(hoop, 2.0)),
        ("action-angle", pendulum, jobs.action_angle_table(pendulum)),
        ("reduction", planetary, jobs.reduction_with_curves(planetary)),
        ("no reduction", pendulum, jobs.reduction_with_curves(pendulum)),
        ("run", double, jobs.integrate(double, 1.0, 11)),
    ]


def test_every_job_value_survives_pickling():
    for label, _, value in _every_job():
        copy = pickle.loads(pickle.dumps(value))
        assert_same(value, copy, label)


def test_a_reduction_comes_back_with_its_numeric_functions():
    """The sliders redraw from functions made where the setup was: none is made again."""
    compiled = _compiled("planetary_motion")
    setup, curves = jobs.reduction_with_curves(compiled)
    copy, _ = pickle.loads(pickle.dumps((setup, curves)))
    made = set(copy.reduction._functions)
    assert {name for name, _ in made} == {"V_eff", "H_red"}
    parameters = jobs.parameters_of(compiled)
    p_cyclic = 0.9 * setup.p_cyclic
    here = jobs.reduction_curves(setup, parameters, p_cyclic)
    there = jobs.reduction_curves(copy, parameters, p_cyclic)
    assert_same(here, there, "curves")
    assert set(copy.reduction._functions) == made
    q = np.linspace(0.5, 3.0, 7)
    for a, b in zip(setup.quadratic(q, p_cyclic), copy.quadratic(q, p_cyclic), strict=True):
        np.testing.assert_array_equal(a, b)


def test_jobs_run_in_worker_processes_as_in_this_one():
    """As the window runs them: the system crosses as its mechanics (compiled again in the
    worker, with its parameter values), the value comes back."""
    pendulum = _compiled("simple_pendulum").with_parameters({"g": 4.0})
    planetary = _compiled("planetary_motion")
    cases = [
        (jobs.equilibria, pendulum),
        (jobs.action_angle_table, pendulum),
        (jobs.reduction_with_curves, planetary),
    ]
    started = [processes.submit(f, compiled, what=f.__name__) for f, compiled in cases]
    for (function, compiled), job in zip(cases, started, strict=True):
        assert_same(function(compiled), job.result(WAIT), function.__name__)
