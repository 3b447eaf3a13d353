"""Files are written whole or not at all; outputs are checked before any work."""

import os

import pytest

from systems.files import atomic_path, write_problem


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
