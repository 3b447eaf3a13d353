"""Systems in matrix form (``Mechanics.matrix_form``): every consumer of the symbolic layer
gives finite, right numbers, or says in one sentence why a feature needs closed forms.

Above four coordinates a mass matrix M(q, t) that is neither diagonal nor constant is left
unsolved: the velocities in H and Hamilton's equations stand for the solution of
``M qdot = p - a``. The scenes: pendulum chains, a chain on a cart (a cyclic coordinate),
a chain whose pivot is shaken (a(q, t) and a rheonomic L), a chain whose rods breathe
(a rheonomic M(t)) and a chain on a turntable (gyroscopic: H conserved but not T + V).
A three-link chain forced into matrix form must give the numbers of its closed form.
"""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest
import sympy

from systems import mechanics as mechanics_module
from systems import report
from systems.compiled import compile_system
from systems.families import pendulum_chain
from systems.integrators import choose_method
from systems.integrators.choice import potential_at_start, stiffness_ratio
from systems.mechanics import DerivationError, derive
from systems.scene import parse_scene
from systems.simulation import stream
from systems.start_check import check_start
from systems.textbook import jobs
from systems.textbook.conservation import _functions as conservation_functions
from systems.workprecision import linear_reference

WANTS = ("rhs", "hamiltonian", "velocities")


def _sum(terms) -> str:
    return " + ".join(terms)


def _scene(title: str, names: list[str], parameters: str, kinetic: str, potential: str, start):
    initial = "\n".join(f"{name} = {value:g}" for name, value in start.items())
    coordinates = ", ".join(f'"{x}"' for x in names)
    return (
        f'title = "{title}"\n[system]\ncoordinates = [{coordinates}]\n'
        f'parameters = {{ {parameters} }}\nkinetic = "{kinetic}"\npotential = "{potential}"\n'
        f"[initial]\n{initial}\n"
    )


def _angles(links: int) -> list[str]:
    return [f"q{i}" for i in range(1, links + 1)]


def shaken_chain(links: int) -> str:
    """A chain whose pivot moves as A cos(w t) vertically: a(q, t) and L0(q, t)."""
    q = _angles(links)
    kinetic, heights = [], []
    for k in range(1, links + 1):
        vx = _sum(f"l*{a}_dot*cos({a})" for a in q[:k])
        vy = _sum(["-A*w*sin(w*t)"] + [f"l*{a}_dot*sin({a})" for a in q[:k]])
        kinetic.append(f"(({vx})**2 + ({vy})**2)")
        heights.append(f"(A*cos(w*t) - ({_sum(f'l*cos({a})' for a in q[:k])}))")
    start = {a: 0.3 + 0.1 * i for i, a in enumerate(q)}
    return _scene(
        "Chain with a shaken pivot",
        q,
        "m = 1.0, l = 1.0, g = 9.81, A = 0.1, w = 7.0",
        f"m*({_sum(kinetic)})/2",
        f"m*g*({_sum(heights)})",
        start,
    )


def breathing_chain(links: int) -> str:
    """A chain whose rods all have length l (1 + e sin(w t)): M(q, t)."""
    q = _angles(links)
    length, rate = "l*(1 + e*sin(w*t))", "l*e*w*cos(w*t)"
    kinetic, heights = [], []
    for k in range(1, links + 1):
        s, c = _sum(f"sin({a})" for a in q[:k]), _sum(f"cos({a})" for a in q[:k])
        vx = f"{rate}*({s}) + {length}*({_sum(f'{a}_dot*cos({a})' for a in q[:k])})"
        vy = f"{rate}*({c}) - {length}*({_sum(f'{a}_dot*sin({a})' for a in q[:k])})"
        kinetic.append(f"(({vx})**2 + ({vy})**2)")
        heights.append(f"({c})")
    start = {a: 0.3 + 0.1 * i for i, a in enumerate(q)}
    return _scene(
        "Chain with breathing rods",
        q,
        "m = 1.0, l = 1.0, g = 9.81, e = 0.1, w = 3.0",
        f"m*({_sum(kinetic)})/2",
        f"-m*g*{length}*({_sum(heights)})",
        start,
    )


