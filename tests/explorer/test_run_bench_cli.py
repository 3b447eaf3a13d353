"""The ``run`` and ``bench`` commands: outputs, JSON keys, user errors."""

import csv
import json
import math
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from explorer.cli import main
from tests.systems.scenes import DRIVEN_DAMPED, PLANETARY

SCENES = Path(__file__).resolve().parents[2] / "resources" / "scenes"

ROOT = Path(__file__).resolve().parents[2]
JSON_KEYS = {
    "accuracy",
    "arithmetic",
    "max_constraint_violation",
    "method",
    "why",
    "steps",
    "rhs_evaluations",
    "wall_s",
    "prepare_s",
    "compile_s",
    "t_end",
    "final",
    "max_rel_energy_error",
    "setting",
    "status",
    "message",
}


def run_json(capsys, *args):
    code = main(["run", *args, "--json"])
    return code, json.loads(capsys.readouterr().out)


@pytest.fixture
def fresh_oscillator(tmp_path) -> str:
    """The catalogue's harmonic oscillator with a negligible x**4 term of its own: kernels
    no earlier test of this process compiled."""
    text = (SCENES / "harmonic_oscillator.toml").read_text(encoding="utf-8")
    unique = f"{time.time_ns() % 10**9 + 1}e-24"
    path = tmp_path / "oscillator.toml"
    path.write_text(
        text.replace('potential = "k*x**2/2"', f'potential = "k*x**2/2 + {unique}*x**4"')
    )
    return str(path)


def test_run_json_report_and_csv(tmp_path, capsys, fresh_oscillator):
    out = tmp_path / "osc.csv"
    code, report = run_json(capsys, fresh_oscillator, "--t-end", "3.0", "--out", str(out))
    assert code == 0
    assert set(report) == JSON_KEYS
    assert report["status"] == "ok" and report["message"] == ""
    assert report["max_constraint_violation"] is None  # no constraints
    assert report["t_end"] == 3.0
    # separable: yoshida8 by the classification, priced against DOP853 and taylor
    assert report["method"] in ("yoshida8", "dop853", "taylor") and "measured" in report["why"]
    assert report["steps"] > 0 and report["rhs_evaluations"] >= report["steps"]
    assert report["wall_s"] >= 0 and report["prepare_s"] > 0
    assert 0 < report["compile_s"] < report["prepare_s"]  # the scene's functions, compiled
    final = report["final"]
    assert final["q"]["x"] == pytest.approx(math.cos(3.0), abs=1e-4)
    assert final["qdot"]["x"] == pytest.approx(-math.sin(3.0), abs=1e-4)
    assert final["p"]["x"] == pytest.approx(-math.sin(3.0), abs=1e-4)
    assert report["max_rel_energy_error"] < 1e-4
    with out.open() as handle:
        rows = list(csv.reader(handle))
    assert rows[0] == ["t", "x", "x_dot", "p_x", "H"]
    table = np.array(rows[1:], dtype=float)
    assert table[0, 0] == 0.0 and table[-1, 0] == 3.0
    np.testing.assert_allclose(table[:, 1], np.cos(table[:, 0]), atol=1e-4)
    np.testing.assert_allclose(table[:, 4], 0.5, atol=1e-4)


def test_run_npz_with_a_method_and_step(tmp_path, capsys):
    scene = tmp_path / "planet.toml"
    scene.write_text(PLANETARY)
    out = tmp_path / "planet.npz"
    code, report = run_json(
        capsys, str(scene), "--t-end", "5", "--method", "gauss_legendre6", "--dt", "0.01",
        "--out", str(out),
    )  # fmt: skip
    assert code == 0
    assert report["method"] == "gauss_legendre6" and report["why"].startswith("requested")
    assert report["steps"] == 500
    data = np.load(out)
    assert data["q"].shape[1] == 2 and data["p"].shape == data["q"].shape
    assert list(data["columns"]) == ["t", "r", "theta", "r_dot", "theta_dot", "p_r", "p_theta", "H"]


