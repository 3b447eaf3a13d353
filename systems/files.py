"""Files written as users expect, and output paths checked before any work.

Every file the program writes (``run --out``, exports, ``bench`` outputs, scenes,
sessions, preferences) goes through ``atomic_path``:

- a regular file, or a new one, is written to a temporary file in the same folder and
  renamed onto its name only when complete (``os.replace`` is atomic on one file system),
  so an interruption, a full disk or a crash leaves the old file or none, never half of
  one. An existing file keeps its permissions (and, where the user may, its owner and
  group); a new one gets those the umask allows, as any other program's would;
- a symbolic link is written through: the file it points to is replaced (or created,
  for a dangling link) and the link stays;
- a character device or a named pipe (``/dev/null``, a FIFO a reader waits on) is
  written to: the complete file is copied into it at the end, so a device that fails
  (``/dev/full``) raises an ``OSError`` naming the reason, as does a named pipe that no
  program reads from within ``PIPE_WAIT`` seconds (opening it would wait for ever);
- a folder, a block device or a socket is refused with an ``OSError``.

Files given to be read (scenes, session scripts) go through ``read_file``: anything but a
regular file (a named pipe, ``/dev/zero``, a folder) and a file beyond a size limit are
refused at once, before a byte is read. ``write_rows`` writes a table as CSV lines fast.

Temporary files are hidden, named ``.NAME.RANDOM.phase-explorer-partial.SUFFIX`` beside
the target (in the temporary folder for a device or pipe, whose own folder is not ours),
created exclusively and removed on every way out of the block. No file the program did
not create is ever deleted.
"""

from __future__ import annotations

import errno
import os
import secrets
import shutil
import stat
import tempfile
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import IO

import numpy as np

PARTIAL = "phase-explorer-partial"
"""The mark in every temporary file's name."""

_KINDS = {
    stat.S_IFDIR: "a folder",
    stat.S_IFCHR: "a character device",
    stat.S_IFBLK: "a block device",
    stat.S_IFIFO: "a named pipe",
    stat.S_IFSOCK: "a socket",
    stat.S_IFLNK: "a symbolic link",
}


def kind(mode: int) -> str:
    """What a file of ``st_mode`` ``mode`` is, in words ("a folder", "a named pipe")."""
    return _KINDS.get(stat.S_IFMT(mode), "a file")


def destination(path: str | Path) -> Path:
    """Where writing ``path`` puts a regular file: the end of its chain of symbolic links
    (absolute), or ``path`` itself made absolute."""
    return Path(os.path.realpath(path))


def _streamed(mode: int) -> bool:
    """True for what is written into rather than replaced: devices and pipes."""
    return stat.S_ISCHR(mode) or stat.S_ISFIFO(mode)


def _status(path: Path) -> os.stat_result | None:
    """``os.stat`` of ``path`` (through links), or None if nothing is there.

    Raises
    ------
    OSError
        For a loop of links or a path that cannot be looked at.
    """
    try:
        return os.stat(path)
    except FileNotFoundError:
        return None


def _create_temporary(folder: Path, name: str) -> Path:
    """A new, empty file in ``folder`` named after ``name`` and no user's file.

    Created exclusively (an existing file of that name is never opened or removed) with
    mode 0o666 less the umask, as ``open`` would create ``name``.
    """
    suffix = Path(name).suffix[:16]
    stem = name[:64]
    for _ in range(100):
        temporary = folder / f".{stem}.{secrets.token_hex(4)}.{PARTIAL}{suffix}"
        try:
            handle = os.open(temporary, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_CLOEXEC, 0o666)
        except FileExistsError:
            continue
        os.close(handle)
        return temporary
    raise FileExistsError(f"no free temporary name in {folder}")


@contextmanager
def atomic_path(path: str | Path) -> Iterator[Path]:
    """A temporary path (same suffix) for the caller to write ``path`` through.

    When the block ends without an exception, what the caller wrote becomes ``path``
    (see the module's description for links, devices and pipes); on any exception,
    including ``KeyboardInterrupt``, ``path`` is left as it was. The temporary file is
    removed in every case.

    Raises
    ------
    OSError
        If ``path`` is a folder, a block device or a socket, or cannot be written.
    """
    path = Path(path)
    status = _status(path)
    if status is not None and _streamed(status.st_mode):
        yield from _written_into(path)
        return
    if status is not None and not stat.S_ISREG(status.st_mode):
        raise OSError(f"{path} is {kind(status.st_mode)}, not a file")
    target = destination(path)
    temporary = _create_temporary(target.parent, target.name)
    try:
        yield temporary
        handle = os.open(temporary, os.O_RDONLY | os.O_CLOEXEC)
        try:
            os.fsync(handle)
        finally:
            os.close(handle)
        if status is not None:
            _keep_owner_and_mode(temporary, status)
        os.replace(temporary, target)
    except BaseException:
        temporary.unlink(missing_ok=True)
        raise


def _written_into(path: Path) -> Iterator[Path]:
    """``atomic_path`` for a device or pipe: copied into it once complete."""
    temporary = _create_temporary(Path(tempfile.gettempdir()), path.name)
    try:
        yield temporary
        with temporary.open("rb") as source, open(_open_sink(path), "wb") as sink:
            shutil.copyfileobj(source, sink)
    finally:
        temporary.unlink(missing_ok=True)


PIPE_WAIT = 10.0
"""Seconds ``atomic_path`` waits for a program to read from a named pipe written to."""


