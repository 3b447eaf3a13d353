"""``lyapunov SCENE``: the spectrum, max, MEGNO, SALI and the end time, as text and
JSON; what it refuses, and why, with status 2."""

import json

import pytest

from explorer.cli import main
from tests.systems.scenes import INVERTED_OSCILLATOR


def _json(capsys, *argv) -> dict:
    assert main(["lyapunov", *argv, "--json"]) == 0
    return json.loads(capsys.readouterr().out)


def test_the_json_has_the_exponents_largest_first_max_megno_sali_and_t_end(tmp_path, capsys):
    path = tmp_path / "saddle.toml"
    path.write_text(INVERTED_OSCILLATOR)
    report = _json(capsys, str(path), "--t-end", "2000")
    assert report["t_end"] == 2000.0 and report["status"] == "ok"
    assert report["exponents"] == sorted(report["exponents"], reverse=True)
    assert abs(report["max"] - 1.0) < 1e-3 and report["max"] == report["exponents"][0]
    assert abs(report["exponents"][1] + 1.0) < 1e-3
    assert report["megno"] > 100 and report["verdict"] == "chaotic"
    assert report["sali"] < 1e-12
    assert report["method"] == "dop853" and report["tol"] == 1e-12
    assert report["energy_error"] < 1e-12  # H0 = 0 at the saddle: the absolute error


def test_a_regular_orbit_by_a_symplectic_method(capsys):
    report = _json(capsys, "henon_heiles", "--t-end", "3000", "--method", "yoshida8", "--dt",
                   "0.05")  # fmt: skip
    assert report["method"] == "yoshida8" and report["dt"] == 0.05
    assert len(report["exponents"]) == 4
    assert abs(report["megno"] - 2.0) < 0.1 and report["verdict"] == "regular"
    assert report["max"] < 3e-3
    assert report["energy_error"] < 1e-8  # the orbit itself, by the same steps


def test_a_chaotic_start_given_on_the_command_line(capsys):
    # E = 1/6 on the x = 0 section: p_x = sqrt(2 E - p_y^2) at y = 0
    start = f"x=0,y=0,p_x={(1 / 3) ** 0.5!r},p_y=0"
    report = _json(capsys, "henon_heiles", "--t-end", "2000", "--start", start)
    assert report["max"] > 0.05 and report["megno"] > 20 and report["verdict"] == "chaotic"
    assert abs(report["megno"] - report["max"] * 2000 / 2) < 0.2 * report["megno"]


def test_a_ten_link_chain_in_matrix_form(capsys):
    report = _json(capsys, "pendulum_chain", "--t-end", "10")
    assert len(report["exponents"]) == 20 and abs(report["sum"]) < 1e-8
    assert report["energy_error"] < 1e-8


def test_the_text_names_every_number(capsys):
    assert main(["lyapunov", "harmonic_oscillator", "--t-end", "500", "--exponents", "1"]) == 0
    out = capsys.readouterr().out
    lines = out.splitlines()
    for key in ("exponents", "max", "megno", "sali", "t_end"):  # the keys of --json
        assert any(line.startswith(f"{key}: ") for line in lines), key
    assert "t_end: 500\n" in out and "periodic" in out


@pytest.mark.parametrize(
    "argv, words",
    [
        (["cartesian_pendulum"], ["not available", "[constraints]"]),
        (["henon_heiles", "--method", "logh_yoshida6"], ["logh_yoshida6", "fictitious time"]),
        (["henon_heiles", "--method", "radau"], ["scipy"]),
        (["double_pendulum", "--method", "yoshida8"], ["separable"]),
        (["henon_heiles", "--method", "nope"], ["unknown method"]),
        (["henon_heiles", "--t-end", "inf"], ["--t-end"]),
        (["henon_heiles", "--t-end", "-1"], ["--t-end"]),
        (["henon_heiles", "--t-end", "1e-320"], ["--t-end", "1e-300"]),
        (["henon_heiles", "--exponents", "9"], ["exponents", "1 to 4"]),
        (["henon_heiles", "--tol", "1e-9", "--method", "rk4"], ["rk4", "--dt"]),
        (["no_such_scene"], ["no_such_scene"]),
        (["henon_heiles", "--start", "z=1"], ["--start", "unknown name 'z'"]),
        (["henon_heiles", "--start", "x"], ["--start", "name=value"]),
    ],
)
def test_what_cannot_be_measured_is_refused_with_the_reason(capsys, argv, words):
    assert main(["lyapunov", *argv]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and err.count("\n") == 1
    for word in words:
        assert word in err


def test_sigterm_prints_the_estimates_so_far():
    import signal
    import subprocess
    import sys

    from tests.explorer.test_cli_stops_and_outputs import LAUNCH, ROOT

    process = subprocess.Popen(
        [sys.executable, "-c", LAUNCH, "lyapunov", "double_pendulum", "--t-end", "1e9",
         "--json"],
        stderr=subprocess.PIPE, stdout=subprocess.PIPE, text=True, cwd=ROOT,
    )  # fmt: skip
    try:
        line = process.stderr.readline()  # after the first estimates
        assert line.startswith("integrating to t = 1e+09"), line
        process.send_signal(signal.SIGTERM)
        stdout, stderr = process.communicate(timeout=300)
    finally:
        if process.poll() is None:
            process.kill()
            process.wait()
    assert process.returncode == 128 + signal.SIGTERM, stderr
    report = json.loads(stdout)
    assert report["status"] == "interrupted" and "SIGTERM" in report["message"]
    assert 0 < report["t_end"] < 1e9 and report["max"] > 0
    assert "Traceback" not in stderr
