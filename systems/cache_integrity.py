"""Cache files that heal: checksummed entries, guarded numba caches, a usable directory.

Everything the caches keep (derivations, remembered facts, generated kernel modules,
numba's machine code) is rebuilt from the scene and the code when missing, so a damaged
entry is never an error: it is deleted, rebuilt, and reported in one line on stderr.
Whatever has taken an entry's place (a folder, a named pipe, a link to one, a device) is
damage too: it is removed, never read, so the entry is rebuilt and the next run finds
a sound file.

- ``read_entry`` / ``remove_entry``: an entry's bytes, read without ever blocking on a
  pipe or a device; whatever is at an entry's path removed, a folder with its contents.
- ``write_checked`` / ``read_checked``: a file whose first line holds the sha256 of the
  code version and the body that follow it; an entry that does not verify is deleted.
- ``guard_numba_caches``: numba's per-function cache (an index ``.nbi`` and a data file
  ``.nbc`` per overload in its ``__pycache__``; the index holds numba's version and the
  stamp of the source file) gets a checksum file ``.nbsum`` (one line per file) written
  after each save; a load checks the index and the one data file it reads. An entry that
  does not verify or fails to load is deleted and compiled again.
- ``cache_root`` / ``usable_directory``: a cache directory that cannot be created or
  written (read-only, or a file in its place) is replaced for the session by a temporary
  one, with one warning line.
"""

from __future__ import annotations

import atexit
import contextlib
import glob
import hashlib
import os
import pickle
import re
import shutil
import stat
import sys
import tempfile
import threading
from pathlib import Path
from types import ModuleType

from systems.files import kind

MAGIC = b"phase-explorer-cache 1 sha256="
"""Start of the first line of a checksummed file; the hex digest follows."""

_fallbacks: dict[Path, Path] = {}
_temporary: list[Path] = []
_fallback_lock = threading.Lock()  # the native-build thread may hit the same directory


def report(message: str) -> None:
    """Print one ``phase-explorer: ...`` line on stderr."""
    print(f"phase-explorer: {message}", file=sys.stderr, flush=True)


def _digest(version: str, body: bytes) -> bytes:
    digest = hashlib.sha256(hashlib.sha256(version.encode()).digest())
    digest.update(body)
    return digest.hexdigest().encode()


def write_atomic(path: Path, data: bytes) -> None:
    """Write ``data`` to a temporary file beside ``path``, then rename it into place.

    Raises
    ------
    OSError
        If the file cannot be written; ``path`` is then left as it was.
    """
    handle, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(handle, "wb") as file:
            file.write(data)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def write_checked(path: Path, body: bytes, version: str) -> bool:
    """Store ``body`` at ``path`` under a checksum of ``version`` and ``body``.

    Returns False if the file could not be written (a cache only misses later).
    """
    try:
        write_atomic(path, MAGIC + _digest(version, body) + b"\n" + body)
    except OSError:
        return False
    return True


def read_checked(path: Path, version: str) -> bytes | None:
    """The body stored at ``path`` by ``write_checked`` with the same ``version``.

    Returns None if there is no such file. A file that cannot be read or does not verify
    (cut, edited, random, written by other code), or anything else in its place, is
    deleted, reported on stderr, and None returned, so the caller rebuilds it.
    """
    data = read_entry(path)
    if data is None:
        return None
    header, _, body = data.partition(b"\n")
    if header != MAGIC + _digest(version, body):
        discard(path, "checksum mismatch")
        return None
    return body


class NotAFile(OSError):
    """Raised by ``read_file`` for a folder, a pipe, a device or a socket."""


def read_file(path: Path) -> bytes:
    """The bytes of the regular file ``path`` (through links).

    Opened without blocking, so a named pipe or a device in its place is never waited on
    or read from.

    Raises
    ------
    FileNotFoundError
        If there is nothing at ``path``.
    NotAFile
        If something other than a regular file is.
    OSError
        If it cannot be read.
    """
    handle = os.open(path, os.O_RDONLY | os.O_NONBLOCK | os.O_CLOEXEC)
    with os.fdopen(handle, "rb") as file:
        mode = os.fstat(handle).st_mode
        if not stat.S_ISREG(mode):
            raise NotAFile(f"{kind(mode)} in place of a file")
        return file.read()


def read_entry(path: Path) -> bytes | None:
    """The bytes of the cache entry ``path``, or None if there is none.

    Anything in its place that is not a readable regular file is discarded (removed and
    reported on stderr) and None returned, so the caller rebuilds the entry.
    """
    try:
        return read_file(path)
    except FileNotFoundError:
        return None
    except NotAFile as exc:
        discard(path, str(exc))
    except OSError as exc:
        discard(path, exc.strerror or type(exc).__name__)
    return None


def remove_entry(path: Path) -> None:
    """Remove whatever is at ``path``: a file, a link (not what it points to), a pipe, or
    a folder with its contents. Failures are ignored: the entry is then found damaged
    again, and rejected again, next time."""
    try:
        if stat.S_ISDIR(os.lstat(path).st_mode):
            shutil.rmtree(path)
        else:
            path.unlink()
    except OSError:
        pass