def test_run_energy_error_is_null_when_h_is_not_conserved(tmp_path, capsys):
    scene = tmp_path / "driven.toml"
    scene.write_text(DRIVEN_DAMPED)
    code, report = run_json(capsys, str(scene), "--t-end", "5", "--tol", "1e-8")
    assert code == 0
    assert report["method"] == "dop853"
    assert report["max_rel_energy_error"] is None
    # checked instead by a run at a hundredth of the tolerance
    assert report["accuracy"]["checked_against"] == "dop853 at tol = 1e-10"
    assert report["accuracy"]["accurate"] and report["accuracy"]["final_state_error"] < 1e-6


def test_a_run_the_energy_cannot_check_is_checked_and_may_end_inaccurate(capsys):
    """Euler's default step on the damped pendulum ends 1e-2 from the true state: the run
    says so (status inaccurate, exit 1) instead of ok."""
    code, report = run_json(capsys, "damped_pendulum", "--method", "euler", "--t-end", "10")
    assert code == 1 and report["status"] == "inaccurate"
    assert "euler at dt = " in report["accuracy"]["checked_against"]
    assert report["accuracy"]["final_state_error"] > 1e-4
    assert "take a smaller step (--dt) or an adaptive method" in report["message"]
    assert main(["run", "damped_pendulum", "--method", "euler", "--t-end", "10"]) == 1
    captured = capsys.readouterr()
    assert "checked against euler at dt" in captured.out
    assert captured.err.startswith("inaccurate: the final state is off by about")


def test_run_stops_with_a_problem_status_and_exit_code(capsys):
    code, report = run_json(
        capsys, "simple_pendulum", "--method", "leapfrog", "--dt", "1.5", "--t-end", "100"
    )
    assert code == 1
    assert report["status"] in ("energy_error", "non_finite", "singular", "stalled")
    assert report["message"]
    assert all(math.isfinite(v) for v in report["final"]["q"].values())


@pytest.mark.parametrize(
    "args, fragment",
    [
        (["run", "simple_pendulum", "--method", "euler_maruyama"], "unknown method"),
        (["run", "planetary_motion", "--method", "leapfrog"], "separable"),
        (["run", "simple_pendulum", "--dt", "-1"], "--dt must be a positive finite number"),
        (["run", "simple_pendulum", "--dt", "inf"], "--dt must be a positive finite number"),
        (["run", "simple_pendulum", "--out", "x.txt"], ".csv or .npz"),
        (["bench", "simple_pendulum", "--out", "x.jpg"], ".png or .svg"),
        (["bench", "simple_pendulum", "--methods", "rk5"], "unknown method"),
        # a method never silently drops an effect: refused, naming the effect and a method
        (["run", "damped_pendulum", "--method", "leapfrog"], "drop the dissipation"),
        (["run", "driven_damped_pendulum", "--method", "yoshida4"], "driving force on theta"),
        (["bench", "damped_pendulum", "--methods", "yoshida6"], "use dop853"),
        # settings that mean what they say
        (["run", "damped_pendulum", "--dt", "0.01"], "dop853 is adaptive: it takes a tolerance"),
        (["run", "simple_pendulum", "--tol", "1e-8"], "not a tolerance"),
        (["run", "harmonic_oscillator", "--method", "logh_leapfrog"], "needs V < 0"),
        (["run", "simple_pendulum", "--energy-tolerance", "abc"], "--energy-tolerance"),
        (["run", "simple_pendulum", "--max-steps", "0"], "--max-steps"),
    ],
)
def test_user_errors(args, fragment, capsys):
    assert main(args) == 2
    assert fragment in capsys.readouterr().err


def test_dt_and_tol_are_exclusive():
    result = subprocess.run(
        [sys.executable, str(ROOT / "main.py"), "run", "simple_pendulum", "--dt", "0.1",
         "--tol", "1e-6"],
        capture_output=True, text=True, cwd=ROOT,
    )  # fmt: skip
    assert result.returncode == 2 and "not allowed with" in result.stderr


