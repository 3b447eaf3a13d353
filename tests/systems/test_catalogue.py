"""The catalogue scenes: they load, derive, agree with sympy's LagrangesMethod, and draw.

The reference equations are built independently of ``systems.expressions`` and
``systems.mechanics``: the scene's own text is read with ``sympy.parse_expr`` (the catalogue
is trusted text), coordinates become ``dynamicsymbols`` and ``<q>_dot`` their time
derivatives, and ``sympy.physics.mechanics.LagrangesMethod`` forms Lagrange's equations
``M qddot = F``. LagrangesMethod takes forces as (point or frame, vector) pairs, which a
scene does not have; the scene's effects are generalized forces Q_j = -dR/d(q_j_dot) +
forces_j, so they are added to the right-hand side here: the reference is
``M_ref qddot = F_ref + Q``. For a scene given by its Hamiltonian the Lagrangian is taken
from ``mechanics.lagrangian`` (the inverse Legendre transform), which is checked separately
by transforming it back to the scene's Hamiltonian.
"""

from __future__ import annotations

import math
import random
import tomllib

import numpy as np
import pytest
import sympy
from sympy.parsing.sympy_parser import (
    convert_xor,
    parse_expr,
    standard_transformations,
)
from sympy.physics.mechanics import LagrangesMethod, dynamicsymbols

from systems.mechanics import DerivationError, derive
from systems.scene import catalogue, load_scene

# Other parts of the application refer to these names: they must all exist.
REQUIRED = (
    "harmonic_oscillator",
    "simple_pendulum",
    "planetary_motion",
    "spherical_pendulum",
    "variable_length_pendulum",
    "damped_pendulum",
    "double_pendulum",
    "driven_damped_pendulum",
    "henon_heiles",
    "atwood_machine",
    "coupled_oscillators",
    "kepler_cartesian",
    "stiff_spring_pendulum",
    "bead_on_rotating_hoop",
)
NAMES = sorted({entry.name for entry in catalogue()} | set(REQUIRED))
# LagrangesMethod takes over a minute for the ten-link chain; the large scenes' families
# are checked against it at 5 and 8 links in tests/systems/test_large_systems.py
REFERENCE_MAX_COORDINATES = 6
SMALL = [
    entry.name
    for entry in catalogue()
    if len(tomllib.loads(entry.path.read_text())["system"]["coordinates"])
    <= REFERENCE_MAX_COORDINATES
]
RELATIVE_TOLERANCE = 1e-10
STATES = 6
PRECISION = 30  # digits for evaluating both sides, so rounding cannot blur the comparison


@pytest.fixture(scope="module")
def derived():
    """Each scene loaded and derived once for the whole module."""
    cache = {}

    def get(name):
        if name not in cache:
            scene = load_scene(name)
            cache[name] = (scene, derive(scene))
        return cache[name]

    return get


def test_catalogue_has_every_required_scene():
    present = {entry.name for entry in catalogue()}
    assert set(REQUIRED) <= present, f"missing: {sorted(set(REQUIRED) - present)}"


@pytest.mark.parametrize("name", NAMES)
def test_scene_loads_and_derives(name, derived):
    scene, mech = derived(name)
    assert scene.name == name
    assert scene.title.strip() and scene.description.strip()
    assert mech.n == len(scene.coordinates)
    assert len(mech.hamilton_equations) == 2 * mech.n
    assert mech.mass_matrix is not None and mech.forcing is not None


# -- agreement with sympy.physics.mechanics.LagrangesMethod ---------------------------------


def _reference_symbols(scene, mech):
    """Names as the scene writes them -> objects of the reference computation."""
    t = dynamicsymbols._t
    q = [dynamicsymbols(name) for name in scene.coordinates]
    names = {"t": t, "pi": sympy.pi}
    names.update({name: mech.params[name] for name, _ in scene.parameters})
    for name, qi in zip(scene.coordinates, q, strict=True):
        names[name] = qi
        names[f"{name}_dot"] = qi.diff(t)
    return t, q, names


def _read(text, names):
    """Parse trusted catalogue text with sympy itself, independent of systems.expressions."""
    functions = {
        name: getattr(sympy, name)
        for name in "sin cos tan exp log sqrt sinh cosh tanh asin acos atan atan2 Abs".split()
    }
    transformations = standard_transformations + (convert_xor,)
    return parse_expr(
        text, local_dict={**functions, **names}, transformations=transformations, evaluate=True
    )


def _to_dynamic(expr, scene, mech, q, t):
    """An expression in the scene's plain symbols -> dynamicsymbols."""
    first = {v: qi.diff(t) for v, qi in zip(mech.qdot, q, strict=True)}
    second = {s: qi for s, qi in zip(mech.q, q, strict=True)}
    return expr.xreplace(first).xreplace(second).xreplace({mech.t: t})


