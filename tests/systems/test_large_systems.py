"""Systems of more than four coordinates whose mass matrix is diagonal: lattices and
particles in Cartesian coordinates derive for any size (issue 12), and run right."""

from __future__ import annotations

import math

import numpy as np
import pytest

from systems.compiled import compile_system
from systems.mechanics import derive
from systems.scene import load_scene, parse_scene
from systems.simulation import Run, Sampler


def fpu_scene(n: int, form: str) -> str:
    """An FPU-alpha chain of ``n`` unit masses with fixed ends, from T and V or from H."""
    q = [f"q{i}" for i in range(1, n + 1)]

    def bond(i: int) -> str:
        right = q[i] if i < n else "0"
        left = q[i - 1] if i >= 1 else "0"
        return f"({right} - {left})"

    springs = " + ".join(f"{bond(i)}**2/2 + alpha*{bond(i)}**3/3" for i in range(n + 1))
    if form == "tv":
        body = f'kinetic = "{" + ".join(f"{x}_dot**2/2" for x in q)}"\npotential = "{springs}"'
    else:
        body = f'hamiltonian = "{" + ".join(f"p_{x}**2/2" for x in q)} + {springs}"'
    start = "\n".join(
        f"{x} = {math.sin(math.pi * (i + 1) / (n + 1)):.12f}" for i, x in enumerate(q)
    )
    names = ", ".join(f'"{x}"' for x in q)
    return (
        f'title = "FPU {n}"\n[system]\ncoordinates = [{names}]\n'
        f"parameters = {{ alpha = 0.25 }}\n{body}\n[initial]\n{start}\n"
    )


def trajectory(text: str, t_end: float, samples: int = 20) -> np.ndarray:
    mechanics = derive(parse_scene(text))
    compiled = compile_system(mechanics, ["rhs", "hamiltonian", "separable"])
    run = Run(compiled, method="yoshida8", t_end=t_end, diagnostics=("H",))
    rows = list(Sampler(run, np.linspace(0.0, t_end, samples + 1)))
    assert run.finished and run.t == pytest.approx(t_end)
    return np.array([y for _, y in rows]), mechanics


def test_an_fpu_chain_from_t_and_v_and_from_h_gives_the_same_trajectory():
    from_tv, mechanics_tv = trajectory(fpu_scene(12, "tv"), 20.0)
    from_h, mechanics_h = trajectory(fpu_scene(12, "h"), 20.0)
    assert mechanics_tv.classification.separable and mechanics_h.classification.separable
    assert mechanics_h.momenta is not None  # the Legendre transform inverted, at n = 12
    np.testing.assert_allclose(from_tv, from_h, atol=1e-11)
    assert np.max(np.abs(from_tv[-1] - from_tv[0])) > 0.1  # it moved


def test_the_figure_eight_returns_after_one_period():
    """Chenciner-Montgomery initial conditions to Simo's 8 digits: back to about 1e-7."""
    mechanics = derive(load_scene("figure_eight"))
    compiled = compile_system(mechanics, ["rhs", "hamiltonian", "separable"])
    period = 6.32591398
    run = Run(compiled, method="yoshida8", t_end=period, dt=period / 2000)
    y0 = run.y0.copy()
    rows = list(Sampler(run, [period]))
    assert rows[-1][0] == pytest.approx(period)
    assert np.max(np.abs(rows[-1][1] - y0)) < 1e-6
