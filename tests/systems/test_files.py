"""Files are written whole or not at all; outputs are checked before any work."""

import errno
import os
import socket
import stat
import tempfile
import threading
from pathlib import Path

import pytest

from systems.files import PARTIAL, atomic_path, write_problem


def test_a_failed_write_leaves_the_old_file_and_no_litter(tmp_path):
    target = tmp_path / "out.csv"
    target.write_text("old content\n")
    with pytest.raises(RuntimeError), atomic_path(target) as temporary:
        temporary.write_text("half of the new")
        raise RuntimeError("interrupted")
    assert target.read_text() == "old content\n"
    assert os.listdir(tmp_path) == ["out.csv"]


def test_a_finished_write_replaces_the_file(tmp_path):
    target = tmp_path / "out.csv"
    target.write_text("old")
    with atomic_path(target) as temporary:
        assert temporary.parent == tmp_path and temporary.suffix == ".csv"
        temporary.write_text("new")
    assert target.read_text() == "new"
    assert os.listdir(tmp_path) == ["out.csv"]


def test_write_problems_are_named(tmp_path):
    assert write_problem(tmp_path / "fine.csv") is None
    assert "does not exist" in write_problem(tmp_path / "missing" / "x.csv")
    assert "is a folder" in write_problem(tmp_path)
    readonly = tmp_path / "ro"
    readonly.mkdir()
    readonly.chmod(0o500)
    try:
        if os.access(readonly, os.W_OK):
            pytest.skip("running as a user who may write anywhere (root)")
        assert "not writable" in write_problem(readonly / "x.csv")
    finally:
        readonly.chmod(0o700)
    assert os.listdir(tmp_path) == ["ro"]  # the probe left nothing


# -- files written as users expect (issue 24, item 4) ---------------------------------------


def litter(folder) -> list[str]:
    """Temporary files left in ``folder``."""
    return sorted(name for name in os.listdir(folder) if PARTIAL in name)


def write(path, text: str) -> None:
    with atomic_path(path) as temporary:
        temporary.write_text(text)


def test_a_temporary_file_is_hidden_beside_its_target_under_a_name_of_its_own(tmp_path):
    with atomic_path(tmp_path / "out.csv") as temporary:
        assert temporary.parent == tmp_path and temporary.suffix == ".csv"
        assert temporary.name.startswith(".out.csv.") and PARTIAL in temporary.name
    long = "x" * 250 + ".csv"  # the longest name a folder takes, nearly: no room to add
    write(tmp_path / long, "fits")
    assert (tmp_path / long).read_text() == "fits" and litter(tmp_path) == []


@pytest.mark.parametrize("stop", [RuntimeError, KeyboardInterrupt, SystemExit])
def test_no_temporary_file_is_left_on_any_way_out(tmp_path, stop):
    write(tmp_path / "done.csv", "done")
    with pytest.raises(stop), atomic_path(tmp_path / "stopped.csv") as temporary:
        temporary.write_text("half")
        raise stop()
    assert sorted(os.listdir(tmp_path)) == ["done.csv"]


def test_a_symbolic_link_is_written_through_to_its_target(tmp_path):
    (tmp_path / "data").mkdir()
    target = tmp_path / "data" / "run.csv"
    target.write_text("old")
    link = tmp_path / "latest.csv"
    link.symlink_to(Path("data") / "run.csv")  # relative, as `ln -s` users write them
    write(link, "new")
    assert link.is_symlink() and os.readlink(link) == str(Path("data") / "run.csv")
    assert target.read_text() == "new"
    assert litter(tmp_path) == [] and litter(tmp_path / "data") == []
    chain = tmp_path / "chain.csv"
    chain.symlink_to(link)
    write(chain, "newer")
    assert chain.is_symlink() and link.is_symlink() and target.read_text() == "newer"


def test_a_dangling_link_creates_its_target(tmp_path):
    link = tmp_path / "out.csv"
    link.symlink_to(tmp_path / "made.csv")
    assert write_problem(link) is None
    write(link, "made")
    assert link.is_symlink() and (tmp_path / "made.csv").read_text() == "made"


def test_problems_behind_links_are_named(tmp_path):
    into_nowhere = tmp_path / "out.csv"
    into_nowhere.symlink_to(tmp_path / "missing" / "x.csv")
    assert f"the folder {tmp_path / 'missing'} does not exist" in write_problem(into_nowhere)
    loop = tmp_path / "loop.csv"
    loop.symlink_to(loop)
    assert "symbolic links" in write_problem(loop)
    with pytest.raises(OSError):
        write(loop, "never")
    assert loop.is_symlink() and litter(tmp_path) == []


