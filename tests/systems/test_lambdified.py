"""Lambdified functions that cross between processes as source text
(``systems.lambdified``), and the constraint forces, whose functions they are, made in a
worker process and evaluated in this one."""

from __future__ import annotations

import pickle

import numpy as np
import sympy

from systems import constraint_forces as cf
from systems import processes
from systems.compiled import compile_system
from systems.lambdified import Lambdified, lambdify
from systems.mechanics import derive
from systems.scene import load_scene

WAIT = 120.0
"""Seconds a test waits at most for a worker (a busy machine; never a measurement)."""

x, y = sympy.symbols("x y")


def test_a_lambdified_function_evaluates_the_same_after_pickling():
    exprs = [
        sympy.sin(x) * y + sympy.sqrt(x) * sympy.sin(x),  # a common subexpression
        sympy.Piecewise((x, x > 1), (y, True)),
        sympy.pi * x + sympy.exp(-y),
        sympy.Max(x, y) + sympy.Abs(y) + sympy.atan2(y, x),
        sympy.Integer(3),
    ]
    f = lambdify([x, y], exprs, modules="numpy", cse=True)
    copy = pickle.loads(pickle.dumps(f))
    assert isinstance(copy, Lambdified) and copy.source == f.source
    xs, ys = np.linspace(0.5, 2.0, 7), np.linspace(-1.0, 1.0, 7)
    for a, b in zip(f(xs, ys), copy(xs, ys), strict=True):
        np.testing.assert_array_equal(a, b)
    again = pickle.loads(pickle.dumps(copy))  # a copy pickles as well as the original
    np.testing.assert_array_equal(again(xs, ys)[0], f(xs, ys)[0])


def test_constraint_forces_made_in_a_worker_are_evaluated_here():
    """As the constraint-forces panel does: ``analyse`` in a worker process, its
    functions rebuilt from their source here, filed under this process's derivation."""
    mechanics = derive(load_scene("cartesian_pendulum"))
    compiled = compile_system(mechanics, ())
    there = processes.submit(cf.analyse, mechanics, what="constraint forces").result(WAIT)
    here = cf.analyse(mechanics)
    assert there is not here and there.k == here.k == 1
    assert there.particles == here.particles and there.descriptions == here.descriptions
    t = np.linspace(0.0, 1.0, 5)
    Y = np.tile(compiled.initial_state(), (len(t), 1))
    Y[:, 2] += np.linspace(0.0, 0.5, len(t))  # some velocity: the tension changes
    a, b = here.evaluate(compiled, t, Y), there.evaluate(compiled, t, Y)
    np.testing.assert_array_equal(a.multipliers, b.multipliers)
    np.testing.assert_array_equal(a.reactions, b.reactions)
    np.testing.assert_array_equal(a.power, b.power)
    cf.remember(mechanics, there)  # a valid analysis of this derivation: none made again
    assert cf.known(mechanics) is there and cf.analyse(mechanics) is there


def test_numpy_functions_come_without_numpys_lazy_submodules():
    """``modules="numpy"`` is passed to sympy as the module: the string made sympy run
    ``from numpy import *``, importing numpy.f2py and the rest (0.1 s of derive --json);
    the functions and their values are the same."""
    import subprocess
    import sys

    probe = (
        "import sys, sympy; from systems.lambdified import lambdify; "
        "x = sympy.Symbol('x'); f = lambdify([x], [sympy.sin(x), sympy.Heaviside(x)], "
        "modules='numpy'); print(f(0.5)[0], 'numpy.f2py' in sys.modules)"
    )
    out = subprocess.run(
        [sys.executable, "-c", probe], capture_output=True, text=True, check=True
    ).stdout.split()
    assert float(out[0]) == np.sin(0.5) and out[1] == "False"
    exprs = [sympy.Heaviside(x - 1), sympy.Mod(x, 2 * sympy.pi), sympy.sign(y) * sympy.Abs(x)]
    ours = lambdify([x, y], exprs, modules="numpy")
    sympys = sympy.lambdify([x, y], exprs, modules="numpy")
    a, b = np.array([0.5, 1.5, 7.0]), np.array([-1.0, 2.0, 0.0])
    for mine, theirs in zip(ours(a, b), sympys(a, b), strict=True):
        assert np.array_equal(np.broadcast_to(mine, a.shape), np.broadcast_to(theirs, a.shape))
    assert pickle.loads(pickle.dumps(ours))(a, b)[2].tolist() == [-0.5, 1.5, 0.0]
