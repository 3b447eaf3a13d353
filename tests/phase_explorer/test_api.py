"""The API's values (frozen, shaped as documented) and its refusals: the command line's
sentences, with the keyword's name where the command line names its option."""

from __future__ import annotations

import dataclasses
import re

import numpy as np
import pytest

import phase_explorer as pe
from explorer.cli import main


def cli_error(capsys, *argv: str) -> str:
    """The command line's message for ``argv`` (exit status 2), without ``error: ``."""
    assert main(list(argv)) == 2
    return capsys.readouterr().err.strip().removeprefix("error: ")


def api_error(call) -> str:
    with pytest.raises(pe.UsageError) as caught:
        call()
    assert isinstance(caught.value, ValueError)
    return str(caught.value)


def keywords(text: str) -> str:
    """The command line's option names as the API's keywords: --t-end -> t_end."""
    return re.sub(r"--([a-z][a-z-]*)", lambda m: m.group(1).replace("-", "_"), text)


@pytest.mark.parametrize(
    ("argv", "call"),
    [
        (
            ["run", "simple_pendulum", "--method", "leapfrog", "--tol", "1e-8"],
            lambda s: s.run(method="leapfrog", tol=1e-8),
        ),
        (["run", "simple_pendulum", "--samples", "0"], lambda s: s.run(samples=0)),
        (["run", "simple_pendulum", "--method", "rk5"], lambda s: s.run(method="rk5")),
        (
            ["run", "simple_pendulum", "--method", "dop853", "--dt", "0.1"],
            lambda s: s.run(method="dop853", dt=0.1),
        ),
        (["run", "simple_pendulum", "--every", "-1"], lambda s: s.run(every=-1.0)),
        (
            ["run", "simple_pendulum", "--energy-tolerance", "lots"],
            lambda s: s.run(energy_tolerance="lots"),
        ),
        (
            ["lyapunov", "simple_pendulum", "--method", "radau"],
            lambda s: s.lyapunov(method="radau"),
        ),
        (["lyapunov", "simple_pendulum", "--t-end", "0"], lambda s: s.lyapunov(t_end=0.0)),
        (
            ["lyapunov", "simple_pendulum", "--start", "phi=1"],
            lambda s: s.lyapunov(start={"phi": 1.0}),
        ),
    ],
)
def test_the_pendulum_is_refused_as_the_command_line_refuses_it(capsys, argv, call):
    pendulum = pe.load("simple_pendulum")
    assert api_error(lambda: call(pendulum)) == keywords(cli_error(capsys, *argv))


def test_chaos_maps_and_diagrams_are_refused_alike(capsys, tmp_path):
    out = str(tmp_path / "map.npz")
    henon = pe.load("henon_heiles")
    cases = [
        (["--over", "x,q"], dict(over=("x", "q"))),
        (["--indicator", "sali"], dict(indicator="sali")),
        (["--over", "x,y", "--energy", "0.1"], dict(over=("x", "y"), energy=0.1)),
        (["--ranges", "x=0:1"], dict(ranges={"x": (0.0, 1.0)})),
    ]
    for options, keywords_ in cases:
        argv = ("chaosmap", "henon_heiles", "--grid", "4x4", *options, "--out", out)
        said = cli_error(capsys, *argv)
        asked = api_error(lambda keywords_=keywords_: henon.chaosmap((4, 4), **keywords_))
        assert asked == keywords(said)
    driven = pe.load("driven_damped_pendulum")
    said = cli_error(
        capsys, "bifurcation", "driven_damped_pendulum", "--parameter", "A", "--range",
        "1:1.1:3", "--variable", "q", "--out", out,
    )  # fmt: skip
    assert api_error(lambda: driven.bifurcation("A", [1.0], variable="q")) == keywords(said)
    said = cli_error(
        capsys, "bifurcation", "driven_damped_pendulum", "--parameter", "Q", "--range",
        "1:1.1:3", "--out", out,
    )  # fmt: skip
    assert api_error(lambda: driven.bifurcation("Q", [1.0])) == said


def test_a_trajectory_is_frozen_and_named():
    orbit = pe.load("harmonic_oscillator").run(t_end=2.0, samples=20)
    assert orbit.t.shape == (21,) and orbit.y.shape == (21, 2 * orbit.n)
    assert orbit.qdot.shape == (21, orbit.n) and orbit.H.shape == (21,)
    assert orbit.t[0] == 0.0 and orbit.t[-1] == 2.0
    q = orbit.columns[1]
    np.testing.assert_array_equal(orbit[q], orbit.q[:, 0])
    with pytest.raises(dataclasses.FrozenInstanceError):
        orbit.status = "x"  # type: ignore[misc]
    with pytest.raises(KeyError, match="the columns are"):
        orbit["nothing"]