def test_an_existing_file_keeps_its_mode_and_a_new_one_gets_the_umask(tmp_path):
    existing = tmp_path / "shared.csv"
    existing.write_text("old")
    existing.chmod(0o664)
    write(existing, "new")
    assert stat.S_IMODE(existing.stat().st_mode) == 0o664
    previous = os.umask(0o027)
    try:
        write(tmp_path / "new.csv", "new")
    finally:
        os.umask(previous)
    assert stat.S_IMODE((tmp_path / "new.csv").stat().st_mode) == 0o640
    previous = os.umask(0o002)
    try:
        write(tmp_path / "open.csv", "new")
    finally:
        os.umask(previous)
    assert stat.S_IMODE((tmp_path / "open.csv").stat().st_mode) == 0o664


def test_the_writability_check_deletes_nothing_of_the_users(tmp_path):
    mine = {"OUT.csv.probe": "mine", "OUT.csv.part": "mine too", ".OUT.csv.tmp": "and this"}
    for name, text in mine.items():
        (tmp_path / name).write_text(text)
    assert write_problem(tmp_path / "OUT.csv") is None
    write(tmp_path / "OUT.csv", "rows")
    assert {p.name: p.read_text() for p in tmp_path.iterdir()} == {**mine, "OUT.csv": "rows"}


@pytest.fixture
def temporary_folder(tmp_path, monkeypatch):
    """The system's temporary folder, redirected to see what is left in it."""
    folder = tmp_path / "tmp"
    folder.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(folder))
    return folder


@pytest.mark.skipif(not Path("/dev/full").exists(), reason="no /dev/full")
def test_a_full_device_fails_with_its_reason_and_stays_a_device(tmp_path, temporary_folder):
    link = tmp_path / "out.csv"
    link.symlink_to("/dev/full")
    assert write_problem(link) is None  # writable; the full disk shows when written
    with pytest.raises(OSError) as failure:
        write(link, "rows\n" * 10_000)
    assert failure.value.errno == errno.ENOSPC
    assert link.is_symlink() and Path("/dev/full").is_char_device()
    assert os.listdir(temporary_folder) == [] and litter(tmp_path) == []


@pytest.mark.skipif(not Path("/dev/null").exists(), reason="no /dev/null")
def test_a_device_is_written_into_never_replaced(tmp_path, temporary_folder):
    link = tmp_path / "discard.csv"
    link.symlink_to("/dev/null")
    write(link, "rows")
    assert link.is_symlink() and Path("/dev/null").is_char_device()
    assert os.listdir(temporary_folder) == []


def test_a_named_pipe_is_written_into(tmp_path, temporary_folder):
    pipe = tmp_path / "out.csv"
    os.mkfifo(pipe)
    received = []
    reader = threading.Thread(target=lambda: received.append(pipe.read_text()), daemon=True)
    reader.start()
    write(pipe, "rows\n")
    reader.join(timeout=60)
    assert received == ["rows\n"]
    assert stat.S_ISFIFO(os.lstat(pipe).st_mode) and os.listdir(temporary_folder) == []


def test_a_folder_or_socket_in_place_of_the_file_is_refused(tmp_path, monkeypatch):
    folder = tmp_path / "out.csv"
    folder.mkdir()
    assert "is a folder" in write_problem(folder)
    with pytest.raises(OSError, match="is a folder"):
        write(folder, "never")
    server = socket.socket(socket.AF_UNIX)
    monkeypatch.chdir(tmp_path)  # a socket's path is short: bound relative to its folder
    server.bind("out.sock")
    try:
        assert "is a socket" in write_problem(tmp_path / "out.sock")
        with pytest.raises(OSError, match="is a socket"):
            write(tmp_path / "out.sock", "never")
    finally:
        server.close()
    assert litter(tmp_path) == [] and folder.is_dir()


@pytest.mark.skipif(os.geteuid() != 0, reason="only root may give a file to another user")
def test_a_file_written_by_root_keeps_its_owner_and_group(tmp_path):
    existing = tmp_path / "theirs.csv"
    existing.write_text("old")
    os.chown(existing, 12345, 12346)
    existing.chmod(0o2640)  # set-group-id too, which a change of owner clears
    write(existing, "new")
    status = existing.stat()
    assert (status.st_uid, status.st_gid) == (12345, 12346)
    assert stat.S_IMODE(status.st_mode) == 0o2640
