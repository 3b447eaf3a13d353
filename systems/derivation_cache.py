"""On-disk cache of derivations, so a scene opened again skips sympy entirely.

Numba already caches the machine code of a scene's kernels; what remained on a second
opening was the symbolic derivation itself (about a second for the double pendulum). A
derivation is a pure function of the scene's text and of the code that derives it, so the
key is a hash of both: the scene as TOML (its title, system, effects, parameters, initial
state and drawing) and the source of the modules that parse and derive, with sympy's
version. Editing any of them simply misses the cache. A file that cannot be read is
ignored and written anew.

``remembered`` keeps smaller facts computed from a derivation the same way (the method
choice, the printed kernel source), keyed also by the code that computes them: on a
second opening they cost a file read instead of tens of milliseconds of sympy each.
"""

from __future__ import annotations

import dataclasses
import hashlib
import os
import pickle
from collections.abc import Callable
from functools import cache
from pathlib import Path

import sympy

import systems.expressions
import systems.mechanics
import systems.scene


@cache
def _code_version() -> str:
    digest = hashlib.sha256(sympy.__version__.encode())
    for module in (systems.expressions, systems.scene, systems.mechanics):
        digest.update(Path(module.__file__).read_bytes())
    return digest.hexdigest()


def _path(scene) -> Path:
    from systems.codegen import cache_dir

    key = hashlib.sha256((_code_version() + scene.to_toml()).encode()).hexdigest()[:32]
    folder = cache_dir().parent / "derivations"
    folder.mkdir(parents=True, exist_ok=True)
    return folder / f"{key}.pickle"


def enabled() -> bool:
    return os.environ.get("PHASE_EXPLORER_DERIVATION_CACHE", "1") != "0"


def load(scene):
    """The cached derivation of ``scene`` (with ``scene`` itself attached), or None."""
    if not enabled():
        return None
    path = _path(scene)
    try:
        with path.open("rb") as handle:
            mechanics = pickle.load(handle)
    except (OSError, EOFError, pickle.UnpicklingError, AttributeError, ImportError, TypeError):
        return None
    if not isinstance(mechanics, systems.mechanics.Mechanics):
        return None
    return dataclasses.replace(mechanics, scene=scene, _cache={})


def store(mechanics) -> None:
    """Write ``mechanics`` for its scene; failures only mean a later miss."""
    if not enabled():
        return
    path = _path(mechanics.scene)
    tmp = path.with_suffix(f".tmp{os.getpid()}")
    try:
        with tmp.open("wb") as handle:
            pickle.dump(dataclasses.replace(mechanics, _cache={}), handle)
        os.replace(tmp, path)
    except (OSError, pickle.PicklingError, TypeError, AttributeError):
        tmp.unlink(missing_ok=True)


def code_hash(*modules) -> str:
    """A short hash of the source files of ``modules`` (part of a ``remembered`` tag)."""
    digest = hashlib.sha256()
    for module in modules:
        digest.update(Path(module.__file__).read_bytes())
    return digest.hexdigest()[:16]


def remembered(scene, tag: str, compute: Callable[[], str]) -> str:
    """``compute()`` for ``scene``, or the text it returned for the same scene and tag.

    ``tag`` must change whenever the answer could (include ``code_hash`` of the modules
    that compute it). Without the cache (``PHASE_EXPLORER_DERIVATION_CACHE=0``) this is
    ``compute()``.
    """
    if not enabled():
        return compute()
    base = _path(scene)
    name = hashlib.sha256(tag.encode()).hexdigest()[:16]
    path = base.with_name(f"{base.stem}-{name}.txt")
    try:
        return path.read_text()
    except OSError:
        pass
    text = compute()
    tmp = path.with_suffix(f".tmp{os.getpid()}")
    try:
        tmp.write_text(text)
        os.replace(tmp, path)
    except OSError:
        tmp.unlink(missing_ok=True)
    return text