def test_a_scene_in_text_a_path_and_a_name_load_alike(tmp_path):
    from systems.scene import scene_path

    text = scene_path("harmonic_oscillator").read_text(encoding="utf-8")
    copy = tmp_path / "mine.toml"
    copy.write_text(text, encoding="utf-8")
    by_name, by_path, by_text = (
        pe.load("harmonic_oscillator"), pe.load(copy), pe.load(text)
    )  # fmt: skip
    assert by_name.derive().hamiltonian == by_path.derive().hamiltonian
    assert by_text.derive().hamiltonian == by_name.derive().hamiltonian
    assert by_path.name == "mine"
    with pytest.raises(pe.SceneError, match="no catalogue scene"):
        pe.load("no_such_scene")
    with pytest.raises(pe.UsageError, match="unknown parameter"):
        by_name.with_parameters(nothing=1.0)


def test_a_chaos_map_over_two_variables_keeps_the_rest_of_the_start():
    oscillators = pe.load("coupled_oscillators")
    names = oscillators.state_names
    found = oscillators.chaosmap(
        (3, 2), over=(names[0], names[1]), ranges={names[0]: (-1, 1)}, t_end=20
    )
    assert found.megno.shape == (2, 3) and found.axes == (names[0], names[1])
    np.testing.assert_array_equal(found.xs, [-1.0, 0.0, 1.0])
    assert found.energy is None and found.chaotic_fraction == 0.0


def test_a_section_says_how_each_orbit_ended_and_its_energy():
    henon = pe.load("henon_heiles")
    two = henon.section(t_end=50, starts=[{"y": 0.1}, {"y": 0.2}])
    assert two.status == ("ok", "ok") and two.energy is None  # two energies
    assert set(two.orbit) <= {0, 1} and two.points().shape == (len(two.t), 2)
    on = henon.section(t_end=50, points=[(0.1, 0.0)], energy=0.1)
    assert on.energy == pytest.approx(0.1) and on.status == ("ok",)
    with pytest.raises(pe.UsageError, match="give points"):
        henon.section(energy=0.1)
    with pytest.raises(pe.UsageError, match="two degrees of freedom"):
        pe.load("simple_pendulum").section()
    strobe = pe.load("driven_damped_pendulum").section(t_end=60)
    assert strobe.kind == "stroboscopic"
    np.testing.assert_allclose(np.diff(strobe.t), 3 * np.pi, rtol=1e-12)


def test_the_api_and_the_command_line_compute_the_same_map_and_diagram(tmp_path, capsys):
    out = tmp_path / "map.npz"
    argv = ["chaosmap", "henon_heiles", "--grid", "5x4", "--energy", "0.125", "--t-end", "40"]
    assert main([*argv, "--out", str(out), "--json"]) == 0
    capsys.readouterr()
    said = np.load(out)
    found = pe.load("henon_heiles").chaosmap((5, 4), energy=0.125, t_end=40)
    np.testing.assert_array_equal(found.megno, said["megno"])
    np.testing.assert_array_equal(found.lyapunov, said["lyapunov"])
    np.testing.assert_array_equal(found.xs, said["x"])

    out = tmp_path / "diagram.npz"
    argv = ["bifurcation", "driven_damped_pendulum", "--parameter", "A", "--range", "1.0:1.1:4"]
    assert main([*argv, "--transient", "300", "--samples", "8", "--out", str(out)]) == 0
    capsys.readouterr()
    said = np.load(out)
    diagram = pe.load("driven_damped_pendulum").bifurcation(
        "A", np.linspace(1.0, 1.1, 4), transient=300, samples=8
    )
    np.testing.assert_array_equal(diagram.samples, said["samples"])
    # a tolerance reaches taylor's steps from either side, and changes them
    assert main([*argv, "--transient", "30", "--samples", "4", "--tol", "1e-9",
                 "--out", str(out)]) == 0  # fmt: skip
    capsys.readouterr()
    said = np.load(out)
    driven = pe.load("driven_damped_pendulum")
    looser = driven.bifurcation("A", np.linspace(1.0, 1.1, 4), transient=30, samples=4, tol=1e-9)
    np.testing.assert_array_equal(looser.samples, said["samples"])
    tight = driven.bifurcation("A", np.linspace(1.0, 1.1, 4), transient=30, samples=4)
    assert looser.method == tight.method == "taylor"
    assert not np.array_equal(looser.samples, tight.samples)
    assert np.allclose(looser.samples, tight.samples, atol=1e-6)