def _reference(scene, mech):
    """(M_ref, F_ref + Q) from LagrangesMethod, in dynamicsymbols."""
    t, q, names = _reference_symbols(scene, mech)
    if scene.kind == "hamiltonian":
        lagrangian = _to_dynamic(mech.lagrangian, scene, mech, q, t)
    elif scene.kind == "lagrangian":
        lagrangian = _read(scene.lagrangian, names)
    else:
        potential = _read(scene.potential, names) if scene.potential is not None else 0
        if scene.particles:  # T and gravity's V from the positions, without systems.particles
            kinetic = 0
            for particle in scene.particles:
                mass = _read(particle.mass, names)
                position = [_read(c, names) for c in particle.position]
                kinetic += mass * sum(c.diff(t) ** 2 for c in position) / 2
                if scene.gravity is not None:
                    field = (
                        [_read(g, names) for g in scene.gravity]
                        if isinstance(scene.gravity, tuple)
                        else [0, -_read(scene.gravity, names), 0][: len(position)]
                    )
                    potential -= mass * sum(g * c for g, c in zip(field, position, strict=True))
        else:
            kinetic = _read(scene.kinetic, names)
        lagrangian = kinetic - potential
    method = LagrangesMethod(lagrangian, q)
    method.form_lagranges_equations()
    qd = [qi.diff(t) for qi in q]
    forces = [sympy.S.Zero] * len(q)
    enabled = set(scene.enabled_effects())
    if "dissipation" in enabled:
        rayleigh = _read(scene.dissipation, names)
        forces = [f - sympy.diff(rayleigh, v) for f, v in zip(forces, qd, strict=True)]
    for name, text in scene.forces:
        if f"forces.{name}" in enabled:
            forces[scene.coordinates.index(name)] += _read(text, names)
    return method.mass_matrix, method.forcing + sympy.Matrix(forces), t, q


def _random_state(scene, mech, rng, scene_parameters=True):
    """Plain-symbol values: coordinates in [0.3, 1.7] (away from r = 0 and sin(theta) = 0),
    velocities of either sign, a time in [0, 5]; the scene's parameter values, or random
    ones in [0.5, 2] (so that, e.g., equal masses cannot hide a swapped index)."""
    values = {qi: rng.uniform(0.3, 1.7) for qi in mech.q}
    values.update({v: rng.choice((-1, 1)) * rng.uniform(0.2, 2.0) for v in mech.qdot})
    values[mech.t] = rng.uniform(0.0, 5.0)
    for name, value in scene.parameters:
        values[mech.params[name]] = value if scene_parameters else rng.uniform(0.5, 2.0)
    return values


def _floats(values):
    return {s: sympy.Float(v, PRECISION) for s, v in values.items()}


def _numeric(matrix, values):
    evaluated = matrix.xreplace(_floats(values)).evalf(PRECISION)
    return np.array([[complex(e) for e in row] for row in evaluated.tolist()]).real


@pytest.mark.parametrize("name", SMALL)
def test_accelerations_agree_with_lagranges_method(name, derived):
    scene, mech = derived(name)
    M_ref, F_ref, t, q = _reference(scene, mech)
    # The reference lives in dynamicsymbols: map derivatives first, then the functions.
    to_plain = {qi.diff(t): v for qi, v in zip(q, mech.qdot, strict=True)}
    to_plain_q = {qi: s for qi, s in zip(q, mech.q, strict=True)}
    M_ref = M_ref.xreplace(to_plain).xreplace(to_plain_q).xreplace({t: mech.t})
    F_ref = F_ref.xreplace(to_plain).xreplace(to_plain_q).xreplace({t: mech.t})
    leftover = (M_ref.free_symbols | F_ref.free_symbols) - (
        set(mech.q) | set(mech.qdot) | {mech.t} | set(mech.params.values())
    )
    assert not leftover, f"reference still has {leftover}"
    rng = random.Random(f"catalogue:{name}")
    for i in range(STATES):
        values = _random_state(scene, mech, rng, scene_parameters=i % 2 == 0)
        ours = np.linalg.solve(_numeric(mech.mass_matrix, values), _numeric(mech.forcing, values))
        ref = np.linalg.solve(_numeric(M_ref, values), _numeric(F_ref, values))
        assert np.all(np.isfinite(ref))
        error = np.linalg.norm(ours - ref) / max(np.linalg.norm(ref), 1e-300)
        assert error <= RELATIVE_TOLERANCE, (
            f"{name}: accelerations differ at {values}: ours {ours.ravel()}, "
            f"LagrangesMethod {ref.ravel()}, relative error {error:.3e}"
        )