def _open_sink(path: Path) -> int:
    """A descriptor of the device or pipe ``path`` opened for writing.

    Opening a named pipe nobody reads from would wait for a reader for ever: a reader
    is waited for ``PIPE_WAIT`` seconds, then the pipe is refused (``OSError``, ENXIO).
    Once open, the writes wait for the reader as usual.
    """
    waited = 0.0
    while True:
        try:
            handle = os.open(path, os.O_WRONLY | os.O_NONBLOCK | os.O_CLOEXEC)
            break
        except OSError as exc:
            if exc.errno != errno.ENXIO:
                raise
            if waited >= PIPE_WAIT:
                reason = f"no program read from this named pipe within {PIPE_WAIT:g} s"
                raise OSError(exc.errno, reason, str(path)) from None
        time.sleep(0.05)
        waited += 0.05
    os.set_blocking(handle, True)
    return handle


def _keep_owner_and_mode(temporary: Path, status: os.stat_result) -> None:
    """Give ``temporary`` the permissions of the file it replaces, and its owner and
    group where this process may (root may; a user may give a group they belong to)."""
    own = os.stat(temporary)
    if (own.st_uid, own.st_gid) != (status.st_uid, status.st_gid):
        try:
            os.chown(temporary, status.st_uid, status.st_gid)
        except OSError:
            try:
                os.chown(temporary, -1, status.st_gid)
            except OSError:
                pass  # the new owner's file, as any editor that renames would leave it
    os.chmod(temporary, stat.S_IMODE(status.st_mode))  # after chown, which clears set-id bits


def write_problem(path: str | Path) -> str | None:
    """Why ``path`` cannot be written (a missing or unwritable folder, a folder or another
    non-file in its place), or None. For checking an output before a long computation.

    Only a temporary file of the program's own (``atomic_path``'s name) is created and
    removed to find out; nothing else is touched.
    """
    path = Path(path)
    try:
        status = _status(path)
    except OSError as exc:
        return f"cannot write {path}: {exc.strerror or exc}"
    if status is not None and stat.S_ISDIR(status.st_mode):
        return f"{path} is a folder; give a file name"
    if status is not None and _streamed(status.st_mode):
        return None if os.access(path, os.W_OK) else f"{path} is not writable"
    if status is not None and not stat.S_ISREG(status.st_mode):
        return f"{path} is {kind(status.st_mode)}; give a file name"
    target = destination(path)
    folder = target.parent
    if not folder.is_dir():
        return f"the folder {folder} does not exist"
    if not os.access(folder, os.W_OK | os.X_OK):
        return f"the folder {folder} is not writable"
    if status is not None and not os.access(target, os.W_OK):
        return f"{path} exists and is not writable"
    try:
        _create_temporary(folder, target.name).unlink()
    except OSError as exc:
        return f"cannot write in {folder}: {exc.strerror or exc}"
    return None


class FileTooLarge(OSError):
    """A file refused by ``read_file`` for its size; ``size`` is how large it is."""

    def __init__(self, path: str | Path, size: int, limit: int):
        super().__init__(
            errno.EFBIG, f"the file is {size:,} bytes, more than the {limit:,} allowed", str(path)
        )
        self.size = size
        self.limit = limit


def read_file(path: str | Path, limit: int) -> bytes:
    """The bytes of the regular file ``path``, refused at once if it is anything else.

    A named pipe would make a plain read wait for a writer for ever, and ``/dev/zero``
    or ``/dev/urandom`` would be read until memory runs out: the file is opened without
    waiting (``O_NONBLOCK``), its kind and size are checked on the open file, and at most
    ``limit`` bytes are read.

    Raises
    ------
    FileTooLarge
        When the file holds more than ``limit`` bytes.
    OSError
        When it cannot be opened (missing, not permitted, a loop of links) or is not a
        regular file (a folder, a named pipe, a device, a socket); ``strerror`` says why
        in words.
    """
    try:
        handle = os.open(path, os.O_RDONLY | os.O_NONBLOCK | os.O_CLOEXEC)
    except OSError as exc:
        if exc.errno == errno.ENXIO:  # what opening a socket says
            raise OSError(exc.errno, "it is a socket, not a file", str(path)) from None
        raise
    try:
        status = os.fstat(handle)
        if not stat.S_ISREG(status.st_mode):
            raise OSError(errno.EINVAL, f"it is {kind(status.st_mode)}, not a file", str(path))
        if status.st_size > limit:
            raise FileTooLarge(path, status.st_size, limit)
        chunks, size = [], 0
        while size <= limit:
            chunk = os.read(handle, min(limit + 1 - size, 1 << 20))
            if not chunk:
                break
            chunks.append(chunk)
            size += len(chunk)
        if size > limit:  # it grew while read, or /proc said 0 bytes
            raise FileTooLarge(path, size, limit)
        return b"".join(chunks)
    finally:
        os.close(handle)


CSV_BLOCK = 4096
"""Rows ``write_rows`` formats at a time."""


def write_rows(handle: IO[str], table: np.ndarray, first: str = "") -> None:
    """Write the rows of ``table`` (k, m) to the text ``handle`` as CSV lines.

    Each number is written as ``repr`` writes it (the shortest text that reads back to
    the same float: ``0.1``, ``nan``, ``inf``), with ``\\r\\n`` line ends, as
    ``csv.writer`` writes ``[repr(v) for v in row]``, a block of rows at a time (a
    300 000-row trajectory in about a second). ``first`` (with its comma) is put before
    every row.
    """
    for start in range(0, len(table), CSV_BLOCK):
        rows = np.asarray(table[start : start + CSV_BLOCK], dtype=float).tolist()
        handle.write("".join(first + ",".join(map(repr, row)) + "\r\n" for row in rows))
