"""Derivations and equilibria as text for people, and as JSON-ready data.

Qt-free, so the CLI (``derive``) and the window (its Derivation text and equilibrium
lines, the Textbook tabs' captions) say the same thing without the window importing CLI
code. Display names (θ₁, θ̇₁, p_θ₁) come from ``systems.display``; the JSON keeps the
scene's own names.
"""

from __future__ import annotations

import random
import re
import weakref
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import sympy

from systems import constraints
from systems.calculus import Calculus, Unsupported, to_symengine
from systems.classification import describe_cyclic
from systems.derivation_cache import remembered_job
from systems.display import (
    combine_trig,
    display_names,
    expanded_terms,
    for_display,
    latex_name,
    latex_names,
    tidied,
)
from systems.expressions import as_expr
from systems.symmetries import ENERGY, ROTATIONS, TRANSLATIONS

try:
    import symengine
except ImportError:  # pragma: no cover - a dependency; sympy alone is only slower
    symengine = None

if TYPE_CHECKING:
    from systems.mechanics import Mechanics
    from systems.scene import Scene

PRETTY_NODES = 300
"""Expressions with more nodes are shown on one line: sympy's two-dimensional layout costs
more than linear time, and a twenty-link chain's equations are thousands of nodes."""

PRETTY_CHARS = 600
"""The same limit for a symengine expression, by the length of its text."""

SORTED_NODES = 2000
"""Expressions with more nodes are printed without sorting their terms (``order="none"``):
sorting a sum of thousands of products cost seconds."""


@dataclass(frozen=True)
class Title:
    """The scene's title, at the head of a derivation (underlined with ``=``)."""

    title: str


@dataclass(frozen=True)
class Heading:
    """The title of a block of a derivation (underlined with ``-``)."""

    title: str


@dataclass(frozen=True)
class Row:
    """One equation of a derivation: ``label = expr`` (``label: lhs = rhs`` for an Eq).

    ``expr`` is a sympy expression or equation, a symengine expression (``_Compact``) or
    a ``sympy.Tuple`` (a vector); ``latex_label`` is the label in LaTeX
    (``systems.typeset`` writes ``latex_label = latex(expr)``; an Eq's label is its
    tag); ``text``, where given, is the row's text (written without sympy); ``note``
    says in words what the typeset row is (``quadratic in q̇``), as its text label does.
    """

    label: str
    expr: object
    latex_label: str
    text: str | None = None
    note: str = ""


Part = Title | Heading | Row | str
"""What a derivation is made of (``derivation_parts``): a sentence is a ``str``."""


def one_line(expression: sympy.Basic) -> str:
    """A sympy expression as one line of text: ``p_θ²/(2·m·r²) − k/r``.

    Parameters
    ----------
    expression : sympy.Basic
        Usually already renamed for display by ``systems.display.for_display``.

    Returns
    -------
    str
        ``sympy.sstr`` with squares, cubes and fourth powers as superscripts, π, ``·`` for
        products and ``−`` for minus.
    """
    text = sympy.sstr(expression, order="none" if _larger(expression, SORTED_NODES) else None)
    return _glyphs(text)


def _glyphs(text: str) -> str:
    """Powers as superscripts, π, ``·`` and ``−`` in the text of an expression."""
    for power, glyph in (("**2", "²"), ("**3", "³"), ("**4", "⁴")):
        text = text.replace(power, glyph)
    text = re.sub(r"\bpi\b", "π", text)
    return text.replace("**", "^").replace("*", "·").replace("-", "−")


def readable(mechanics: Mechanics, equilibria: bool = True) -> str:
    """The derivation laid out for a person, with sympy's pretty printer.

    Parameters
    ----------
    mechanics : Mechanics
        A derived scene.
    equilibria : bool
        Whether to end with the equilibria (virtual work). ``False`` leaves out their
        search (a second or more), for the window, which shows its result apart when it
        arrives.

    Returns
    -------
    str
        Title, coordinates and parameters, L, Lagrange's equations, accelerations, momenta,
        H, Hamilton's equations, classification, conserved quantities and (optionally)
        equilibria, one block each.

        For a system in matrix form (``Mechanics.matrix_form``) Lagrange's equations are
        ``M q̈ = F`` with M's entries on and above the diagonal and F entry by entry, H is
        ``½ (p − a)ᵀ M⁻¹ (p − a) − L₀`` with a and L₀, and a sentence
        (``matrix_form_sentence``) says that the velocities are solved numerically at
        every step; those parts are tidied (``_Compact``), checked against the
        derivation. Expressions beyond ``PRETTY_NODES`` nodes are printed on one line, so
        a twenty-link chain is laid out in about a second.
    """
    return "\n".join(text_lines(derivation_parts(mechanics, equilibria), mechanics.scene))


def derivation_parts(mechanics: Mechanics, equilibria: bool = True) -> list[Part]:
    """What ``readable`` lays out, part by part: titles, sentences and ``Row`` equations
    (``text_lines`` writes them as text, ``systems.typeset`` as LaTeX)."""
    scene = mechanics.scene
    shown = display_names(scene)
    names = latex_names(scene)
    params = ", ".join(f"{shown[k]} = {v:g}" for k, v in scene.parameters) or "none"
    lines: list[Part] = [Title(scene.title)]
    if scene.description:
        lines.append(scene.description)
    coordinates = ", ".join(shown[q] for q in scene.coordinates)
    lines.append(f"coordinates: {coordinates}; parameters: {params}")
    lines.append(degrees_of_freedom_sentence(mechanics))
    if scene.enabled_effects():
        lines.append(f"effects on: {', '.join(scene.enabled_effects())}")
    if scene.particles:
        lines += particles_lines(scene)
    lines += constraints_lines(mechanics)
    if mechanics.matrix_form is not None:
        lines += _matrix_form_lines(mechanics, shown, names)
    else:
        lines += _closed_form_lines(mechanics, shown, names)
    lines += [Heading("Classification")]
    lines += [f"- {sentence}" for sentence in mechanics.classification.describe()]
    cyclic = describe_cyclic(mechanics.cyclic, mechanics.conserved, shown)
    lines.append(f"- {cyclic}")
    if mechanics.conserved:
        conserved = dict(mechanics.conserved)
        if mechanics.matrix_form is not None:
            conserved.update(_compact(mechanics).conserved)
        rows = [
            (shown.get(name, name), expr, names.get(name) or sympy.latex(sympy.Symbol(name)))
            for name, expr in conserved.items()
        ]
        lines += _block("Conserved quantities", rows)
    lines += _noether_lines(mechanics)
    if equilibria:
        lines += _equilibria_lines(mechanics)
    return lines


