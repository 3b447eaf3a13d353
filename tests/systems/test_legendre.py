"""Square-root Lagrangians: the closed-form Legendre transform (issue 26 item 5)."""

import random
import time

import pytest
import sympy

from systems.legendre import square_root_transform
from systems.mechanics import derive
from systems.report import derivation_json
from systems.scene import parse_scene


def _scene(coordinates, parameters, lagrangian, title="square root"):
    names = ", ".join(f'"{q}"' for q in coordinates)
    values = ", ".join(f"{k} = {v}" for k, v in parameters.items())
    start = "\n".join(f"{q} = 0.5" for q in coordinates)
    return parse_scene(
        f'title = "{title}"\n[system]\ncoordinates = [{names}]\nparameters = {{ {values} }}\n'
        f'lagrangian = "{lagrangian}"\n[initial]\n{start}\n'
    )


VELOCITY = "(x_dot**2 + y_dot**2)/c**2"
SQUARE_ROOT_SCENES = {
    "relativistic 1D": (["x"], {"m": 1.3, "c": 2.0, "k": 0.7},
                        "-m*c**2*sqrt(1 - x_dot**2/c**2) - k*x**2/2"),
    "relativistic 2D": (["x", "y"], {"m": 1.0, "c": 1.0, "k": 1.0},
                        f"-m*c**2*sqrt(1 - {VELOCITY}) - k*(x**2 + y**2)/2"),
    "free 2D": (["x", "y"], {"m": 1.0, "c": 3.0}, f"-m*c**2*sqrt(1 - {VELOCITY})"),
    "relativistic 3D": (["x", "y", "z"], {"m": 0.8, "c": 2.0, "g": 9.81},
                        "-m*c**2*sqrt(1 - (x_dot**2 + y_dot**2 + z_dot**2)/c**2) - m*g*z"),
    "polar": (["r", "theta"], {"m": 1.0, "c": 2.0, "k": 1.0},
              "-m*c**2*sqrt(1 - (r_dot**2 + r**2*theta_dot**2)/c**2) + k/r"),
    "magnetic": (["x", "y"], {"m": 1.0, "c": 2.0, "e": 0.5, "B": 1.5},
                 f"-m*c**2*sqrt(1 - {VELOCITY}) + e*B*(x*y_dot - y*x_dot)/2"),
    "f(x)": (["x"], {"a": 0.6}, "-sqrt(1 - x_dot**2)*(1 + a*x**2)"),
    "cos(x)": (["x"], {"a": 1.0}, "-sqrt(1 - x_dot**2)*cos(a*x)"),
    "written c sqrt(c**2 - v**2)": (["x", "y"], {"m": 1.0, "c": 2.0},
                                    "m*c*(c - sqrt(c**2 - x_dot**2 - y_dot**2))"),
}  # fmt: skip


def _random_state(mechanics, rng):
    """Values of the parameters (the scene's), coordinates and velocities below c."""
    values = {mechanics.params[k]: v for k, v in mechanics.scene.parameter_values.items()}
    for x in mechanics.q:
        values[x] = rng.uniform(0.2, 1.2) if x.name == "r" else rng.uniform(-1.0, 1.0)
    speed = 0.9 * min([values[s] for s in values if s.name == "c"] + [1.0])
    for v in mechanics.qdot:
        values[v] = rng.uniform(-speed, speed) / (len(mechanics.qdot) ** 0.5)
    return values


@pytest.mark.parametrize("name", sorted(SQUARE_ROOT_SCENES))
def test_the_transform_agrees_with_the_direct_legendre_transform(name):
    """At random states: p = dL/dqdot, then qdot(q, p) gives qdot back, H(q, p) equals
    p.qdot - L, Hamilton's pdot equals dL/dq, and the conserved H in the velocities
    equals H."""
    mechanics = derive(_scene(*SQUARE_ROOT_SCENES[name]))
    L, q, qdot, p = mechanics.lagrangian, mechanics.q, mechanics.qdot, mechanics.p
    rng = random.Random(name)
    for _ in range(6):
        values = _random_state(mechanics, rng)
        momenta = {
            pi: float(sympy.diff(L, v).xreplace(values)) for pi, v in zip(p, qdot, strict=True)
        }
        at_p = {**values, **momenta}
        for v, velocity in zip(qdot, mechanics.velocities, strict=True):
            assert float(velocity.xreplace(at_p)) == pytest.approx(values[v], rel=1e-12)
        direct = sum(momenta[pi] * values[v] for pi, v in zip(p, qdot, strict=True)) - float(
            L.xreplace(values)
        )
        assert float(mechanics.hamiltonian.xreplace(at_p)) == pytest.approx(direct, rel=1e-12)
        assert float(mechanics.conserved["H"].xreplace(values)) == pytest.approx(direct, rel=1e-12)
        for i, x in enumerate(q):
            pdot = float(mechanics.hamilton_equations[len(q) + i].xreplace(at_p))
            assert pdot == pytest.approx(float(sympy.diff(L, x).xreplace(values)), abs=1e-12)


@pytest.mark.parametrize("name", sorted(SQUARE_ROOT_SCENES))
def test_square_root_lagrangians_are_transformed_in_closed_form(name):
    """No ``Abs`` and no solver's branches: the parameters positive in the scene are taken
    positive, so sqrt(m**2 c**4) is m c**2."""
    mechanics = derive(_scene(*SQUARE_ROOT_SCENES[name]))
    assert not mechanics.hamiltonian.has(sympy.Abs)
    assert all(not v.has(sympy.Abs) for v in mechanics.velocities)