def test_bench_writes_csv_and_figures(tmp_path, capsys):
    table = tmp_path / "wp.csv"
    png = tmp_path / "wp.png"
    args = ["bench", "harmonic_oscillator", "--t-end", "5", "--methods", "leapfrog,dop853"]
    assert main([*args, "--levels", "3", "--csv", str(table), "--out", str(png)]) == 0
    captured = capsys.readouterr()
    assert "3/6" in captured.err  # the progress line
    assert "matrix exponential" in captured.out
    with table.open() as handle:
        rows = list(csv.DictReader(handle))
    assert len(rows) == 6
    leapfrog = [r for r in rows if r["method"] == "leapfrog"]
    errors = [float(r["final_error"]) for r in leapfrog]
    assert errors[0] > errors[1] > errors[2]  # halving the step helps
    assert float(leapfrog[0]["energy_error"]) > 0
    assert png.stat().st_size > 5000
    svg = tmp_path / "wp.svg"
    assert main([*args, "--levels", "2", "--out", str(svg)]) == 0
    text = svg.read_text()
    assert text.startswith("<?xml") and "<path" in text


def test_a_run_over_its_step_budget_stops_with_status_budget(capsys):
    args = ["run", "simple_pendulum", "--t-end", "1000", "--dt", "1e-6", "--max-steps", "1000"]
    code, report = run_json(capsys, *args[1:])
    assert code == 1 and report["status"] == "budget"
    assert "budget" in report["message"] and report["steps"] == 0  # refused before running
    code, report = run_json(capsys, "planetary_motion", "--t-end", "100", "--max-steps", "50")
    assert code == 1 and report["status"] == "budget" and report["steps"] == 50


def test_energy_guard_off_shows_leapfrog_bounded_and_euler_growing(capsys):
    # the classic demonstration: at a large step leapfrog's energy error stays bounded,
    # explicit Euler's grows without bound
    common = ["--t-end", "200", "--dt", "0.2", "--energy-tolerance", "off"]
    code, leap = run_json(capsys, "simple_pendulum", "--method", "leapfrog", *common)
    assert code == 0 and leap["status"] == "ok" and 1e-4 < leap["max_rel_energy_error"] < 0.2
    code, euler = run_json(capsys, "simple_pendulum", "--method", "euler", *common)
    assert code == 0 and euler["max_rel_energy_error"] > 10 * leap["max_rel_energy_error"]
    code, guarded = run_json(capsys, "simple_pendulum", "--method", "euler", "--dt", "0.2")
    assert code == 1 and guarded["status"] == "energy_error"


