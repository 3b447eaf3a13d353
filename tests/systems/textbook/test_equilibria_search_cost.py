"""The equilibrium search does only the work it needs (issue 26 item 6): a potential that
is a sum over independent blocks of coordinates is solved block by block (every
combination of the blocks' roots), and the search imports only what it uses.

No test here measures time: ``benchmarks/derive_command.py`` does, against sympy."""

import itertools
import math
import os
import subprocess
import sys

import numpy as np
import pytest

from systems.families import pendulum_chain
from systems.mechanics import derive
from systems.scene import parse_scene
from systems.textbook.equilibria import _blocks, _unit_starts, search_equilibria


def test_a_chain_of_eight_links_has_all_its_256_equilibria():
    # V = -m g l sum (n - i + 1) cos q_i: each link down or up, 2^8 equilibria; the scan
    # of 400 starts in eight dimensions found 204 of them
    search = search_equilibria(derive(parse_scene(pendulum_chain(8))))
    assert len(search.equilibria) == 256
    found = {tuple(round(abs(v) / math.pi) for v in e.q.values()) for e in search.equilibria}
    assert found == set(itertools.product((0, 1), repeat=8))
    for e in search.equilibria:
        assert all(min(abs(v), abs(abs(v) - math.pi)) < 1e-12 for v in e.q.values())
    stable = [e for e in search.equilibria if e.stable]
    assert len(stable) == 1 and set(stable[0].q.values()) == {0.0}


def test_coupled_blocks_are_solved_together():
    assert _blocks([True, False, False, True], 2) == [[0], [1]]
    assert _blocks([True, True, True, True], 2) == [[0, 1]]
    # 0-2 coupled, 1 alone, 3-4 coupled
    pattern = np.zeros((5, 5), dtype=bool)
    pattern[0, 2] = pattern[2, 0] = pattern[3, 4] = True
    assert _blocks(list(pattern.ravel()), 5) == [[0, 2], [1], [3, 4]]


def test_two_independent_double_wells_give_nine_equilibria():
    scene = parse_scene(
        """
title = "Two double wells"
[system]
coordinates = ["x", "y"]
kinetic = "(x_dot**2 + y_dot**2)/2"
potential = "(x**2 - 1)**2 + (y**2 - 4)**2/4"
"""
    )
    search = search_equilibria(derive(scene), symbolic=False)
    points = sorted(tuple(round(v, 9) for v in e.q.values()) for e in search.equilibria)
    assert points == sorted(itertools.product((-1.0, 0.0, 1.0), (-2.0, 0.0, 2.0)))
    assert sum(e.stable for e in search.equilibria) == 4


def test_halton_starts_fill_the_cube_off_its_faces():
    unit = _unit_starts(6)
    assert unit.shape == (400, 6)
    assert unit.min() >= 0.01 and unit.max() <= 0.99
    # every one of 4 slabs of every axis holds about a quarter of the points
    counts = [np.histogram(unit[:, j], bins=4, range=(0, 1))[0] for j in range(6)]
    assert np.all(np.abs(np.array(counts) - 100) <= 10)
    assert np.array_equal(unit, _unit_starts(6))  # the same starts in every run


@pytest.mark.parametrize(
    "statement",
    [
        "from systems.textbook import search_equilibria",
        "import systems.textbook.equilibria",
        "import systems.report",
    ],
)
def test_the_equilibrium_search_imports_only_what_it_uses(statement):
    probe = (
        f"import sys; {statement}; "
        "print(sorted(m for m in ('scipy.integrate', 'scipy.stats', "
        "'systems.textbook.action', 'systems.textbook.routhian') if m in sys.modules))"
    )
    out = subprocess.run(
        [sys.executable, "-c", probe], capture_output=True, text=True, check=True
    ).stdout
    assert out.strip() == "[]"


