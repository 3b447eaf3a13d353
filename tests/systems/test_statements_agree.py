"""The derivation's statements never contradict each other (issue 26 item 8), over every
catalogue scene, every users' scene and a generated set.

Each statement of ``derive``'s text is read back and held against the others and against
the data it was made from (``Mechanics``, the equilibrium search): one of scleronomic /
rheonomic, holonomic / nonholonomic, ...; "simple system" exactly when scleronomic,
holonomic and conservative; "H is conserved" exactly when H is listed conserved, never
with "time dependent"; each cyclic coordinate's momentum listed conserved; "natural" exactly
when T (the velocity part of L) is a homogeneous quadratic in the velocities; a
rheonomic transformation never under a scleronomic classification; the equilibria listed
or "none", never both, each with the search's verdict; no note calls a scleronomic system
rheonomic. Statements about explicitly time-dependent systems' constant solutions (the
Floquet block) are checked only for their heading.
"""

from __future__ import annotations

import random
import re
from pathlib import Path
from unittest import mock

import pytest
import sympy
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from systems import textbook
from systems.display import display_names
from systems.mechanics import derive
from systems.report import readable
from systems.scene import load_scene, parse_scene
from systems.textbook import floquet
from systems.textbook.equilibria import search_equilibria

ROOT = Path(__file__).resolve().parents[2]
SCENES = sorted(
    [
        *(ROOT / "resources" / "scenes").glob("*.toml"),
        *(ROOT / "tests" / "user_systems").glob("*.toml"),
    ]
    + sorted(Path("/work/shared/user-systems").glob("*.toml")),
    key=str,
)
PAIRS = [
    ("scleronomic", "rheonomic"),
    ("holonomic", "nonholonomic"),
    ("bilateral", "unilateral"),
    ("conservative", "not conservative"),
    ("simple system", "general system"),
    ("autonomous", "time dependent"),
    ("H is conserved", "H is not conserved"),
    ("natural", "not natural"),
    ("separable", "not separable"),
]


def _block(text: str, heading: str) -> list[str]:
    """The lines under ``heading`` (its underline skipped) up to the next blank line."""
    lines = text.splitlines()
    if heading not in lines:
        return []
    start = lines.index(heading) + 2
    end = next((i for i in range(start, len(lines)) if not lines[i].strip()), len(lines))
    return lines[start:end]


def _homogeneous_quadratic(mechanics) -> bool:
    """T(q, 2 v) == 4 T(q, v) at random states (T the velocity part of L)."""
    T = mechanics.kinetic
    if T is None:
        return True  # a Hamiltonian-only scene: natural is decided from H
    doubled = T.xreplace({v: 2 * v for v in mechanics.qdot})
    rng = random.Random(5)
    symbols = sorted(T.free_symbols | doubled.free_symbols, key=str)
    f = sympy.lambdify(symbols, [T, doubled], modules="math")
    for _ in range(5):
        try:
            a, b = f(*(rng.uniform(0.3, 1.7) for _ in symbols))
        except (ValueError, ZeroDivisionError, OverflowError):
            continue
        if abs(b - 4 * a) > 1e-9 * max(1.0, abs(b)):
            return False
    return True


def _text_and_search(mechanics):
    """``readable(mechanics)``, and the result of the call ``search_equilibria(mechanics)``
    its equilibria were written from, if it made that call (else None).

    The text is held against that very search, not against a second one: the search is
    the costliest part of the text (on fpu_chain 3 s of CPU), and a second call with the
    same arguments only repeats it. A search made with any other arguments is not kept.
    """
    made = []

    def recorded(m, *args, **kwargs):
        result = search_equilibria(m, *args, **kwargs)
        if m is mechanics and not args and not kwargs:
            made.append(result)
        return result

    with mock.patch.object(textbook, "search_equilibria", recorded):
        text = readable(mechanics)
    return text, (made[-1] if made else None)


