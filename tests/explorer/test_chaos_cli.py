"""``chaosmap`` and ``bifurcation``: what they write and print, and the mistakes they
refuse with status 2 and a message naming what to fix."""

import json

import numpy as np
import pytest

from explorer.cli import main


def _json(capsys, *argv) -> dict:
    assert main([*argv, "--json"]) == 0
    return json.loads(capsys.readouterr().out)


def test_chaosmap_json_has_the_fraction_threshold_time_and_grid(tmp_path, capsys):
    out = tmp_path / "map.npz"
    report = _json(capsys, "chaosmap", "henon_heiles", "--grid", "16x12", "--energy", "0.125",
                   "--t-end", "300", "--out", str(out))  # fmt: skip
    assert report["indicator"] == "megno" and report["threshold"] == 4.0
    assert 0.2 < report["chaotic_fraction"] < 0.8 and report["wall_s"] > 0
    grid = report["grid"]
    assert (grid["x"], grid["y"], grid["nx"], grid["ny"]) == ("y", "p_y", 16, 12)
    assert grid["energy"] == 0.125 and grid["section"] == {"coordinate": "x", "value": 0.0}
    assert report["t_end"] == pytest.approx(300.0) and report["method"] == "yoshida4"
    data = np.load(out)
    assert data["megno"].shape == (12, 16) and data["x"].shape == (16,)
    done = data["status"] == 0
    assert done.sum() == grid["orbits"] and np.isnan(data["megno"][~done]).all()
    assert np.mean(data["megno"][done] > 4.0) == report["chaotic_fraction"]


def test_chaosmap_lyapunov_csv_over_two_variables(tmp_path, capsys):
    out = tmp_path / "map.csv"
    report = _json(capsys, "chaosmap", "double_pendulum", "--grid", "4x3", "--over",
                   "theta1,theta2", "--ranges", "theta1=-2:2,theta2=-2:2", "--t-end", "20",
                   "--indicator", "lyapunov", "--out", str(out))  # fmt: skip
    assert report["grid"]["energy"] is None and report["grid"]["x"] == "theta1"
    assert report["method"] == "gauss_legendre4" and report["threshold"] > 0
    rows = out.read_text().splitlines()
    assert rows[0] == "theta1,theta2,megno,lyapunov,megno_now,status" and len(rows) == 13


def test_chaosmap_png(tmp_path, capsys):
    out = tmp_path / "map.png"
    assert main(["chaosmap", "henon_heiles", "--grid", "8x8", "--t-end", "50", "--out",
                 str(out)]) == 0  # fmt: skip
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    text = capsys.readouterr().out
    assert "chaotic fraction" in text and "wrote" in text


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["henon_heiles", "--grid", "10by10"], "--grid must be N x M"),
        (["henon_heiles", "--grid", "1x10"], "at least 2 starts a side"),
        (["henon_heiles", "--indicator", "sali"], "--indicator is megno or lyapunov"),
        (["henon_heiles", "--over", "x,y", "--energy", "0.1"], "has none"),
        (["henon_heiles", "--over", "x,q"], "--over takes two different state variables"),
        (["henon_heiles", "--ranges", "x=0:1"], "the section's axes are y and p_y"),
        (["henon_heiles", "--ranges", "y=1:0"], "low end must be below"),
        (["henon_heiles", "--energy", "-1"], "no start of the grid lies on the section"),
        (["henon_heiles", "--method", "dop853"], "fixed-step methods"),
        (["simple_pendulum"], "--over NAME,NAME"),
        (["henon_heiles", "--t-end", "inf"], "--t-end must be a positive finite time"),
    ],
)
def test_chaosmap_mistakes(tmp_path, capsys, argv, message):
    assert main(["chaosmap", *argv, "--out", str(tmp_path / "m.npz")]) == 2
    assert message in capsys.readouterr().err


def test_chaosmap_output_is_checked_before_the_work(tmp_path, capsys):
    assert main(["chaosmap", "henon_heiles", "--out", str(tmp_path / "m.txt")]) == 2
    assert ".png, .npz or .csv" in capsys.readouterr().err
    assert main(["chaosmap", "henon_heiles", "--out", str(tmp_path / "no" / "m.png")]) == 2