def turntable_chain(links: int) -> str:
    """A horizontal chain on a table turning at W, in the table's frame: gyroscopic a(q)."""
    q = _angles(links)
    kinetic = []
    for k in range(1, links + 1):
        x, y = _sum(f"l*cos({a})" for a in q[:k]), _sum(f"l*sin({a})" for a in q[:k])
        xd = _sum(f"-l*{a}_dot*sin({a})" for a in q[:k])
        yd = _sum(f"l*{a}_dot*cos({a})" for a in q[:k])
        kinetic.append(f"(({xd} - W*({y}))**2 + ({yd} + W*({x}))**2)")
    springs = _sum(f"(1 - cos({b} - {a}))" for a, b in zip(q, q[1:], strict=False))
    start = {a: 0.2 * i for i, a in enumerate(q)} | {"q1_dot": 0.3}
    return _scene(
        "Chain on a turntable",
        q,
        "m = 1.0, l = 1.0, W = 1.5, k = 3.0",
        f"m*({_sum(kinetic)})/2",
        f"k*({springs})",
        start,
    )


def cart_chain(links: int) -> str:
    """A chain hanging from a cart free to roll: x is cyclic, p_x conserved."""
    q = _angles(links)
    kinetic, heights = ["M0*x_dot**2/2"], []
    for k in range(1, links + 1):
        vx = _sum(["x_dot"] + [f"l*{a}_dot*cos({a})" for a in q[:k]])
        vy = _sum(f"l*{a}_dot*sin({a})" for a in q[:k])
        kinetic.append(f"m*(({vx})**2 + ({vy})**2)/2")
        heights.append(_sum(f"l*cos({a})" for a in q[:k]))
    start = {a: 0.3 + 0.1 * i for i, a in enumerate(q)} | {"x_dot": 0.5}
    return _scene(
        "Chain on a cart",
        ["x", *q],
        "M0 = 2.0, m = 1.0, l = 1.0, g = 9.81",
        _sum(kinetic),
        f"-m*g*({_sum(heights)})",
        start,
    )


@pytest.fixture(scope="module")
def chain5():
    mechanics = derive(parse_scene(pendulum_chain(5)))
    return mechanics, compile_system(mechanics, WANTS)


def test_chains_of_five_and_six_links_derive_in_matrix_form():
    for n in (5, 6):
        mechanics = derive(parse_scene(pendulum_chain(n)))
        form = mechanics.matrix_form
        assert form is not None and form.mass_matrix.shape == (n, n)
        assert mechanics.velocities == mechanics.qdot
        with pytest.raises(DerivationError, match="symbolic accelerations"):
            mechanics.accelerations()
        assert mechanics.classification.hamiltonian_conserved


