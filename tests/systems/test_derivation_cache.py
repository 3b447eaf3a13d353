import sympy

from systems import derivation_cache
from systems.mechanics import derive
from tests.systems.scenes import PLANETARY, scene


def test_a_second_derivation_comes_from_the_cache_and_is_equal(tmp_path, monkeypatch):
    monkeypatch.setenv("PHASE_EXPLORER_CACHE", str(tmp_path))
    first = derive(scene(PLANETARY))
    assert derivation_cache.load(scene(PLANETARY)) is not None
    again = scene(PLANETARY)
    second = derive(again)
    assert second.scene is again
    assert sympy.simplify(second.hamiltonian - first.hamiltonian) == 0
    assert second.hamilton_equations == first.hamilton_equations
    assert second.classification == first.classification
    assert second.cyclic == first.cyclic


def test_a_cached_double_pendulum_is_the_one_derived(tmp_path, monkeypatch):
    """Its Hamilton's equations are kept unevaluated (v(q, p) put into dL/dq as built):
    the cache gives back the same expressions, not their evaluated forms."""
    from systems.scene import load_scene

    monkeypatch.setenv("PHASE_EXPLORER_CACHE", str(tmp_path))
    first = derive(load_scene("double_pendulum"))
    second = derivation_cache.load(load_scene("double_pendulum"))
    assert second is not None
    assert second.hamilton_equations == first.hamilton_equations
    assert second.hamiltonian == first.hamiltonian
    assert second.conserved == first.conserved


def test_another_scene_text_misses(tmp_path, monkeypatch):
    monkeypatch.setenv("PHASE_EXPLORER_CACHE", str(tmp_path))
    derive(scene(PLANETARY))
    changed = scene(PLANETARY.replace("k = 0.8", "k = 0.9"))
    assert derivation_cache.load(changed) is None


def test_unreadable_file_is_ignored(tmp_path, monkeypatch):
    monkeypatch.setenv("PHASE_EXPLORER_CACHE", str(tmp_path))
    s = scene(PLANETARY)
    derivation_cache._path(s).write_bytes(b"not a pickle")
    assert derivation_cache.load(s) is None
    assert derive(s).cyclic == ("theta",)


def test_a_remembered_value_is_computed_once_per_key_and_tag(tmp_path, monkeypatch):
    monkeypatch.setenv("PHASE_EXPLORER_CACHE", str(tmp_path))
    calls = []

    def compute(value):
        calls.append(value)
        return {"value": value}

    assert derivation_cache.remembered_value("a", "v1", lambda: compute(1)) == {"value": 1}
    assert derivation_cache.remembered_value("a", "v1", lambda: compute(2)) == {"value": 1}
    assert derivation_cache.remembered_value("b", "v1", lambda: compute(3)) == {"value": 3}
    assert derivation_cache.remembered_value("a", "v2", lambda: compute(4)) == {"value": 4}
    assert calls == [1, 3, 4]
    monkeypatch.setenv("PHASE_EXPLORER_DERIVATION_CACHE", "0")
    assert derivation_cache.remembered_value("a", "v1", lambda: compute(5)) == {"value": 5}