def discard(path: Path, reason: str) -> None:
    """Delete the damaged cache entry ``path`` and say so in one line on stderr."""
    remove_entry(path)
    report(f"cache entry {path} was damaged ({reason}); rebuilding it")


# -- numba's on-disk cache ------------------------------------------------------------------


SUMS_HEADER = b"phase-explorer-nbsum 2\n"
"""First line of a ``.nbsum`` file: one line ``<sha256 hex> <file name>`` follows per file
of the function (the index and each data file). A file without it is of the first
format, one sha256 over all the files together (``HealingCache._legacy_checksum``)."""


class _Damaged(Exception):
    """Raised through numba's loader by ``HealingCache._load_data``: the data file does not
    match its checksum (``reason``; "" when it has none). Not an ``OSError``, which numba's
    loader takes for a file removed meanwhile and swallows."""

    def __init__(self, reason: str):
        super().__init__(reason)
        self.reason = reason


class HealingCache:
    """numba's cache of one function, with checksums and a rebuild for damaged entries.

    Wraps the dispatcher's ``FunctionCache`` (every other attribute is the wrapped
    cache's). ``save_overload`` records a sha256 of each of the function's files (the
    index and one data file per overload) in a ``.nbsum`` file beside the index;
    ``load_overload`` first checks the index, and the one data file numba then reads
    (through ``_load_data``, which takes the place of numba's reader of that cache), and
    deletes an entry that does not match, or that then fails to load, so numba compiles
    the function again. A loop with three overloads of 0.8 MB each hashed all three at
    every load.
    """

    def __init__(self, cache, index: str):
        self._inner = cache
        self._index = Path(index)
        self._sums = Path(index[: -len(".nbi")] + ".nbsum")
        cache_file = getattr(cache, "_cache_file", None)
        # numba reads a data file by name through this method of its cache file: an
        # unknown numba without it has every file checked before each load instead
        self._per_file = callable(getattr(cache_file, "_load_data", None)) and callable(
            getattr(cache_file, "_data_path", None)
        )
        if self._per_file:
            cache_file._load_data = self._load_data

    def __getattr__(self, name: str):
        return getattr(self._inner, name)

    def load_overload(self, sig, target_context):
        """numba's compile result for ``sig`` from disk, or None to have it compiled."""
        problem = self.verify(index_only=self._per_file)
        if problem is None:
            try:
                return self._inner.load_overload(sig, target_context)
            except _Damaged as exc:
                problem = exc.reason
            except Exception as exc:  # noqa: BLE001 - any failure to load means damage
                problem = f"failed to load: {type(exc).__name__}"
        self.discard(problem)
        return None

    def save_overload(self, sig, data) -> None:
        """Save as numba does, then record the checksums of the function's files."""
        try:
            self._inner.save_overload(sig, data)
            write_atomic(self._sums, self._checksum())
        except OSError:
            self.discard("")  # a full disk or read-only folder: only a later miss

    def verify(self, index_only: bool = False) -> str | None:
        """None if the entry is absent or its files match their checksums (only the
        index's with ``index_only``), else why not ("" when it has no checksums: written
        by an older version, or interrupted)."""
        if not os.path.lexists(self._index):
            return None
        recorded = self._recorded()
        if isinstance(recorded, str):
            return recorded
        paths = [self._index] if index_only else [self._index, *self._data_files()]
        for path in paths:
            problem = _mismatch(recorded, path)
            if problem is not None:
                return problem
        return None

    def discard(self, reason: str) -> None:
        """Delete the function's index, data and checksum files; report a non-empty reason."""
        for path in [self._index, self._sums, *self._data_files()]:
            remove_entry(path)
        if reason:
            report(f"cache entry {self._index} was damaged ({reason}); rebuilding it")

    def _load_data(self, name: str):
        """numba's ``IndexDataCacheFile._load_data``: the data file ``name`` unpickled, once
        it matches its checksum.

        Raises
        ------
        _Damaged
            If it does not (or has none, or something else is in its place).
        FileNotFoundError
            If there is no such file and none was recorded (numba then compiles).
        """
        path = Path(self._inner._cache_file._data_path(name))
        recorded = self._recorded()
        if isinstance(recorded, str):
            raise _Damaged(recorded)
        try:
            data = read_file(path)
        except FileNotFoundError:
            if path.name in recorded:
                raise _Damaged("checksum mismatch") from None
            raise
        except OSError as exc:
            raise _Damaged(str(exc) if isinstance(exc, NotAFile) else "unreadable") from None
        problem = _mismatch(recorded, path, data)
        if problem is not None:
            raise _Damaged(problem)
        return pickle.loads(data)  # noqa: S301 - our own cache, checked just now

    def _recorded(self) -> dict[str, bytes] | str:
        """The recorded checksums by file name, or why there are none ("" for no file).

        A file of the first format that matches the files on disk is rewritten in this
        one (once per entry: nothing is compiled again)."""
        try:
            data = read_file(self._sums)
        except FileNotFoundError:
            return ""
        except NotAFile as exc:
            return str(exc)
        except OSError as exc:
            return exc.strerror or type(exc).__name__
        if not data.startswith(SUMS_HEADER):
            if data != self._legacy_checksum():
                return "checksum mismatch"
            data = self._checksum()
            with contextlib.suppress(OSError):
                write_atomic(self._sums, data)
        recorded = {}
        stem = re.escape(self._index.name[: -len(".nbi")].encode())
        for line in data[len(SUMS_HEADER) :].splitlines():
            found = re.fullmatch(rb"([0-9a-f]{64}) (" + stem + rb"(\.[0-9]+\.nbc|\.nbi))", line)
            if found is None:  # a line cut or changed: not one this class writes
                return "checksum mismatch"
            recorded[found[2].decode()] = found[1]
        return recorded

    def _data_files(self) -> list[Path]:
        stem = self._index.name[: -len(".nbi")]
        return sorted(self._index.parent.glob(f"{glob.escape(stem)}.*.nbc"))

    def _checksum(self) -> bytes:
        """The ``.nbsum`` file of the index and data files on disk."""
        lines = [SUMS_HEADER]
        for path in [self._index, *self._data_files()]:
            try:
                lines.append(_file_digest(read_file(path)) + b" " + path.name.encode() + b"\n")
            except OSError:
                pass  # not recorded: found damaged when numba reads it
        return b"".join(lines)

    def _legacy_checksum(self) -> bytes:
        """The first format: one sha256 over the names and contents of all the files."""
        digest = hashlib.sha256()
        for path in [self._index, *self._data_files()]:
            digest.update(f"{path.name}\n".encode())
            try:
                digest.update(hashlib.sha256(read_file(path)).digest())
            except OSError:
                digest.update(b"missing")
        return digest.hexdigest().encode() + b"\n"