@pytest.mark.parametrize("links", [1, 6])
def test_derive_json_of_a_chain_imports_no_scipy(links, tmp_path):
    """A chain's equilibria come from Newton's method (numpy) and its frequencies from
    numpy's Cholesky and eigh: ``derive --json`` imported scipy.optimize and scipy.linalg
    for them, a quarter of a second of its time (issue 26 item 6); and an autonomous
    system's ``floquet`` (None) is decided without importing the Floquet module."""
    path = tmp_path / "chain.toml"
    path.write_text(pendulum_chain(links))
    probe = (
        "import contextlib, io, json, sys; from explorer.cli import main; "
        f"sys.argv = ['main.py', 'derive', {str(path)!r}, '--json']; out = io.StringIO()\n"
        "with contextlib.redirect_stdout(out): main()\n"
        "print(len(json.loads(out.getvalue())['equilibria']), "
        "sorted(m for m in sys.modules if m.split('.')[0] == 'scipy' "
        "or m == 'systems.textbook.floquet'))"
    )
    env = {**os.environ, "PHASE_EXPLORER_DERIVATION_CACHE": "0"}
    out = subprocess.run(
        [sys.executable, "-c", probe], capture_output=True, text=True, check=True, env=env
    ).stdout
    assert out.split(maxsplit=1) == [str(2**links), "[]\n"]


def _problem(text: str):
    from systems.textbook._numeric import with_parameters
    from systems.textbook.equilibria import _Problem, _region, equilibrium_potential

    mechanics = derive(parse_scene(text))
    U, _ = equilibrium_potential(mechanics)
    names = mechanics.scene.coordinates
    periodic = tuple(n for n in names if n.startswith("q"))
    region = _region(names, periodic, None, mechanics.scene.view)
    numeric = with_parameters(U, mechanics, None)
    return _Problem(mechanics, numeric, list(mechanics.q), names, (), periodic, region, None)


SCENES = {
    "double well": ("x", "(x**2 - 1)**2"),
    "degenerate x**6": ("x", "x**6"),
    "tilted cosine": ("q", "-cos(q) - 0.3*sin(3*q)"),
    "coupled": ("x, y", "(x**2 + y**2 - 1)**2 + x*y/4"),
    "pendulum pair": ("q1, q2", "-2*cos(q1) - cos(q2) + cos(q1 - q2)/3"),
}


@pytest.mark.parametrize("name", sorted(SCENES))
def test_newton_from_every_start_finds_the_roots_the_hybrid_method_finds(name):
    """The search's roots with Newton's method first (scipy's hybrid method only for the
    starts it does not bring to a root) are those of the hybrid method from every start."""
    coordinates, potential = SCENES[name]
    names = [c.strip() for c in coordinates.split(",")]
    text = (
        f'title = "{name}"\n[system]\ncoordinates = {names!r}\n'.replace("'", '"')
        + f'kinetic = "({" + ".join(f"{q}_dot**2" for q in names)})/2"\n'
        + f'potential = "{potential}"\n'
    )
    problem = _problem(text)
    everything = list(range(problem.m))
    starts, base = problem.starts(), np.zeros(problem.m)
    newton = problem._roots(everything, starts, base)
    hybrid = problem._roots(everything, starts, base, newton=False)
    assert len(newton) == len(hybrid) > 0
    assert all(problem.index(x, hybrid) >= 0 for x in newton)


def test_the_generalized_eigenproblem_agrees_with_scipy():
    import scipy.linalg

    from systems.textbook.equilibria import _generalized_eigh

    rng = np.random.default_rng(5)
    for n in (1, 2, 6):
        A, B = rng.normal(size=(n, n)), rng.normal(size=(n, n))
        K, M = A + A.T, B @ B.T + n * np.eye(n)
        w2, vectors = _generalized_eigh(K, M)
        expected, _ = scipy.linalg.eigh(K, M)
        assert np.allclose(w2, expected, rtol=1e-12, atol=1e-12)
        assert np.allclose(vectors.T @ M @ vectors, np.eye(n), atol=1e-12)
        assert np.allclose(K @ vectors, M @ vectors * w2, atol=1e-10)
    with pytest.raises(np.linalg.LinAlgError):
        _generalized_eigh(np.eye(2), np.diag([1.0, -1.0]))
