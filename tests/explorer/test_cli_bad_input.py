"""Hostile files and options on the command line: exit 2 with a message, never a traceback.

The named cases of issue 11 first, then two property tests (hypothesis): random TOML
documents given to ``derive``, and random option values given to ``run``, must end with
status 0, 1 (a run that stopped and said why) or 2 (a user error), within a time bound.
"""

from __future__ import annotations

import csv
import math
import os
import time
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from explorer.cli import main

ROOT = Path(__file__).resolve().parents[2]
HARMONIC = (ROOT / "resources" / "scenes" / "harmonic_oscillator.toml").read_text()
PLANETARY = (ROOT / "resources" / "scenes" / "planetary_motion.toml").read_text()
_EXPLORE = int(os.environ.get("FUZZ_EXAMPLES", "0"))


def write(tmp_path: Path, text: str, name: str = "scene.toml") -> str:
    path = tmp_path / name
    path.write_text(text)
    return str(path)


def user_error(capsys, *argv: str) -> str:
    code = main(list(argv))
    err = capsys.readouterr().err
    assert code == 2, err
    assert err.startswith("error: ") and "Traceback" not in err, err
    return err


# -- files -----------------------------------------------------------------------------------


@pytest.mark.parametrize("command", ["derive", "run"])
def test_binary_and_deep_files(tmp_path, capsys, command):
    binary = tmp_path / "binary.toml"
    binary.write_bytes(os.urandom(3000) + b"\xc3\x28")
    assert "not a text file" in user_error(capsys, command, str(binary))
    deep = write(tmp_path, "a = " + "[" * 600 + "]" * 600 + "\n", "deep.toml")
    assert "nested" in user_error(capsys, command, deep)


@pytest.mark.parametrize(
    "change, words",
    [
        (("links = [", 'links = [[["a"], "a"], '), ["drawing.links[0]"]),
        (("t_end = 20.0", 't_end = "abc"'), ["view.t_end"]),
        (('phase = ["x", "p_x"]', 'phase = ["zz", 5]'), ["view.phase"]),
        (("m = 1.0", "m = 0.0"), ["singular", "zero parameters: m"]),
        (('potential = "k*x**2/2"', 'potential = "sqrt(-k)*x"'), ["not a number"]),
        (('potential = "k*x**2/2"', 'potential = "x*(((10**-60)**100)**100)**100"'), ["power"]),
    ],
)
def test_each_bad_scene_is_a_user_error(tmp_path, capsys, change, words):
    old, new = change
    assert old in HARMONIC
    path = write(tmp_path, HARMONIC.replace(old, new, 1))
    start = time.process_time()
    message = user_error(capsys, "run", path, "--t-end", "1")
    assert time.process_time() - start < 30.0
    for word in words:
        assert word in message, message


@pytest.mark.parametrize("r", ["0.0", "1e-300"])
def test_kepler_from_the_centre_is_refused(tmp_path, capsys, r):
    path = write(tmp_path, PLANETARY.replace("r = 1.0", f"r = {r}", 1))
    assert "singular" in user_error(capsys, "run", path)


def test_a_hamiltonian_with_a_quartic_kinetic_term_derives(tmp_path, capsys):
    text = 'title = "q"\n[system]\ncoordinates = ["x"]\nhamiltonian = "p_x**4/4 + x**2/2"\n'
    assert main(["derive", write(tmp_path, text + "[initial]\nx = 1.0\np_x = 0.5\n")]) == 0
    assert "no small-oscillation frequency" in capsys.readouterr().out


# -- options -----------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "options, words",
    [
        (["--method", "dop853", "--tol", "1e-300"], ["--tol 1e-300"]),
        (["--method", "dop853", "--tol", "inf"], ["--tol"]),
        (["--method", "dop853", "--tol", "2"], ["between"]),
        (["--dt", "1e300"], ["longer than the whole run"]),
        (["--dt", "1e-15", "--t-end", "1000"], ["resolution"]),
        (["--dt", "inf"], ["--dt"]),
        (["--t-end", "nan"], ["--t-end"]),
        (["--t-end", "inf"], ["--every"]),
        (["--t-end", "-1"], ["--t-end"]),
        (["--out", "/nonexistent/dir/x.csv"], ["--out"]),
        (["--out", "x.txt"], [".csv or .npz"]),
    ],
)
def test_run_options_checked_before_running(capsys, options, words):
    start = time.process_time()
    message = user_error(capsys, "run", "harmonic_oscillator", *options)
    assert time.process_time() - start < 30.0
    for word in words:
        assert word in message, message


def test_export_refuses_an_endless_run(tmp_path, capsys):
    out = str(tmp_path / "x.png")
    assert "finite" in user_error(
        capsys, "export", "harmonic_oscillator", "--t-end", "inf", "--out", out
    )
    assert not Path(out).exists()


def test_an_endless_run_streams_to_disk_until_its_budget(tmp_path, capsys):
    out = tmp_path / "endless.csv"
    code = main(
        ["run", "harmonic_oscillator", "--t-end", "inf", "--every", "1.0", "--out", str(out)]
        + ["--method", "leapfrog", "--dt", "0.01", "--max-steps", "50000"]
    )
    assert code == 1 and "budget" in capsys.readouterr().err
    with out.open() as handle:
        rows = list(csv.reader(handle))
    assert rows[0][:2] == ["t", "x"]
    times = [float(row[0]) for row in rows[1:]]
    assert len(times) == 501 and times[0] == 0.0
    assert all(abs(t - k) < 0.011 for k, t in enumerate(times))
    x = [float(row[1]) for row in rows[1:]]
    assert all(abs(xi - math.cos(ti)) < 1e-2 for xi, ti in zip(x, times, strict=True))  # leapfrog


