"""On-disk cache of derivations, so a scene opened again skips sympy entirely.

Numba already caches the machine code of a scene's kernels; what remained on a second
opening was the symbolic derivation itself (about a second for the double pendulum). A
derivation is a pure function of the scene's text and of the code that derives it, so the
key is a hash of both: the scene as TOML (its title, system, effects, parameters, initial
state and drawing) and the source of the modules that parse and derive, with sympy's
version. Editing any of them simply misses the cache. Every file carries a checksum of its
contents and of that code version (``systems.cache_integrity.write_checked``); one that
does not verify or load is deleted, reported in one line on stderr, and derived anew.

``remembered`` keeps smaller facts computed from a derivation the same way (the method
choice, the printed kernel source), keyed also by the code that computes them: on a
second opening they cost a file read instead of tens of milliseconds of sympy each.
``remembered_value`` keeps any picklable value by a key of its own (a formula's type,
``systems.typeset``: seconds of mathtext a scene).
"""

from __future__ import annotations

import contextlib
import contextvars
import dataclasses
import functools
import hashlib
import io
import os
import pickle
from collections.abc import Callable
from functools import cache
from pathlib import Path
from typing import TypeVar

import numpy as np
import sympy

import systems.calculus
import systems.classification
import systems.constraints
import systems.display
import systems.expressions
import systems.mechanics
import systems.particles
import systems.scene
import systems.symmetries
from systems.cache_integrity import (
    MAGIC,
    cache_root,
    discard,
    read_checked,
    usable_directory,
    write_checked,
)

T = TypeVar("T")


@cache
def _code_version() -> str:
    digest = hashlib.sha256(MAGIC + sympy.__version__.encode())  # MAGIC: the file format
    for module in (
        systems.expressions,
        systems.legendre,
        systems.scene,
        systems.mechanics,
        systems.calculus,
        systems.classification,
        systems.constraints,
        systems.display,
        systems.particles,
        systems.symmetries,
    ):
        digest.update(Path(module.__file__).read_bytes())
    return digest.hexdigest()


def scene_key(scene) -> str:
    """A hash of ``scene`` (as TOML) and of the code that derives it."""
    return hashlib.sha256((_code_version() + scene.to_toml()).encode()).hexdigest()[:32]


def _path(scene) -> Path:
    return usable_directory(cache_root() / "derivations") / f"{scene_key(scene)}.pickle"


def enabled() -> bool:
    return os.environ.get("PHASE_EXPLORER_DERIVATION_CACHE", "1") != "0"


def load(scene):
    """The cached derivation of ``scene`` (with ``scene`` itself attached), or None."""
    if not enabled():
        return None
    path = _path(scene)
    data = read_checked(path, _code_version())
    if data is None:
        return None
    try:
        mechanics = pickle.loads(data)
        if not isinstance(mechanics, systems.mechanics.Mechanics):
            raise TypeError(f"a pickled {type(mechanics).__name__}, not a derivation")
        return dataclasses.replace(mechanics, scene=scene, _cache={})
    except Exception as exc:  # noqa: BLE001 - whatever a damaged entry raises, derive anew
        discard(path, f"failed to load: {type(exc).__name__}")
        return None


def store(mechanics) -> None:
    """Write ``mechanics`` for its scene; failures only mean a later miss."""
    if not enabled():
        return
    try:
        buffer = io.BytesIO()
        _AsBuilt(buffer).dump(dataclasses.replace(mechanics, _cache={}))
        data = buffer.getvalue()
    except (pickle.PicklingError, TypeError, AttributeError, RecursionError):
        return
    write_checked(_path(mechanics.scene), data, _code_version())


_AS_BUILT = (sympy.Add, sympy.Mul, sympy.Pow)


def _as_built(cls, args):
    return cls(*args, evaluate=False)


