"""A damaged cache entry is deleted, rebuilt and reported in one line on stderr; an
unusable cache directory is replaced by a temporary one (issue 11, deliverable 6).

Every case ends in the right answer, the harmonic oscillator's x(5) = cos 5, from the
same ``run`` command users type, and (where a cache remains) in a rebuilt cache that the
next run uses without complaint. Each test starts from a copy of one cache filled once,
which holds the stepping loops the session compiled (``warmup.copy_drivers``), as an
installation's cache does after ``python main.py warm``: a test pays for rebuilding what it
damaged, not for compiling every loop again. numba's damaged entries are mostly those of
``batch_scalar``, a small loop of the drivers' module that every run loads (H over the
rows), guarded like every other; ``compose_run``, the run's stepping loop (about three
times its compile time), is damaged once, by a truncated index.
"""

import json
import math
import os
import pickle
import random
import shutil
import stat
import tempfile
from pathlib import Path

import pytest

from explorer.cli import main
from systems import cache_integrity, codegen, derivation_cache
from systems.cache_integrity import HealingCache, read_checked, write_checked
from systems.integrators.warmup import copy_drivers

RUN = ["run", "harmonic_oscillator", "--t-end", "5", "--method", "yoshida8"]  # default step
SESSION_CACHE = Path(os.environ["PHASE_EXPLORER_CACHE"])  # tests/conftest.py's, warmed
SMALL = "batch_scalar"  # a drivers' loop every run loads, quick to compile again


def _isolate(monkeypatch, root: Path) -> None:
    monkeypatch.setenv("PHASE_EXPLORER_CACHE", str(root))
    # numba's scene modules and their cache files are what these tests damage; the LLVM
    # functions are compiled anew at each opening and leave nothing on disk
    monkeypatch.setenv("PHASE_EXPLORER_KERNELS", "numba")
    monkeypatch.setattr(codegen, "_loaded", {})
    monkeypatch.setattr(cache_integrity, "_fallbacks", {})
    monkeypatch.setattr(cache_integrity, "_temporary", [])


@pytest.fixture(scope="module")
def pristine(tmp_path_factory) -> Path:
    """A cache filled by one run (derivation, remembered facts, kernels, numba's files)."""
    root = tmp_path_factory.mktemp("pristine") / "cache"
    copy_drivers(SESSION_CACHE, root)  # (False: the run below compiles them)
    with pytest.MonkeyPatch.context() as monkeypatch:
        _isolate(monkeypatch, root)
        assert main([*RUN, "--json"]) == 0
    return root


@pytest.fixture
def cache(pristine, tmp_path, monkeypatch) -> Path:
    root = tmp_path / "cache"
    shutil.copytree(pristine, root)  # copy2 keeps mtimes, part of numba's source stamp
    _isolate(monkeypatch, root)
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path / "tmp"))
    (tmp_path / "tmp").mkdir()
    return root


def run_once(capsys) -> list[str]:
    """Run as a new process would (kernels loaded from disk); check the answer; return
    the ``phase-explorer:`` lines printed on stderr."""
    codegen._loaded.clear()
    code = main([*RUN, "--json"])
    out, err = capsys.readouterr()
    assert code == 0, err
    report = json.loads(out)
    assert report["status"] == "ok"
    assert report["final"]["q"]["x"] == pytest.approx(math.cos(5.0), abs=1e-8)
    return [line for line in err.splitlines() if line.startswith("phase-explorer:")]


def assert_healed(capsys, named: str) -> None:
    """One line naming the damaged entry, then a run that finds the cache sound."""
    lines = run_once(capsys)
    assert len(lines) == 1 and named in lines[0] and "rebuil" in lines[0], lines
    assert run_once(capsys) == []


# -- kinds of damage --------------------------------------------------------------------


def truncate(path: Path) -> None:
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])


def randomise(path: Path) -> None:
    path.write_bytes(random.Random(11).randbytes(max(path.stat().st_size, 64)))


def empty(path: Path) -> None:
    path.write_bytes(b"")