def text_lines(parts: list[Part], scene: Scene) -> list[str]:
    """The lines of text of a derivation's parts: each ``Row`` by ``_rows``."""
    lines: list[str] = []
    for part in parts:
        if isinstance(part, Title):
            lines += [part.title, "=" * len(part.title)]
        elif isinstance(part, Heading):
            lines += ["", part.title, "-" * len(part.title)]
        elif isinstance(part, Row):
            lines += [part.text] if part.text is not None else _rows([part], scene)
        else:
            lines.append(part)
    return lines


def _noether_lines(mechanics: Mechanics) -> list[str]:
    """What each Noether charge is (``systems.symmetries``), and the ``[symmetries]``
    entries that are not listed."""
    lines = []
    for name in mechanics.conserved:
        axis = name[2:]
        if name in ROTATIONS:
            lines.append(f"- {name}: angular momentum about the {axis} axis (Noether: rotations)")
        elif name in TRANSLATIONS:
            lines.append(f"- {name}: total linear momentum along {axis} (Noether: translations)")
        elif name == ENERGY:
            lines.append(
                f"- {name}: the energy of L without its total time derivative dF(q, t)/dt "
                "(H of these momenta is E \u2212 \u2202F/\u2202t, and not conserved)"
            )
        elif name != "H" and not name.startswith("p_"):
            lines.append(f"- {name}: the charge of the generator [symmetries] {name}")
    left_out = [name for name, _ in mechanics.scene.symmetries if name not in mechanics.conserved]
    if left_out:
        lines.append(
            f"- not conserved, or the same as a quantity above: {', '.join(left_out)} "
            "([symmetries]: L changes along the generator, or an effect or a constraint "
            "does work along it)"
        )
    return lines


def _closed_form_lines(
    mechanics: Mechanics, shown: dict[str, str], names: dict[str, str]
) -> list[Part]:
    """L, Lagrange's equations, accelerations, momenta, H and Hamilton's equations, each
    in closed form (``names``: the LaTeX of the scene's names)."""
    scene = mechanics.scene
    lines: list[Part] = []
    # with constraints these are the free coordinates' equations (see constraints_lines)
    free = ""
    if scene.nonholonomic_constraints or scene.unilateral_constraints:
        free = " (free, without the constraint force −Aᵀ λ)"
    elif scene.holonomic_constraints:
        free = " (free, without −Φ_qᵀ λ)"
    if mechanics.lagrangian is not None:
        lines += _block("Lagrangian", [("L", mechanics.lagrangian, "L")])
        equations = [
            (f"({i + 1})", eq, f"({i + 1})") for i, eq in enumerate(mechanics.lagrange_equations())
        ]
        lines += _block("Lagrange's equations" + free, equations)
        try:
            accelerations = zip(scene.coordinates, mechanics.accelerations(), strict=True)
            rows = [(shown[f"{q}_ddot"], a, names[f"{q}_ddot"]) for q, a in accelerations]
            lines += _block("Accelerations" + free, rows)
        except ValueError:
            pass
    if mechanics.momenta is not None:
        rows = [
            (shown[p], m, names[p])
            for p, m in zip(scene.momentum_names, mechanics.momenta, strict=True)
        ]
        lines += _block("Generalized momenta p = dL/dq̇", rows)
    lines += _block("Hamiltonian", [("H", mechanics.hamiltonian, "H")])
    coordinates = list(scene.coordinates) + list(scene.momentum_names)
    rows = [
        (f"d{shown[name]}/dt", expr, _dotted(name, names))
        for name, expr in zip(coordinates, mechanics.hamilton_equations, strict=True)
    ]
    lines += _block("Hamilton's equations" + free, rows)
    return lines


def _dotted(name: str, names: dict[str, str]) -> str:
    """The time derivative of a coordinate or momentum in LaTeX: ``\\dot{x}``,
    ``\\dot{p}_{x}`` (``names``: ``systems.display.latex_names``)."""
    if f"{name}_dot" in names:
        return names[f"{name}_dot"]
    return "\\dot{p}" + names[name][1:]


def matrix_form_sentence(mechanics: Mechanics) -> str:
    """Why a system in matrix form has no closed-form velocities, in one sentence."""
    return (
        "The velocities q̇ = M⁻¹(p − a) are solved numerically at every step (a Cholesky "
        f"factorisation of M), because their closed form for {mechanics.n} coordinates "
        "with a coupled mass matrix would be too large; q̇ below stands for that solution."
    )


