"""A scene's Taylor functions come from one decomposition, whichever derivation of its
equations a process holds: one read back from the disk (unpickled) decomposes into
other nodes than the fresh one, and a batch function written from one and run with the
other's width read garbage (``compiled.decomposition_of``)."""

import pickle

import numpy as np

from systems.compiled import compile_system
from systems.integrators.registry import STEPPERS, make_runner
from systems.mechanics import derive
from systems.scene import load_scene
from systems.simulation import ensemble
from systems.taylor.decompose import decompose_mechanics


def test_a_derivation_read_back_runs_the_same_functions_as_the_fresh_one():
    fresh = derive(load_scene("double_pendulum"))
    read_back = pickle.loads(pickle.dumps(fresh))
    # the premise: without it this test would check nothing
    assert len(decompose_mechanics(fresh).nodes) != len(decompose_mechanics(read_back).nodes)
    first = compile_system(fresh)
    assert first.taylor().width  # the scalar code written from the fresh derivation
    second = compile_system(read_back)
    assert second.taylor().width == first.taylor().width
    # the batch function (its own decomposition once) runs the rows the single runs do
    y0 = second.initial_state()
    Y0 = y0 + np.linspace(0.0, 0.2, 9)[:, None] * np.array([1.0, -1.0, 0.5, 0.0])
    t, Y, status = ensemble(second, Y0, method="taylor", t_end=2.0, samples=3, batched=True)
    assert not status.any()
    for row, start in enumerate(Y0):
        runner = make_runner(second, STEPPERS["taylor"], start, 0.0, 2.0, None, None)
        outcome = runner.advance(10**9, 2, samples=t)
        assert np.array_equal(outcome.y[:3], Y[row]), row
