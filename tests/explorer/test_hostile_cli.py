"""The hostile probe of issue 24 (item 6), kept as a corpus: every command answers
hostile options, paths, outputs and signals with a message and an exit status from a
small set, never a traceback, a hang or a crash.

Most cases run ``explorer.cli.main`` in this process; signals, pipes and a window's
replay run ``main.py`` in a subprocess. Limits are CPU time (or a generous ``timeout``
of a subprocess, which only stops a hang), never wall-clock assertions: the machine may
be busy. Hypothesis draws options (inf, nan, 1e308, 5e-324, -0.0, huge whole numbers,
text), paths (a missing folder, a folder, a named pipe, /dev/full, /dev/zero, a loop of
links) and signals; ``FUZZ_EXAMPLES=N`` explores further than the fixed examples CI runs.
"""

from __future__ import annotations

import csv
import errno
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from explorer.cli import main
from explorer.session import ScriptError, load, parse
from explorer.session.script import MAX_COMMANDS, MAX_WAIT
from systems.files import PARTIAL

ROOT = Path(__file__).resolve().parents[2]
HARMONIC = (ROOT / "resources" / "scenes" / "harmonic_oscillator.toml").read_text()
_EXPLORE = int(os.environ.get("FUZZ_EXAMPLES", "0"))
CPU_LIMIT = 60.0
"""CPU seconds one in-process command may take: a bound against a runaway, not a timing."""
HANG = 300
"""Seconds a subprocess may take before it counts as hung (the machine may be busy)."""

FUZZ = settings(
    deadline=None,
    derandomize=not _EXPLORE,
    max_examples=_EXPLORE or 30,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture],
    database=None,
)


def call(capsys, *argv: str) -> tuple[int, str, str]:
    """``main(argv)`` in this process: (status, stdout, stderr), checked to be clean.

    Clean: a status of 0, 1, 2 or 128 + a signal, no traceback, at most ``CPU_LIMIT`` s
    of CPU. argparse's own refusals (a value that is no number) exit 2 as SystemExit.
    """
    start = time.process_time()
    try:
        code = main(list(argv))
    except SystemExit as exc:
        code = exc.code
    spent = time.process_time() - start
    out, err = capsys.readouterr()
    assert code in (0, 1, 2, 129, 130, 143), (argv, code, err)
    assert "Traceback" not in err, (argv, err)
    assert spent < CPU_LIMIT, (argv, spent)
    return code, out, err


def refused(capsys, *argv: str) -> str:
    """``main(argv)`` must exit 2 with one ``error:`` message; returns stderr."""
    code, _, err = call(capsys, *argv)
    assert code == 2 and "error: " in err, (argv, code, err)
    return err


def litter(folder: Path) -> list[str]:
    return sorted(name for name in os.listdir(folder) if PARTIAL in name)


def scene_file(folder: Path, potential: str, name: str = "scene.toml") -> str:
    path = folder / name
    path.write_text(HARMONIC.replace('potential = "k*x**2/2"', f'potential = "{potential}"', 1))
    return str(path)


SUFFIXES = (".csv", ".png", ".svg", ".txt", ".toml")


@pytest.fixture(scope="module")
def places(tmp_path_factory) -> dict[str, str]:
    """Hostile paths by name, as ``.csv`` (``with_suffix`` gives the others, which exist
    as well); made once for the module."""
    folder = tmp_path_factory.mktemp("hostile")
    for suffix in SUFFIXES:
        (folder / f"folder{suffix}").mkdir()
        os.mkfifo(folder / f"pipe{suffix}")
        (folder / f"loop_a{suffix}").symlink_to(f"loop_b{suffix}")
        (folder / f"loop_b{suffix}").symlink_to(f"loop_a{suffix}")
        (folder / f"full{suffix}").symlink_to("/dev/full")
        (folder / f"null{suffix}").symlink_to("/dev/null")
        (folder / f"zero{suffix}").symlink_to("/dev/zero")
    with open(folder / "huge.csv", "wb") as handle:  # sparse: no disk used
        handle.truncate(50 * 2**20)
    for suffix in SUFFIXES[1:]:
        (folder / f"huge{suffix}").symlink_to("huge.csv")
    named = {name: str(folder / f"{name}.csv") for name in ("folder", "pipe", "full", "null")}
    return {
        **named,
        "zero": str(folder / "zero.csv"),
        "missing folder": str(folder / "no such folder" / "out.csv"),
        "loop": str(folder / "loop_a.csv"),
        "huge": str(folder / "huge.csv"),
        "urandom": "/dev/urandom",
        "root": str(folder),
    }