def test_bifurcation_npz_and_json(tmp_path, capsys):
    out = tmp_path / "orbit.npz"
    report = _json(capsys, "bifurcation", "driven_damped_pendulum", "--parameter", "A",
                   "--range", "1.06:1.07:3", "--transient", "20000", "--samples", "8",
                   "--start", f"theta={-np.pi / 2!r},theta_dot=0", "--out", str(out))  # fmt: skip
    assert report["periods"] == [1, 1, 2]  # period 2 from 1.0663
    assert report["drive_period"] == pytest.approx(3 * np.pi)
    assert report["method"] == "taylor" and report["variable"] == "p_theta"
    assert report["tol"] == np.finfo(float).eps and report["steps_per_period"] is None
    assert len(report["steps"]) == 3 and min(report["steps"]) > 2123 * 10
    assert "tolerance" in report["checked"] and "not checked" in report["checked"]
    assert report["transient_periods"] == 2123  # 20000 / 3 pi, rounded up
    data = np.load(out)
    assert data["samples"].shape == (3, 8, 2) and np.allclose(data["values"], [1.06, 1.065, 1.07])


def test_bifurcation_png(tmp_path, capsys):
    out = tmp_path / "orbit.png"
    assert main(["bifurcation", "driven_damped_pendulum", "--parameter", "A", "--range",
                 "1.0:1.5:20", "--transient", "100", "--out", str(out)]) == 0  # fmt: skip
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert "orbit diagram over A" in capsys.readouterr().out


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["driven_damped_pendulum", "--parameter", "Q", "--range", "1:2:3"], "no parameter 'Q'"),
        (["henon_heiles", "--parameter", "A", "--range", "1:2:3"], "does not depend on t"),
        (["driven_damped_pendulum", "--parameter", "A", "--range", "1:2"], "--range takes A:B:N"),
        (["driven_damped_pendulum", "--parameter", "A", "--range", "1:1:5"], "two different ends"),
        (["driven_damped_pendulum", "--parameter", "A", "--range", "1:2:3", "--variable", "x"],
         "--variable is one of theta, p_theta"),
        (["driven_damped_pendulum", "--parameter", "A", "--range", "1:2:3", "--samples", "0"],
         "samples per value"),
        (["driven_damped_pendulum", "--parameter", "A", "--range", "1:2:3", "--method", "rk4",
          "--tol", "1e-9"], "rk4 takes a number of steps a period, not a tolerance"),
        (["driven_damped_pendulum", "--parameter", "A", "--range", "1:2:3",
          "--steps-per-period", "400"], "taylor takes a tolerance, not a number of steps"),
    ],
)  # fmt: skip
def test_bifurcation_mistakes(tmp_path, capsys, argv, message):
    assert main(["bifurcation", *argv, "--out", str(tmp_path / "b.npz")]) == 2
    assert message in capsys.readouterr().err


@pytest.mark.parametrize("command", ["chaosmap", "bifurcation"])
def test_a_malformed_dask_value_is_refused_before_the_work(tmp_path, capsys, command):
    argv = ["henon_heiles"] if command == "chaosmap" else ["driven_damped_pendulum",
            "--parameter", "A", "--range", "1:1.1:3"]  # fmt: skip
    assert main([command, *argv, "--out", str(tmp_path / "m.npz"), "--dask", "host:8786"]) == 2
    err = capsys.readouterr().err
    assert "--dask takes auto" in err and "tcp://HOST:PORT, not 'host:8786'" in err
    assert "orbits" not in err  # refused before the work was announced


@pytest.mark.parametrize("command", ["chaosmap", "bifurcation"])
def test_dask_without_the_extra_names_it(tmp_path, capsys, monkeypatch, command):
    import sys

    monkeypatch.setitem(sys.modules, "distributed", None)  # import distributed fails
    argv = ["henon_heiles"] if command == "chaosmap" else ["driven_damped_pendulum",
            "--parameter", "A", "--range", "1:1.1:3"]  # fmt: skip
    assert main([command, *argv, "--out", str(tmp_path / "m.npz"), "--dask", "auto"]) == 2
    assert 'an optional extra that is not installed: pip install -e ".[dask]"' in (
        capsys.readouterr().err
    )


class _Terminal:
    """A text stream that says it is a terminal."""

    def __init__(self):
        import io

        self.buffer = io.StringIO()
        self.write = self.buffer.write
        self.flush = self.buffer.flush

    def isatty(self) -> bool:
        return True


def test_the_progress_bar_is_drawn_on_a_terminal_only_and_never_with_json():
    import io

    from explorer.commands.progress import terminal_progress

    terminal = _Terminal()
    with terminal_progress("orbits", stream=terminal) as progress:
        progress(256, 1000)
        progress(1000, 1000)
    assert "orbits" in terminal.buffer.getvalue() and "1000/1000" in terminal.buffer.getvalue()
    with terminal_progress("orbits", stream=_Terminal(), json_output=True) as progress:
        assert progress is None
    with terminal_progress("orbits", stream=io.StringIO()) as progress:
        assert progress is None
