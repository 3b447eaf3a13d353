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


def test_taylor_map_refuses_a_step(tmp_path, capsys):
    argv = ["chaosmap", "henon_heiles", "--grid", "4x4", "--method", "taylor", "--dt", "0.1"]
    assert main([*argv, "--out", str(tmp_path / "x.npz")]) == 2
    assert "tolerance, not a step" in capsys.readouterr().err