# -- properties ----------------------------------------------------------------------------------

EXPRESSIONS = st.sampled_from(
    [
        "m*x_dot**2/2", "k*x**2/2", "x_dot**2/2 - x**2/2", "p_x**2/2 + x**4", "1/x", "sqrt(x)",
        "log(-1)", "x_dot", "0", "sin(", "__import__('os')", "x**x**x**x", "(x+1)**100",
        "1e308*1e308", "y_dot**2/2", "x*y_dot - y*x_dot", "m*(x_dot**2 + y_dot**2)/2",
        "t*x", "cos(w*t)*x", "m", "", "  ", "p_y",
    ]
)  # fmt: skip
LEAVES = (
    st.booleans()
    | st.integers(-(10**30), 10**30)
    | st.floats(allow_nan=True, allow_infinity=True)
    | EXPRESSIONS
    | st.text(max_size=8)
)
VALUES = st.recursive(
    LEAVES,
    lambda inner: (
        st.lists(inner, max_size=3)
        | st.dictionaries(
            st.sampled_from(["x", "y", "m", "k", "a", "bob", "origin"]), inner, max_size=3
        )
    ),
    max_leaves=6,
)
BASE = {
    "title": "Fuzz",
    "system": {
        "coordinates": ["x", "y"],
        "parameters": {"m": 1.0, "k": 2.0},
        "kinetic": "m*(x_dot**2 + y_dot**2)/2",
        "potential": "k*(x**2 + y**2)/2 + x*y**2",
    },
    "effects": {"dissipation": "x_dot**2/10", "forces": {"x": "cos(t)"}},
    "initial": {"x": 0.1, "y_dot": 0.2},
    "drawing": {"points": {"bob": ["x", "y"]}, "links": [["origin", "bob"]], "trace": ["bob"]},
    "view": {"t_end": 5.0, "phase": ["x", "p_x"], "ranges": {"x": [-1.0, 1.0]}},
}
PATHS = st.sampled_from(
    [(table, key) for table, content in BASE.items() if isinstance(content, dict)
     for key in [*content, "junk"]] + [("title", None), ("system", None), ("view", None)]
)  # fmt: skip
MUTATIONS = st.lists(
    st.tuples(PATHS, st.sampled_from(["set", "delete"]), VALUES | EXPRESSIONS), max_size=3
)


def mutated(mutations) -> dict:
    """``BASE`` with some entries replaced by random values or deleted."""
    import copy

    document = copy.deepcopy(BASE)
    for (table, key), action, value in mutations:
        if key is None:
            if action == "delete":
                document.pop(table, None)
            else:
                document[table] = value
        elif isinstance(document.get(table), dict):
            if action == "delete":
                document[table].pop(key, None)
            else:
                document[table][key] = value
    return document


def _toml(document: dict) -> str:
    from systems.scene import _key, _value

    top = [f"{_key(k)} = {_value(v)}" for k, v in document.items() if not isinstance(v, dict)]
    for name, table in document.items():
        if isinstance(table, dict):
            top += [f"[{name}]"] + [f"{_key(k)} = {_value(v)}" for k, v in table.items()]
    return "\n".join(top) + "\n"


FUZZ = settings(
    deadline=None,
    derandomize=not _EXPLORE,
    max_examples=_EXPLORE or 60,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture],
    database=None,
)


@FUZZ
@given(mutations=MUTATIONS, cut=st.integers(0, 400))
def test_random_scenes_derive_or_are_refused(tmp_path_factory, mutations, cut):
    text = _toml(mutated(mutations))
    if cut % 5 == 0:  # a file cut short, as an interrupted save would leave it
        text = text[: cut % max(len(text), 1)]
    path = write(tmp_path_factory.mktemp("fuzz"), text)
    start = time.process_time()
    code = main(["derive", path])
    assert code in (0, 2)
    assert time.process_time() - start < 30.0


NUMBERS = st.sampled_from(["0", "-1", "1e-300", "1e-15", "0.01", "0.5", "1", "1e300", "inf", "nan"])
OPTION_VALUES = {
    "--dt": NUMBERS,
    "--tol": NUMBERS,
    "--t-end": NUMBERS,
    "--every": NUMBERS,
    "--samples": st.sampled_from(["0", "1", "7", "100000", "-5"]),
    "--max-steps": st.sampled_from(["0", "1", "1000", "200000", "-1"]),
    "--energy-tolerance": NUMBERS | st.just("off"),
    "--method": st.sampled_from(
        [
            "dop853",
            "leapfrog",
            "radau",
            "gauss_legendre6",
            "yoshida8",
            "logh_leapfrog",
            "rk4",
            "euler",
            "no such method",
        ]
    ),
}
OPTIONS = st.lists(
    st.sampled_from(sorted(OPTION_VALUES)).flatmap(
        lambda flag: st.tuples(st.just(flag), OPTION_VALUES[flag])
    ),
    max_size=4,
)  # fmt: skip


@FUZZ
@given(
    scene=st.sampled_from(["harmonic_oscillator", "damped_pendulum", "planetary_motion"]),
    options=OPTIONS,
)
def test_random_run_options_run_or_are_refused(tmp_path_factory, scene, options):
    argv = ["run", scene]
    for flag, value in dict(options).items():
        argv += [flag, value]
    if "--t-end" not in argv:
        argv += ["--t-end", "2"]
    if "--max-steps" not in argv:
        argv += ["--max-steps", "200000"]
    start = time.process_time()
    try:
        code = main(argv)
    except SystemExit as exc:  # argparse: a value that is not a number
        code = exc.code
    assert code in (0, 1, 2)
    assert time.process_time() - start < 60.0
