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
  (``/dev/full``) raises an ``OSError`` naming the reason;
- a folder, a block device or a socket is refused with an ``OSError``.

Temporary files are hidden, named ``.NAME.RANDOM.phase-explorer-partial.SUFFIX`` beside
the target (in the temporary folder for a device or pipe, whose own folder is not ours),
created exclusively and removed on every way out of the block. No file the program did
not create is ever deleted.
"""

from __future__ import annotations

import os
import secrets
import shutil
import stat
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

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
        with temporary.open("rb") as source, path.open("wb") as sink:
            shutil.copyfileobj(source, sink)
    finally:
        temporary.unlink(missing_ok=True)


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
