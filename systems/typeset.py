"""The derivation typeset: each equation as LaTeX, and as the outlines of its glyphs.

``systems.report`` lays a derivation out in parts (``derivation_parts``); here each of
its ``Row`` equations becomes a ``Formula``: its LaTeX, from sympy's printer with the
scene's names (``theta1_dot`` -> ``\\dot{\\theta}_{1}``, ``systems.display.latex_names``),
which the window copies and ``derive --latex`` prints; and an ``Outline``, the glyphs of
that LaTeX as matplotlib's mathtext draws them (Computer Modern, no TeX install, no
pyplot), as vector paths at font size 1. The window scales an outline to its own font
and paints it in its palette's colour; exports draw the same paths as vectors.

All of it runs where the text is laid out: in a worker process for the window (the GUI
never runs sympy or the mathtext parser), in the command line's process for ``derive``.
An equation whose LaTeX mathtext refuses, or that is too large to set on one line, has
no outline and is shown as its text; its LaTeX can still be copied.
"""

from __future__ import annotations

import dataclasses
import functools
import re
import sys
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import sympy

from systems import report
from systems.derivation_cache import remembered_job
from systems.display import for_display, latex_names
from systems.expressions import as_expr

if TYPE_CHECKING:
    from systems.mechanics import Mechanics
    from systems.scene import Scene

LATEX_NODES = 3000
"""Expressions with more nodes get no LaTeX (printing them costs seconds, and nobody
pastes a twenty-link chain's forcing term into a handout): their text is copied instead."""

OUTLINE_CHARS = 1000
"""LaTeX longer than this is not set in type: one line of it would be many screens wide.
The window shows such an equation as wrapped text."""

FONT_FAMILY = "cm"
"""mathtext's font set: Computer Modern, as in the textbook."""

REFERENCE_SIZE = 100.0
"""The font size the outlines are measured at before scaling to 1 (matplotlib's own
``TextToPath.FONT_SCALE``)."""


@dataclass(frozen=True, eq=False)
class Outline:
    """The glyphs of a formula as paths, in ems (font size 1), y up, baseline at y = 0.

    ``vertices`` (N, 2) float32 and ``codes`` (N,) uint8 are a ``matplotlib.path.Path``
    (1 move, 2 line, 3 quadratic, 4 cubic Bézier, 79 close); ``width`` is the advance,
    ``ascent`` the height above the baseline, ``descent`` below it.
    """

    vertices: np.ndarray
    codes: np.ndarray
    width: float
    ascent: float
    descent: float


@dataclass(frozen=True)
class Heading:
    """A heading: ``level`` 0 is the scene's title, 1 a block's title."""

    title: str
    level: int = 1


@dataclass(frozen=True)
class Sentence:
    """A sentence of the derivation (a ``- `` at its start makes it an item of a list)."""

    text: str


@dataclass(frozen=True)
class Formula:
    """One equation: ``text`` on one line (``L = m·l²·θ̇²/2``), ``latex`` (None where too
    large), ``outline`` (None where not set in type), ``tag`` (``(1)``) and ``note``
    (``quadratic in q̇``).

    ``pieces``: the equation cut where a line may break (``break_pieces``), each set in
    type; side by side they are ``outline`` (or, where ``outline`` is a fraction, the same
    equation with ``1/D`` taken out of it). The first ``lead`` pieces end with the
    relation (``H =``): continuation lines are indented to its end. Empty where the
    equation has nowhere to break.
    """

    text: str
    latex: str | None
    outline: Outline | None
    tag: str = ""
    note: str = ""
    pieces: tuple[Outline, ...] = ()
    lead: int = 0


@dataclass(frozen=True)
class Typeset:
    """A derivation typeset: its parts in order, and the whole of it as ``text``
    (``systems.report.readable``'s)."""

    title: str
    parts: tuple[Heading | Sentence | Formula, ...]
    text: str

    @property
    def formulas(self) -> list[Formula]:
        return [part for part in self.parts if isinstance(part, Formula)]

    def latex_document(self) -> str:
        """The derivation as a LaTeX document (amsmath), for ``derive --latex``."""
        return latex_document(self)


