"""Periodic orbits by shooting and Newton, with their Floquet multipliers
(``systems.textbook.periodic_orbits``, issue 26 item 4)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
import scipy.integrate

from explorer.cli import main
from systems.mechanics import derive
from systems.scene import load_scene
from systems.textbook.periodic_orbits import periodic_orbit

FIGURE_EIGHT_PERIOD = 6.32591398  # Chenciner & Montgomery (2000), Simó's digits


def test_figure_eight_is_periodic_and_linearly_stable():
    # the catalogue's start: x1 = -x2 = (0.97000436, -0.24308753), v3 = -2 v1 = -2 v2
    orbit = periodic_orbit(derive(load_scene("figure_eight")))  # period: the first return
    assert orbit.converged and orbit.closure < 1e-10
    assert orbit.period == pytest.approx(FIGURE_EIGHT_PERIOD, abs=5e-6)  # the start: 9 digits
    start = dict(zip(orbit.names, orbit.start, strict=True))
    assert start["x1"] == pytest.approx(0.97000436, abs=1e-6)
    assert start["y1"] == pytest.approx(-0.24308753, abs=1e-6)
    mus = np.array(orbit.multipliers)
    # Hamiltonian flow: det M = 1; every multiplier on the unit circle (known linearly
    # stable, Simó 2002); 8 at 1: the flow and energy, the centre of mass (4) and the
    # rotation with its angular momentum
    assert orbit.determinant == pytest.approx(1.0, abs=1e-8)
    assert np.allclose(np.abs(mus), 1.0, atol=1e-5)
    assert orbit.at_one == 8
    nontrivial = mus[np.abs(mus - 1) > 1e-3]
    assert len(nontrivial) == 4 and np.all(np.abs(nontrivial.imag) > 0.01)
    assert orbit.verdict.word == "stable"


def _henon_heiles_y_axis_period(energy: float) -> tuple[float, float]:
    """The top turning point and the period of the y-axis oscillation (x = 0) of
    Hénon–Heiles at ``energy``, by quadrature: E - V(y) = (y - a)(y - b)(y - c)/3."""
    a, b, c = sorted(np.roots([1 / 3, -1 / 2, 0.0, energy]).real)
    integral, _ = scipy.integrate.quad(
        lambda y: 1 / math.sqrt(2 * (c - y) / 3), a, b, weight="alg", wvar=(-0.5, -0.5)
    )
    return b, 2 * integral


def test_henon_heiles_y_axis_orbit_at_energy_one_eighth():
    top, period = _henon_heiles_y_axis_period(1 / 8)
    mechanics = derive(load_scene("henon_heiles"))
    orbit = periodic_orbit(mechanics, {"x": 0.0, "y": top, "p_x": 0.0, "p_y": 0.0})
    assert orbit.converged
    assert orbit.period == pytest.approx(period, rel=1e-8)
    assert orbit.start[1] == pytest.approx(top, abs=1e-8)  # held on its energy level
    mus = np.array(orbit.multipliers)
    assert orbit.at_one == 2
    assert abs(orbit.product - 1) < 1e-9 and orbit.determinant == pytest.approx(1, abs=1e-9)
    pair = mus[np.argsort(np.abs(mus - 1))[2:]]
    assert abs(pair[0] * pair[1] - 1) < 1e-8  # symplectic pairing mu, 1/mu
    assert orbit.verdict.word in ("stable", "unstable")
    assert (orbit.verdict.word == "stable") == bool(np.allclose(np.abs(pair), 1, atol=1e-6))


def test_periodic_command(capsys):
    top, period = _henon_heiles_y_axis_period(1 / 8)
    start = f"x=0,y={float(top)!r},p_x=0,p_y=0"
    assert main(["periodic", "henon_heiles", "--start", start, "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["converged"] and data["period"] == pytest.approx(period, rel=1e-8)
    assert data["multipliers_at_one"] == 2
    assert main(["periodic", "kapitza_pendulum", "--start", "theta=3.1"]) == 0
    out = capsys.readouterr().out
    assert "T = 0.1047197551" in out and "stable" in out
    assert main(["periodic", "henon_heiles", "--start", "z=1"]) == 2
    assert "unknown name 'z'" in capsys.readouterr().err
