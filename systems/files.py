"""Files written whole or not at all, and output paths checked before any work.

Every file the program writes goes to a temporary file in the same folder first and is
renamed onto its name only when complete (``os.replace`` is atomic on one file system),
so an interruption, a full disk or a crash leaves the old file or none, never half of one.
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path


@contextmanager
def atomic_path(path: str | Path) -> Iterator[Path]:
    """A temporary path beside ``path`` (same suffix) for the caller to write; renamed onto
    ``path`` when the block ends without an exception, deleted otherwise."""
    path = Path(path)
    handle, temporary = tempfile.mkstemp(
        dir=path.parent, prefix=f".{path.name}.", suffix=f".part{path.suffix}"
    )
    os.close(handle)
    temporary = Path(temporary)
    try:
        yield temporary
        with temporary.open("rb+") as written:
            os.fsync(written.fileno())
        os.replace(temporary, path)
    except BaseException:
        temporary.unlink(missing_ok=True)
        raise


def write_problem(path: str | Path) -> str | None:
    """Why ``path`` cannot be written (a missing or unwritable folder, a folder in its
    place), or None. For checking an output before a long computation."""
    path = Path(path)
    folder = path.parent if str(path.parent) else Path(".")
    if path.is_dir():
        return f"{path} is a folder; give a file name"
    if not folder.is_dir():
        return f"the folder {folder} does not exist"
    if not os.access(folder, os.W_OK | os.X_OK):
        return f"the folder {folder} is not writable"
    if path.exists() and not os.access(path, os.W_OK):
        return f"{path} exists and is not writable"
    try:
        with atomic_path(path.with_name(path.name + ".probe")) as probe:
            probe.write_bytes(b"")
        path.with_name(path.name + ".probe").unlink()
    except OSError as exc:
        return f"cannot write in {folder}: {exc.strerror or exc}"
    return None
