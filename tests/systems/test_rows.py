"""H over vectors of rows (``systems.rows``) is the scalar H of each row, to the vector
math library's few units in the last place, for every function the scene language has,
any number of rows, and code read back from the disk in a fresh process."""

import json
import os
import subprocess
import sys

import numpy as np
import pytest

from systems import rows
from systems.compiled import ROWS_FROM, compile_system
from systems.mechanics import derive
from systems.scene import load_scene, parse_scene
from tests.systems.test_llvm_kernels import EVERY_FUNCTION

needs_libmvec = pytest.mark.skipif(
    rows._libmvec() is None, reason="no libmvec, or a CPU without AVX2 and FMA"
)


def _compiled(scene):
    text_or_name = scene
    scene = parse_scene(text_or_name) if "\n" in text_or_name else load_scene(text_or_name)
    return compile_system(derive(scene), ("rhs", "hamiltonian"))


def _one_by_one(compiled, t, Y):
    """H row by row: the scalar function (fewer than ``ROWS_FROM`` rows)."""
    return np.array([compiled.hamiltonian(t[i], Y[i : i + 1])[0] for i in range(len(Y))])


def _states(compiled, count, seed=3):
    rng = np.random.default_rng(seed)
    y0 = compiled.initial_state()
    return y0 + rng.uniform(-0.8, 0.8, (count, len(y0)))


@needs_libmvec
@pytest.mark.parametrize(
    "scene", [EVERY_FUNCTION, "double_pendulum", "driven_damped_pendulum", "spherical_pendulum"],
    ids=["every_function", "double_pendulum", "driven", "spherical_pendulum"],
)  # fmt: skip
def test_rows_are_the_scalar_function(scene):
    compiled = _compiled(scene)
    assert compiled.rows() is not None
    for count in (ROWS_FROM, ROWS_FROM + 1, ROWS_FROM + 2, ROWS_FROM + 3, 403):
        Y = _states(compiled, count)
        t = np.linspace(0.0, 7.0, count)  # a driven scene's H depends on t
        found = compiled.hamiltonian(t, Y)
        expected = _one_by_one(compiled, t, Y)
        # the vector functions are within 4 units in the last place; H's terms cancel
        # by at most a few binary digits here
        np.testing.assert_allclose(found, expected, rtol=0, atol=2e-14 * np.abs(expected).max())
        assert np.isfinite(found).all()


@needs_libmvec
def test_each_row_is_its_own():
    """Rows are not exchanged between lanes: H of the reversed states is the reverse."""
    compiled = _compiled("double_pendulum")
    Y = _states(compiled, 64)
    forward = compiled.hamiltonian(0.0, Y)
    assert np.array_equal(compiled.hamiltonian(0.0, Y[::-1]), forward[::-1])
    assert len(np.unique(forward)) == len(forward)


def test_a_system_in_matrix_form_keeps_the_scalar_loop():
    """The velocity solve is not written over rows: the scalar loop serves, exactly."""
    compiled = _compiled("pendulum_chain")
    assert compiled.mechanics.matrix_form is not None
    assert compiled.rows() is None
    Y = _states(compiled, 40)
    assert np.array_equal(compiled.hamiltonian(0.0, Y), _one_by_one(compiled, np.zeros(40), Y))


PROBE = """
import json, sys
import numpy as np
from systems.compiled import compile_system
from systems.mechanics import derive
from systems.scene import load_scene
compiled = compile_system(derive(load_scene("double_pendulum")), ("rhs", "hamiltonian"))
Y = compiled.initial_state() + np.linspace(-1, 1, 40)[:, None] * np.array([1.0, -0.5, 0.3, 2.0])
print(json.dumps([compiled.rows() is not None, compiled.hamiltonian(0.0, Y).tolist()]))
"""


@needs_libmvec
def test_rows_read_from_the_disk_in_a_fresh_process(tmp_path):
    """The second process reads the text and the machine code from the cache and loads
    the vector library itself (once it was loaded only while writing the text: the
    code read back called address 0)."""
    env = {**os.environ, "PHASE_EXPLORER_CACHE": str(tmp_path)}
    env.pop("PHASE_EXPLORER_DERIVATION_CACHE", None)
    answers = []
    for _ in range(2):
        done = subprocess.run(
            [sys.executable, "-c", PROBE], env=env, capture_output=True, text=True, timeout=300
        )
        assert done.returncode == 0, done.stderr[-2000:]
        answers.append(json.loads(done.stdout.strip().splitlines()[-1]))
    assert any(tmp_path.rglob("*.o"))
    (built, first), (loaded, second) = answers
    assert built and loaded
    assert first == second
