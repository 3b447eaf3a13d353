"""Builds of former versions of the drivers leave the cache (``codegen.prune_drivers``):
the current build and the most recently used others stay, whatever their age."""

import os
import sys

from systems import codegen


def _build(folder, key: str, used: float) -> None:
    """A fake build ``key``: its module and two of numba's files, last used at ``used``."""
    name = codegen._name(key, True)
    module = folder / f"{name}.py"
    module.write_text("# a former build\n")
    cached = folder / "__pycache__"
    cached.mkdir(exist_ok=True)
    for suffix in ("_add-42.py311.nbi", "_add-42.py311.1.nbc"):
        (cached / f"{name}.{suffix}").write_bytes(b"x")
    os.utime(module, (used, used))


def test_old_builds_go_and_the_current_and_recent_stay(tmp_path, monkeypatch):
    monkeypatch.setattr(codegen, "cache_dir", lambda: tmp_path)
    current = codegen._driver_key()
    _build(tmp_path, current, used=1.0)  # the oldest mark, yet the current build
    for age, key in enumerate(["a" * 20, "b" * 20, "c" * 20, "d" * 20]):
        _build(tmp_path, key, used=1000.0 - age)  # a is the most recently used
    scene_module = tmp_path / "pe_kernels_0123.py"  # a scene's module: not a build
    scene_module.write_text("# a scene\n")

    removed = codegen.prune_drivers(keep=3)

    assert sorted(removed) == [codegen._name("c" * 20, True), codegen._name("d" * 20, True)]
    left = sorted(p.name.split(".")[0] for p in tmp_path.glob("*.py"))
    assert left == sorted(
        [codegen._name(k, True) for k in (current, "a" * 20, "b" * 20)] + ["pe_kernels_0123"]
    )
    cached = {p.name.split(".")[0] for p in (tmp_path / "__pycache__").iterdir()}
    assert cached == {codegen._name(k, True) for k in (current, "a" * 20, "b" * 20)}
    assert codegen.prune_drivers(keep=3) == []


def test_loading_the_drivers_marks_their_build_as_used():
    """``driver_module`` marks its file (the test session's cache has it built)."""
    module = codegen.driver_module()
    path = codegen.cache_dir() / f"{module.__name__}.py"
    os.utime(path, (1.0, 1.0))
    codegen._loaded.pop(codegen._driver_key())
    try:
        codegen.driver_module()  # imported again: a module of its own
    finally:
        codegen._loaded[codegen._driver_key()] = module
        sys.modules[module.__name__] = module
    assert path.stat().st_mtime > 1.0
