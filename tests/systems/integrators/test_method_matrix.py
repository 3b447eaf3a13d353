"""Every registered method against every kind of system: refused with a reason, or right.

A method added to the registry runs through this matrix automatically. On a damped and a
driven oscillator and a conservative one, all with exact solutions, a method either
refuses the system (``applies_to`` gives the reason, e.g. that a splitting would drop the
damping) or reproduces the exact solution with its declared order (fixed steps) or within
its tolerance (adaptive methods). A method that runs and drops an effect fails here.
"""

import math

import pytest

from systems.compiled import compile_system
from systems.integrators import STEPPERS
from systems.mechanics import derive
from systems.scene import parse_scene
from systems.simulation import required_wants, stream

BASE = """
[system]
coordinates = ["x"]
parameters = {{ m = 1.0, k = 1.0, b = 0.2, F = 0.5, w = 0.7 }}
kinetic = "m*x_dot**2/2"
potential = "k*x**2/2"
{effects}
[initial]
x = {x0}
x_dot = 0.0
"""
GAMMA, W0 = 0.1, 1.0
WD = math.sqrt(W0**2 - GAMMA**2)
SYSTEMS = {
    "damped": (
        BASE.format(effects='[effects]\ndissipation = "b*x_dot**2/2"\n', x0=1.0),
        lambda t: math.exp(-GAMMA * t) * (math.cos(WD * t) + GAMMA / WD * math.sin(WD * t)),
    ),
    "driven": (
        BASE.format(effects='[effects]\nforces = { x = "F*cos(w*t)" }\n', x0=0.0),
        lambda t: 0.5 / (1 - 0.49) * (math.cos(0.7 * t) - math.cos(t)),
    ),
    "conservative": (BASE.format(effects="", x0=1.0), math.cos),
}
T_END = 10.0
# fixed steps in the asymptotic range of each order, above round-off
STEPS = {1: (0.01, 0.005), 2: (0.05, 0.025), 4: (0.1, 0.05), 6: (0.2, 0.1), 8: (0.4, 0.2)}


def final_error(compiled, method, exact, max_step=None, **setting) -> float:
    options = {} if max_step is None else {"max_step": max_step, "max_points": 10**6}
    blocks = list(
        stream(compiled, method=method, t_end=T_END, energy_tolerance=None, **options, **setting)
    )
    last = blocks[-1]
    assert last.status == "ok", (method, last.message)
    assert last.t[-1] == T_END
    if max_step is not None:  # every step kept: none longer than the bound
        t = [0.0] + [float(time) for block in blocks for time in block.t]
        longest = max(b - a for a, b in zip(t, t[1:], strict=False))
        assert longest <= max_step * (1 + 1e-12), (method, longest)
    return abs(last.y[-1, 0] - exact(T_END))


@pytest.mark.parametrize("kind", sorted(SYSTEMS))
@pytest.mark.parametrize("method", sorted(STEPPERS))
def test_method_on_system_is_refused_or_right(method, kind):
    text, exact = SYSTEMS[kind]
    mechanics = derive(parse_scene(text, source=f"<{kind}>"))
    stepper = STEPPERS[method]
    refusal = stepper.applies_to(mechanics)
    if kind in ("damped", "driven") and stepper.family.name in ("composition", "logh"):
        # the splittings step only T(p) and V(q, t): they must refuse, naming the effect
        assert refusal is not None and ("dissipation" in refusal or "force on x" in refusal)
    if refusal is not None:
        assert len(refusal) > 20 and method in refusal
        return
    compiled = compile_system(mechanics, required_wants(method) | {"hamiltonian"})
    if stepper.setting == "tol":
        error = final_error(compiled, method, exact, tol=1e-8)
        assert error < 1e-5, (method, kind, error)
        # a bound on the steps (a drawn run's) keeps them short and the answer right
        bounded = final_error(compiled, method, exact, max_step=0.05, tol=1e-8)
        assert bounded < 1e-5, (method, kind, bounded)
        return
    coarse, fine = STEPS[min(stepper.order, 8)]
    e1 = final_error(compiled, method, exact, dt=coarse)
    e2 = final_error(compiled, method, exact, dt=fine)
    order = math.log2(e1 / e2) if e2 > 0 else math.inf
    if e1 < 1e-11:
        return  # at round-off already (Gauss methods are exact for quadratic energies)
    # order 8 on a linear system: the leading error term nearly cancels and no step range
    # is cleanly asymptotic above round-off (test_steppers checks it on the pendulum)
    slack = 2.0 if stepper.order >= 8 else 0.6
    assert order > stepper.order - slack, (method, kind, e1, e2, order)
    assert e2 < 0.05