def with_suffix(path: str, suffix: str) -> str:
    """``path`` with ``suffix`` in place of ``.csv`` (the fixture made that file too)."""
    return path.removesuffix(".csv") + suffix if path.endswith(".csv") else path


def _no_sweep(monkeypatch) -> None:
    """A sweep would be a failure of the test: what is refused is refused before it."""

    def sweep(*args, **kwargs):
        raise AssertionError("the sweep started")

    monkeypatch.setattr("systems.workprecision.sweep", sweep)


# -- bench: outputs and bounds checked before the sweep ---------------------------------------


@pytest.mark.parametrize("option", ["--out", "--csv"])
@pytest.mark.parametrize("where", ["missing folder", "folder", "loop"])
def test_bench_outputs_are_checked_before_the_sweep(capsys, monkeypatch, places, option, where):
    _no_sweep(monkeypatch)
    path = with_suffix(places[where], ".png" if option == "--out" else ".csv")
    err = refused(capsys, "bench", "harmonic_oscillator", "--t-end", "1", option, path)
    assert option in err


@pytest.mark.parametrize(
    "options, words",
    [
        (["--t-end", "inf"], "positive finite"),
        (["--t-end", "nan"], "positive finite"),
        (["--t-end", "-1"], "positive finite"),
        (["--t-end", "-0.0"], "positive finite"),
        (["--t-end", "5e-324"], "at least 1e-300"),
        (["--t-end", "1e308"], "more than 1e308 steps"),
        (["--t-end", "1e7"], "allowed"),
        (["--levels", "200"], "--levels must be 2 to 12"),
        (["--levels", "0"], "--levels must be 2 to 12"),
        (["--levels", "-5"], "--levels must be 2 to 12"),
        (["--levels", "9" * 40], "--levels must be 2 to 12"),
    ],
)
def test_bench_refuses_absurd_times_and_levels_before_the_sweep(
    capsys, monkeypatch, options, words
):
    _no_sweep(monkeypatch)
    argv = ["bench", "harmonic_oscillator", *options]
    if "--t-end" not in options:
        argv += ["--t-end", "1"]
    assert words in refused(capsys, *argv)


def _full_disk(monkeypatch) -> None:
    """Every file written through ``atomic_path`` meets a full disk when it is synced."""

    def fsync(handle):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr("systems.files.os.fsync", fsync)


@pytest.mark.parametrize("option, name", [("--csv", "sweep.csv"), ("--out", "sweep.png")])
def test_bench_on_a_full_disk_ends_with_a_message(tmp_path, capsys, monkeypatch, option, name):
    _full_disk(monkeypatch)
    out = tmp_path / name
    argv = ["bench", "harmonic_oscillator", "--t-end", "0.5", "--levels", "2"]
    argv += ["--methods", "leapfrog", option, str(out)]
    code, stdout, err = call(capsys, *argv)
    assert code == 2 and f"could not write {out}: No space left on device" in err, err
    assert "leapfrog" in stdout  # the table was printed before
    assert os.listdir(tmp_path) == []


@pytest.mark.parametrize("suffix", [".png", ".svg", ".csv"])
@pytest.mark.parametrize("device", [True, False])
def test_export_on_a_full_disk_ends_with_a_message(
    tmp_path, capsys, monkeypatch, places, suffix, device
):
    if device:
        out = with_suffix(places["full"], suffix)
        monkeypatch.setattr("tempfile.tempdir", str(tmp_path))
    else:
        _full_disk(monkeypatch)
        out = str(tmp_path / f"figure{suffix}")
    code, _, err = call(capsys, "export", "harmonic_oscillator", "--t-end", "0.5", "--out", out)
    assert code == 2 and f"could not write {out}" in err, err
    assert "No space left on device" in err or "the disk full" in err, err
    assert "libpng" not in err
    assert os.listdir(tmp_path) == []


# -- standard output closed or full -----------------------------------------------------------


