"""The equilibrium search does only the work it needs (issue 26 item 6): a potential that
is a sum over independent blocks of coordinates is solved block by block (every
combination of the blocks' roots), and the search imports only what it uses.

No test here measures time: ``benchmarks/derive_command.py`` does, against sympy."""

import itertools
import math
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
