"""``chaosmap --method taylor``: adaptive Taylor orbits with MEGNO in their series."""

import json

import numpy as np

from explorer.cli import main


def test_taylor_map_json_and_npz_against_the_default_map(tmp_path, capsys):
    """A 12 x 10 Hénon–Heiles map at E = 1/8 to t = 300 with taylor: the report names
    the method and its tolerance (no step), and its verdicts are the default map's
    (yoshida4) but for a few boundary cells."""
    runs = {}
    for method in ("taylor", "yoshida4"):
        out = tmp_path / f"{method}.npz"
        argv = ["chaosmap", "henon_heiles", "--grid", "12x10", "--energy", "0.125"]
        assert main([*argv, "--t-end", "300", "--method", method, "--out", str(out), "--json"]) == 0
        runs[method] = (json.loads(capsys.readouterr().out), np.load(out))
    report, data = runs["taylor"]
    assert report["method"] == "taylor" and report["dt"] is None
    assert report["tol"] == np.finfo(float).eps and report["t_end"] == 300.0
    other = runs["yoshida4"][1]
    done = (data["status"] == 0) & (other["status"] == 0)
    assert done.sum() == report["grid"]["orbits"] > 40
    differ = np.mean((data["megno"][done] > 4) != (other["megno"][done] > 4))
    assert differ <= 0.08, differ


def test_a_looser_tolerance_and_the_options_that_do_not_fit(tmp_path, capsys):
    out = str(tmp_path / "x.npz")
    argv = ["chaosmap", "henon_heiles", "--grid", "4x4", "--t-end", "50", "--out", out]
    assert main([*argv, "--method", "taylor", "--tol", "1e-10", "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["method"] == "taylor" and report["tol"] == 1e-10
    assert main([*argv, "--method", "taylor", "--dt", "0.1"]) == 2
    assert "tolerance, not a step" in capsys.readouterr().err
    assert main([*argv, "--method", "yoshida4", "--tol", "1e-10"]) == 2
    assert "--tol goes with --method taylor" in capsys.readouterr().err
    assert main([*argv, "--method", "taylor", "--tol", "1e-20"]) == 2
    assert "between 1e-16 and 1" in capsys.readouterr().err