def typeset_derivation(
    mechanics: Mechanics, equilibria: bool = False, outlines: bool = True
) -> Typeset:
    """The derivation of ``mechanics`` typeset (``equilibria``: with the equilibria, as
    ``readable``; the window shows them apart when their search ends).

    ``outlines=False`` leaves the glyphs out (``with_outlines`` adds them): the window
    shows the equations as text at once, and in type once a second worker has set them
    (mathtext's parser takes about 0.2 ms a character of LaTeX: seconds for a ten-link
    chain, a tenth of a second for a pendulum).
    """
    scene = mechanics.scene
    parts = report.derivation_parts(mechanics, equilibria)
    typeset: list[Heading | Sentence | Formula] = []
    for part in parts:
        if isinstance(part, report.Title):
            typeset.append(Heading(part.title, 0))
        elif isinstance(part, report.Heading):
            typeset.append(Heading(part.title))
        elif isinstance(part, report.Row):
            typeset.append(formula(part, scene, outlines))
        else:
            typeset.append(Sentence(part))
    text = "\n".join(report.text_lines(parts, scene))
    return Typeset(scene.title, tuple(typeset), text)


@remembered_job
def typeset_as_text(mechanics: Mechanics) -> Typeset:
    """``typeset_derivation`` without outlines and equilibria: the window's first job of a
    layout (a worker process runs it: a function by module and name). Remembered on disk
    for the scene (a second of sympy for the double pendulum, every opening)."""
    return typeset_derivation(mechanics, outlines=False)


def with_outlines(typeset: Typeset, set_in=None) -> Typeset:
    """``typeset`` with every formula's outline (``outline``) and line pieces (each
    formula's remembered on disk: ``set_in_type``, or ``set_in``)."""
    set_in = set_in_type if set_in is None else set_in
    parts = tuple(
        dataclasses.replace(part, **set_in(part.latex))
        if isinstance(part, Formula) and part.latex is not None and part.outline is None
        else part
        for part in typeset.parts
    )
    return dataclasses.replace(typeset, parts=parts)


class _NotKnown(Exception):
    pass


def _with_outlines_known(typeset: Typeset):
    """``with_outlines(typeset)`` from the disk alone, or ``derivation_cache.MISSING``."""
    from systems import derivation_cache

    tag = _type_tag()

    def known(latex: str) -> dict:
        value = derivation_cache.known_value(latex, tag)
        if value is derivation_cache.MISSING:
            raise _NotKnown
        return value

    try:
        return with_outlines(typeset, known)
    except _NotKnown:
        return derivation_cache.MISSING


with_outlines.from_cache = _with_outlines_known


def formula(row: report.Row, scene: Scene, outlines: bool = True) -> Formula:
    """A ``Row`` of the report as a ``Formula`` (with its outline if ``outlines``)."""
    expr = row.expr
    tag = ""
    if isinstance(expr, sympy.Eq):
        tag = row.label
    latex = row_latex(row, scene)
    typeset = set_in_type(latex) if latex is not None and outlines else {"outline": None}
    return Formula(text=_one_line(row, scene), latex=latex, tag=tag, note=row.note, **typeset)


def row_latex(row: report.Row, scene: Scene) -> str | None:
    """``latex_label = latex(expr)`` (``lhs = rhs`` for an equation), or None when the
    expression is too large (``LATEX_NODES``) or symengine's text of it is."""
    expr = row.expr
    if not isinstance(expr, sympy.Basic):  # symengine, from report._Compact
        if len(str(expr)) > report.PRETTY_CHARS:
            return None
        expr = as_expr(expr)
    if isinstance(expr, sympy.Tuple):
        items = [expression_latex(e, scene) for e in expr]
        if any(item is None for item in items):
            return None
        return f"{row.latex_label} = \\left({', '.join(items)}\\right)"
    if isinstance(expr, sympy.Eq):
        sides = [expression_latex(side, scene) for side in (expr.lhs, expr.rhs)]
        return None if None in sides else " = ".join(sides)
    body = expression_latex(expr, scene)
    return None if body is None else f"{row.latex_label} = {body}"