def contradictions(mechanics) -> list[str]:
    """Every pair of statements of the derivation that do not agree, as sentences."""
    text, search = _text_and_search(mechanics)
    found = []
    items = [line[2:] for line in _block(text, "Classification") if line.startswith("- ")]
    said = {}
    for yes, no in PAIRS:
        positive = [i for i in items if i.startswith(yes) and not i.startswith(no)]
        negative = [i for i in items if i.startswith(no)]
        if len(positive) + len(negative) != 1:
            found.append(f"{yes!r} / {no!r}: said {len(positive) + len(negative)} times")
        said[yes] = bool(positive)
    c = mechanics.classification
    for key, statement in [
        ("rheonomic", not said["scleronomic"]),
        ("holonomic", said["holonomic"]),
        ("bilateral", said["bilateral"]),
        ("conservative", said["conservative"]),
        ("simple", said["simple system"]),
        ("hamiltonian_conserved", said["H is conserved"]),
        ("natural", said["natural"]),
        ("separable", said["separable"]),
    ]:
        if c.as_dict()[key] != statement:
            found.append(
                f"the text says {key} = {statement}, the classification {c.as_dict()[key]}"
            )
    # with a total time derivative in L the text says the motion is autonomous (Lagrange's
    # equations) and why H and Hamilton's equations carry t: time_dependent is the latter
    if not c.gauge_time and c.time_dependent == said["autonomous"]:
        found.append(f"the text says autonomous = {said['autonomous']}, time_dependent too")
    simple = said["scleronomic"] and said["holonomic"] and said["conservative"]
    if said["simple system"] != simple:
        found.append("'simple system' disagrees with scleronomic, holonomic and conservative")
    conserved = "H" in mechanics.conserved
    if said["H is conserved"] != conserved:
        found.append(f"'H is conserved' is {said['H is conserved']}, H listed: {conserved}")
    if said["H is conserved"] and c.time_dependent:
        found.append("H conserved in a time-dependent system")
    if said["natural"] != _homogeneous_quadratic(mechanics):
        found.append(f"'natural' is {said['natural']} but T is not so")
    shown = display_names(mechanics.scene)
    cyclic_line = next((i for i in items if i.startswith("cyclic coordinates: ")), "")
    names = [shown.get(n, n) for n in mechanics.cyclic]
    expected = "cyclic coordinates: " + (", ".join(names) if names else "none")
    if not cyclic_line.startswith(expected):
        found.append(f"{cyclic_line!r} where the derivation has {expected!r}")
    for name in mechanics.cyclic:  # a cyclic coordinate's momentum is conserved, or not so said
        momentum = f"p_{shown.get(name, name)}"
        listed = f"p_{name}" in mechanics.conserved
        denied = re.search(rf"{re.escape(momentum)}\b[^;]* not conserved", cyclic_line)
        if listed == bool(denied):
            found.append(f"{name} is cyclic: p_{name} listed {listed}, said not conserved: "
                         f"{bool(denied)}")  # fmt: skip
    labels = {
        m[1] for line in _block(text, "Conserved quantities") if (m := re.match(r"(\S+) = ", line))
    }
    if ("H" in labels) != conserved:
        found.append(f"the conserved quantities show H: {'H' in labels}, H conserved: {conserved}")
    if "The transformation is rheonomic" in text and said["scleronomic"]:
        found.append("a rheonomic transformation in a scleronomic system")
    # the equilibria: listed or none, each as the search decided
    heading = floquet.HEADING if floquet.explicit_time(mechanics) else None
    if heading is not None:
        if heading not in text:
            found.append("an explicitly time-dependent system without the Floquet heading")
        return found
    block = _block(text, "Equilibria (virtual work: dV/dq = 0)")
    listed = [line for line in block if line.startswith("- ")]
    none = [line for line in block if line.startswith("none")]
    if bool(listed) == bool(none):
        found.append(f"equilibria listed ({len(listed)}) and 'none' ({len(none)})")
    if any("rheonomic" in line for line in block) and said["scleronomic"]:
        found.append("an equilibrium note calls a scleronomic system rheonomic")
    if search is None:
        search = search_equilibria(mechanics)
    if search.method == "not computed":
        return found
    if len(listed) != len(search.equilibria):
        found.append(f"{len(listed)} equilibria shown, {len(search.equilibria)} found")
    for line, e in zip(listed, search.equilibria, strict=False):
        verdict = line.split(": ", 1)[1] if ": " in line else line
        if e.continuum is not None:
            word = "stable across" if e.stable else "unstable across"
            agrees = word in line or ("U is constant around" in line and e.stable)
        else:
            agrees = verdict.startswith("stable") == e.stable
        if not agrees:
            found.append(f"{line!r} where the search says stable = {e.stable}")
    return found


