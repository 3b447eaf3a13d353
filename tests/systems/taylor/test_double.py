"""The state's orders 1 and 2 in double-double (``systems.taylor.double``) against
Hamilton's equations evaluated in 40 digits, and against the double coefficients."""

import numpy as np
import pytest
import sympy

from systems.compiled import compile_system
from systems.taylor.coefficients import taylor_coefficients
from systems.taylor.compiled import decomposition_of, load_taylor
from systems.taylor.double import compensated
from tests.systems.taylor.test_compiled import SCENES
from tests.systems.taylor.test_systems import _mechanics


def _exact_orders(mechanics, t: float, state: np.ndarray, P: np.ndarray) -> np.ndarray:
    """(2, m): the state's orders 1 and 2 at the exact binary values ``state`` (m, 2):
    y and comp, the state y - comp), t and P, in 40 digits: f, and (J f + df/dt) / 2."""
    variables = (*mechanics.q, *mechanics.p)
    equations = [sympy.sympify(e) for e in mechanics.hamilton_equations]
    parameters = [mechanics.params[name] for name, _ in mechanics.scene.parameters]
    values = {
        v: sympy.Rational(y) - sympy.Rational(c) for v, (y, c) in zip(variables, state, strict=True)
    }
    values.update({p: sympy.Rational(float(v)) for p, v in zip(parameters, P, strict=True)})
    values[mechanics.t] = sympy.Rational(t)
    first = [f.subs(values).evalf(40) for f in equations]
    second = []
    for f in equations:
        total = sympy.diff(f, mechanics.t)
        total += sum(sympy.diff(f, v) * g for v, g in zip(variables, equations, strict=True))
        second.append((total.subs(values) / 2).evalf(40))
    return np.array([first, second], dtype=object)


@pytest.mark.parametrize("name", ["kepler_cartesian", "planetary_motion", "henon_heiles"])
def test_orders_1_and_2_are_double_double_of_the_compensated_state(name):
    """Scenes of sums, products, quotients and half powers only: the state's orders 1 and
    2, high plus low part, are those of ``y - comp`` to double-double accuracy (measured:
    3.1e-32, 7.4e-32 and 1.7e-32 of each order's largest), where the double coefficients
    of ``y`` are good to 1e-16 of ``y`` only."""
    mechanics = _mechanics(name)
    d = decomposition_of(mechanics)
    assert all(compensated(node) for node in d.nodes if not node.constant)
    double = load_taylor(mechanics).double()
    compiled = compile_system(mechanics, ("rhs",))
    P = compiled.parameters
    rng = np.random.default_rng(11)
    worst = 0.0
    for _ in range(4):
        y = compiled.initial_state() * rng.uniform(0.8, 1.2, d.m) + rng.uniform(-0.1, 0.1, d.m)
        comp = rng.uniform(-1, 1, d.m) * np.spacing(y)
        t = float(rng.uniform(0.0, 2.0))
        out = double.orders(t, y, comp, P)
        exact = _exact_orders(mechanics, t, np.stack([y, comp], axis=1), P)
        for k in (0, 1):
            scale = max(abs(v) for v in exact[k])
            for i in range(d.m):
                value = sympy.Float(out[2 * k, i], 40) + sympy.Float(out[2 * k + 1, i], 40)
                worst = max(worst, float(abs(value - exact[k][i]) / scale))
    assert worst <= 1e-30, worst


@pytest.mark.parametrize("name", SCENES)
def test_the_double_double_orders_are_the_double_ones_to_round_off(name):
    """Every scene (every function the parser has among them: the transcendental nodes
    keep their double values): high plus low part within 4e-15 of the reference
    evaluator's orders 1 and 2 of each column's largest, the high part the double-double
    rounded (|low| at most half an ulp of it)."""
    mechanics = _mechanics(name)
    d = decomposition_of(mechanics)
    double = load_taylor(mechanics).double()
    compiled = compile_system(mechanics, ("rhs",))
    P = compiled.parameters * 1.1
    y0 = compiled.initial_state() + 0.1
    out = double.orders(0.4, y0, np.zeros(d.m), P)
    want = taylor_coefficients(d, 0.4, y0, P, 2)
    for k in (1, 2):
        high, low = out[2 * (k - 1)], out[2 * k - 1]
        scale = np.maximum(np.abs(want[k]).max(), 1e-300)
        assert np.all(np.abs(high + low - want[k]) <= 4e-15 * scale), (k, high, want[k])
        assert np.all(np.abs(low) <= np.abs(np.spacing(high)) / 2), (k, low)