def expression_latex(expr: sympy.Basic, scene: Scene) -> str | None:
    """An expression tidied for reading, in LaTeX with the scene's names; None beyond
    ``LATEX_NODES``."""
    expr = report._for_reading(as_expr(expr), scene)
    if report._larger(expr, LATEX_NODES):
        return None
    names = latex_names(scene)
    symbols = {s: names[s.name] for s in expr.free_symbols if getattr(s, "name", "") in names}
    order = "none" if report._larger(expr, report.SORTED_NODES) else None
    return sympy.latex(expr, symbol_names=symbols, order=order)


def _one_line(row: report.Row, scene: Scene) -> str:
    """The row as one line of text: the report's own text where it has one."""
    if row.text is not None:
        return row.text
    expr = row.expr
    if not isinstance(expr, sympy.Basic):
        return f"{row.label} = {expr}"
    shown = for_display(report._for_reading(expr, scene), scene)
    if isinstance(shown, sympy.Eq):
        return f"{row.label}: {report.one_line(shown.lhs)} = {report.one_line(shown.rhs)}"
    return f"{row.label} = {report.one_line(shown)}"


# -- LaTeX within mathtext's subset -------------------------------------------------------

_REWRITES = (
    # sympy prints atan2 as an operator with a subscript 2
    (re.compile(r"\\operatorname\{atan\}_\{2\}"), r"\\mathrm{atan2}"),
    (re.compile(r"\\operatorname\{"), r"\\mathrm{"),
    (re.compile(r"\\text\{"), r"\\mathrm{"),
    # display style, as in an equation of the textbook: mathtext's \frac is set small
    (re.compile(r"\\[td]?frac\b"), r"\\dfrac"),
    (re.compile(r"\\(?:displaystyle|limits|nolimits)\b\s*"), ""),
)


def mathtext_of(latex: str) -> str:
    """``latex`` rewritten within matplotlib mathtext's subset (``\\operatorname`` and
    ``\\text`` as ``\\mathrm``, every fraction as ``\\dfrac``), as one math string."""
    for pattern, replacement in _REWRITES:
        latex = pattern.sub(replacement, latex)
    return f"${latex}$"


@functools.lru_cache(maxsize=4096)
def outline(latex: str) -> Outline | None:
    """The glyph outlines of ``latex`` set by mathtext, or None when mathtext refuses it
    (or it is longer than ``OUTLINE_CHARS``): then the formula is shown as text."""
    if len(latex) > OUTLINE_CHARS:
        return None
    try:
        return _outline(mathtext_of(latex))
    except Exception:  # noqa: BLE001 - mathtext raises ValueError and others on bad input
        return None


@functools.cache
def _text_to_path():
    from matplotlib.font_manager import FontProperties
    from matplotlib.textpath import TextToPath

    prop = FontProperties(size=REFERENCE_SIZE, math_fontfamily=FONT_FAMILY)
    return TextToPath(), prop


def _outline(math: str) -> Outline:
    maker, prop = _text_to_path()
    width, height, descent = maker.get_text_width_height_descent(math, prop, ismath=True)
    vertices, codes = maker.get_text_path(prop, math, ismath=True)
    scale = 1.0 / REFERENCE_SIZE  # the paths come at matplotlib's FONT_SCALE, 100
    vertices = np.asarray(vertices, dtype=np.float32).reshape(-1, 2) * np.float32(scale)
    return Outline(
        vertices=vertices,
        codes=np.asarray(codes, dtype=np.uint8),
        width=width * scale,
        ascent=(height - descent) * scale,
        descent=descent * scale,
    )


def outlines_of(latexes: tuple[str, ...]) -> dict[str, Outline | None]:
    """The outlines of several formulas at once (None for one mathtext refuses): the
    window's inline formulas, set in a worker process (``explorer.inline_math``). Each is
    remembered on disk by the formula, like ``set_in_type``; ``outlines_of.from_cache``
    gives them all without a process when every one is there."""
    from systems import derivation_cache

    tag = _type_tag()
    return {
        latex: derivation_cache.remembered_value(
            f"outline {latex}", tag, lambda latex=latex: outline(latex)
        )
        for latex in latexes
    }