def test_the_relativistic_oscillator_prints_the_textbook_h_symmetric_in_x_and_y():
    """sympy.solve gave an H with Abs(c) in one term only, unsimplified (issue 26)."""
    mechanics = derive(_scene(*SQUARE_ROOT_SCENES["relativistic 2D"]))
    s = {x.name: x for x in mechanics.scene.symbols.values()}
    m, c, k, x, y, p_x, p_y = (s[n] for n in ("m", "c", "k", "x", "y", "p_x", "p_y"))
    textbook = c * sympy.sqrt(m**2 * c**2 + p_x**2 + p_y**2) + k * (x**2 + y**2) / 2
    assert sympy.expand(mechanics.hamiltonian - textbook) == 0
    swap = {x: y, y: x, p_x: p_y, p_y: p_x}
    assert mechanics.hamiltonian.xreplace(swap) == mechanics.hamiltonian
    data = derivation_json(mechanics)
    assert data["hamiltonian"] == "c*sqrt(c**2*m**2 + p_x**2 + p_y**2) + k*(x**2 + y**2)/2"
    energy = sympy.sympify(data["conserved"]["H"], locals=s)
    v2 = s["x_dot"] ** 2 + s["y_dot"] ** 2
    assert (
        sympy.simplify(energy - (m * c**2 / sympy.sqrt(1 - v2 / c**2) + k * (x**2 + y**2) / 2)) == 0
    )


def test_a_relativistic_derivation_costs_a_fraction_of_a_second_of_cpu(monkeypatch):
    """A guard against a blow-up, in CPU time: sympy.solve took 3 s (8 s under a
    profiler) for the two-dimensional oscillator; the closed form about 0.1 s."""
    monkeypatch.setenv("PHASE_EXPLORER_DERIVATION_CACHE", "0")
    start = time.process_time()
    derive(_scene(*SQUARE_ROOT_SCENES["relativistic 3D"]))
    assert time.process_time() - start < 2.0


def test_the_sign_of_an_unknown_coefficient_is_kept():
    """-sqrt(1 - x_dot**2) cos(x): cos may have either sign, so H = sign(cos x) sqrt(...)
    (constant where the transform exists: cos x = 0 makes the velocity Hessian zero)."""
    mechanics = derive(_scene(*SQUARE_ROOT_SCENES["cos(x)"]))
    assert mechanics.hamiltonian.has(sympy.sign)
    x, p_x = mechanics.q[0], mechanics.p[0]
    a = mechanics.params["a"]
    value = mechanics.hamiltonian.xreplace({x: 2.0, p_x: 0.5, a: 1.0})
    assert float(value) == pytest.approx(-((0.25 + sympy.cos(2.0) ** 2) ** 0.5))


def _symbols(*names):
    return sympy.symbols(names, real=True)


def test_forms_outside_the_square_root_class_are_left_to_the_general_solver():
    x, v, w, p, r, c = _symbols("x", "v", "w", "p", "r", "c")
    # a radicand with a part linear in the velocity (a moving frame)
    assert square_root_transform(-sympy.sqrt(1 - (v + x) ** 2), (x,), (v,), (p,)) is None
    # a velocity outside the root beyond a linear term
    assert square_root_transform(-sympy.sqrt(1 - v**2) + v**2, (x,), (v,), (p,)) is None
    # two different radicands
    L = -sympy.sqrt(1 - v**2) - sympy.sqrt(1 - w**2)
    assert square_root_transform(L, (x, r), (v, w), (p, c)) is None
    # a quadratic Lagrangian has no root
    assert square_root_transform(v**2 / 2 - x**2 / 2, (x,), (v,), (p,)) is None


def test_a_non_diagonal_radicand_is_inverted_by_cofactors():
    x, y, u, v, p, q = _symbols("x", "y", "u", "v", "p", "q")
    L = -sympy.sqrt(1 - u**2 - u * v - v**2) - x**2 / 2
    transform = square_root_transform(L, (x, y), (u, v), (p, q))
    assert transform is not None
    point = {x: 0.3, y: 0.1, u: 0.2, v: -0.4}
    momenta = {p: sympy.diff(L, u).xreplace(point), q: sympy.diff(L, v).xreplace(point)}
    at_p = {**point, **momenta}
    assert [float(e.xreplace(at_p)) for e in transform.velocities] == pytest.approx([0.2, -0.4])
    direct = momenta[p] * 0.2 - momenta[q] * 0.4 - L.xreplace(point)
    assert float(transform.hamiltonian.xreplace(at_p)) == pytest.approx(float(direct))


def test_a_lagrangian_that_would_expand_enormously_is_not_expanded():
    """The top level of L is expanded to find its terms, unless that would exceed
    ``EXPANSION_LIMIT`` terms: (a sum of 10 velocities)**10 (92378 terms, 7 s to expand)
    is refused as a square-root Lagrangian at once."""
    vs = sympy.symbols("v0:10", real=True)
    x = sympy.Symbol("x", real=True)
    ps = sympy.symbols("p0:10", real=True)
    start = time.process_time()
    assert square_root_transform(sympy.Add(*vs) ** 10, (x,) * 10, vs, ps) is None
    assert time.process_time() - start < 2.0
