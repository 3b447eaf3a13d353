"""What an edit in the system editor changed, as session lines. Free of Qt.

The editor sends each debounced edit as the tables of a scene document
(``SystemEditorPanel.data()``). ``form`` flattens such a document, with the editor's
"Given by" choice, into what a script can set; ``edit_lines`` compares two forms and
writes the ``edit``, ``parameters``, ``effect`` and ``initial`` lines that turn the first
into the second: every field and table of the document, the particles, gravity,
constraints, symmetries, drawing and view included. Parameter *values* are not
compared: a value typed or dragged is sent on its own (``set``), without a rebuild.
"""

from __future__ import annotations

from typing import Any

from explorer.session.script import line, number, table_text

EXPRESSIONS = ("kinetic", "potential", "lagrangian", "hamiltonian")
TABLES = ("constraints", "symmetries", "drawing", "view")
"""Tables of the document written whole, as ``edit TABLE {...}``, whatever the "Given by"."""


def _text(value: Any) -> str:
    if isinstance(value, bool):
        return str(value).lower()
    if isinstance(value, int | float):
        return number(float(value))
    return str(value)


def gravity_text(value: Any) -> str:
    """``system.gravity`` as typed in the editor's field: a magnitude, or a vector in
    brackets (so that a vector of one component stays a vector); "" for none."""
    if value is None:
        return ""
    if isinstance(value, list | tuple):
        return "[" + ", ".join(_text(v) for v in value) + "]"
    return _text(value)


def kind_of(system: dict, particles: bool = False) -> str:
    """How a document's system is given: ``energies``, ``lagrangian``, ``hamiltonian`` or
    ``particles`` (the document has ``[particles]``)."""
    if particles:
        return "particles"
    return next((k for k in ("lagrangian", "hamiltonian") if k in system), "energies")


def form(data: dict, kind: str | None = None, previous: dict | None = None) -> dict:
    """A document of the editor, flattened for comparison.

    ``kind`` is the editor's "Given by" choice (read from the document if None).
    ``previous``, the form before, supplies what the document leaves out because the
    "Given by" hides it (the editor keeps it): the last text seen in each expression
    field, and the last particles and gravity.
    """
    system = data.get("system") or {}
    effects = data.get("effects") or {}
    texts = dict(previous["texts"]) if previous else {}
    for key in EXPRESSIONS:
        if key in system:
            texts[key] = _text(system[key])
    if "particles" in data:
        particles, gravity = data["particles"], gravity_text(system.get("gravity"))
    elif previous:
        particles, gravity = previous["particles"], previous["gravity"]
    else:
        particles, gravity = None, ""
    return {
        "title": _text(data.get("title", "")),
        "coordinates": ", ".join(str(q) for q in system.get("coordinates") or []),
        "given-by": kind or kind_of(system, "particles" in data),
        "shown": {key: _text(system[key]) for key in EXPRESSIONS if key in system},
        "texts": texts,
        "parameters": tuple(
            (str(name), _text(value)) for name, value in (system.get("parameters") or {}).items()
        ),
        "dissipation": _text(effects.get("dissipation", "")),
        "forces": {str(q): _text(f) for q, f in (effects.get("forces") or {}).items()},
        "disabled": frozenset(str(key) for key in effects.get("disabled") or ()),
        "initial": {str(name): _text(value) for name, value in (data.get("initial") or {}).items()},
        "particles": particles,
        "gravity": gravity,
        "tables": {key: data.get(key) or None for key in TABLES},
    }


def edit_lines(before: dict, after: dict) -> list[tuple[tuple, str]]:
    """The lines from form ``before`` to form ``after``: ``(key, line)``, in script order.

    ``key`` names what the line sets (``("edit", "kinetic")``, ``("initial", names)``...):
    the recorder replaces a line by the next one with the same key (typing, dragging).
    Initial values of a coordinate that is new in this edit are left to the editor, which
    fills the table for new coordinates itself.
    """
    lines: list[tuple[tuple, str]] = []
    for field in ("title", "coordinates", "given-by"):
        if after[field] != before[field]:
            lines.append((("edit", field), line("edit", field, after[field])))
    for key, text in after["shown"].items():
        if text != before["texts"].get(key, ""):
            lines.append((("edit", key), line("edit", key, text)))
    if after["given-by"] == "particles":
        if after["particles"] != before["particles"]:
            lines.append((("edit", "particles"), table_line("particles", after["particles"])))
        if after["gravity"] != before["gravity"]:
            lines.append((("edit", "gravity"), line("edit", "gravity", after["gravity"])))
    names_after = [name for name, _ in after["parameters"]]
    if names_after != [name for name, _ in before["parameters"]]:
        words = [f"{name}={value}" for name, value in after["parameters"]]
        lines.append((("parameters",), line("parameters", *words)))
    if after["dissipation"] != before["dissipation"]:
        lines.append((("edit", "dissipation"), line("edit", "dissipation", after["dissipation"])))
    for q in dict.fromkeys([*before["forces"], *after["forces"]]):
        text = after["forces"].get(q, "")
        if text != before["forces"].get(q, ""):
            lines.append((("edit", f"forces.{q}"), line("edit", f"forces.{q}", text)))
    for key in sorted(after["disabled"] ^ before["disabled"]):
        if _effect_text(before, key) and _effect_text(after, key):
            state = "off" if key in after["disabled"] else "on"
            lines.append((("effect", key), line("effect", key, state)))
    changed = _initial_words(before, after)
    if changed:
        names = tuple(word.partition("=")[0] for word in changed)
        lines.append((("initial", names), line("initial", *changed)))
    for key in TABLES:
        if after["tables"][key] != before["tables"][key]:
            lines.append((("edit", key), table_line(key, after["tables"][key])))
    return lines


def table_line(field: str, table: dict | None) -> str:
    """``edit FIELD {...}``: single quotes around the table where it allows, as easier to
    read than escaped double quotes."""
    text = table_text(table)
    if text and "'" not in text:
        return f"edit {field} '{text}'"
    return line("edit", field, text)


def _owner(name: str, coordinates: list[str]) -> str | None:
    """The coordinate whose value, velocity or momentum ``name`` is, or None."""
    for q in coordinates:
        if name in (q, f"{q}_dot", f"p_{q}"):
            return q
    return None


def _counterpart(name: str, q: str) -> str | None:
    """``q_dot`` for ``p_q`` and the other way round; None for ``q`` itself."""
    return {f"{q}_dot": f"p_{q}", f"p_{q}": f"{q}_dot"}.get(name)


def _initial_words(before: dict, after: dict) -> list[str]:
    """``NAME=VALUE`` for each initial value typed (``NAME=`` for one cleared).

    A row renamed from ``p_q`` to ``q_dot`` (or back) is its new name with its value: a
    replay renames the row as the user did. Values of coordinates new in this edit, or
    gone, are the editor's business.
    """
    old = [q.strip() for q in before["coordinates"].split(",") if q.strip()]
    new = [q.strip() for q in after["coordinates"].split(",") if q.strip()]
    words = []
    for name, value in after["initial"].items():
        q = _owner(name, new)
        if before["initial"].get(name) != value and (q is None or q in old):
            words.append(f"{name}={value}")
    for name in before["initial"]:
        q = _owner(name, new)
        if name in after["initial"] or q is None or q not in old:
            continue
        if _counterpart(name, q) not in after["initial"]:
            words.append(f"{name}=")
    return words


def _effect_text(state: dict, key: str) -> str:
    if key == "dissipation":
        return state["dissipation"]
    return state["forces"].get(key.removeprefix("forces."), "")