def _python(*argv: str, **options) -> subprocess.CompletedProcess:
    environment = {**os.environ, "PYTHONPATH": str(ROOT)}
    return subprocess.run(
        [sys.executable, str(ROOT / "main.py"), *argv],
        cwd=ROOT,
        env=environment,
        timeout=HANG,
        **options,
    )


def test_a_reader_that_closes_the_pipe_ends_the_command_quietly():
    process = subprocess.Popen(
        [sys.executable, str(ROOT / "main.py"), "derive", "simple_pendulum"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        cwd=ROOT,
    )
    process.stdout.close()  # before anything is written: every write meets a closed pipe
    try:
        _, err = process.communicate(timeout=HANG)
    finally:
        if process.poll() is None:
            process.kill()
    assert process.returncode == 0, err
    assert err == b"", err


def test_derive_piped_into_head_ends_quietly():
    done = subprocess.run(
        f"{sys.executable} main.py derive double_pendulum | head -1",
        shell=True,
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=HANG,
    )
    assert done.stdout.strip() == "Double pendulum"
    assert done.stderr == "", done.stderr


@pytest.mark.skipif(not Path("/dev/full").exists(), reason="no /dev/full")
@pytest.mark.parametrize("command", [["derive", "simple_pendulum"], ["list"]])
def test_standard_output_on_a_full_device_is_one_message(command):
    with open("/dev/full", "w") as full:
        done = _python(*command, stdout=full, stderr=subprocess.PIPE, text=True)
    assert done.returncode == 1
    assert done.stderr == "error: could not write the output: No space left on device\n"


# -- scenes: flat minima, towers of powers, times too short -----------------------------------


@pytest.mark.parametrize(
    "potential",
    [
        "x**8",
        "k*x**10",
        "-x**8",
        "x**7",
        "x**x**x**x**x",
        "((((((x**2)**2)**2)**2)**2)**2)**2",
        "x**(x**(x**(x**(x**(x**(x**x))))))",
        "k*x**(2**2**2)",
        "(Abs(x - 1) + Abs(x + 1) - 2)**2",
    ],
)
@pytest.mark.parametrize("command", ["derive", "run"])
def test_flat_minima_and_towers_of_powers_derive_or_are_refused(
    tmp_path, capsys, potential, command
):
    path = scene_file(tmp_path, potential)
    argv = [command, path] + (["--t-end", "0.5", "--samples", "5"] if command == "run" else [])
    code, out, _ = call(capsys, *argv)
    assert code in (0, 1, 2)
    if potential in ("x**8", "k*x**10") and command == "derive":
        assert code == 0
        assert "x = 0: stable" in out and "as the power" in out and "curve" not in out


@pytest.mark.parametrize("t_end", ["5e-324", "1e-310", "-0.0"])
def test_a_time_too_short_to_step_is_refused(tmp_path, capsys, t_end):
    refused(capsys, "run", "harmonic_oscillator", "--t-end", t_end)
    refused(capsys, "export", "harmonic_oscillator", "--t-end", t_end, "--out", "x.png")
    path = tmp_path / "short.toml"
    path.write_text(HARMONIC.replace("t_end = 20.0", f"t_end = {t_end}", 1))
    assert "view.t_end" in refused(capsys, "run", str(path))


# -- scene and session files that are no files ----------------------------------------------


SCENE_PLACES = ["pipe", "zero", "urandom", "folder", "loop", "huge", "null"]


@pytest.mark.parametrize("where", SCENE_PLACES)
@pytest.mark.parametrize("command", ["derive", "run", "export", "bench"])
def test_a_scene_that_is_no_file_is_refused_at_once(capsys, monkeypatch, places, where, command):
    _no_sweep(monkeypatch)
    scene = with_suffix(places[where], ".toml")
    argv = [command, scene]
    if command == "export":
        argv += ["--out", str(Path(places["root"]) / "never.png")]
    err = refused(capsys, *argv)
    assert scene in err


@pytest.mark.parametrize("where", SCENE_PLACES)
def test_a_session_that_is_no_file_is_refused_at_once(capsys, places, where):
    session = places[where]
    with pytest.raises(ScriptError):
        load(session)
    code, _, err = call(capsys, "open", "--session", session, "--offscreen", "--exit")
    assert code == 2 and session in err


def test_a_session_of_too_many_lines_is_refused(tmp_path):
    path = tmp_path / "long.session"
    path.write_text("wait 0\n" * 100_000)
    with pytest.raises(ScriptError, match=f"more than {MAX_COMMANDS:,} commands"):
        load(path)


TIMES = st.sampled_from(
    ["inf", "-inf", "nan", "1e308", "-1e308", "1e-300", "5e-324", "-0.0", "0", "-1", "3600",
     "3600.5", "1e999", "9" * 40, "abc", "1_000", "0x10", "1e3"]
)  # fmt: skip


@FUZZ
@given(verb=st.sampled_from(["wait", "run-until", "run-until-timeout"]), value=TIMES)
def test_absurd_session_times_are_refused_or_bounded(verb, value):
    text = f"run-until 1 timeout={value}" if verb == "run-until-timeout" else f"{verb} {value}"
    try:
        (command,) = parse(text)
    except ScriptError as exc:
        assert exc.line == 1
        return
    parsed = command.value if verb == "wait" else command.value[verb == "run-until-timeout"]
    assert 0 <= parsed and (verb == "run-until" or parsed <= MAX_WAIT)


# -- Ctrl+C while a finished run's file is written ---------------------------------------------


def _signal_during_write(monkeypatch, signals: list[int]) -> None:
    """Send ``signals`` to this process while the rows are being written, one after the
    first block of rows and the next after the second: where a real Ctrl+C lands."""
    import systems.files

    write_rows = systems.files.write_rows
    pending = list(signals)

    def interrupted(handle, table, first=""):
        for start in range(0, len(table), systems.files.CSV_BLOCK):
            write_rows(handle, table[start : start + systems.files.CSV_BLOCK], first)
            if pending:
                os.kill(os.getpid(), pending.pop(0))
                for _ in range(1000):  # the handler runs at the next bytecode boundaries
                    time.sleep(0.001)

    monkeypatch.setattr(systems.files, "write_rows", interrupted)


def _rows(path: Path) -> list[list[str]]:
    with path.open(newline="") as handle:
        return list(csv.reader(handle))


LONG_RUN = ["run", "harmonic_oscillator", "--t-end", "2", "--method", "leapfrog", "--dt", "1e-4"]
LONG_RUN += ["--samples", "20000"]
"""20 001 rows, a step each: five blocks of ``write_rows``."""


@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM])
def test_a_signal_while_a_finished_run_is_written_keeps_the_file(
    tmp_path, capsys, monkeypatch, signum
):
    _signal_during_write(monkeypatch, [signum])
    out = tmp_path / "run.csv"
    argv = [*LONG_RUN, "--out", str(out)]
    code, _, err = call(capsys, *argv)
    assert code == 128 + signum, err
    assert f"finishing writing {out} first" in err and f"finished writing {out}" in err
    rows = _rows(out)
    assert len(rows) == 20002 and float(rows[-1][0]) == 2.0
    assert len({len(row) for row in rows}) == 1
    assert litter(tmp_path) == []


