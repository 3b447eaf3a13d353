import json
import signal
import subprocess
import sys
from pathlib import Path

import pytest
import sympy

from explorer.cli import main
from tests.systems.scenes import PENDULUM, PLANETARY

ROOT = Path(__file__).resolve().parents[2]


def test_derive_json_reads_back(tmp_path, capsys):
    path = tmp_path / "planet.toml"
    path.write_text(PLANETARY)
    assert main(["derive", str(path), "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["coordinates"] == ["r", "theta"]
    assert report["cyclic"] == ["theta"]
    assert report["classification"]["hamiltonian_is_energy"] is True
    assert report["classification"]["simple"] is True
    assert report["classification"]["rheonomic"] is False
    names = {
        n: sympy.Symbol(n)
        for n in ["r", "theta", "r_dot", "theta_dot", "p_r", "p_theta", "m", "k", "t"]
    }
    m, k, r, thd = names["m"], names["k"], names["r"], names["theta_dot"]
    momentum = sympy.sympify(report["momenta"]["theta"], locals=names)
    assert sympy.simplify(momentum - m * r**2 * thd) == 0
    rddot = sympy.sympify(report["accelerations"]["r"], locals=names)
    assert sympy.simplify(m * rddot - m * r * thd**2 + k / r**2) == 0
    H = sympy.sympify(report["hamiltonian"], locals=names)
    assert sympy.simplify(sympy.diff(H, names["p_r"]) - names["p_r"] / m) == 0
    assert set(report["hamilton_equations"]) == {"r", "theta", "p_r", "p_theta"}
    assert set(report["conserved"]) == {"H", "p_theta"}


def test_derive_readable(tmp_path, capsys):
    path = tmp_path / "pendulum.toml"
    path.write_text(PENDULUM)
    assert main(["derive", str(path)]) == 0
    out = capsys.readouterr().out
    assert "Hamilton's equations" in out and "scleronomic" in out and "θ" in out


def test_user_errors_exit_2_with_one_clear_line(tmp_path):
    path = tmp_path / "bad.toml"
    path.write_text(PENDULUM.replace("cos(theta)", "cos(theta"))
    result = subprocess.run(
        [sys.executable, str(ROOT / "main.py"), "derive", str(path)],
        capture_output=True,
        text=True,
        cwd=ROOT,
    )
    assert result.returncode == 2
    assert result.stderr.strip().splitlines() == [
        f"error: {path}: system.potential: syntax error: '(' was never closed (at position 11)"
    ]


def test_unknown_scene_exits_2(capsys):
    assert main(["derive", "no_such_scene"]) == 2
    assert "no catalogue scene or file named 'no_such_scene'" in capsys.readouterr().err


def test_list(capsys):
    assert main(["list", "--json"]) == 0
    rows = json.loads(capsys.readouterr().out)
    assert isinstance(rows, list)


def test_derive_json_lists_equilibria(tmp_path, capsys):
    path = tmp_path / "pendulum.toml"
    path.write_text(PENDULUM)
    assert main(["derive", str(path), "--json"]) == 0
    equilibria = json.loads(capsys.readouterr().out)["equilibria"]
    by_angle = {round(e["q"]["theta"], 9): e for e in equilibria}
    assert set(by_angle) == {0.0, round(3.141592653589793, 9)}
    assert by_angle[0.0]["stable"] and not by_angle[round(3.141592653589793, 9)]["stable"]
    (omega,) = by_angle[0.0]["frequencies"]
    assert abs(omega - (9.81 / 0.7) ** 0.5) < 1e-9


def test_run_reports_the_constraint_violation_and_writes_the_multipliers(tmp_path, capsys):
    out = tmp_path / "cartesian.csv"
    args = ["run", "cartesian_pendulum", "--t-end", "5", "--samples", "50", "--json"]
    assert main([*args, "--out", str(out)]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["method"] == "constrained_dop853"
    assert 0.0 <= report["max_constraint_violation"] <= 1e-10
    header, *rows = out.read_text().splitlines()
    assert header.split(",") == [
        "t", "x", "y", "x_dot", "y_dot", "p_x", "p_y", "H", "lambda_1",
    ]  # fmt: skip
    t, x, y, x_dot, y_dot, _, _, _, lam = map(float, rows[10].split(","))
    assert 2 * lam == pytest.approx(9.81 * -y + (x * y_dot - y * x_dot) ** 2, rel=1e-9)
    assert main(["run", "simple_pendulum", "--t-end", "1", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["max_constraint_violation"] is None
    assert main(["run", "cartesian_pendulum", "--method", "leapfrog", "--json"]) == 2
    assert "ignore the scene's [constraints]" in capsys.readouterr().err


def test_derive_json_has_the_degrees_of_freedom(capsys):
    assert main(["derive", "cartesian_pendulum", "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["degrees_of_freedom"] == 1
    assert report["constraints"]["holonomic"] == ["-l**2 + x**2 + y**2"]


def test_run_says_when_taylor_runs_in_double_double(capsys):
    """A taylor tolerance below machine epsilon turns on double-double orders 1 and 2:
    ``run`` says so (``arithmetic``), and says ``double`` otherwise."""
    assert main(["run", "harmonic_oscillator", "--method", "taylor", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["arithmetic"] == "double"
    given = ["run", "harmonic_oscillator", "--method", "taylor", "--tol", "1e-16"]
    assert main([*given, "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["arithmetic"] == "double-double"
    assert main(given) == 0
    assert "in double-double" in capsys.readouterr().out


def test_a_crash_in_compiled_code_names_where_it_happened():
    """A command leaves Python's fault handler on: a segmentation fault (here a read at
    address 0, as a crash in Qt's or numba's code) prints the Python stack on stderr
    instead of ending the process with only its status."""
    crash = (
        "import ctypes, sys\nfrom explorer.cli import main\nmain(['list'])\nctypes.string_at(0)\n"
    )
    process = subprocess.run(
        [sys.executable, "-c", crash],
        capture_output=True,
        text=True,
        cwd=Path(__file__).parents[2],
        timeout=120,
    )
    assert process.returncode == -11
    assert "Segmentation fault" in process.stderr and "string_at" in process.stderr


def test_a_figure_left_to_the_exit_does_not_crash_the_process():
    """After a command that started Qt, the entry point ends the process without PySide's
    deletion of what Python still holds: a panel left to the exit in a reference cycle
    (as one whose construction Ctrl+C interrupted) crashed it there with SIGSEGV, after
    the command's work was done (the cycle not collected by then: here, no collection at
    all). The other exit handlers still run, and the output is written whole."""
    script = (
        "import atexit, gc, sys\n"
        "from explorer.app import application\n"
        "from explorer.headless import make_panel\n"
        "from explorer.cli import entry\n"
        "app = application()\n"
        "view = make_panel('phase')\n"
        "view.show()\n"
        "app.processEvents()\n"
        "view.close()\n"
        "gc.disable()\n"
        "cycle = [view, None]\n"
        "cycle[1] = cycle\n"
        "del view, cycle\n"
        "atexit.register(print, 'the exit handlers ran')\n"
        "entry(['list'])\n"
    )
    process = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, cwd=ROOT, timeout=300
    )
    assert process.returncode == 0, (process.returncode, process.stderr[-3000:])
    assert "double_pendulum" in process.stdout
    assert process.stdout.rstrip().endswith("the exit handlers ran")


def test_ctrl_c_before_any_command_ends_quietly(monkeypatch, capsys):
    """A Ctrl+C in ``main``'s first steps (turning the fault handler on imported a module,
    where a SIGINT sent at once landed) or as ``main`` returns is "stopped (Ctrl+C)" and
    status 130, never a traceback."""
    import explorer.cli as cli

    def interrupted(*_args):
        raise KeyboardInterrupt

    monkeypatch.setattr(cli, "_name_crashes", interrupted)
    try:
        assert cli.main(["list"]) == 130
    except KeyboardInterrupt:  # not let through: it would stop the test session
        pytest.fail("Ctrl+C escaped main")
    assert capsys.readouterr().err == "stopped (Ctrl+C)\n"
    monkeypatch.setattr(cli, "main", interrupted)
    ended_qt = []
    monkeypatch.setattr(cli, "_end_qt", ended_qt.append)  # this process may hold a window
    previous = signal.getsignal(signal.SIGINT)
    try:
        with pytest.raises(SystemExit) as ended:
            try:
                cli.entry(["list"])
            except KeyboardInterrupt:
                pytest.fail("Ctrl+C escaped entry")
        assert signal.getsignal(signal.SIGINT) is signal.SIG_IGN  # the status is decided
    finally:
        signal.signal(signal.SIGINT, previous)
    assert ended.value.code == 130 and ended_qt == [130]
    assert capsys.readouterr().err == "stopped (Ctrl+C)\n"
