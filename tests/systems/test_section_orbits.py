"""Section portraits in SIMD batches (``systems.section_orbits``) against single runs."""

from __future__ import annotations

import numpy as np
import pytest

from systems.compiled import compile_system
from systems.mechanics import derive
from systems.scene import load_scene
from systems.section import Section
from systems.section_orbits import default_starts, section_portrait
from systems.simulation import Run

EPS = float(np.finfo(float).eps)


def _compiled(name):
    return compile_system(derive(load_scene(name)), ("rhs", "hamiltonian"))


def _single_run_crossings(compiled, y0, section, t_end, period=None):
    """The crossings a single taylor ``Run`` locates on its own series."""
    run = Run(
        compiled, method="taylor", tol=EPS, y0=y0, t_end=t_end,
        section=(section.coordinate, section.value, 1), max_points=8,
    )  # fmt: skip
    times, states = [], []
    while not run.finished:
        block = run.advance(1.0)
        times.extend(block.events_t)
        states.extend(block.events_y)
        assert block.status in ("running", "ok"), block.message
    return np.array(times), np.array(states).reshape(-1, len(y0)), run.steps


def test_henon_heiles_portrait_is_the_single_runs_crossings():
    """11 orbits of Hénon–Heiles at E = 1/8 (a full SIMD batch and a part one on any CPU)
    to t = 300 in batches: each orbit's crossings of x = 0 (p_x > 0) are those a single
    taylor run finds on its own series, to round-off in time and state, with the same
    steps; every crossing is on the section and at the energy."""
    compiled = _compiled("henon_heiles")
    section = Section(0, 0.0, 1)
    E = 1 / 8
    starts = default_starts(compiled, section, E, 11)
    assert starts.shape == (11, 4)
    portrait = section_portrait(compiled, section, E, starts, t_end=300.0)
    assert portrait.method == "taylor" and portrait.trusted.all(), portrait.messages
    assert portrait.status == ["ok"] * 11 and np.all(portrait.reached == 300.0)
    assert portrait.energy_error.max() < 1e-12
    for r, y0 in enumerate(starts):
        t, y, steps = _single_run_crossings(compiled, y0, section, 300.0)
        assert portrait.steps[r] == steps, r
        assert len(t) == len(portrait.t[r]) > 20, r
        assert np.abs(portrait.t[r] - t).max() <= 1e-12 * 300, r
        assert np.abs(portrait.y[r] - y).max() <= 1e-12, r
        assert np.abs(portrait.y[r][:, 0]).max() <= 1e-15
        assert (portrait.y[r][:, 2] > 0).all()
        H = compiled.hamiltonian(0.0, portrait.y[r])
        assert np.abs(H - E).max() < 1e-13


def test_points_on_the_section_capped_crossings_and_untrusted_orbits():
    """Starts given as (y, p_y) points (a point outside the energy's region left out);
    an orbit stops when it has its crossings; an orbit that escapes (y = 5: beyond the
    saddles V falls without bound and y runs off to infinity in finite time) is not
    trusted, nor is any orbit under an energy tolerance below what the runs keep."""
    compiled = _compiled("henon_heiles")
    section = Section(0, 0.0, 1)
    points = [(0.1, 0.0), (0.0, 0.2), (0.5, 0.5), (5.0, 5.0)]
    portrait = section_portrait(compiled, section, 1 / 8, points, t_end=1000.0, crossings=7)
    assert len(portrait.t) == 3 and portrait.starts[2, 1] == 5.0
    assert [len(t) for t in portrait.t[:2]] == [7, 7] and portrait.status[:2] == ["full"] * 2
    assert (portrait.reached[:2] < 1000.0).all() and portrait.trusted.tolist() == [1, 1, 0]
    assert portrait.messages[2].startswith("orbit 2") and "not trusted" in portrait.summary()
    strict = section_portrait(
        compiled, section, 1 / 8, points[:2], t_end=50.0, energy_tolerance=1e-300
    )  # fmt: skip
    assert not strict.trusted.any() and strict.energy_error.max() < 1e-13
    assert "cannot be trusted" in strict.messages[0]


def test_a_cut_on_an_angle_is_crossed_at_every_turn():
    """The double pendulum's section on an angle (crossed at value + 2 pi j): the batch
    finds the crossings a single run finds (``events.periodic_brackets``)."""
    compiled = _compiled("double_pendulum")
    scene = compiled.mechanics.scene
    from systems.angles import angle_coordinates

    section = Section.from_scene(scene, angle_coordinates(compiled.mechanics))
    y0 = compiled.initial_state()
    E = float(compiled.hamiltonian(0.0, y0[None, :])[0]) + 10.0  # energy enough to turn over
    starts = default_starts(compiled, section, E, 3)
    assert np.abs(starts[:, section.shown]).max() < np.pi
    portrait = section_portrait(compiled, section, E, starts, t_end=30.0)
    assert portrait.trusted.all(), portrait.messages
    for r, y in enumerate(starts):
        t, states, _ = _single_run_crossings(compiled, y, section, 30.0)
        assert len(t) == len(portrait.t[r]) > 5, r
        assert np.abs(portrait.t[r] - t).max() <= 1e-11, r
        assert np.abs(portrait.y[r] - states).max() <= 1e-10, r
    turned = np.concatenate(portrait.y)[:, section.coordinate] - section.value
    assert np.abs(np.remainder(turned + np.pi, 2 * np.pi) - np.pi).max() < 1e-12


def test_refused_where_taylor_does_not_apply_unless_falling_back():
    """A scene taylor refuses (the matrix form): the reason, or with ``fallback`` one run
    an orbit with the scene's method, whose crossings are also on the section."""
    compiled = _compiled("pendulum_chain")
    section = Section.from_scene(compiled.mechanics.scene)
    from systems.integrators.registry import STEPPERS

    reason = STEPPERS["taylor"].applies_to(compiled.mechanics)
    assert reason is not None
    y0 = compiled.initial_state()
    E = float(compiled.hamiltonian(0.0, y0[None, :])[0])
    with pytest.raises(ValueError, match="taylor"):
        section_portrait(compiled, section, E, y0[None, :], t_end=5.0)
    portrait = section_portrait(compiled, section, E, y0[None, :], t_end=5.0, fallback=True)
    assert portrait.method != "taylor" and portrait.status == ["ok"] and len(portrait.t[0])
    assert np.abs(portrait.y[0][:, section.coordinate] - section.value).max() < 1e-12