def flip_a_byte(path: Path) -> None:
    data = bytearray(path.read_bytes())
    data[len(data) // 2] ^= 0xFF
    path.write_bytes(bytes(data))


def drop_last_line(path: Path) -> None:
    lines = path.read_bytes().rstrip(b"\n").split(b"\n")
    path.write_bytes(b"\n".join(lines[:-1]) + b"\n")


def numba_file(cache: Path, function: str, suffix: str) -> Path:
    [path] = (cache / "kernels" / "__pycache__").glob(f"*.{function}-*.py*{suffix}")
    return path


def stored_text(cache: Path, containing: bytes) -> Path:
    [path] = [p for p in (cache / "derivations").glob("*.txt") if containing in p.read_bytes()]
    return path


# -- numba's files ----------------------------------------------------------------------


@pytest.mark.parametrize(
    ("function", "suffix", "damage"),
    [
        ("compose_run", ".nbi", truncate),
        (SMALL, ".nbc", randomise),  # every overload's: only the one loaded is checked
        ("rhs", ".nbc", flip_a_byte),
        ("hamiltonian", ".nbi", empty),
        (SMALL, ".nbsum", flip_a_byte),
    ],
)
def test_damaged_numba_files_are_rebuilt(cache, capsys, function, suffix, damage):
    if suffix == ".nbc":
        for path in overloads(cache, function):
            damage(path)
    else:
        damage(numba_file(cache, function, suffix))
    assert_healed(capsys, f".{function}-")


def data_files_read(monkeypatch, capsys) -> list[Path]:
    """The numba data files (``.nbc``) a run reads through the guards, once per read."""
    read = []
    original = cache_integrity.read_file

    def recording(path):
        read.append(Path(path))
        return original(path)

    with monkeypatch.context() as patched:
        patched.setattr(cache_integrity, "read_file", recording)
        assert run_once(capsys) == []
    return [path for path in read if path.suffix == ".nbc"]


def overloads(cache: Path, function: str) -> list[Path]:
    return sorted((cache / "kernels" / "__pycache__").glob(f"*.{function}-*.nbc"))


def test_loading_an_overload_checks_only_its_own_data_file(cache, capsys, monkeypatch):
    # compose_run has three overloads (with and without sampled times and sections) of
    # 0.2-0.9 MB each: the run loads two, and each load hashed all three
    read = [p for p in data_files_read(monkeypatch, capsys) if p in overloads(cache, "compose_run")]
    assert 0 < len(read) < len(overloads(cache, "compose_run")) == 3
    assert len(set(read)) == len(read)


def test_a_damaged_overload_is_found_when_it_is_loaded_and_only_then(cache, capsys, monkeypatch):
    read = data_files_read(monkeypatch, capsys)
    [unread, *_] = [p for p in overloads(cache, "compose_run") if p not in read]
    randomise(unread)  # never read by this run: nothing to say, nothing rebuilt
    assert run_once(capsys) == []
    assert all(p.exists() for p in overloads(cache, "compose_run"))
    [loaded, *_] = [p for p in read if p in overloads(cache, SMALL)]
    flip_a_byte(loaded)
    assert_healed(capsys, f".{SMALL}-")


def _first_format(cache: Path, function: str) -> Path:
    """Write ``function``'s checksums in the first format (one sha256 over every file)."""
    index = numba_file(cache, function, ".nbi")
    guard = HealingCache(None, str(index))
    guard._sums.write_bytes(guard._legacy_checksum())
    return guard._sums


def test_checksums_of_the_first_format_are_rewritten_without_a_rebuild(cache, capsys):
    sums = _first_format(cache, SMALL)
    data = {p: p.stat().st_mtime_ns for p in sums.parent.glob(f"*.{SMALL}-*.nb[ci]")}
    assert run_once(capsys) == []
    assert sums.read_bytes().startswith(cache_integrity.SUMS_HEADER)
    assert {p: p.stat().st_mtime_ns for p in data} == data  # loaded, not compiled again
    assert run_once(capsys) == []


def test_a_damaged_entry_under_checksums_of_the_first_format_is_rebuilt(cache, capsys):
    _first_format(cache, SMALL)
    flip_a_byte(overloads(cache, SMALL)[-1])  # checked with the others as before
    assert_healed(capsys, f".{SMALL}-")


def test_a_numba_entry_that_verifies_but_fails_to_load_is_rebuilt(cache, capsys):
    index = numba_file(cache, SMALL, ".nbi")
    truncate(index)
    guard = HealingCache(None, str(index))
    guard._sums.write_bytes(guard._checksum())  # damaged before its checksum was taken
    lines = run_once(capsys)
    assert len(lines) == 1 and SMALL in lines[0] and "failed to load" in lines[0]
    assert run_once(capsys) == []


def test_numba_entries_without_checksums_are_rebuilt_silently(cache, capsys):
    # as written before checksums, or interrupted before its checksum: the scene's
    # functions and a loop of the drivers (not every loop: each one the run loads is
    # compiled again, compose_run alone for seconds, by the same path as this one)
    folder = cache / "kernels" / "__pycache__"
    unsummed = [*folder.glob("pe_kernels_*.nbsum"), numba_file(cache, SMALL, ".nbsum")]
    assert len(unsummed) > 2
    for sums in unsummed:
        sums.unlink()
    randomise(numba_file(cache, SMALL, ".nbi"))
    assert run_once(capsys) == []
    assert numba_file(cache, SMALL, ".nbsum").exists()
    assert numba_file(cache, "rhs", ".nbsum").exists()
    assert run_once(capsys) == []


def test_an_edited_kernel_module_is_rewritten_never_run(cache, capsys):
    [module] = (cache / "kernels").glob("pe_kernels_*.py")
    source = module.read_text()
    assert source.count("out[0] = v_x*v_k") == 1  # grad_potential, the force yoshida8 uses
    module.write_text(source.replace("out[0] = v_x*v_k", "out[0] = 0.0"))  # would freeze p
    assert_healed(capsys, module.name)
    assert module.read_text() == source


@pytest.mark.parametrize("damage", [drop_last_line, empty, truncate, randomise])
def test_a_damaged_stored_kernel_source_is_rebuilt(cache, capsys, damage):
    path = stored_text(cache, b"def grad_potential(")
    damage(path)
    assert_healed(capsys, path.name)


def test_a_junk_method_choice_is_rebuilt(cache, capsys):
    path = stored_text(cache, b"yoshida8\n")
    path.write_text("junk")
    assert_healed(capsys, path.name)
    assert b"yoshida8\n" in path.read_bytes()


class _Boom:
    def __reduce__(self):
        return (_explode, ())


def _explode():
    raise RuntimeError("a pickle that raises while loading")


def _checked_pickle(path: Path, obj) -> None:
    write_checked(path, pickle.dumps(obj), derivation_cache._code_version())


@pytest.mark.parametrize(
    "damage",
    [
        randomise,
        truncate,
        lambda path: path.write_bytes(pickle.dumps({"not": "a derivation"})),
        lambda path: _checked_pickle(path, {"not": "a derivation"}),
        lambda path: _checked_pickle(path, _Boom()),
    ],
    ids=["random", "truncated", "other-object", "checked-other-object", "raises-on-load"],
)
def test_bad_derivation_pickles_are_rebuilt(cache, capsys, damage):
    [path] = (cache / "derivations").glob("*.pickle")
    damage(path)
    assert_healed(capsys, path.name)


def test_checked_files_reject_any_change_and_other_code(tmp_path, capsys):
    path = tmp_path / "entry"
    assert read_checked(path, "v1") is None  # a miss says nothing
    assert write_checked(path, b"body\nlines\n", "v1")
    assert read_checked(path, "v1") == b"body\nlines\n"
    assert capsys.readouterr().err == ""
    assert read_checked(path, "v2") is None  # written by other code
    assert not path.exists()
    write_checked(path, b"body\nlines\n", "v1")
    drop_last_line(path)
    assert read_checked(path, "v1") is None and not path.exists()
    assert capsys.readouterr().err.count("phase-explorer: cache entry") == 2


# -- something else in an entry's place ---------------------------------------------------


def a_folder(path: Path) -> None:
    path.unlink()
    path.mkdir()
    (path / "inside").write_text("kept by nobody")


def a_named_pipe(path: Path) -> None:
    path.unlink()
    os.mkfifo(path)  # never opened: reading it would wait for a writer for ever


def a_link_to_a_folder(path: Path) -> None:
    elsewhere = path.parent.parent / f"elsewhere-{path.name}"
    elsewhere.mkdir()
    path.unlink()
    path.symlink_to(elsewhere)


def _entries(cache: Path) -> dict[str, Path]:
    return {
        "derivation": next((cache / "derivations").glob("*.pickle")),
        "stored text": stored_text(cache, b"def grad_potential("),
        "kernel module": next((cache / "kernels").glob("pe_kernels_*.py")),
        "numba index": numba_file(cache, SMALL, ".nbi"),
        "numba data": numba_file(cache, "rhs", ".1.nbc"),
        "numba checksums": numba_file(cache, "hamiltonian", ".nbsum"),
    }


@pytest.mark.parametrize("damage", [a_folder, a_named_pipe, a_link_to_a_folder])
@pytest.mark.parametrize(
    "entry",
    ["derivation", "stored text", "kernel module", "numba index", "numba data", "numba checksums"],
)
def test_a_non_file_in_place_of_an_entry_is_removed_and_rebuilt(cache, capsys, entry, damage):
    path = _entries(cache)[entry]
    damage(path)
    if damage is a_link_to_a_folder:
        target = path.resolve()
    named = path.name.split("-")[0] if entry.startswith("numba") else path.name
    assert_healed(capsys, named)  # reported once, never again
    assert path.is_file() and not path.is_symlink()
    if damage is a_link_to_a_folder:
        assert target.is_dir()  # the link is removed, never what it points to


# -- unusable directories ---------------------------------------------------------------


def _read_only(root: Path, monkeypatch, how: str) -> None:
    if how == "chmod":
        for folder, _, _ in os.walk(root):
            os.chmod(folder, stat.S_IRUSR | stat.S_IXUSR)
        if os.geteuid() == 0 and os.access(root, os.W_OK):
            pytest.skip("root writes through chmod")  # (not when it lacks CAP_DAC_OVERRIDE)
    else:  # as access(2) answers for a read-only mount
        access = os.access
        monkeypatch.setattr(
            os, "access", lambda path, mode: access(path, mode) and Path(path) != root
        )


def _fallback_with_drivers(monkeypatch, name: str) -> None:
    """The temporary directory the program falls back to starts with the session's
    stepping loops in its ``name`` folder, as an installation's cache holds them: the
    program would compile them there as in any empty cache (what ``warm`` does), which is
    not what these tests are about. The scene's functions are still written there."""
    mkdtemp = tempfile.mkdtemp

    def seeded(*args, **kwargs) -> str:
        folder = mkdtemp(*args, **kwargs)
        copy_drivers(SESSION_CACHE, Path(folder) / name)
        return folder

    monkeypatch.setattr(tempfile, "mkdtemp", seeded)


@pytest.mark.parametrize("how", ["chmod", "read-only-mount"])
def test_a_read_only_cache_directory_falls_back(cache, capsys, monkeypatch, how):
    _fallback_with_drivers(monkeypatch, cache.name)
    before = sorted(p.name for p in cache.rglob("*"))
    try:
        _read_only(cache, monkeypatch, how)
        lines = run_once(capsys)
        assert run_once(capsys) == []  # warned once per session
    finally:
        for folder, _, _ in os.walk(cache):
            os.chmod(folder, stat.S_IRWXU)
    assert len(lines) == 1 and "warning" in lines[0] and str(cache) in lines[0], lines
    assert sorted(p.name for p in cache.rglob("*")) == before
    [fallback] = cache_integrity._temporary
    assert fallback.parent == Path(tempfile.tempdir)
    assert list((fallback / cache.name / "kernels").glob("pe_kernels_*.py"))


def test_a_file_in_place_of_the_cache_directory_falls_back(tmp_path, capsys, monkeypatch):
    root = tmp_path / "cache"
    root.write_text("not a directory")
    _isolate(monkeypatch, root)
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    _fallback_with_drivers(monkeypatch, root.name)
    lines = run_once(capsys)
    assert len(lines) == 1 and "warning" in lines[0] and "a file is in its place" in lines[0]
    assert root.read_text() == "not a directory"
    [fallback] = cache_integrity._temporary
    assert list((fallback / "cache" / "derivations").glob("*.pickle"))