class _AsBuilt(pickle.Pickler):
    """Pickles sums, products and powers as they are, not as their constructors would
    rebuild them: the derivation keeps some unevaluated (``systems.calculus.replaced``),
    and a cached derivation must be the one derived (loading is faster, too)."""

    def reducer_override(self, obj):
        if type(obj) in _AS_BUILT:
            return _as_built, (type(obj), obj.args)
        return NotImplemented


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
    ``compute()``. The stored text is checked against its checksum (of the text and the
    tag) before it is returned; one that does not verify is computed again.
    """
    if not enabled():
        must_compute()
        return compute()
    base = _path(scene)
    name = hashlib.sha256(tag.encode()).hexdigest()[:16]
    path = base.with_name(f"{base.stem}-{name}.txt")
    data = read_checked(path, tag)
    if data is not None:
        return data.decode()  # verified: the UTF-8 that was written
    must_compute()
    text = compute()
    write_checked(path, text.encode(), tag)
    return text


def remembered_value(key: str, tag: str, compute: Callable[[], T]) -> T:
    """``compute()``, or the value it returned for the same ``key`` and ``tag``, pickled.

    ``key`` names what is computed (any text: it is hashed), ``tag`` the code that
    computes it (include ``code_hash`` of its modules and the versions of the libraries
    it uses). Without the cache (``PHASE_EXPLORER_DERIVATION_CACHE=0``) this is
    ``compute()``. An entry that does not verify or load is deleted, reported in one
    line, and computed again; a value that cannot be pickled is only returned.
    """
    if not enabled():
        must_compute()
        return compute()
    value = known_value(key, tag)
    if value is not MISSING:
        return value
    must_compute()
    value = compute()
    try:
        data = pickle.dumps(value, protocol=pickle.HIGHEST_PROTOCOL)
    except (pickle.PicklingError, TypeError, AttributeError, RecursionError):
        return value
    write_checked(_value_path(key, tag), data, tag)
    return value


def _value_path(key: str, tag: str) -> Path:
    name = hashlib.sha256(f"{key}\0{tag}".encode()).hexdigest()[:32]
    return usable_directory(cache_root() / "values") / f"{name}.pickle"


class NotKnown(Exception):  # noqa: N818 - what happened, not an error
    """Raised inside ``only_known()`` where an answer would have to be computed."""


_ONLY_KNOWN = contextvars.ContextVar("only_known", default=False)


@contextlib.contextmanager
def only_known():
    """Within: ``remembered``, ``remembered_value`` and ``mechanics.derive`` raise
    ``NotKnown`` instead of computing what is not on disk (this thread only)."""
    token = _ONLY_KNOWN.set(True)
    try:
        yield
    finally:
        _ONLY_KNOWN.reset(token)


def must_compute() -> None:
    """Called before computing what the cache did not have: raises ``NotKnown`` within
    ``only_known()``."""
    if _ONLY_KNOWN.get():
        raise NotKnown


class _Missing:
    def __repr__(self) -> str:
        return "MISSING"


MISSING = _Missing()
"""What ``known_value`` and a remembered job's ``from_cache`` give for an answer not
on disk."""


def known_value(key: str, tag: str):
    """The value ``remembered_value(key, tag, ...)`` would return without computing, or
    ``MISSING`` (no entry, the cache off, or an entry that does not verify or load)."""
    if not enabled():
        return MISSING
    path = _value_path(key, tag)
    data = read_checked(path, tag)
    if data is None:
        return MISSING
    try:
        return pickle.loads(data)
    except Exception as exc:  # noqa: BLE001 - whatever a damaged entry raises, compute anew
        discard(path, f"failed to load: {type(exc).__name__}")
        return MISSING


@cache
def package_version() -> str:
    """A hash of every module of ``systems`` and the versions of the libraries its numbers
    come from: the tag of a remembered job, whose answer may depend on any of them."""
    import importlib.metadata

    root = Path(systems.mechanics.__file__).parent
    digest = hashlib.sha256(MAGIC)
    for path in sorted(root.rglob("*.py")):
        digest.update(str(path.relative_to(root)).encode() + b"\0" + path.read_bytes())
    for library in ("numpy", "scipy", "sympy", "symengine", "numba", "llvmlite", "matplotlib"):
        try:
            digest.update(f"{library} {importlib.metadata.version(library)}\0".encode())
        except importlib.metadata.PackageNotFoundError:
            digest.update(f"{library} absent\0".encode())
    return digest.hexdigest()[:32]


class _Unkeyed(Exception):
    """An argument a remembered job cannot name by its contents."""


def _key_of(value) -> str:
    """Text naming ``value`` by its contents: a derivation by its scene's key (and a
    compiled system also by its parameter values), numbers and text by ``repr``, arrays
    by their bytes, containers by their items, other plain data by its pickle; a
    cancellation token by nothing (it changes no answer). A class names its instances
    itself with a ``__job_key__()`` method (``CompiledSystem``, ``Cancel``)."""
    if value is None or isinstance(value, (bool, int, float, complex, str)):
        return f"{type(value).__name__}:{value!r}"
    named = getattr(type(value), "__job_key__", None)
    if named is not None:
        return f"{type(value).__qualname__}:{named(value)}"
    if isinstance(value, systems.mechanics.Mechanics):
        return f"mechanics:{scene_key(value.scene)}"
    if isinstance(value, systems.scene.Scene):
        return f"scene:{scene_key(value)}"
    if isinstance(value, np.ndarray):
        data = np.ascontiguousarray(value)
        return f"array:{data.dtype.str}:{data.shape}:{hashlib.sha256(data.tobytes()).hexdigest()}"
    if isinstance(value, (tuple, list)):
        return f"{type(value).__name__}(" + ",".join(map(_key_of, value)) + ")"
    if isinstance(value, dict):
        items = sorted((_key_of(k), _key_of(v)) for k, v in value.items())
        return "dict(" + ",".join(f"{k}={v}" for k, v in items) + ")"
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        fields = dataclasses.fields(value)
        inner = ",".join(f"{f.name}={_key_of(getattr(value, f.name))}" for f in fields)
        return f"{type(value).__qualname__}({inner})"
    raise _Unkeyed(type(value).__qualname__)


def remembered_job(function: Callable[..., T]) -> Callable[..., T]:
    """``function`` (a pure job: its answer a function of its arguments' contents and of
    ``systems``' code) remembered on disk by its arguments (``remembered_value``, tagged
    with ``package_version``). The returned function has the same module and name (a
    worker process finds it by them) and a ``from_cache(*args, **kwargs)`` that gives the
    remembered answer or ``MISSING`` without computing: ``systems.processes.Job`` asks it
    first and starts no process for an answer already on disk.

    Arguments it cannot name by their contents (``_key_of``) make the call compute, as
    without the cache."""

    name = f"{function.__module__}.{function.__qualname__}"

    def key(args, kwargs) -> str | None:
        try:
            return f"job {name} " + _key_of((tuple(args), dict(kwargs)))
        except _Unkeyed:
            return None

    @functools.wraps(function)
    def job(*args, **kwargs):
        found = key(args, kwargs)
        if found is None:
            return function(*args, **kwargs)
        return remembered_value(found, package_version(), lambda: function(*args, **kwargs))

    def from_cache(*args, **kwargs):
        found = key(args, kwargs)
        return MISSING if found is None else known_value(found, package_version())

    job.from_cache = from_cache
    return job