def test_a_second_ctrl_c_abandons_the_write_and_keeps_the_old_file(tmp_path, capsys, monkeypatch):
    _signal_during_write(monkeypatch, [signal.SIGINT, signal.SIGINT])
    out = tmp_path / "run.csv"
    out.write_text("the previous run\n")
    argv = [*LONG_RUN, "--out", str(out)]
    code, _, err = call(capsys, *argv)
    assert code == 130 and "Ctrl+C again abandons it" in err, err
    assert out.read_text() == "the previous run\n"
    assert litter(tmp_path) == []


def test_a_long_table_is_written_in_seconds_of_cpu(tmp_path):
    """300 000 rows (issue 24: 240 s); the bound is generous, against a per-value loop."""
    import numpy as np

    from systems.files import write_rows

    table = np.random.default_rng(1).standard_normal((300_000, 8))
    start = time.process_time()
    with (tmp_path / "t.csv").open("w", newline="") as handle:
        write_rows(handle, table)
    assert time.process_time() - start < 20.0
    back = np.loadtxt(tmp_path / "t.csv", delimiter=",")
    assert np.array_equal(back, table)


# -- signals, in a subprocess -----------------------------------------------------------------


LAUNCH = (
    "import signal, sys\n"
    "signal.signal(signal.SIGINT, signal.default_int_handler)\n"
    "for s in (signal.SIGTERM, signal.SIGHUP): signal.signal(s, signal.SIG_DFL)\n"
    "signal.pthread_sigmask(signal.SIG_UNBLOCK, [signal.SIGINT, signal.SIGTERM, signal.SIGHUP])\n"
    "from explorer.cli import entry\n"
    "try:\n"
    "    print('launched', file=sys.stderr, flush=True)\n"
    "except KeyboardInterrupt:\n"
    "    sys.exit(128 + signal.SIGINT)\n"
    "entry(sys.argv[1:])\n"
)
"""``main.py`` (as the ``phase-explorer`` entry point runs it), started with the three
signals at their defaults whatever the test worker's; it says so on stderr once loaded.
A SIGINT sent as soon as that is read can land while the launcher still prints it,
before the command: that ends it as Python's default would, without a traceback of the
launcher's own (a run at load 9 failed so)."""