def _matrix_form_lines(
    mechanics: Mechanics, shown: dict[str, str], latex: dict[str, str]
) -> list[Part]:
    """The derivation of a system in matrix form: M and F of ``M q̈ = F`` entry by entry,
    the momenta, H as ``½ (p − a)ᵀ M⁻¹ (p − a) − L₀`` and Hamilton's equations with the
    velocities left to the numerical solve (``latex``: the LaTeX of the scene's names)."""
    scene = mechanics.scene
    compact = _compact(mechanics)
    n = mechanics.n
    names = list(scene.coordinates)
    index = [_subscript(i, n) for i in range(n)]
    lines = _block("Lagrangian", [("L", mechanics.lagrangian, "L")])
    lines.append(Heading("Lagrange's equations: M q̈ = F"))
    lines.append(
        "M = ∂²L/∂q̇∂q̇ is symmetric; its entries on and above the diagonal, then F "
        "(∂L/∂q, less the parts of d/dt ∂L/∂q̇ without accelerations, plus the effects):"
    )
    for i in range(n):  # one line each, renamed as text: n (n + 1) / 2 of them
        for j in range(i, n):
            entry = compact.mass_matrix[i][j]
            label = f"M{index[i]},{index[j]}"
            text = f"{label} = {_display_text(_text(entry), shown)}"
            lines.append(Row(label, entry, f"M_{{{i + 1},{j + 1}}}", text))
    lines += _row_parts([(f"F{index[i]}", compact.forcing[i], f"F_{{{i + 1}}}") for i in range(n)])
    lines.append(
        f"(the accelerations are not formed symbolically: M, {n} by {n} and coupled, is "
        "factorised numerically at every step)"
    )
    lines.append(Heading("Generalized momenta p = ∂L/∂q̇ = M q̇ + a"))
    rows = [
        (shown[f"p_{q}"], m, latex[f"p_{q}"]) for q, m in zip(names, compact.momenta, strict=True)
    ]
    lines += _row_parts(rows)
    lines.append(Heading("Hamiltonian"))
    lines.append("H = ½ (p − a)ᵀ M⁻¹ (p − a) − L₀, with M as above,")
    if all(a == 0 for a in compact.shift):
        lines.append("a = ∂L/∂q̇ at q̇ = 0: zero (no terms linear in the velocities), and")
    else:
        lines.append("a = ∂L/∂q̇ at q̇ = 0 (the terms linear in the velocities):")
        lines += _row_parts(
            [(f"a{index[i]}", a, f"a_{{{i + 1}}}") for i, a in enumerate(compact.shift)]
        )
    lines.append(Row("L₀ = L at q̇ = 0", compact.rest, "L_{0}", note="L at q̇ = 0"))
    lines.append(matrix_form_sentence(mechanics))
    half = "H = \\frac{1}{2} (p - a) \\cdot \\dot{q} - L_{0}"
    lines += _row_parts([("H = (p − a)·q̇/2 − L₀", compact.hamiltonian, half)])
    lines.append(Heading("Hamilton's equations (q̇ solved from M q̇ = p − a)"))
    rows = [(f"d{shown[q]}/dt", sympy.Symbol(f"{q}_dot"), latex[q]) for q in names]
    rows = [(label, e, f"\\frac{{d{name}}}{{dt}}") for label, e, name in rows]
    for i, (q, e) in enumerate(zip(names, compact.pdot, strict=True)):
        partial = f"\\frac{{\\partial L}}{{\\partial {latex[q]}}} + Q_{{{i + 1}}}"
        label = f"d{shown[f'p_{q}']}/dt = ∂L/∂{shown[q]} + Q{index[i]}"
        rows.append((label, e, f"{_dotted(f'p_{q}', latex)} = {partial}"))
    lines += _row_parts(rows)
    return lines


def particles_lines(scene: Scene) -> list[Part]:
    """The particles of a scene: transformation equations, velocities, T = T2 + T1 + T0,
    the gravitational V, and whether the transformation is rheonomic.

    Parameters
    ----------
    scene : Scene
        A scene with ``particles`` (``[]`` for one without).

    Returns
    -------
    list of Part
        Parts of a derivation (``text_lines`` writes them), starting with a heading.
    """
    derived = scene.transformation
    if derived is None:
        return []

    def vector(components) -> str:
        shown = [one_line(for_display(c, scene)) for c in components]
        return "(" + ", ".join(shown) + ")"

    lines: list[Part] = [Heading("Particles: transformation equations r = r(q, t)")]
    for name, mass, position in zip(derived.names, derived.masses, derived.positions, strict=True):
        m = one_line(for_display(mass, scene))
        text = f"r_{name} = {vector(position)}, mass {m}"
        r = f"\\mathbf{{r}}_{{{latex_name(name)}}}"
        lines.append(Row(f"r_{name}", sympy.Tuple(*position), r, text, f"mass {m}"))
    lines.append(Heading("Velocities v = dr/dt = (∂r/∂q)·q̇ + ∂r/∂t"))
    for name, velocity in zip(derived.names, derived.velocities, strict=True):
        v = f"\\mathbf{{v}}_{{{latex_name(name)}}}"
        lines.append(Row(f"v_{name}", sympy.Tuple(*velocity), v, f"v_{name} = {vector(velocity)}"))
    T2, T1, T0 = derived.kinetic_parts
    rows = [
        Row("T₂ (quadratic in q̇)", T2, "T_{2}", note="quadratic in q̇"),
        Row("T₁ (linear in q̇)", T1, "T_{1}", note="linear in q̇"),
        Row("T₀ (free of q̇)", T0, "T_{0}", note="free of q̇"),
    ]
    if scene.gravity is not None:
        gravity = "V = -\\sum m \\, \\mathbf{g} \\cdot \\mathbf{r}"
        rows.append(Row("V from gravity = −Σ m g·r", derived.potential, gravity, note="gravity"))
    lines += [Heading("Kinetic energy T = Σ m |v|²/2 = T₂ + T₁ + T₀"), *rows]
    if derived.depends_on_time:
        lines.append(
            "The transformation is rheonomic: some r depends on t explicitly, so T has "
            "parts T₁ and T₀ as well as T₂ (in general)."
        )
    else:
        lines.append(
            "The transformation is scleronomic: no r depends on t explicitly, so T = T₂ is "
            "quadratic in the velocities."
        )
    return lines


def degrees_of_freedom_sentence(mechanics: Mechanics) -> str:
    """``degrees of freedom: f`` and, with constraints, where f comes from.

    With nonholonomic constraints both counts are given: the velocity degrees of freedom
    (coordinates minus independent holonomic and nonholonomic constraints, the f of
    ``derive --json``) and the configuration's (nonholonomic constraints do not reduce
    the coordinates). Unilateral constraints reduce neither.
    """
    from systems.constraints import (
        configuration_degrees_of_freedom,
        counts,
        degrees_of_freedom,
    )

    f, n, k = degrees_of_freedom(mechanics), mechanics.n, counts(mechanics.scene)
    if not sum(k.values()):
        return f"degrees of freedom: {f} (one per coordinate, no constraints)"
    kh = n - configuration_degrees_of_freedom(mechanics)
    if k["nonholonomic"]:
        kn = n - f - kh
        holonomic = f"{kh} independent holonomic − " if kh else ""
        text = (
            f"degrees of freedom: {f} for the velocities = {n} coordinates − {holonomic}"
            f"{kn} nonholonomic constraint{'s' if kn != 1 else ''}; "
            f"the configuration needs {n - kh} coordinates (nonholonomic constraints do not "
            "integrate to equations between them)"
        )
    elif k["holonomic"]:
        plural = "s" if kh != 1 else ""
        text = f"degrees of freedom: {f} = {n} coordinates − {kh} independent constraint{plural}"
    else:
        text = f"degrees of freedom: {f} (one per coordinate)"
    if k["unilateral"]:
        text += (
            f"; {k['unilateral']} unilateral constraint{'s' if k['unilateral'] != 1 else ''} "
            "g ≥ 0 restrict where the system may go, not how many coordinates it needs"
        )
    return text


