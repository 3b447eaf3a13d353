"""Round-off of the implicit Gauss methods grows like sqrt(t) (Brouwer's law), not like t.

On the harmonic oscillator Gauss-Legendre methods conserve the quadratic energy exactly,
so every bit of energy error is round-off. A biased step (an iteration stopped at a
tolerance, coefficients that are not symplectic once rounded) makes it drift like t.
"""

import math

import numpy as np
import pytest

from systems.integrators.registry import STEPPERS, make_runner
from tests.systems.integrators.handwritten import OSCILLATOR, Handwritten, module

TIMES = np.geomspace(50.0, 2 * math.pi * 1e4, 10)  # up to 1e4 periods


def energy_errors(mod, method, dt, y0):
    system = Handwritten(mod, [1.0, 1.0])
    runner = make_runner(system, STEPPERS[method], y0, 0.0, math.inf, dt, None)
    H0 = 0.5 * (y0 @ y0)
    errors = []
    for t in TIMES:
        while runner.t < t:
            runner.advance(10**8, 2, until=t)
        errors.append(abs(0.5 * (runner.y @ runner.y) / H0 - 1.0))
    return np.array(errors)


@pytest.mark.parametrize(
    "method, dt", [("implicit_midpoint", 0.05), ("gauss_legendre4", 0.2), ("gauss_legendre6", 0.3)]
)
def test_gauss_energy_round_off_grows_like_sqrt_t(method, dt):
    mod = module(OSCILLATOR)
    # an ensemble of starts: one run's error is a random walk, its slope is noisy
    starts = [
        r * np.array([math.cos(a), math.sin(a)])
        for r, a in zip(np.linspace(1.0, 1.9, 8), np.linspace(0.1, 5.9, 8), strict=True)
    ]
    rms = np.sqrt(np.mean([energy_errors(mod, method, dt, y0) ** 2 for y0 in starts], axis=0))
    slope = np.polyfit(np.log(TIMES), np.log(rms), 1)[0]
    assert slope <= 0.6, (method, slope, rms)
    assert rms[-1] < 1e-13