def test_methods_lists_the_registry_with_refusals(capsys):
    assert main(["methods", "damped_pendulum", "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    by_name = {row["method"]: row for row in data["methods"]}
    assert data["automatic"] == "taylor"  # measured: cheaper than dop853 at the same accuracy
    assert by_name["dop853"]["takes"] == "tol"
    assert not by_name["leapfrog"]["applies"] and "dissipation" in by_name["leapfrog"]["why_not"]
    assert by_name["gauss_legendre6"]["applies"] and by_name["rk4"]["family"] == "runge_kutta"
    assert main(["methods"]) == 0 and "yoshida8" in capsys.readouterr().out


def test_out_is_checked_before_integrating_and_written_whole(tmp_path, capsys):
    missing = tmp_path / "no_such_folder" / "x.csv"
    assert main(["run", "simple_pendulum", "--out", str(missing)]) == 2
    assert "does not exist" in capsys.readouterr().err
    (tmp_path / "folder.csv").mkdir()
    assert main(["run", "simple_pendulum", "--out", str(tmp_path / "folder.csv")]) == 2
    assert "is a folder" in capsys.readouterr().err
    (tmp_path / "folder.csv").rmdir()
    out = tmp_path / "x.npz"
    assert main(["run", "simple_pendulum", "--t-end", "1", "--out", str(out), "--json"]) == 0
    capsys.readouterr()
    assert np.load(out)["t"][-1] == 1.0
    assert sorted(p.name for p in tmp_path.iterdir()) == ["x.npz"]


def test_rows_are_chosen_by_simulation_time_not_wall_time(tmp_path, capsys):
    # the same command writes the same file, whatever the machine's speed
    a, b = tmp_path / "a.csv", tmp_path / "b.csv"
    args = ["run", "double_pendulum", "--t-end", "20", "--samples", "400"]
    assert main([*args, "--out", str(a)]) == 0
    assert main([*args, "--out", str(b)]) == 0
    capsys.readouterr()
    assert a.read_bytes() == b.read_bytes()
    with a.open() as handle:
        rows = list(csv.DictReader(handle))
    assert len(rows) == 401 and float(rows[-1]["t"]) == 20.0
    every = tmp_path / "every.npz"
    assert (
        main(["run", "simple_pendulum", "--t-end", "10", "--every", "0.5", "--out", str(every)])
        == 0
    )
    t = np.load(every)["t"]
    assert len(t) == 21 and np.all(np.diff(t) > 0) and t[-1] == 10.0


@pytest.mark.parametrize(
    "args, fragment",
    [
        (["--t-end", "inf"], "--every"),
        (["--samples", "0"], "--samples"),
        (["--every", "-1"], "--every"),
    ],
)
def test_bad_run_lengths_and_rows_are_refused(args, fragment, capsys):
    assert main(["run", "simple_pendulum", *args]) == 2
    assert fragment in capsys.readouterr().err


def test_ctrl_c_stops_a_run_and_writes_the_rows_so_far(tmp_path):
    import signal
    import time

    out = tmp_path / "long.csv"
    out.write_text("old\n")
    # a terminal's Ctrl+C: the child starts with SIGINT handled and unblocked, whatever
    # the test worker's own state (a worker once passed SIGINT on ignored or blocked, and
    # the run went on to its end)
    launch = (
        "import runpy, signal, sys; signal.signal(signal.SIGINT, signal.default_int_handler); "
        "signal.pthread_sigmask(signal.SIG_UNBLOCK, [signal.SIGINT]); "
        "sys.argv = ['main.py', *sys.argv[1:]]; runpy.run_path('main.py', run_name='__main__')"
    )
    process = subprocess.Popen(
        [sys.executable, "-c", launch, "run", "double_pendulum", "--t-end", "1e5", "--out",
         str(out)],
        stderr=subprocess.PIPE, stdout=subprocess.PIPE, text=True, cwd=ROOT,
    )  # fmt: skip
    try:
        line = process.stderr.readline()  # printed when the integration starts
        assert "integrating" in line
        time.sleep(1.5)
        process.send_signal(signal.SIGINT)
        stdout, stderr = process.communicate(timeout=120)
    except subprocess.TimeoutExpired:
        process.kill()  # never left behind (the window tests count this process's children)
        _, stderr = process.communicate()
        pytest.fail(f"the run did not stop within 120 s of Ctrl+C; its stderr:\n{stderr}")
    finally:
        if process.poll() is None:
            process.kill()
            process.wait()
    assert process.returncode == 130, stderr
    assert "interrupted at t = " in stderr and "Traceback" not in stderr
    with out.open() as handle:
        rows = list(csv.DictReader(handle))
    assert len(rows) >= 2 and 0 < float(rows[-1]["t"]) < 1e5
    assert "interrupted" in stdout


def test_ctrl_c_while_a_sweep_compiles_ends_it_with_a_message(tmp_path):
    """An empty cache: the sweep compiles its methods' stepping loops first. Ctrl+C as
    soon as it has started is never swallowed (no 'no compiled object yet' later)."""
    import os
    import signal

    env = {**os.environ, "PHASE_EXPLORER_CACHE": str(tmp_path / "cache")}
    process = subprocess.Popen(
        [sys.executable, "main.py", "bench", "double_pendulum", "--levels", "2"],
        cwd=Path(__file__).resolve().parents[2],
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        # the kernels folder appears when the first compile begins
        end = time.monotonic() + 300
        while not (tmp_path / "cache" / "kernels").exists() and process.poll() is None:
            assert time.monotonic() < end, "the sweep never started compiling"
            time.sleep(0.05)
        process.send_signal(signal.SIGINT)
        out, err = process.communicate(timeout=300)
    finally:
        if process.poll() is None:
            process.kill()
            process.wait()
    assert process.returncode == 130, err[-2000:]
    assert "stopped (Ctrl+C)" in err
    assert "Traceback" not in err and "no compiled object" not in err