def constraints_lines(mechanics: Mechanics) -> list[Part]:
    """The constraints (holonomic Φ(q, t) = 0 with γ, nonholonomic a·q̇ + b = 0 with γ,
    unilateral g(q, t) ≥ 0 with the coefficient of restitution) and a sentence on the
    equations with multipliers, or ``[]`` for a scene without constraints."""
    from systems.constraints import RESTITUTION, restitution_index, rows

    pieces = rows(mechanics)
    if pieces is None:
        return []
    scene = mechanics.scene
    index = [_subscript(i, pieces.k) for i in range(pieces.k)]
    lines: list[Part] = []
    titles = {
        "holonomic": ("Holonomic constraints Φ(q, t) = 0", "Φ", "\\Phi"),
        "nonholonomic": ("Nonholonomic constraints a(q, t)·q̇ + b(q, t) = 0", "Ψ", "\\Psi"),
        "unilateral": ("Unilateral constraints g(q, t) ≥ 0", "g", "g"),
    }
    for kind, (title, letter, latex) in titles.items():
        chosen = [i for i, k in enumerate(pieces.kinds) if k == kind]
        if not chosen:
            continue
        rows_ = [(f"{letter}{index[i]}", pieces.values[i], f"{latex}_{{{i + 1}}}") for i in chosen]
        if kind != "unilateral":
            rows_ += [(f"γ{index[i]}", pieces.gamma[i], f"\\gamma_{{{i + 1}}}") for i in chosen]
        lines += _block(title, rows_)
    lines.append(
        "The equations below are those of the free coordinates. With the constraints they "
        "carry one Lagrange multiplier λ each: M q̈ + Aᵀ λ = F and A q̈ = γ, with A the "
        "rows ∂Φ/∂q and a, solved for q̈ and λ at every step; ṗ gets the constraint force "
        "−Aᵀ λ, and every step is projected back onto the constraints (the constrained "
        "integrators)."
    )
    if "unilateral" in pieces.kinds:
        at = restitution_index(scene)
        e = "1 (elastic: the scene has no restitution parameter)"
        if at is not None:
            e = f"{scene.parameters[at][1]:g} (the parameter {RESTITUTION})"
        lines.append(
            "A unilateral constraint acts only in contact. Where a step reaches g = 0 it "
            "ends there: an impact reverses the normal velocity G q̇ + g_t times the "
            f"coefficient of restitution e = {e}; a rebound too slow to leave makes a "
            "resting contact, a row of A whose λ ≤ 0 pushes, released when λ would pull."
        )
    return lines


def constraints_json(mechanics: Mechanics) -> dict | None:
    """The constraints as JSON-ready data, or None without constraints, in the scene's
    names: ``holonomic`` (Φ_i), ``jacobian`` (rows of ∂Φ_i/∂q) and ``gamma`` (the
    right-hand sides of Φ_q q̈ = γ); ``nonholonomic`` (a·q̇ + b), ``coefficients`` (rows
    of a), ``free_terms`` (b) and ``nonholonomic_gamma`` (those of a q̈ = γ);
    ``unilateral`` (g, each ≥ 0), ``unilateral_gradient`` (rows of ∂g/∂q) and
    ``restitution`` (e, 1 without the parameter; None without unilateral constraints);
    ``multipliers`` (the CSV columns, one per constraint in this order);
    ``configuration_degrees_of_freedom`` (n minus independent holonomic constraints) and
    ``velocity_degrees_of_freedom`` (the top-level ``degrees_of_freedom``: nonholonomic
    constraints subtracted too)."""
    from systems.constraints import (
        configuration_degrees_of_freedom,
        degrees_of_freedom,
        multiplier_names,
        restitution_index,
        rows,
    )

    pieces = rows(mechanics)
    if pieces is None:
        return None
    scene = mechanics.scene
    n = mechanics.n

    def kind(name: str) -> list[int]:
        return [i for i, k in enumerate(pieces.kinds) if k == name]

    def matrix(chosen: list[int]) -> list[list[str | None]]:
        return [[_text(pieces.jacobian[i, j], scene) for j in range(n)] for i in chosen]

    def texts(values, chosen: list[int]) -> list[str | None]:
        return [_text(values[i], scene) for i in chosen]

    h, nh, u = kind("holonomic"), kind("nonholonomic"), kind("unilateral")
    at = restitution_index(scene)
    restitution = None
    if u:
        restitution = 1.0 if at is None else float(scene.parameters[at][1])
    return {
        "holonomic": texts(pieces.values, h),
        "jacobian": matrix(h),
        "gamma": texts(pieces.gamma, h),
        "nonholonomic": texts(pieces.values, nh),
        "coefficients": matrix(nh),
        "free_terms": texts(pieces.time_derivative, nh),
        "nonholonomic_gamma": texts(pieces.gamma, nh),
        "unilateral": texts(pieces.values, u),
        "unilateral_gradient": matrix(u),
        "restitution": restitution,
        "multipliers": multiplier_names(scene),
        "configuration_degrees_of_freedom": configuration_degrees_of_freedom(mechanics),
        "velocity_degrees_of_freedom": degrees_of_freedom(mechanics),
    }


def particles_json(scene: Scene) -> dict | None:
    """The particles of a scene as JSON-ready data, or None for a scene without them.

    Returns
    -------
    dict or None
        ``positions`` (name -> the components of r(q, t)), ``velocities`` (name -> the
        components of dr/dt in q, q̇, t), ``masses`` (name -> m), ``kinetic``
        (``{"T2", "T1", "T0"}``: the parts of T quadratic, linear and free of the
        velocities), ``gravity_potential`` (V = −Σ m g·r, "0" without gravity) and
        ``transformation_depends_on_time`` (True exactly when some r depends on t
        explicitly: a rheonomic transformation).
    """
    derived = scene.transformation
    if derived is None:
        return None
    T2, T1, T0 = derived.kinetic_parts
    return {
        "positions": {
            name: [_text(c) for c in r]
            for name, r in zip(derived.names, derived.positions, strict=True)
        },
        "velocities": {
            name: [_text(c) for c in v]
            for name, v in zip(derived.names, derived.velocities, strict=True)
        },
        "masses": dict(zip(derived.names, map(_text, derived.masses), strict=True)),
        "kinetic": {"T2": _text(T2), "T1": _text(T1), "T0": _text(T0)},
        "gravity_potential": _text(derived.potential),
        "transformation_depends_on_time": derived.depends_on_time,
    }


def _subscript(i: int, n: int) -> str:
    """Subscript digits of coordinate ``i`` (0-based) of ``n``: ₁, ₁₂."""
    return str(i + 1).translate(str.maketrans("0123456789", "₀₁₂₃₄₅₆₇₈₉"))