def _outlines_known(latexes: tuple[str, ...]):
    """``outlines_of(latexes)`` from the disk alone, or ``derivation_cache.MISSING``."""
    from systems import derivation_cache

    tag = _type_tag()
    found = {}
    for latex in latexes:
        value = derivation_cache.known_value(f"outline {latex}", tag)
        if value is derivation_cache.MISSING:
            return value
        found[latex] = value
    return found


outlines_of.from_cache = _outlines_known


# -- equations broken across lines -------------------------------------------------------

BREAK_EMS = 14.0
"""An equation narrower than this (in ems) is never broken: it fits any dock."""

FACTOR_EMS = 18.0
r"""A term wider than this (in ems) is cut again before each of its fractions
(``… × \dfrac{a}{b}``)."""


def set_in_type(latex: str) -> dict:
    """``latex`` set in type: ``outline``, and ``pieces`` and ``lead`` where it is wide
    enough to be broken across lines and has places to break (``break_pieces``).

    Returns a dict of ``Formula``'s fields. Pieces whose type mathtext refuses are left
    out (the equation is then shown whole, scaled to the width). Remembered on disk by
    the formula (``derivation_cache.remembered_value``): mathtext takes seconds for a
    scene's derivation (3.7 s for the double pendulum's, under load), every time a
    window opened it, and the formulas of a scene edited are mostly those set before.
    """
    from systems import derivation_cache

    return derivation_cache.remembered_value(latex, _type_tag(), lambda: _set_in_type(latex))


@functools.cache
@functools.cache
def _type_tag() -> str:
    """What a formula's type depends on besides its LaTeX: this module and matplotlib."""
    import matplotlib

    from systems import derivation_cache

    return f"type {derivation_cache.code_hash(sys.modules[__name__])} {matplotlib.__version__}"


def _set_in_type(latex: str) -> dict:
    whole = outline(latex)
    found: dict = {"outline": whole, "pieces": (), "lead": 0}
    if whole is None or whole.width < BREAK_EMS or len(latex) > OUTLINE_CHARS:
        return found
    cut = break_pieces(latex)
    if cut is None:
        return found
    texts, lead = cut
    pieces = [outline(text) for text in texts]
    if any(piece is None for piece in pieces):
        return found
    again: list[Outline] = []
    for index, (text, piece) in enumerate(zip(texts, pieces, strict=True)):
        finer = (_fraction(text) or _factors(text)) if piece.width > FACTOR_EMS else None
        shown = [outline(part) for part in finer] if finer else []
        if finer and all(part is not None for part in shown):
            again += shown
            lead += len(shown) - 1 if index < lead else 0
        else:
            again.append(piece)
    found["pieces"] = tuple(again)
    found["lead"] = lead
    return found


def joined(pieces: tuple[Outline, ...]) -> Outline:
    """``pieces`` side by side on one baseline, as one outline."""
    vertices, codes, x = [], [], 0.0
    for piece in pieces:
        vertices.append(piece.vertices + np.array([x, 0.0], dtype=np.float32))
        codes.append(piece.codes)
        x += piece.width
    return Outline(
        vertices=np.concatenate(vertices) if vertices else np.zeros((0, 2), np.float32),
        codes=np.concatenate(codes) if codes else np.zeros(0, np.uint8),
        width=x,
        ascent=max((piece.ascent for piece in pieces), default=0.0),
        descent=max((piece.descent for piece in pieces), default=0.0),
    )