@pytest.mark.parametrize("name", NAMES)
def test_symbolic_accelerations_agree_with_the_mass_matrix(name, derived):
    """``Mechanics.accelerations()`` (solved symbolically) agrees with solving M qddot = F."""
    scene, mech = derived(name)
    if mech.matrix_form is not None:  # solved numerically, and says so
        with pytest.raises(DerivationError, match="only formed for up to"):
            mech.accelerations()
        return
    accelerations = sympy.Matrix(mech.accelerations())
    rng = random.Random(f"accelerations:{name}")
    for _ in range(3):
        values = _random_state(scene, mech, rng)
        ours = np.linalg.solve(_numeric(mech.mass_matrix, values), _numeric(mech.forcing, values))
        symbolic = _numeric(accelerations, values)
        error = np.linalg.norm(symbolic - ours) / max(np.linalg.norm(ours), 1e-300)
        assert error <= RELATIVE_TOLERANCE, f"{name}: relative error {error:.3e}"


@pytest.mark.parametrize(
    "name", [n for n in NAMES if n in REQUIRED and load_scene(n).kind == "hamiltonian"]
)
def test_lagrangian_of_a_hamiltonian_scene_transforms_back(name, derived):
    """The Lagrangian used as reference above is the Legendre transform of the scene's H."""
    scene, mech = derived(name)
    symbols = {str(s): s for s in scene.symbols.values()}
    H_scene = _read(scene.hamiltonian, symbols)
    momenta = [sympy.diff(mech.lagrangian, v) for v in mech.qdot]
    H_back = sum(p * v for p, v in zip(momenta, mech.qdot, strict=True)) - mech.lagrangian
    rng = random.Random(f"legendre:{name}")
    for _ in range(STATES):
        values = _floats(_random_state(scene, mech, rng))
        p_values = {
            p: sympy.Float(m.xreplace(values).evalf(PRECISION), PRECISION)
            for p, m in zip(mech.p, momenta, strict=True)
        }
        expected = float(H_scene.xreplace({**values, **p_values}).evalf(PRECISION))
        got = float(H_back.xreplace(values).evalf(PRECISION))
        assert math.isclose(got, expected, rel_tol=1e-10, abs_tol=1e-12)


# -- drawing, initial state and view ---------------------------------------------------------


@pytest.mark.parametrize("name", NAMES)
def test_drawing_refers_to_known_points_and_evaluates(name, derived):
    scene, mech = derived(name)
    drawing = scene.drawing
    assert drawing is not None and len(drawing.points) >= 1, f"{name} has nothing to draw"
    known = set(drawing.point_names) | {"origin"}
    assert len(set(drawing.point_names)) == len(drawing.points)
    for a, b in drawing.links:
        assert a in known and b in known, f"{name}: link {a}-{b} names an unknown point"
        assert a != b
    assert set(drawing.trace) <= known
    # Every point is finite at the initial state and at t = 0.
    state = {s: 0.0 for s in mech.q}
    state.update({s: v for s, v in zip(mech.q, _initial_q(scene), strict=True)})
    state[mech.t] = 0.0
    state.update({mech.params[k]: v for k, v in scene.parameters})
    for point, _, _ in drawing.points:
        for axis in "xy":
            expr = scene.expression(f"drawing.points.{point}.{axis}")
            value = complex(expr.xreplace(_floats(state)).evalf())
            assert math.isfinite(value.real) and value.imag == 0, f"{name}: {point}.{axis}"


def _initial_q(scene):
    values = scene.initial_values
    return [values.get(q, 0.0) for q in scene.coordinates]


@pytest.mark.parametrize("name", NAMES)
def test_initial_names_are_valid(name, derived):
    scene, _ = derived(name)
    valid = set(scene.coordinates) | set(scene.velocity_names) | set(scene.momentum_names)
    given = scene.initial_values
    assert given, f"{name}: no initial state"
    assert set(given) <= valid
    for v, p in zip(scene.velocity_names, scene.momentum_names, strict=True):
        assert not (v in given and p in given)
    # No mixture of velocities and momenta: the conversion fills missing velocities with 0.
    assert not (set(given) & set(scene.velocity_names) and set(given) & set(scene.momentum_names))
    assert all(math.isfinite(value) for value in given.values())