def _launch(*argv: str) -> subprocess.Popen:
    environment = {**os.environ, "PYTHONPATH": str(ROOT), "QT_QPA_PLATFORM": "offscreen"}
    return subprocess.Popen(
        [sys.executable, "-c", LAUNCH, *argv],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        cwd=ROOT,
        env=environment,
    )


def _finish(process: subprocess.Popen) -> tuple[str, str]:
    try:
        return process.communicate(timeout=HANG)
    finally:
        if process.poll() is None:
            process.kill()
            process.wait()


@settings(FUZZ, max_examples=_EXPLORE or 5)
@given(
    command=st.sampled_from(["run", "endless", "export", "derive"]),
    signum=st.sampled_from([signal.SIGINT, signal.SIGTERM, signal.SIGHUP]),
    delay=st.floats(0.0, 3.0),
)
def test_a_signal_at_any_moment_stops_a_command_cleanly(tmp_path_factory, command, signum, delay):
    folder = tmp_path_factory.mktemp("signal")
    out = folder / ("out.png" if command == "export" else "out.csv")
    argv = {
        "run": ["run", "harmonic_oscillator", "--t-end", "5", "--samples", "100000"],
        "endless": ["run", "harmonic_oscillator", "--t-end", "inf", "--every", "0.01"],
        "export": ["export", "harmonic_oscillator", "--t-end", "5"],
        "derive": ["derive", "double_pendulum"],
    }[command]
    if command != "derive":
        argv += ["--out", str(out)]
    process = _launch(*argv)
    assert process.stderr.readline() == "launched\n"
    time.sleep(delay)  # where the signal lands, not an assertion
    process.send_signal(signum)
    _, err = _finish(process)
    # -signum: SIGTERM or SIGHUP before the command set its handlers, which ended the
    # process as their default does (the shell reports 128 + signum for both)
    assert process.returncode in (0, 1, 2, 128 + signum, -signum), err
    assert "Traceback" not in err, err
    assert litter(folder) == []
    if out.suffix == ".csv" and out.exists():  # whole rows only, all of one width
        rows = _rows(out)
        assert rows and len({len(row) for row in rows}) == 1


def test_ctrl_c_stops_a_session_replay_cleanly(tmp_path):
    started = tmp_path / "started.toml"
    session = tmp_path / "long.session"
    session.write_text(f"open harmonic_oscillator\nsave {started}\nplay\nwait 600\n")
    process = _launch("open", "--session", str(session), "--offscreen", "--exit")
    assert process.stderr.readline() == "launched\n"
    end = time.monotonic() + HANG
    while not started.exists() and process.poll() is None and time.monotonic() < end:
        time.sleep(0.05)
    process.send_signal(signal.SIGINT)
    _, err = _finish(process)
    assert process.returncode == 130, err
    assert f"stopped (Ctrl+C) at {session}:" in err and "Traceback" not in err, err


def test_run_until_an_absurd_time_is_a_script_error_soon(tmp_path):
    session = tmp_path / "far.session"
    session.write_text("open harmonic_oscillator\nplay\nrun-until 1e308\n")
    process = _launch("open", "--session", str(session), "--offscreen", "--exit")
    _, err = _finish(process)
    assert process.returncode == 2, err
    assert f"{session}:3: at speed 1, t = 1e+308 is" in err and "beyond the" in err, err


# -- the probe: random options and paths, every command ---------------------------------------