def _depths(latex: str) -> list[int]:
    """The bracket depth before each character of ``latex``: ``{}``, ``()``, ``[]``,
    ``\\left`` and ``\\right`` (escaped braces ``\\{`` ``\\}`` count only after them)."""
    depths = [0] * (len(latex) + 1)
    depth, i, n = 0, 0, len(latex)
    while i < n:
        depths[i] = depth
        char = latex[i]
        if char == "\\":
            j = i + 1
            while j < n and latex[j].isalpha():
                j += 1
            name = latex[i + 1 : j]
            if not name:
                j = min(i + 2, n)  # \{ \} \, \; and the like
            if name in ("left", "right"):
                depth += 1 if name == "left" else -1
                while j < n and latex[j] == " ":
                    j += 1
                if j < n and latex[j] == "\\":
                    k = j + 1
                    while k < n and latex[k].isalpha():
                        k += 1
                    j = max(k, j + 2)
                else:
                    j += 1
            for k in range(i + 1, min(j, n)):
                depths[k] = depth
            i = j
            continue
        if char in "{([":
            depth += 1
        elif char in "})]":
            depth -= 1
        i += 1
    depths[n] = depth
    return depths


def _terms(latex: str, depth: int = 0) -> list[tuple[str, str]]:
    """``latex`` cut at its `` + `` and `` - `` at ``depth``: (sign, term) pairs, the
    first sign ``""``."""
    depths = _depths(latex)
    cuts = [
        i
        for i in range(1, len(latex) - 2)
        if latex[i - 1 : i + 2] in (" + ", " - ") and depths[i] == depth
    ]
    found, start, sign = [], 0, ""
    for i in cuts:
        found.append((sign, latex[start : i - 1].strip()))
        sign, start = latex[i], i + 2
    found.append((sign, latex[start:].strip()))
    return [(sign, term) for sign, term in found if term]


def _matching(latex: str, start: int) -> int:
    """The index just past the group that opens with the ``{`` at ``start``."""
    depth = 0
    for i in range(start, len(latex)):
        if latex[i] == "{" and latex[i - 1 : i] != "\\":
            depth += 1
        elif latex[i] == "}" and latex[i - 1 : i] != "\\":
            depth -= 1
            if depth == 0:
                return i + 1
    return -1


def break_pieces(latex: str) -> tuple[list[str], int] | None:
    """Where ``latex`` (``lhs = rhs``) may be broken across lines: its pieces, each a
    math string of its own, and how many of them make the left side with the relation.

    A line breaks before a `` + `` or `` - `` of a side's sum, after a comma of a tuple
    ``(a, b)``, and before each term of a fraction's long numerator (``\\dfrac{N}{D}``
    is then set as ``\\dfrac{1}{D} (N)``). Each piece carries the spacing that joins it
    to the one before (``{}+ b``): set side by side they read as the equation did.
    None where there is nowhere to break (or a matrix, which mathtext cannot set).
    """
    if "\\begin" in latex:
        return None
    depths = _depths(latex)
    relations = [i for i in range(1, len(latex) - 2) if latex[i - 1 : i + 2] == " = "]
    relations = [i for i in relations if depths[i] == 0]
    if relations:
        left, right = latex[: relations[-1] - 1].strip(), latex[relations[-1] + 2 :].strip()
    else:
        left, right = "", latex.strip()
    pieces = _side(left) if left else []
    if left:
        pieces[-1] += " ={}"
    lead = len(pieces)
    body = _side(right)
    if pieces:
        body[0] = "{}" + body[0] if not body[0].startswith("{}") else body[0]
    pieces += body
    if len(pieces) - (1 if lead else 0) < 1 or len(pieces) < 2:
        return None
    return pieces, lead


def _side(latex: str) -> list[str]:
    """One side of an equation cut into pieces (one piece where it cannot be cut)."""
    terms = _terms(latex)
    if len(terms) > 1:
        return [_signed(sign, term) for sign, term in terms]
    if latex.startswith("\\left(") and latex.endswith("\\right)"):
        inner = latex[len("\\left(") : -len("\\right)")]
        depths = _depths(inner)
        commas = [i for i, c in enumerate(inner) if c == "," and depths[i] == 0]
        if commas and _depths(latex)[len(latex) - len("\\right)")] == 1:
            items, start = [], 0
            for i in commas:
                items.append(inner[start:i].strip())
                start = i + 1
            items.append(inner[start:].strip())
            return (
                ["\\left(\\right." + items[0] + ",\\ "]
                + [item + ",\\ " for item in items[1:-1]]
                + [items[-1] + "\\left.\\right)"]
            )
    return _fraction(latex) or [latex]