def test_derive_json_of_a_chain_parses_with_its_mass_matrix(tmp_path, capsys):
    from explorer.cli import main

    path = tmp_path / "chain5.toml"
    path.write_text(pendulum_chain(5))
    assert main(["derive", str(path), "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["matrix_form"] is True and data["accelerations"] is None
    assert len(data["mass_matrix"]) == 5 and all(len(row) == 5 for row in data["mass_matrix"])
    names = {s: sympy.Symbol(s) for s in ("q1", "q2", "l", "m", "q1_dot", "p_q1")}
    q1, q2, l, m = names["q1"], names["q2"], names["l"], names["m"]
    M12 = sympy.sympify(data["mass_matrix"][0][1], locals=names)
    assert sympy.simplify(M12 - 4 * l**2 * m * sympy.cos(q1 - q2)) == 0
    assert data["shift"] == ["0"] * 5 and "q1_dot" in data["hamiltonian"]
    for text in (*data["hamilton_equations"].values(), *data["momenta"].values(), data["rest"]):
        sympy.sympify(text)  # reads back
    stable = [e for e in data["equilibria"] if e["stable"]]
    assert len(stable) == 1 and len(stable[0]["frequencies"]) == 5
    assert np.all(np.isfinite(stable[0]["frequencies"]))


def test_the_report_lays_out_m_and_f_and_says_the_velocities_are_solved(chain5):
    mechanics, _ = chain5
    text = report.readable(mechanics, equilibria=False)
    assert "solved numerically at every step" in text
    assert "H = ½ (p − a)ᵀ M⁻¹ (p − a) − L₀" in text
    assert "M₁,₂ = 4·l²·m·cos(q₁ − q₂)" in text and "M₅,₅ = l²·m" in text
    assert "Accelerations" not in text
    (line,) = [row for row in text.splitlines() if row.startswith("F₁ = ")]
    assert "sin(q₁ - q₂)" in line and len(line) < 200  # a few terms, not the raw derivative


def _forced(text: str, monkeypatch):
    """The scene forced into matrix form (not read from, nor written to, the cache)."""
    monkeypatch.setenv("PHASE_EXPLORER_DERIVATION_CACHE", "0")
    monkeypatch.setattr(mechanics_module, "SYMBOLIC_INVERSE_LIMIT", 1)
    forced = derive(parse_scene(text))
    assert forced.matrix_form is not None
    return forced


def _both(text: str, monkeypatch):
    """The scene derived in closed form and forced into matrix form."""
    monkeypatch.setenv("PHASE_EXPLORER_DERIVATION_CACHE", "0")
    closed = derive(parse_scene(text))
    assert closed.matrix_form is None
    return closed, _forced(text, monkeypatch)


@pytest.mark.parametrize("text", [shaken_chain(3), turntable_chain(3), breathing_chain(3)])
def test_the_tidy_forms_equal_the_derived_ones(text, monkeypatch):
    """Every tidied entry of the report (M, a, L0, F, momenta, dp/dt, conserved H) was
    checked against the derivation and kept: nothing fell back to the raw form. Three
    links forced into matrix form: a(q, t), a gyroscopic a(q), and M(q, t)."""
    monkeypatch.setattr(report, "VERIFY_NODES", 10**9)
    mechanics = _forced(text, monkeypatch)
    compact = report._form_compact(mechanics)
    tidy = [*compact.forcing, *compact.momenta, *compact.pdot, *compact.conserved.values()]
    assert all(not isinstance(e, sympy.Basic) for e in tidy)  # symengine: the tidy ones
    form = mechanics.matrix_form
    changed = [compact.mass_matrix[0][j] is not form.mass_matrix[0, j] for j in range(3)]
    assert all(changed)  # cos(q1 - qj), not sin sin + cos cos
    if mechanics.scene.title.endswith("turntable"):
        assert mechanics.classification.hamiltonian_is_energy is False and "H" in compact.conserved
        assert mechanics.classification.rheonomic and not mechanics.classification.time_dependent
        assert all(a != 0 for a in compact.shift)
    text = report.readable(mechanics, equilibria=False)
    assert "solved numerically at every step" in text and "for 3 coordinates" in text


def test_method_choice_start_check_and_references(chain5):
    mechanics, compiled = chain5
    ratio = stiffness_ratio(mechanics)
    assert np.isfinite(ratio) and ratio > 1.0
    method, _ = choose_method(mechanics)
    assert method == "gauss_legendre6"
    V = potential_at_start(mechanics)
    q0 = compiled.initial_state()[:5]
    assert V == pytest.approx(-9.81 * sum((5 - i) * np.cos(q0[i]) for i in range(5)), rel=1e-12)
    y0 = check_start(compiled)
    assert np.all(np.isfinite(y0))
    assert linear_reference(compiled, y0, 1.0) is None


def test_initial_state_from_velocities_and_from_momenta():
    text = turntable_chain(5)
    mechanics = derive(parse_scene(text))
    compiled = compile_system(mechanics, WANTS)
    y0 = compiled.initial_state()
    qdot = np.array([0.3, 0, 0, 0, 0])
    values = dict(zip(mechanics.q, y0[:5], strict=True))
    values |= {mechanics.params[name]: value for name, value in mechanics.scene.parameters}
    M = np.array(mechanics.matrix_form.mass_matrix.xreplace(values), dtype=float)
    a = np.array(mechanics.matrix_form.shift.xreplace(values), dtype=float).ravel()
    np.testing.assert_allclose(y0[5:], M @ qdot + a, rtol=1e-12)
    np.testing.assert_allclose(compiled.velocities(0.0, y0[None])[0], qdot, atol=1e-12)
    angles = [(name, value) for name, value in mechanics.scene.initial if name != "q1_dot"]
    momenta = list(zip(mechanics.scene.momentum_names, map(float, y0[5:]), strict=True))
    scene = replace(mechanics.scene, initial=tuple(angles + momenta))
    given = compile_system(replace(mechanics, scene=scene), WANTS)
    np.testing.assert_allclose(given.initial_state(), y0, rtol=1e-12)
    np.testing.assert_allclose(check_start(given), y0, rtol=1e-12)


def test_h_is_conserved_along_a_run(chain5):
    _, compiled = chain5
    blocks = list(stream(compiled, method="dop853", t_end=2.0, tol=1e-11, diagnostics=("H",)))
    assert blocks[-1].status == "ok"
    H = np.concatenate([b.diagnostics["H"] for b in blocks])
    assert np.max(np.abs(H - H[0])) < 1e-9 * abs(H[0])


def test_every_textbook_job_runs_on_a_chain(chain5):
    mechanics, compiled = chain5
    found = jobs.equilibria(compiled).search.equilibria
    stable = [e for e in found if e.stable]
    assert len(stable) == 1 and np.all(np.isfinite(stable[0].frequencies))
    # hanging down: M_ij = 6 - max(i, j), K = diag(g (6 - i)) for unit masses and rods
    i = np.arange(1, 6)
    M, K = 6.0 - np.maximum.outer(i, i), np.diag(9.81 * (6.0 - i))
    omega = np.sqrt(np.linalg.eigvals(np.linalg.solve(M, K)).real)
    np.testing.assert_allclose(stable[0].frequencies, np.sort(omega), rtol=1e-8)
    energy = jobs.energy(compiled, 1.0)
    balance = energy.balance
    for values in (balance.hamiltonian, balance.rate, balance.partial, balance.power):
        assert np.all(np.isfinite(values))
    assert np.ptp(balance.hamiltonian) < 1e-8 * abs(balance.hamiltonian[0])
    np.testing.assert_allclose(balance.energy, balance.hamiltonian, rtol=1e-12)
    principle = jobs.principle(compiled, 0.5, 1, 0, 0.05)
    assert np.all(np.isfinite(principle.action)) and abs(principle.slope) < 1e-4
    setup = jobs.reduction_setup(compiled)
    assert setup.reduction is None and "cyclic" in setup.reason and not setup.needs_closed_form
    assert "one-degree" in jobs.action_angle_reason(compiled)


def test_two_point_problem_on_a_chain(chain5):
    _, compiled = chain5
    result = jobs.two_point(compiled, [0.1] * 5, [0.15] * 5, 0.3)
    assert result.action_path.converged and np.isfinite(result.action_path.action)
    assert result.shooting_error == "" and np.isfinite(result.shooting_path.action)


def test_routh_reduction_says_why_not():
    mechanics = derive(parse_scene(cart_chain(4)))
    assert mechanics.matrix_form is not None and "p_x" in mechanics.conserved
    setup = jobs.reduction_setup(compile_system(mechanics, WANTS))
    assert setup.reduction is None and setup.needs_closed_form
    assert setup.reason.startswith(
        "Routh's reduction needs the Legendre transform in closed form, which a system of 5 "
        "coordinates with a coupled mass matrix leaves to the numerical solver"
    )


def test_rheonomic_mass_matrix_energy_theorem():
    """dH/dt = -dL/dt (partial): with M(t) the partial holds M's and a's time dependence."""
    mechanics = derive(parse_scene(breathing_chain(5)))
    assert mechanics.matrix_form.mass_matrix.has(mechanics.t)
    assert not mechanics.classification.hamiltonian_conserved
    compiled = compile_system(mechanics, WANTS)
    assert choose_method(mechanics)[0] == "dop853"
    b = jobs.energy(compiled, 1.0).balance
    assert np.max(np.abs(b.rate - b.predicted)) < 1e-5 * np.max(np.abs(b.rate))
    assert np.max(np.abs(b.partial)) > 1.0  # H does change


@pytest.mark.parametrize("text", [pendulum_chain(3), shaken_chain(3)])
def test_matrix_form_gives_the_numbers_of_the_closed_form(text, monkeypatch):
    closed, forced = _both(text, monkeypatch)
    assert choose_method(closed) == choose_method(forced)
    assert stiffness_ratio(forced) == pytest.approx(stiffness_ratio(closed), rel=1e-10)
    assert potential_at_start(forced) == pytest.approx(potential_at_start(closed), rel=1e-12)
    compiled = [compile_system(m, WANTS) for m in (closed, forced)]
    y0 = [check_start(c) for c in compiled]
    np.testing.assert_allclose(y0[1], y0[0], rtol=1e-12)
    rng = np.random.default_rng(5)
    t = rng.uniform(0.0, 2.0, 50)
    Y = y0[0] + rng.normal(0.0, 0.5, (50, 6))
    values = [conservation_functions(m, None)(t, *Y.T) for m in (closed, forced)]
    np.testing.assert_allclose(values[1], values[0], rtol=1e-10, atol=1e-10)
    rates = [np.array([c.rhs(s, y) for s, y in zip(t[:5], Y[:5], strict=True)]) for c in compiled]
    np.testing.assert_allclose(rates[1], rates[0], rtol=1e-10, atol=1e-10)
    np.testing.assert_allclose(compiled[1].hamiltonian(t, Y), values[0][0], rtol=1e-10)
    np.testing.assert_allclose(
        compiled[1].velocities(t, Y), compiled[0].velocities(t, Y), rtol=1e-10
    )