NUMBERS = st.sampled_from(
    ["inf", "-inf", "nan", "1e308", "-1e308", "5e-324", "-0.0", "0", "-1", "1e-300", "0.5",
     "2", "1e999", "9" * 30, "-" + "9" * 30, "abc", "", "1e3"]
)  # fmt: skip
WHOLE = st.sampled_from(["0", "-1", "1", "2", "3", "200", "9" * 30, "nan", "x", "1e3", ""])
# half of the draws are a good output or scene, so that the other options get their turn
OUTPUTS = st.just("fine") | st.sampled_from(
    ["missing folder", "folder", "pipe", "loop", "full", "null", "zero"]
)  # fmt: skip
SCENES = st.just("harmonic_oscillator") | st.sampled_from(
    ["pipe", "zero", "urandom", "folder", "loop", "huge", "no_such", "double_pendulum"]
)  # fmt: skip


def _path(places: dict, folder: Path, name: str, suffix: str) -> str:
    """The output ``name`` of ``places`` as a file with ``suffix`` ("fine": a new file
    in ``folder``)."""
    if name == "fine":
        return str(folder / f"out{suffix}")
    return with_suffix(places[name], suffix)


def _scene(places: dict, name: str) -> str:
    return with_suffix(places[name], ".toml") if name in places else name


@FUZZ
@given(
    scene=SCENES,
    options=st.fixed_dictionaries(
        {},
        optional={
            "--t-end": NUMBERS,
            "--dt": NUMBERS,
            "--every": NUMBERS,
            "--samples": WHOLE,
            "--max-steps": WHOLE,
            "--energy-tolerance": NUMBERS,
        },
    ),
    output=st.none() | OUTPUTS,
)
def test_run_answers_hostile_options_and_paths(
    tmp_path_factory, capsys, monkeypatch, places, scene, options, output
):
    monkeypatch.setattr("systems.files.PIPE_WAIT", 0.1)
    argv = ["run", _scene(places, scene)]
    for flag, value in options.items():
        argv += [flag, value]
    if "--t-end" not in options:
        argv += ["--t-end", "0.5"]
    if "--max-steps" not in options:
        argv += ["--max-steps", "100000"]
    if output is not None:
        argv += ["--out", _path(places, tmp_path_factory.mktemp("run"), output, ".csv")]
    call(capsys, *argv)


@settings(FUZZ, max_examples=_EXPLORE or 20)
@given(
    scene=SCENES,
    t_end=st.none() | NUMBERS,
    levels=st.none() | WHOLE,
    out=st.none() | OUTPUTS,
    table=st.none() | OUTPUTS,
)
def test_bench_answers_hostile_options_and_paths(
    tmp_path_factory, capsys, monkeypatch, places, scene, t_end, levels, out, table
):
    monkeypatch.setattr("systems.files.PIPE_WAIT", 0.1)
    folder = tmp_path_factory.mktemp("bench")
    argv = ["bench", _scene(places, scene), "--methods", "leapfrog,dop853"]
    argv += ["--t-end", "0.3" if t_end is None else t_end]
    argv += ["--levels", "2" if levels is None else levels]
    if out is not None:
        argv += ["--out", _path(places, folder, out, ".png")]
    if table is not None:
        argv += ["--csv", _path(places, folder, table, ".csv")]
    call(capsys, *argv)
    assert litter(folder) == []


@settings(FUZZ, max_examples=_EXPLORE or 15)
@given(
    scene=SCENES,
    t_end=st.none() | NUMBERS,
    size=st.none() | WHOLE,
    out=OUTPUTS,
    suffix=st.sampled_from([".png", ".svg", ".csv", ".txt"]),
)
def test_export_answers_hostile_options_and_paths(
    tmp_path_factory, capsys, monkeypatch, places, scene, t_end, size, out, suffix
):
    monkeypatch.setattr("systems.files.PIPE_WAIT", 0.1)
    folder = tmp_path_factory.mktemp("export")
    argv = ["export", _scene(places, scene), "--t-end", "0.5" if t_end is None else t_end]
    if size is not None:
        argv += ["--width", size]
    argv += ["--out", _path(places, folder, out, suffix)]
    call(capsys, *argv)
    assert litter(folder) == []


@FUZZ
@given(scene=SCENES, json=st.booleans())
def test_derive_answers_hostile_paths(capsys, places, scene, json):
    call(capsys, "derive", _scene(places, scene), *(["--json"] if json else []))