def test_a_damaged_remembered_value_is_computed_again(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("PHASE_EXPLORER_CACHE", str(tmp_path))
    derivation_cache.remembered_value("a", "v1", lambda: [1.5])
    [entry] = (tmp_path / "values").iterdir()
    entry.write_bytes(entry.read_bytes()[:-3])
    assert derivation_cache.remembered_value("a", "v1", lambda: [2.5]) == [2.5]
    assert "damaged" in capsys.readouterr().err
    assert derivation_cache.remembered_value("a", "v1", lambda: [3.5]) == [2.5]


def test_a_remembered_job_is_answered_from_the_disk_by_its_arguments(tmp_path, monkeypatch):
    """``remembered_job``: computed once per arguments' contents; ``from_cache`` gives
    the answer without computing, and MISSING before it is known or for an argument it
    cannot name."""
    import numpy as np

    monkeypatch.setenv("PHASE_EXPLORER_CACHE", str(tmp_path))
    calls = []

    def analyse(mechanics, values, start=None):
        calls.append(values.tolist())
        return {"n": len(mechanics.scene.coordinates), "sum": float(values.sum())}

    job = derivation_cache.remembered_job(analyse)
    mechanics = derive(scene(PLANETARY))
    values = np.array([1.0, 2.0])
    assert job.from_cache(mechanics, values) is derivation_cache.MISSING
    assert job(mechanics, values) == {"n": 2, "sum": 3.0}
    # the same contents (another array, the scene derived again) are one entry
    again = derive(scene(PLANETARY))
    assert job.from_cache(again, np.array([1.0, 2.0])) == {"n": 2, "sum": 3.0}
    assert job(again, np.array([1.0, 2.0])) == {"n": 2, "sum": 3.0}
    assert calls == [[1.0, 2.0]]
    # other values, another scene, another keyword: not the same answer
    assert job.from_cache(mechanics, np.array([1.0, 2.5])) is derivation_cache.MISSING
    other = derive(scene(PLANETARY.replace("k = 0.8", "k = 0.9")))
    assert job.from_cache(other, values) is derivation_cache.MISSING
    assert job.from_cache(mechanics, values, start=0.5) is derivation_cache.MISSING
    # an argument it cannot name by its contents: computed every time, never answered
    assert job.from_cache(mechanics, values, start=object()) is derivation_cache.MISSING
    job(mechanics, values, start=object())
    job(mechanics, values, start=object())
    assert len(calls) == 3
    # without the cache nothing is answered
    monkeypatch.setenv("PHASE_EXPLORER_DERIVATION_CACHE", "0")
    assert job.from_cache(mechanics, values) is derivation_cache.MISSING


def test_a_job_the_disk_answers_starts_no_process(tmp_path, monkeypatch):
    """``processes.Job`` asks ``from_cache`` first: the normal-mode analysis of a scene
    analysed before comes back without a worker (no pid), equal to the worker's, and
    ``on_done`` is still called from another thread."""
    import threading

    import numpy as np

    from systems import normal_modes, processes

    monkeypatch.setenv("PHASE_EXPLORER_CACHE", str(tmp_path))
    mechanics = derive(scene(PLANETARY))
    args = (mechanics, None, np.array([1.0, 0.0]))
    first = processes.submit(normal_modes.analyse, *args, what="the normal modes")
    assert first.pid is not None  # not known yet: a worker computed and remembered it
    computed = first.result(timeout=120)
    called = []
    done = threading.Event()

    def on_done(job):
        called.append(threading.current_thread() is not threading.main_thread())
        done.set()

    second = processes.submit(normal_modes.analyse, *args, on_done=on_done)
    assert second.pid is None and second.done()
    assert repr(second.result()) == repr(computed)
    assert done.wait(10) and called == [True]
    second.cancel()  # harmless on an answered job
    assert repr(second.result()) == repr(computed)


def test_build_code_from_the_disk_only_for_a_scene_derived_before(tmp_path, monkeypatch):
    """``build_code.from_cache``: MISSING for a scene never derived (``only_known``: the
    derivation raises NotKnown instead of running), else the derivation and the code a
    worker would return."""
    import pytest

    from systems.sources import build_code

    monkeypatch.setenv("PHASE_EXPLORER_CACHE", str(tmp_path))
    assert build_code.from_cache(PLANETARY) is derivation_cache.MISSING
    with derivation_cache.only_known(), pytest.raises(derivation_cache.NotKnown):
        derive(scene(PLANETARY))
    mechanics, code = build_code(PLANETARY)
    known, known_code = build_code.from_cache(PLANETARY)
    assert known.hamilton_equations == mechanics.hamilton_equations
    assert (known_code.text, known_code.names, known_code.backend) == (
        code.text,
        code.names,
        code.backend,
    )
    # a text longer than a scene is read in a worker, whose CPU limit bounds reading it
    long = PLANETARY + "\n#" + "x" * 30_000
    assert build_code.from_cache(long) is derivation_cache.MISSING