def derivation_text(mechanics: Mechanics) -> str:
    """The derivation laid out for a person without the equilibria (the window shows
    them apart, when their search has finished: ``equilibria_lines``)."""
    return readable(mechanics, equilibria=False)


@remembered_job
def equilibria_lines(mechanics: Mechanics) -> list[str]:
    """One sentence per equilibrium (virtual work), or why there are none."""
    lines, note = equilibria_sentences(mechanics, digits=4)
    if not lines:
        return [f"no equilibrium: {note}" if note else "no equilibrium found"]
    return lines


def equilibria_sentences(mechanics: Mechanics, digits: int = 6) -> tuple[list[str], str]:
    """One sentence per equilibrium (virtual work, small oscillations), and the search's note.

    Parameters
    ----------
    mechanics : Mechanics
        A derived scene; its equilibria are searched at the scene's parameter values.
    digits : int
        Significant digits of coordinates and frequencies.

    Returns
    -------
    sentences : list[str]
        ``"θ = 0: stable, ω = 3.13"`` or ``"θ = 3.14: unstable (maximum)"``, one per
        equilibrium; a gyroscopically stabilized one, a degenerate one (what decided it)
        and a set of equilibria (``"the circle x² + y² = 1 (through x = 1, y = 0): a curve
        of equilibria, neutral along it; stable across it, ω = 1.414"``) say so.
    note : str
        Why there are none, or what the search assumed; empty if nothing to say.
    """
    from systems.textbook import floquet, search_equilibria

    if floquet.explicit_time(mechanics):  # driven: constant solutions, Floquet multipliers
        return floquet.report(mechanics, display_names(mechanics.scene), digits)
    search = search_equilibria(mechanics)
    if search.method == "not computed":  # saying "none" would be a wrong answer
        return [search.reason[0].upper() + search.reason[1:]], ""
    shown = display_names(mechanics.scene)
    unilateral = set()
    if search.multipliers:
        kinds = constraints.rows(mechanics).kinds
        unilateral = {
            n for n, k in zip(search.multipliers, kinds, strict=True) if k == "unilateral"
        }
    lines = []
    for eq in search.equilibria:
        where = ", ".join(f"{shown.get(k, k)} = {v:.{digits}g}" for k, v in eq.q.items())
        omegas = ", ".join(f"{w:.{digits}g}" for w in eq.frequencies)
        rates = ", ".join(f"{r:.{digits}g}" for r in eq.growth_rates)
        gyroscopic = bool(np.any(np.asarray(eq.gyroscopic) != 0))
        if eq.continuum is not None:
            what = {1: "a curve", 2: "a surface"}.get(
                eq.continuum.dimension, f"a {eq.continuum.dimension}-dimensional set"
            )
            across = "unstable across it"
            if eq.stable:  # no frequency where nothing is across (a set as wide as the space)
                across = f"stable across it, \u03c9 = {omegas}" if omegas else "stable across it"
            if not eq.stable and rates:
                across += f" (growth rate {rates})"
            through = "" if "through" in eq.continuum.description else f" (through {where})"
            if eq.continuum.dimension >= mechanics.n:  # no direction is across it
                lines.append(  # U may be constant on a part of the space only
                    f"U is constant around {where}: every configuration there is an "
                    "equilibrium, neutral (a body at rest stays at rest)"
                )
                continue
            lines.append(
                f"{eq.continuum.description}{through}: {what} of equilibria, neutral along it; "
                f"{across}"
            )
        elif eq.kind == "degenerate":
            verdict = "stable" if eq.stable else "unstable"
            if eq.verdict == "undecided":
                verdict = "stability undecided"
            frequencies = f", \u03c9 = {omegas}" if eq.stable and omegas else ""
            lines.append(f"{where}: {verdict}{frequencies}; {eq.decided_by}")
        elif eq.stable and not eq.frequencies and eq.multipliers and eq.decided_by:
            lines.append(f"{where}: stable, without oscillation: {eq.decided_by}")
        elif eq.stable and not eq.frequencies:
            lines.append(
                f"{where}: stable, with no small-oscillation frequency (the inertia there is "
                "zero or infinite, so the motion is not harmonic)"
            )
        elif eq.stable and eq.kind != "minimum":
            lines.append(
                f"{where}: stable by gyroscopic stabilization (U has a {eq.kind}), "
                f"\u03c9 = {omegas}"
            )
        elif eq.stable:
            extra = " (with the gyroscopic terms)" if gyroscopic else ""
            lines.append(f"{where}: stable, \u03c9 = {omegas}{extra}")
        elif gyroscopic and rates:
            lines.append(f"{where}: unstable ({eq.kind}), growth rate {rates}")
        else:
            lines.append(f"{where}: unstable ({eq.kind})")
        if eq.multipliers and "\u03bb" not in lines[-1]:  # (unless said already)
            lines[-1] += "; constraint force " + _constraint_force(eq, unilateral, digits)
    return lines, search.reason or ""


def _constraint_force(eq, unilateral: set[str], digits: int) -> str:
    """``"λ₁ = 4.905"``, ``"λ₁ = -9.81 (in contact)"``: the multipliers of an equilibrium
    on constraints; those of the unilateral constraints out of contact are left out."""
    subscripts = str.maketrans(
        "0123456789", "\u2080\u2081\u2082\u2083\u2084\u2085\u2086\u2087\u2088\u2089"
    )
    parts = []
    for name, value in eq.multipliers.items():
        if name in unilateral and name not in eq.contacts:
            continue
        label = "\u03bb" + name.rsplit("_", 1)[-1].translate(subscripts)
        contact = " (in contact)" if name in eq.contacts else ""
        parts.append(f"{label} = {value:.{digits}g}{contact}")
    return ", ".join(parts) if parts else "no constraint force (every contact free)"


