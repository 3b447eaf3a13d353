"""What an edit in the system editor changed, as session lines. Free of Qt.

The editor sends each debounced edit as the tables of a scene document
(``SystemEditorPanel.data()``). ``form`` flattens such a document, with the editor's
"Given by" choice, into what a script can set; ``edit_lines`` compares two forms and
writes the ``edit``, ``parameters``, ``effect`` and ``initial`` lines that turn the first
into the second. Parameter *values* are not compared: a value typed or dragged is sent
on its own (``set``), without a rebuild.
"""

from __future__ import annotations

from typing import Any

from explorer.session.script import line, number

EXPRESSIONS = ("kinetic", "potential", "lagrangian", "hamiltonian")
NOT_RECORDED = "# not recorded: the drawing was edited in the editor (do it again after this line)"
UNRECORDED_TABLES = ("particles", "constraints", "symmetries")
"""Tables the editor edits that a script has no lines for: a change is noted, as the
drawing's is."""


def not_recorded(what: list[str]) -> str:
    """The comment line for edits of the tables ``what`` that a script cannot replay."""
    return f"# not recorded: {', '.join(what)} edited in the editor (do it again after this line)"


def _text(value: Any) -> str:
    if isinstance(value, bool):
        return str(value).lower()
    if isinstance(value, int | float):
        return number(float(value))
    return str(value)


def kind_of(system: dict, particles: bool = False) -> str:
    """How a document's system is given: ``energies``, ``lagrangian``, ``hamiltonian`` or
    ``particles`` (the document has ``[particles]``)."""
    if particles:
        return "particles"
    return next((k for k in ("lagrangian", "hamiltonian") if k in system), "energies")


def form(data: dict, kind: str | None = None, previous: dict | None = None) -> dict:
    """A document of the editor, flattened for comparison.

    ``kind`` is the editor's "Given by" choice (read from the document if None).
    ``previous``, the form before, supplies the last text seen in each expression field
    the document leaves out (a field hidden under another "Given by" keeps its text).
    """
    system = data.get("system") or {}
    effects = data.get("effects") or {}
    texts = dict(previous["texts"]) if previous else {}
    for key in EXPRESSIONS:
        if key in system:
            texts[key] = _text(system[key])
    return {
        "title": _text(data.get("title", "")),
        "coordinates": ", ".join(str(q) for q in system.get("coordinates") or []),
        "given-by": kind or kind_of(system, bool(data.get("particles"))),
        "shown": {key: _text(system[key]) for key in EXPRESSIONS if key in system},
        "texts": texts,
        "parameters": tuple(
            (str(name), _text(value)) for name, value in (system.get("parameters") or {}).items()
        ),
        "dissipation": _text(effects.get("dissipation", "")),
        "forces": {str(q): _text(f) for q, f in (effects.get("forces") or {}).items()},
        "disabled": frozenset(str(key) for key in effects.get("disabled") or ()),
        "initial": {str(name): _text(value) for name, value in (data.get("initial") or {}).items()},
        "drawing": data.get("drawing"),
        "tables": {key: data.get(key) for key in UNRECORDED_TABLES}
        | {"gravity": system.get("gravity")},
    }


def edit_lines(before: dict, after: dict) -> list[tuple[tuple, str]]:
    """The lines from form ``before`` to form ``after``: ``(key, line)``, in script order.

    ``key`` names what the line sets (``("edit", "kinetic")``, ``("initial", names)``...):
    the recorder replaces a line by the next one with the same key (typing, dragging).
    An initial value whose name is new (the coordinates changed) is left to the editor,
    which fills the table for new coordinates itself.
    """
    lines: list[tuple[tuple, str]] = []
    for field in ("title", "coordinates", "given-by"):
        if after[field] != before[field]:
            lines.append((("edit", field), line("edit", field, after[field])))
    for key, text in after["shown"].items():
        if text != before["texts"].get(key, ""):
            lines.append((("edit", key), line("edit", key, text)))
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
    changed = [
        f"{name}={value}"
        for name, value in after["initial"].items()
        if name in before["initial"] and before["initial"][name] != value
    ]
    if changed:
        names = tuple(word.partition("=")[0] for word in changed)
        lines.append((("initial", names), line("initial", *changed)))
    if after["drawing"] != before["drawing"]:
        lines.append((("drawing",), NOT_RECORDED))
    changed_tables = [k for k, v in after["tables"].items() if v != before["tables"].get(k)]
    if changed_tables:
        lines.append((("tables",), not_recorded(changed_tables)))
    return lines


def _effect_text(state: dict, key: str) -> str:
    if key == "dissipation":
        return state["dissipation"]
    return state["forces"].get(key.removeprefix("forces."), "")
