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