def derivation_json(mechanics: Mechanics) -> dict:
    """The derivation as JSON-ready data.

    Parameters
    ----------
    mechanics : Mechanics
        A derived scene; its equilibria are searched too.

    Returns
    -------
    dict
        ``title``, ``coordinates``, ``parameters``, ``lagrangian``, ``accelerations``
        (None when M cannot be solved symbolically), ``momenta``, ``hamiltonian``,
        ``hamilton_equations``, ``cyclic``, ``conserved``, ``classification``,
        ``equilibria``, ``matrix_form`` (bool), ``mass_matrix``, ``shift`` and
        ``rest`` (None unless ``matrix_form``), and ``particles`` (``particles_json``:
        the transformation equations, None without particles), ``degrees_of_freedom``
        (coordinates minus independent holonomic and nonholonomic constraints: the
        velocity degrees of freedom) and ``constraints``
        (``constraints_json``, None without constraints; the accelerations and
        Hamilton's equations are then those of the free coordinates, without the
        multipliers' force), with the scene's own names; every expression is a string
        that ``sympy.sympify`` reads back.

        For a system in matrix form (``Mechanics.matrix_form``: many coordinates and a
        coupled mass matrix) the velocities are not solved in closed form:
        ``mass_matrix`` (n rows of n strings) is M(q, t) = ∂²L/∂q̇∂q̇, ``shift`` (n
        strings) is a(q, t) = ∂L/∂q̇ at q̇ = 0 and ``rest`` is L0(q, t) = L at q̇ = 0, so
        that ``L = q̇ᵀ M q̇/2 + a·q̇ + L0``; in ``hamiltonian`` (``(p - a)·q̇/2 - L0``) and
        ``hamilton_equations`` (``q̇_i`` and ``∂L/∂q_i + Q_i``) each ``<q>_dot`` stands
        for the solution of ``M q̇ = p - a``, which the integrators compute numerically
        at every step; ``accelerations`` is None. M, a, the momenta ``M q̇ + a``, the
        ``p_<q>`` equations and the conserved quantities are tidied for reading (sines
        and cosines combined) where that was checked to give the same values.
    """
    from systems.constraints import degrees_of_freedom
    from systems.mechanics import DerivationError
    from systems.textbook import equilibria_json

    scene = mechanics.scene

    def read(expr) -> str | None:
        return _text(expr, scene)

    try:
        accelerations = dict(
            zip(scene.coordinates, map(read, mechanics.accelerations()), strict=True)
        )
    except DerivationError:
        accelerations = None
    names = list(scene.coordinates) + list(scene.momentum_names)
    momenta = mechanics.momenta
    equations = list(mechanics.hamilton_equations)
    conserved = dict(mechanics.conserved)
    hamiltonian = mechanics.hamiltonian
    form = mechanics.matrix_form
    matrix = {"matrix_form": form is not None, "mass_matrix": None, "shift": None, "rest": None}
    if form is not None:
        compact = _compact(mechanics)
        momenta = compact.momenta
        equations[mechanics.n :] = compact.pdot
        conserved.update(compact.conserved)
        hamiltonian = compact.hamiltonian
        matrix["mass_matrix"] = [[_text(e) for e in row] for row in compact.mass_matrix]
        matrix["shift"] = [_text(e) for e in compact.shift]
        matrix["rest"] = _text(compact.rest)
    return {
        "title": scene.title,
        "coordinates": list(scene.coordinates),
        "parameters": scene.parameter_values,
        "lagrangian": read(mechanics.lagrangian),
        "accelerations": accelerations,
        "momenta": None
        if momenta is None
        else dict(zip(scene.coordinates, map(read, momenta), strict=True)),
        "hamiltonian": read(hamiltonian),
        "hamilton_equations": dict(zip(names, map(read, equations), strict=True)),
        "cyclic": list(mechanics.cyclic),
        "conserved": {name: read(expr) for name, expr in conserved.items()},
        "classification": mechanics.classification.as_dict(),
        "equilibria": equilibria_json(mechanics),
        "floquet": _floquet_json(mechanics),
        **matrix,
        "particles": particles_json(scene),
        "degrees_of_freedom": degrees_of_freedom(mechanics),
        "constraints": constraints_json(mechanics),
    }


def _floquet_json(mechanics: Mechanics) -> dict | None:
    """``floquet.derive_json``, which is None for a system whose L (or H) has no t at all:
    decided here, without importing ``systems.textbook.floquet`` for it."""
    expression = mechanics.lagrangian if mechanics.lagrangian is not None else None
    if expression is None:
        expression = mechanics.hamiltonian
    if not as_expr(expression).has(mechanics.t):
        return None
    from systems.textbook import floquet

    return floquet.derive_json(mechanics)


def _for_reading(expr: sympy.Basic, scene: Scene) -> sympy.Basic:
    """``expr`` (or both sides of an equation) tidied for reading: the derivation keeps
    its expressions as derived. Systems of more than ``SYMBOLIC_INVERSE_LIMIT``
    coordinates are shown as derived (tidying each of a 32-particle lattice's 64
    equations took 8 s, for a display no one reads in full)."""
    from systems.mechanics import SYMBOLIC_INVERSE_LIMIT

    if len(scene.coordinates) > SYMBOLIC_INVERSE_LIMIT:
        return expr
    if isinstance(expr, sympy.Eq):
        return sympy.Eq(tidied(expr.lhs), tidied(expr.rhs), evaluate=False)
    return tidied(expr) if isinstance(expr, sympy.Expr) else expr


def _text(expr, scene: Scene | None = None) -> str | None:
    """An expression (sympy, or symengine from ``_Compact``) as text sympify reads back;
    with ``scene``, tidied for reading first (``_for_reading``)."""
    if expr is None:
        return None
    if not isinstance(expr, sympy.Basic):
        return str(expr)
    if scene is not None:
        expr = _for_reading(expr, scene)
    return sympy.sstr(expr, order="none") if _larger(expr, SORTED_NODES) else str(expr)


def _display_text(text: str, names: dict[str, str]) -> str:
    """The text of an expression with the scene's names replaced by display names
    (``systems.display``) and ``_glyphs``: ``one_line`` without sympy."""
    text = re.sub(r"\b[A-Za-z_]\w*\b", lambda m: names.get(m[0], m[0]), text)
    return _glyphs(text)


def _larger(expr: sympy.Basic, limit: int) -> bool:
    """True if ``expr`` has more than ``limit`` nodes (counting stops there)."""
    if not isinstance(expr, sympy.Basic):
        return False
    for count, _ in enumerate(sympy.preorder_traversal(expr)):
        if count >= limit:
            return True
    return False


def _block(title: str, rows: list[tuple[str, object, str]]) -> list[Part]:
    """A heading and its rows, each ``(label, expression, LaTeX label)``."""
    return [Heading(title), *_row_parts(rows)]


def _row_parts(rows: list[tuple[str, object, str]]) -> list[Row]:
    return [Row(label, expr, latex) for label, expr, latex in rows]