@pytest.mark.parametrize("name", NAMES)
def test_view_is_well_formed(name, derived):
    scene, mech = derived(name)
    view = scene.view
    phase_names = set(scene.coordinates) | set(scene.momentum_names)
    assert set(view) <= {"t_end", "phase", "ranges", "section", "angles"}
    assert isinstance(view.get("t_end"), int | float) and view["t_end"] > 0
    phase = view.get("phase")
    assert isinstance(phase, list) and len(phase) == 2 and set(phase) <= phase_names
    assert phase[1] == f"p_{phase[0]}", "the phase view shows a coordinate and its momentum"
    drawing_area = {"x", "y"} - set(scene.coordinates)  # the mechanism view's x and y
    for key, bounds in view.get("ranges", {}).items():
        assert key in phase_names | drawing_area, f"{name}: range for unknown variable {key!r}"
        assert len(bounds) == 2 and bounds[0] < bounds[1]
    section = view.get("section")
    if section is not None:
        assert mech.n == 2 and mech.classification.conservative
        assert set(section) == {"coordinate", "value"}
        assert section["coordinate"] in scene.coordinates
        assert section["coordinate"] not in {name.removeprefix("p_") for name in phase}


@pytest.mark.parametrize("name", NAMES)
def test_scene_round_trips_through_toml(name, derived):
    from systems.scene import parse_scene

    scene, _ = derived(name)
    again = parse_scene(scene.to_toml(), source=scene.source, name=scene.name)
    assert again == scene
    assert dict(again.view) == dict(scene.view)


# -- the physics the scenes are meant to show -------------------------------------------------


def _value(expr, mech, scene, state):
    values = {mech.params[k]: v for k, v in scene.parameters}
    values.update(state)
    return float(expr.xreplace(_floats(values)).evalf())


def test_pendulum_bobs_hang_below_the_pivot_at_rest(derived):
    for name, point in [
        ("simple_pendulum", "bob"),
        ("damped_pendulum", "bob"),
        ("driven_damped_pendulum", "bob"),
        ("spherical_pendulum", "bob"),
        ("variable_length_pendulum", "bob"),
        ("stiff_spring_pendulum", "bob"),
        ("double_pendulum", "bob2"),
        ("bead_on_rotating_hoop", "bead"),
    ]:
        scene, mech = derived(name)
        rest = {s: 0.0 for s in mech.q} | {mech.t: 0.0}
        if "r" in scene.coordinates:
            rest[scene.symbols["r"]] = 1.0
        x = _value(scene.expression(f"drawing.points.{point}.x"), mech, scene, rest)
        y = _value(scene.expression(f"drawing.points.{point}.y"), mech, scene, rest)
        assert abs(x) < 1e-12 and y < 0, f"{name}: {point} at ({x}, {y})"


def test_classification_of_the_showcase_scenes(derived):
    cls = {name: derived(name)[1].classification for name in REQUIRED}
    assert cls["variable_length_pendulum"].hamiltonian_is_energy is False
    assert cls["variable_length_pendulum"].time_dependent
    assert cls["variable_length_pendulum"].rheonomic
    assert cls["bead_on_rotating_hoop"].hamiltonian_conserved
    assert cls["bead_on_rotating_hoop"].hamiltonian_is_energy is False
    # the hoop turns (rheonomic), yet the equations in its frame have no t: the t in its
    # drawing does not make it time dependent
    assert cls["bead_on_rotating_hoop"].rheonomic
    assert not cls["bead_on_rotating_hoop"].time_dependent
    assert not cls["damped_pendulum"].conservative
    assert not cls["driven_damped_pendulum"].conservative
    assert cls["kepler_cartesian"].separable and cls["henon_heiles"].separable
    assert not cls["double_pendulum"].separable
    for name in ("harmonic_oscillator", "simple_pendulum", "planetary_motion", "double_pendulum"):
        assert cls[name].hamiltonian_is_energy is True and cls[name].hamiltonian_conserved
        assert cls[name].simple and not cls[name].rheonomic
    assert derived("planetary_motion")[1].cyclic == ("theta",)
    assert derived("spherical_pendulum")[1].cyclic == ("phi",)


def test_kepler_orbits_have_eccentricity_one_half(derived):
    for name in ("planetary_motion", "kepler_cartesian"):
        scene, mech = derived(name)
        init = scene.initial_values
        k, m = scene.parameter_values["k"], scene.parameter_values["m"]
        if name == "planetary_motion":
            r, v = init["r"], init["r"] * init["theta_dot"]
            radial = init.get("r_dot", 0.0)
        else:
            r = math.hypot(init["x"], init.get("y", 0.0))
            v = math.hypot(init.get("x_dot", 0.0), init.get("y_dot", 0.0))
            radial = 0.0
        energy = m * (v**2 + radial**2) / 2 - k / r
        angular = m * r * v
        e = math.sqrt(1 + 2 * energy * angular**2 / (m * k**2))
        assert e == pytest.approx(0.5, abs=1e-6), name