def _file_digest(data: bytes) -> bytes:
    return hashlib.sha256(data).hexdigest().encode()


def _mismatch(recorded: dict[str, bytes], path: Path, data: bytes | None = None) -> str | None:
    """None if ``path`` (its bytes ``data`` if read already) matches its recorded checksum;
    "" if it has none; else why not."""
    if path.name not in recorded:
        return "" if os.path.lexists(path) else None
    if data is None:
        try:
            data = read_file(path)
        except NotAFile as exc:
            return str(exc)
        except OSError:
            return "checksum mismatch"
    return None if _file_digest(data) == recorded[path.name] else "checksum mismatch"


def guard_numba_caches(module: ModuleType) -> list[HealingCache]:
    """Put a ``HealingCache`` around the cache of every cached numba function of ``module``.

    Returns the guards (an unknown numba whose caches lack the expected index file is
    left unguarded: it then only loses the healing).
    """
    guards = []
    for value in vars(module).values():
        cache = getattr(value, "_cache", None)
        index = getattr(getattr(cache, "_cache_file", None), "_index_path", None)
        if isinstance(cache, HealingCache):
            guards.append(cache)
        elif isinstance(index, str) and index.endswith(".nbi"):
            value._cache = HealingCache(cache, index)
            guards.append(value._cache)
    return guards


def verify_numba_caches(module: ModuleType) -> bool:
    """Check every guarded numba cache entry of ``module``, discarding damaged ones.

    Returns True if none was damaged (absent entries are fine).
    """
    sound = True
    for guard in guard_numba_caches(module):
        problem = guard.verify()
        if problem is not None:
            guard.discard(problem)
            sound = False
    return sound


# -- the cache directory --------------------------------------------------------------------


def cache_root() -> Path:
    """The cache's top directory: ``PHASE_EXPLORER_CACHE``, else
    ``~/.cache/phase-explorer``, or a temporary stand-in if that is not usable."""
    root = os.environ.get("PHASE_EXPLORER_CACHE")
    return usable_directory(Path(root) if root else Path.home() / ".cache" / "phase-explorer")


def usable_directory(path: Path) -> Path:
    """``path``, created if need be, or, if it cannot be written, a temporary directory.

    The replacement lasts for the session (it is removed at exit) and is announced once
    with a warning line on stderr.
    """
    if path in _fallbacks:
        return _fallbacks[path]
    try:
        path.mkdir(parents=True, exist_ok=True)
    except FileExistsError:
        return fall_back(path, "a file is in its place")
    except OSError as exc:
        return fall_back(path, exc.strerror or type(exc).__name__)
    if not os.access(path, os.W_OK | os.X_OK):
        return fall_back(path, "read-only")
    return path


def fall_back(path: Path, reason: str) -> Path:
    """Use a temporary directory instead of ``path`` from now on; warn once."""
    with _fallback_lock:
        if path not in _fallbacks:
            if not _temporary:
                _temporary.append(Path(tempfile.mkdtemp(prefix="phase-explorer-cache-")))
                atexit.register(shutil.rmtree, _temporary[0], ignore_errors=True)
            fallback = _temporary[0] / path.name
            fallback.mkdir(exist_ok=True)
            _fallbacks[path] = fallback
            report(f"warning: cache directory {path} is not usable ({reason}); using {fallback}")
        return _fallbacks[path]