def _rows(rows: list[Row | tuple[str, object]], scene: Scene) -> list[str]:
    """``label = expression`` lines: sympy's pretty printer for small expressions, one
    line of text for large ones (``PRETTY_NODES``)."""
    lines = []
    names = None
    for row in rows:
        label, expr = (row.label, row.expr) if isinstance(row, Row) else row
        if not isinstance(expr, sympy.Basic):  # symengine, from ``_Compact``
            text = str(expr)
            if len(text) > PRETTY_CHARS:  # renamed as text: no sympy at all
                names = names or display_names(scene)
                lines.append(f"{label} = {_display_text(text, names)}")
                continue
            expr = as_expr(expr)
        shown = for_display(_for_reading(expr, scene), scene)
        head = f"{label}: " if isinstance(expr, sympy.Eq) else f"{label} = "
        if _larger(shown, PRETTY_NODES):
            if isinstance(shown, sympy.Eq):
                lines.append(head + f"{one_line(shown.lhs)} = {one_line(shown.rhs)}")
            else:
                lines.append(head + one_line(shown))
            continue
        art = sympy.pretty(shown, use_unicode=True, wrap_line=False).splitlines() or [""]
        middle = len(art) // 2
        for i, line in enumerate(art):
            lines.append((head if i == middle else " " * len(head)) + line)
    return lines


# -- a system in matrix form, for reading ------------------------------------------------------


@dataclass(frozen=True)
class _Compact:
    """The parts of a system in matrix form, tidied for reading and checked numerically
    against the derivation's (an entry that does not agree is shown as derived).

    ``mass_matrix`` (n lists of n), ``shift`` and ``rest`` are M, a and L0 of
    ``L = q̇ᵀ M q̇/2 + a·q̇ + L0``; ``forcing`` is F of ``M q̈ = F``, written from M, a and
    L0 (Christoffel symbols: a few terms per entry where the derivation's F, the
    unexpanded derivative of L, has thousands); ``momenta`` is M q̇ + a; ``pdot`` is
    ∂L/∂q + Q; ``conserved`` holds H in (q, q̇) as ``q̇ᵀ M q̇/2 − L0`` and the cyclic
    momenta, when they are conserved (a Noether charge, ``L_z`` or a ``[symmetries]``
    name, is not in it: it is shown as derived); ``hamiltonian`` is ``(p − a)·q̇/2 − L0`` (with q̇
    standing for ``M⁻¹ (p − a)``). M, a and L0 are sympy expressions; the others are
    symengine expressions (sympy where symengine is missing, or where the derived form
    is shown instead): ``_rows`` and ``_text`` print either.
    """

    mass_matrix: list[list[sympy.Expr]]
    shift: list[sympy.Expr]
    rest: sympy.Expr
    forcing: list
    momenta: list
    pdot: list
    conserved: dict
    hamiltonian: sympy.Expr


_COMPACT: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def _compact(mechanics: Mechanics) -> _Compact:
    """``_Compact`` of a system in matrix form, formed once per ``Mechanics``."""
    try:
        return _COMPACT[mechanics]
    except KeyError:
        pass
    except TypeError:  # not weak-referenceable
        return _form_compact(mechanics)
    compact = _COMPACT[mechanics] = _form_compact(mechanics)
    return compact


def _form_compact(mechanics: Mechanics) -> _Compact:
    form = mechanics.matrix_form
    n, q, t = mechanics.n, mechanics.q, mechanics.t
    upper = [(i, j) for i in range(n) for j in range(i, n)]
    checker = _Checker(mechanics)
    chosen = checker.choose(
        [(form.mass_matrix[i, j], combine_trig(form.mass_matrix[i, j])) for i, j in upper]
        + [(e, _tidy_small(e)) for e in (*form.shift, form.rest)]
    )
    M = [[None] * n for _ in range(n)]
    for (i, j), entry in zip(upper, chosen, strict=False):
        M[i][j] = M[j][i] = entry
    a, L0 = chosen[len(upper) : len(upper) + n], chosen[-1]
    arguments = (M, a, L0, mechanics.generalized_forces, q, mechanics.qdot, t)
    try:
        forcing, pdot, momenta, energy = _compact_parts(_Algebra(mechanics), *arguments)
    except Unsupported:
        forcing, pdot, momenta, energy = _compact_parts(
            _Algebra(mechanics, engine=False), *arguments
        )
    conserved = {}
    for name in mechanics.conserved:
        if name == "H":
            conserved[name] = energy
        elif name.startswith("p_") and name[2:] in mechanics.scene.coordinates:
            conserved[name] = momenta[mechanics.scene.coordinates.index(name[2:])]
        # other names are Noether charges (systems.symmetries): shown as derived
    derived_momenta = mechanics.momenta or [None] * n
    derived = [
        *mechanics.forcing,
        *derived_momenta,
        *mechanics.hamilton_equations[n:],
        *(mechanics.conserved[name] for name in conserved),
    ]
    shifted = [p - e for p, e in zip(mechanics.p, a, strict=True)]
    hamiltonian = sympy.Add(*[s * v for s, v in zip(shifted, mechanics.qdot, strict=True)]) / 2
    derived.append(mechanics.hamiltonian)
    tidy = [*forcing, *momenta, *pdot, *conserved.values(), hamiltonian - L0]
    chosen = checker.choose(
        [
            (None if d is not None and _larger(d, VERIFY_NODES) else d, e)
            for d, e in zip(derived, tidy, strict=True)
        ]
    )
    return _Compact(
        mass_matrix=M,
        shift=a,
        rest=L0,
        forcing=chosen[:n],
        momenta=chosen[n : 2 * n],
        pdot=chosen[2 * n : 3 * n],
        conserved=dict(zip(conserved, chosen[3 * n : -1], strict=True)),
        hamiltonian=chosen[-1],
    )


VERIFY_NODES = 2000
"""Derived expressions up to this size are compared numerically with their tidy forms. A
larger one (a long chain's F, ∂L/∂q, momenta, energy: hundreds of thousands of nodes in
all) is not: converting it for evaluation cost seconds. Its tidy form is written from M
and a, which are always compared, by identities of any L quadratic in the velocities."""