def _fraction(latex: str) -> list[str] | None:
    """``\\frac{N}{D}`` (after a sign ``{}+ ``) whose numerator is a sum, as the pieces
    of ``\\dfrac{1}{D} (n_1 + n_2 …)``; None for anything else."""
    sign = ""
    for start in ("{}+ ", "{}- ", "- "):
        if latex.startswith(start):
            sign, latex = start, latex[len(start) :]
            break
    for prefix in ("\\frac{", "\\dfrac{"):
        if not latex.startswith(prefix):
            continue
        end = _matching(latex, len(prefix) - 1)
        if end < 0 or latex[end : end + 1] != "{" or _matching(latex, end) != len(latex):
            return None
        numerator, denominator = latex[len(prefix) : end - 1], latex[end + 1 : -1]
        terms = _terms(numerator)
        if len(terms) < 2:
            return None
        texts = [_signed(sign, term) for sign, term in terms]
        texts[0] = f"\\,\\left(\\right.{texts[0]}"
        texts[-1] += "\\left.\\right)"
        return [f"{sign}\\dfrac{{1}}{{{denominator}}}", *texts]
    return None


def _signed(sign: str, term: str) -> str:
    return f"{{}}{sign} {term}" if sign else term


def _factors(piece: str) -> list[str] | None:
    """A wide term cut before each of its fractions after the first (``a \\dfrac{b}{c}
    \\dfrac{d}{e}`` -> ``a \\dfrac{b}{c}``, ``{}\\times \\dfrac{d}{e}``), or None."""
    depths = _depths(piece)
    starts = [
        i
        for i in range(len(piece))
        if depths[i] == 0 and (piece.startswith("\\frac{", i) or piece.startswith("\\dfrac{", i))
    ]
    starts = [i for i in starts if piece[:i].strip(" {}+-")]
    if not starts:
        return None
    found, start = [], 0
    for i in starts:
        found.append(piece[start:i].rstrip())
        start = i
    found.append(piece[start:])
    return [found[0]] + ["{}\\times " + part for part in found[1:]]


# -- a LaTeX document -------------------------------------------------------------------

_TEXT_ESCAPES = str.maketrans(
    {
        "\\": r"\textbackslash{}",
        "&": r"\&",
        "%": r"\%",
        "$": r"\$",
        "#": r"\#",
        "_": r"\_",
        "{": r"\{",
        "}": r"\}",
        "~": r"\textasciitilde{}",
        "^": r"\textasciicircum{}",
    }
)


def latex_text(text: str) -> str:
    """Plain text escaped for a LaTeX document (its Unicode left to the engine)."""
    return text.translate(_TEXT_ESCAPES)


def latex_document(typeset: Typeset) -> str:
    """A standalone LaTeX document of the derivation: headings as sections, sentences
    as paragraphs, each formula an ``equation*`` (``\\tag`` for Lagrange's numbers); a
    formula without LaTeX is its text, verbatim. For LuaLaTeX or XeLaTeX (the sentences
    hold Unicode: θ̇, ∂)."""
    lines = [
        r"\documentclass{article}",
        r"\usepackage{amsmath}",
        r"\usepackage{fontspec}",
        r"\begin{document}",
    ]
    for part in typeset.parts:
        if isinstance(part, Heading):
            command = r"\section*" if part.level == 0 else r"\subsection*"
            lines += ["", f"{command}{{{latex_text(part.title)}}}"]
        elif isinstance(part, Sentence):
            lines += ["", latex_text(part.text)]
        elif part.latex is None:
            lines += ["", r"\begin{verbatim}", part.text, r"\end{verbatim}"]
        else:
            tag = f" \\tag*{{{latex_text(part.tag)}}}" if part.tag else ""
            note = f" \\quad \\text{{({latex_text(part.note)})}}" if part.note else ""
            lines += [r"\begin{equation*}", f"  {part.latex}{note}{tag}", r"\end{equation*}"]
    lines += ["", r"\end{document}", ""]
    return "\n".join(lines)