@pytest.mark.parametrize("path", SCENES, ids=[f"{p.parent.name}/{p.stem}" for p in SCENES])
def test_catalogue_and_users_scenes_never_contradict_themselves(path):
    assert contradictions(derive(load_scene(str(path)))) == []


# -- a generated set ------------------------------------------------------------------------

KINETIC = [
    "m*(x_dot**2 + y_dot**2)/2",
    "m*(x_dot**2 + (1 + x**2)*y_dot**2)/2",
    "m*(x_dot**2 + y_dot**2)/2 + m*w*(x*y_dot - y*x_dot)",  # a rotating frame's T1
    "m*(x_dot**2 + y_dot**2)/2 + m*w**2*(x**2 + y**2)/2",  # and its T0
    "m*(x_dot + w*y)**2/2 + m*y_dot**2/2",
]
POTENTIAL = ["k*x**2/2", "k*(x**2 + y**2)/2", "k*(x**2 - 1)**2/4 + y**2", "-k*cos(x) - k*cos(y)",
             "k*x*y", "0", "k*(x**2 + y**2)/2 + a*x*cos(w*t)"]  # fmt: skip
EXTRA = [
    "",
    '\n[effects]\ndissipation = "b*(x_dot**2 + y_dot**2)/2"',
    '\n[effects]\nforces = { x = "a*y_dot", y = "-a*x_dot" }',  # gyroscopic: no work
    '\n[effects]\nforces = { x = "a*cos(w*t)" }',
]


@st.composite
def generated(draw) -> str:
    kinetic, potential = draw(st.sampled_from(KINETIC)), draw(st.sampled_from(POTENTIAL))
    extra = draw(st.sampled_from(EXTRA))
    gauge = draw(st.sampled_from(["", " + c*(x + t*x_dot)", " + c*y*x_dot + c*x*y_dot"]))
    if gauge:  # as a Lagrangian with a total time derivative
        body = f'lagrangian = "{kinetic} - ({potential}){gauge}"'
    else:
        body = f'kinetic = "{kinetic}"\npotential = "{potential}"'
    return (
        'title = "generated"\n[system]\ncoordinates = ["x", "y"]\n'
        "parameters = { m = 1.3, k = 2.0, w = 0.7, a = 0.4, b = 0.2, c = 0.5 }\n"
        f"{body}{extra}\n"
    )


@settings(
    max_examples=20,
    deadline=None,
    derandomize=True,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)
@given(text=generated())
def test_generated_scenes_never_contradict_themselves(text):
    assert contradictions(derive(parse_scene(text))) == [], text


def test_a_damped_cyclic_coordinate_is_not_read_as_a_conservation_law():
    text = (
        'title = "damped drift"\n[system]\ncoordinates = ["x", "y"]\n'
        'parameters = { m = 1.0, k = 2.0, b = 0.3 }\nkinetic = "m*(x_dot**2 + y_dot**2)/2"\n'
        'potential = "k*x**2/2"\n[effects]\ndissipation = "b*y_dot**2/2"\n'
    )
    mechanics = derive(parse_scene(text))
    assert mechanics.cyclic == ("y",) and "p_y" not in mechanics.conserved
    assert "- cyclic coordinates: y (absent from L; p_y is not conserved" in readable(mechanics)
    assert contradictions(mechanics) == []