def _compact_parts(algebra, M, a, L0, forces, q, v, t):
    """F of ``M q̈ = F``, ∂L/∂q + Q, the momenta M q̇ + a and the energy function
    q̇ᵀ M q̇/2 − L0 of ``L = q̇ᵀ M q̇/2 + a·q̇ + L0``, from M, a and L0 (sympy lists).

    F_i = Σ_{j≤k} C_ijk q̇_j q̇_k + Σ_j (∂_i a_j − ∂_j a_i − ∂_t M_ij) q̇_j + ∂_i L0 − ∂_t a_i
    + Q_i, with C_ijj = ½ ∂_i M_jj − ∂_j M_ij and C_ijk = ∂_i M_jk − ∂_k M_ij − ∂_j M_ik
    (j < k): Lagrange's equations less M q̈, by the Christoffel symbols of M.
    """
    n = len(q)
    to = algebra.to
    Ms = [[to(M[i][j]) if j >= i else None for j in range(n)] for i in range(n)]
    for i in range(n):
        for j in range(i):
            Ms[i][j] = Ms[j][i]
    As = [to(e) for e in a]
    L0s, Qs = to(L0), [to(e) for e in forces]
    vs = [to(e) for e in v]
    variables = (*q, t)
    T = n  # index of t in ``variables``
    dM = []  # dM[k][i][j] = ∂M_ij/∂x_k for x = (q..., t)
    for x in variables:
        rows = [[None] * n for _ in range(n)]
        for i in range(n):
            for j in range(i, n):
                rows[i][j] = rows[j][i] = algebra.diff(Ms[i][j], x)
        dM.append(rows)
    da = [[algebra.diff(e, x) for e in As] for x in variables]
    dL0 = [algebra.diff(L0s, x) for x in q]
    zero = algebra.zero
    forcing, pdot = [], []
    for i in range(n):
        f_terms, g_terms = [], []
        for j in range(n):
            for k in range(j, n):
                if j == k:
                    g = dM[i][j][j] / 2
                    c = g - dM[j][i][j]
                else:
                    g = dM[i][j][k]
                    c = g - dM[k][i][j] - dM[j][i][k]
                if c != zero:
                    f_terms.append(c * vs[j] * vs[k])
                if g != zero:
                    g_terms.append(g * vs[j] * vs[k])
            b = da[i][j] - da[j][i] - dM[T][i][j]
            if b != zero:
                f_terms.append(b * vs[j])
            if da[i][j] != zero:
                g_terms.append(da[i][j] * vs[j])
        f_terms += [dL0[i], -da[T][i], Qs[i]]
        g_terms += [dL0[i], Qs[i]]
        forcing.append(algebra.add(f_terms))
        pdot.append(algebra.add(g_terms))
    momenta = [algebra.add([Ms[i][j] * vs[j] for j in range(n)] + [As[i]]) for i in range(n)]
    energy = algebra.add([Ms[i][j] * vs[i] * vs[j] for i in range(n) for j in range(n)]) / 2 - L0s
    return forcing, pdot, momenta, energy


class _Algebra:
    """Differentiation and sums in symengine (``systems.calculus``), or in sympy."""

    def __init__(self, mechanics: Mechanics, engine: bool = True):
        self.engine = engine and symengine is not None
        if self.engine:
            self.calculus = Calculus(mechanics.scene.symbols.values())
            self.zero = symengine.Integer(0)
        else:
            self.zero = sympy.S.Zero

    def to(self, expr):
        return self.calculus.to_engine(as_expr(expr)) if self.engine else as_expr(expr)

    def diff(self, expr, x):
        if self.engine:
            return expr.diff(self.calculus.variable(x))
        return sympy.diff(expr, x) if x in expr.free_symbols else sympy.S.Zero

    def add(self, terms):
        return symengine.add(*terms) if self.engine else sympy.Add(*terms)


class _Checker:
    """Chooses the tidied form of an expression where it equals the derived one at random
    real points (every symbol in (0.3, 1.7), as the derivation's zero tests do); the
    derived one otherwise, and wherever the values cannot be computed."""

    def __init__(self, mechanics: Mechanics):
        rng = random.Random(4321)
        self.symbols = list(mechanics.scene.symbols.values())
        self.points = [[rng.uniform(0.3, 1.7) for _ in self.symbols] for _ in range(2)]

    def choose(self, pairs: list[tuple]) -> list:
        """For each ``(derived, tidy)``: tidy if it checks out (or derived is None), else
        derived. All are evaluated at once (symengine's Lambdify)."""
        result = [tidy if derived is None else derived for derived, tidy in pairs]
        checked = [k for k, (d, e) in enumerate(pairs) if d is not None and e is not d]
        if not checked:
            return result
        values = self._values([pairs[k][0] for k in checked] + [pairs[k][1] for k in checked])
        if values is None:
            return result
        m = len(checked)
        for index, k in enumerate(checked):
            a, b = values[:, index], values[:, m + index]
            close = np.abs(a - b) <= 1e-9 * np.maximum(1.0, np.abs(a))
            if np.all(np.isfinite(a)) and np.all(close):
                result[k] = pairs[k][1]
        return result

    def _values(self, exprs: list):
        """(points, len(exprs)) complex values, or None if they cannot be computed."""
        if symengine is None:
            return None
        try:
            f = symengine.Lambdify(
                [symengine.Symbol(s.name) for s in self.symbols],
                [to_symengine(e) for e in exprs],
                real=False,
            )
            with np.errstate(all="ignore"):
                return np.array([np.ravel(f(point)) for point in self.points], dtype=complex)
        except (RuntimeError, TypeError, ValueError, NotImplementedError):
            return None


EXPAND_TERMS = 400
"""a and L0 are expanded before ``combine_trig`` when that gives at most this many terms
(a rotating frame's a_i is a sum of products of sums of sines and cosines)."""


def _tidy_small(expr: sympy.Expr) -> sympy.Expr:
    """The shortest of ``expr``, ``combine_trig(expr)`` and, when its expansion is small,
    ``combine_trig(expand(expr))`` with common factors pulled out."""
    expr = as_expr(expr)
    candidates = [expr, combine_trig(expr)]
    if expanded_terms(expr) <= EXPAND_TERMS:
        candidates.append(sympy.factor_terms(combine_trig(sympy.expand(expr))))
    return min(candidates, key=lambda e: len(str(e)))


def _equilibria_heading(mechanics: Mechanics) -> str:
    from systems.textbook import floquet

    if floquet.explicit_time(mechanics):
        return floquet.HEADING
    return "Equilibria (virtual work: dV/dq = 0)"


def _equilibria_lines(mechanics: Mechanics) -> list[Part]:
    lines, note = equilibria_sentences(mechanics)
    title: list[Part] = [Heading(_equilibria_heading(mechanics))]
    if not lines:
        return title + [f"none: {note}" if note else "none found"]
    return title + [f"- {line}" for line in lines] + ([f"({note})"] if note else [])
