"""Session scripts: reading and writing the text (docs/sessions.md). Free of Qt.

A script is one command a line: a verb and its arguments, separated by white space.
``#`` at the start of a word begins a comment that runs to the end of the line; blank
lines are allowed. A word may be quoted: ``"..."`` (with the escapes ``\\\\``, ``\\"``,
``\\n``, ``\\t``, ``\\r``) or ``'...'`` (taken literally); quoted and bare pieces next to
each other form one word, as in a shell.

``parse(text)`` checks the whole script for grammar and returns its ``Command`` list, or
raises ``ScriptError`` naming the first bad line; whatever depends on the scene (is
``k`` a parameter of it?) is checked by the ``Player`` when the line runs. ``line`` and
``quote`` write lines that ``parse`` reads back word for word.
"""

from __future__ import annotations

import difflib
import json
import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from decimal import ROUND_FLOOR, Decimal, localcontext
from pathlib import Path
from typing import Any

EDIT_FIELDS = (
    "title",
    "coordinates",
    "given-by",
    "kinetic",
    "potential",
    "lagrangian",
    "hamiltonian",
    "dissipation",
    "gravity",
)
"""What ``edit`` types as text, besides ``forces.<q>`` (the generalized force on ``q``)."""
TABLE_FIELDS = ("particles", "constraints", "symmetries", "drawing", "view")
"""What ``edit`` sets as a whole table of the scene file, written as a TOML inline table
(``{ bob = { mass = "m", position = ["l*sin(theta)", "-l*cos(theta)"] } }``); an empty
text removes the table."""
BUILDING_VERBS = ("open", "new", "set", "parameters", "initial", "edit", "effect")
"""Verbs whose line may ask for a build: ``did-not-build`` may follow only one of them."""
KINDS = ("energies", "lagrangian", "hamiltonian", "particles")
"""The values of ``edit given-by``: T and V, a Lagrangian, a Hamiltonian, particles and V."""
SHOWN_CHARACTERS = 40
MAX_COMMANDS = 10_000
"""Commands a script may hold: each waits for the window to be idle, at least a poll of
the player (20 ms) and often a build, so 10 000 already replay for minutes."""
MAX_SCRIPT_BYTES = 8 * 2**20
"""Bytes a script file may hold (its ``edit`` lines carry scene texts)."""
MAX_WAIT = 3600.0
MAX_DIAGRAM_VALUES = 5000
"""The most values an ``orbit-diagram`` line (and the Orbit diagram's values box) takes."""
"""The longest ``wait`` and ``run-until ... timeout=``, in seconds of wall time."""
MAX_SECTION_ORBITS = 10_000
"""The most orbits a ``section-fill`` line (and the window's Fill section…) starts, as
``export --poincare --orbits``."""
_ESCAPES = {"\\": "\\", '"': '"', "n": "\n", "t": "\t", "r": "\r"}


class ScriptError(ValueError):
    """A line of a session script that is wrong: ``source:line: reason``.

    Attributes
    ----------
    reason : str
        What is wrong, in one sentence.
    line : int
        The 1-based line number, or 0 for the script as a whole (a file not read).
    source : str
        The script's name (its path as given), for the message.
    """

    def __init__(self, reason: str, line: int = 0, source: str = "<session>"):
        self.reason = reason
        self.line = line
        self.source = source
        super().__init__(str(self))

    def __str__(self) -> str:
        if self.line:
            return f"{self.source}:{self.line}: {self.reason}"
        return f"{self.source}: {self.reason}"


class _Refused(Exception):
    """Raised by a verb's reader; ``parse`` adds the line number."""


@dataclass(frozen=True)
class Command:
    """One line of a script.

    Attributes
    ----------
    verb : str
        The command, lower case (``"run-until"``).
    args : tuple of str
        The words after the verb, unquoted, as written.
    line : int
        Where it was read (1-based); 0 for a command made in code.
    value : object
        The arguments read for the verb (see ``GRAMMAR``): a float for ``dt``, a tuple of
        ``(name, text)`` for ``initial``, ... ``None`` for verbs without arguments.
    """

    verb: str
    args: tuple[str, ...] = ()
    line: int = 0
    value: Any = None

    def text(self) -> str:
        """The command as a script line (``parse`` reads it back to an equal command)."""
        return line(self.verb, *self.args)


# -- words ------------------------------------------------------------------------------


def split(text: str) -> list[str]:
    """The words of one line, unquoted, without its comment.

    Raises
    ------
    ValueError
        A quote that is not closed, or an unknown escape inside double quotes.
    """
    words: list[str] = []
    i, n = 0, len(text)
    while True:
        while i < n and text[i].isspace():
            i += 1
        if i >= n or text[i] == "#":
            return words
        parts: list[str] = []
        while i < n and not text[i].isspace():
            c = text[i]
            if c == '"':
                i = _double_quoted(text, i + 1, parts)
            elif c == "'":
                end = text.find("'", i + 1)
                if end < 0:
                    raise ValueError("a quote ' is not closed on this line")
                parts.append(text[i + 1 : end])
                i = end + 1
            else:
                parts.append(c)
                i += 1
        words.append("".join(parts))


def _double_quoted(text: str, i: int, parts: list[str]) -> int:
    """Read a ``"..."`` piece from after its opening quote; returns the index after it."""
    n = len(text)
    while i < n:
        c = text[i]
        if c == '"':
            return i + 1
        if c == "\\":
            escape = text[i + 1] if i + 1 < n else ""
            if escape not in _ESCAPES:
                raise ValueError(
                    f"unknown escape \\{escape} inside double quotes (write \\\\ for a "
                    "backslash, or use single quotes, which take everything literally)"
                )
            parts.append(_ESCAPES[escape])
            i += 2
        else:
            parts.append(c)
            i += 1
    raise ValueError('a quote " is not closed on this line')


def quote(word: str) -> str:
    """``word`` as ``split`` reads it back: bare when it can be, else in double quotes."""
    if word and word[0] != "#" and not any(c.isspace() or c in "\"'" for c in word):
        return word
    for plain, escaped in (("\\", "\\\\"), ('"', '\\"'), ("\n", "\\n"), ("\t", "\\t")):
        word = word.replace(plain, escaped)
    return '"' + word.replace("\r", "\\r") + '"'


def line(verb: str, *args: object) -> str:
    """A script line: ``verb`` and its arguments, quoted where needed.

    Floats are written by ``number``; everything else by ``str``.
    """
    words = [verb] + [number(a) if isinstance(a, float) else str(a) for a in args]
    return " ".join(quote(word) for word in words)


def number(value: float) -> str:
    """The shortest text that reads back as ``value`` exactly (``2`` for 2.0)."""
    text = repr(float(value))
    return text[:-2] if text.endswith(".0") else text


def time_mark(t: float) -> str:
    """``t`` rounded down to 6 significant digits: a time a run that reached ``t`` passed."""
    with localcontext() as context:
        context.prec = 6
        context.rounding = ROUND_FLOOR
        floored = +Decimal(float(t))
    return number(float(floored))


def _shown(word: str) -> str:
    """A word for a message: quoted, and cut if long."""
    if len(word) > SHOWN_CHARACTERS:
        word = word[: SHOWN_CHARACTERS - 1] + "…"
    return repr(word)


# -- reading the arguments of each verb ---------------------------------------------------


def _float(word: str, what: str) -> float:
    try:
        value = float(word)
    except ValueError:
        raise _Refused(f"{what} must be a number, not {_shown(word)}") from None
    if not math.isfinite(value):
        raise _Refused(f"{what} must be a finite number, not {_shown(word)}")
    return value


def _positive(word: str, what: str) -> float:
    value = _float(word, what)
    if value <= 0:
        raise _Refused(f"{what} must be positive, not {_shown(word)}")
    return value


def _count(args: tuple[str, ...], usage: str, low: int, high: int | None = None) -> None:
    high = low if high is None else high
    if not low <= len(args) <= high:
        raise _Refused(f"usage: {usage}")


def _switch(word: str, usage: str) -> bool:
    if word.lower() in ("on", "off"):
        return word.lower() == "on"
    raise _Refused(f"usage: {usage} (on or off, not {_shown(word)})")


def _assignments(
    args: tuple[str, ...], usage: str, blank: bool = False
) -> tuple[tuple[str, str], ...]:
    """``NAME=VALUE`` words as ``(name, value text)``; each name once; ``blank``: the value
    may be empty (``NAME=``)."""
    if not args:
        raise _Refused(f"usage: {usage}")
    pairs: dict[str, str] = {}
    for word in args:
        name, equals, value = word.partition("=")
        name, value = name.strip(), value.strip()
        if not equals or not name or not (value or blank):
            raise _Refused(f"{_shown(word)} is not NAME=VALUE (usage: {usage})")
        if name in pairs:
            raise _Refused(f"{name} is given twice")
        pairs[name] = value
    return tuple(pairs.items())


def _no_arguments(verb: str) -> Callable[[tuple[str, ...]], None]:
    def read(args: tuple[str, ...]) -> None:
        _count(args, verb, 0)

    return read


def _path(word: str, what: str) -> str:
    """A path as written, refused if no file can have it."""
    if not word.strip():
        raise _Refused(what)
    if "\0" in word:
        raise _Refused(f"{_shown(word)} cannot be a path: it holds a NUL byte (\\0)")
    return word


def _read_open(args):
    _count(args, "open SCENE (a catalogue name or a .toml file)", 1)
    return _path(args[0], "open needs a scene: a catalogue name or a .toml file")


def _read_set(args):
    _count(args, "set PARAMETER VALUE", 2)
    return args[0], _float(args[1], f"the value of {args[0]}")


def _read_initial(args):
    usage = "initial NAME=VALUE ... (q, and q_dot or p_q; NAME= leaves the value blank)"
    return _assignments(args, usage, blank=True)


def _read_parameters(args):
    pairs = _assignments(args, "parameters NAME=VALUE ... (every parameter, in order)")
    return tuple((name, value) for name, value in pairs)


def _read_edit(args):
    fields = ", ".join([*EDIT_FIELDS, *TABLE_FIELDS])
    usage = f"edit FIELD TEXT (FIELD: {fields} or forces.<q>)"
    _count(args, usage, 2)
    field, text = args
    if field in TABLE_FIELDS:
        return field, _read_table(text, f"edit {field}")
    if field not in EDIT_FIELDS and not (field.startswith("forces.") and field[7:]):
        raise _Refused(f"unknown field {_shown(field)}; {usage}")
    if field == "given-by" and text not in KINDS:
        raise _Refused(f"edit given-by takes {', '.join(KINDS)}, not {_shown(text)}")
    return field, text


def _read_table(text: str, what: str) -> dict | None:
    """A TOML inline table (``{ key = value, ... }``) as a dict; None for an empty text."""
    import tomllib

    if not text.strip():
        return None
    example = '{ key = "value" } (or "" for none)'
    try:
        document = tomllib.loads(f"table = {text}")
    except (tomllib.TOMLDecodeError, RecursionError) as exc:
        raise _Refused(f"{what} takes a TOML inline table such as {example}: {exc}") from None
    table = document.get("table")
    if set(document) != {"table"} or not isinstance(table, dict):
        raise _Refused(f"{what} takes one TOML inline table such as {example}, not {_shown(text)}")
    return table


def table_text(table: Mapping[str, Any] | None) -> str:
    """``table`` as a one-line TOML inline table that ``edit`` reads back ("" for None).

    Raises
    ------
    TypeError
        For a value TOML cannot hold (None, an object).
    """
    return "" if table is None else _toml(dict(table))


def _toml(value: Any) -> str:
    """A value as inline TOML. Keys are bare only when TOML allows it (ASCII letters,
    digits, ``_`` and ``-``): ``str.isalnum`` would let ``¹`` through unquoted."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int | float):
        return repr(value)  # inf, -inf and nan are TOML too
    if isinstance(value, str):
        # a JSON string is a TOML basic string, once DEL is escaped as TOML wants
        return json.dumps(value, ensure_ascii=False).replace("\x7f", "\\u007f")
    if isinstance(value, list | tuple):
        return "[" + ", ".join(_toml(v) for v in value) + "]"
    if isinstance(value, Mapping):
        items = ", ".join(f"{_toml_key(str(k))} = {_toml(v)}" for k, v in value.items())
        return "{ " + items + " }" if items else "{}"
    raise TypeError(f"cannot write {value!r} as TOML")


def _toml_key(key: str) -> str:
    bare = key and all(c.isascii() and (c.isalnum() or c in "_-") for c in key)
    return key if bare else _toml(key)


def _read_effect(args):
    usage = "effect KEY on|off (KEY: dissipation or forces.<q>)"
    _count(args, usage, 2)
    key = args[0]
    if key != "dissipation" and not (key.startswith("forces.") and key[7:]):
        raise _Refused(f"unknown effect {_shown(key)}; {usage}")
    return key, _switch(args[1], usage)


def _read_method(args):
    _count(args, "method NAME|auto (see `python main.py methods`)", 1)
    return None if args[0].lower() in ("auto", "automatic") else args[0]


def _read_dt(args):
    _count(args, "dt VALUE|auto", 1)
    return None if args[0].lower() == "auto" else _positive(args[0], "dt")


def _read_speed(args):
    _count(args, "speed VALUE|max (simulated time per second: 0.1 ... 100, or max)", 1)
    word = args[0].lower()
    if word == "max":
        return math.inf
    return _positive(word[:-1] if word.endswith(("x", "×")) else word, "the speed")


def _read_energy_guard(args):
    _count(args, "energy-guard VALUE|off (the largest relative energy error)", 1)
    return None if args[0].lower() == "off" else _positive(args[0], "the energy guard")


def _read_section(args):
    _count(args, "section on|off", 1)
    return _switch(args[0], "section on|off")


def _read_pair(args):
    usage = "pair Q,p_Q (a coordinate and its momentum, e.g. pair theta2,p_theta2)"
    names = [n.strip() for n in ",".join(args).split(",") if n.strip()]
    if len(names) != 2:
        raise _Refused(f"usage: {usage}")
    return names[0], names[1]


def _read_launch(args):
    pairs = _assignments(args, "launch NAME=VALUE ... (q, and q_dot or p_q)")
    return tuple((name, _float(value, name)) for name, value in pairs)


def _read_delete(args):
    _count(args, "delete N (the N-th orbit launched; the main orbit is 0)", 1)
    try:
        key = int(args[0])
    except ValueError:
        raise _Refused(f"delete takes an orbit's number, not {_shown(args[0])}") from None
    if key < 1:
        raise _Refused("delete takes a launched orbit's number (1, 2, ...)")
    return key


def _seconds(value: float, what: str) -> float:
    if value > MAX_WAIT:
        raise _Refused(f"{what} must be at most {MAX_WAIT:g} seconds (an hour), not {value:g}")
    return value


def _read_run_until(args):
    usage = "run-until T [timeout=SECONDS]"
    _count(args, usage, 1, 2)
    t = _float(args[0], "the time T")
    if t < 0:
        raise _Refused(f"the time T must not be negative, not {_shown(args[0])}")
    timeout = None
    if len(args) == 2:
        name, equals, value = args[1].partition("=")
        if name != "timeout" or not equals:
            raise _Refused(f"usage: {usage}")
        timeout = _seconds(_positive(value, "the timeout"), "the timeout")
    return t, timeout


def _read_wait(args):
    _count(args, "wait SECONDS", 1)
    seconds = _float(args[0], "the wait")
    if seconds < 0:
        raise _Refused("the wait must not be negative")
    return _seconds(seconds, "the wait")


def _read_tab(args):
    _count(args, "tab NAME (a panel, or a tab of the editor or the Textbook)", 1)
    return args[0]


def _read_orbit_diagram(args):
    usage = "orbit-diagram PARAMETER LOW HIGH VALUES"
    _count(args, usage, 4)
    low, high = _float(args[1], "LOW"), _float(args[2], "HIGH")
    if not low < high:
        raise _Refused(f"LOW must be below HIGH, not {_shown(args[1])} and {_shown(args[2])}")
    try:
        count = int(args[3])
    except ValueError:
        count = 0
    if not 2 <= count <= MAX_DIAGRAM_VALUES:
        raise _Refused(
            f"VALUES is a whole number from 2 to {MAX_DIAGRAM_VALUES}, not {_shown(args[3])}"
        )
    return args[0], low, high, count


def _read_section_fill(args):
    _count(args, "section-fill ORBITS", 1)
    try:
        count = int(args[0])
    except ValueError:
        count = 0
    if not 1 <= count <= MAX_SECTION_ORBITS:
        raise _Refused(
            f"ORBITS is a whole number from 1 to {MAX_SECTION_ORBITS}, not {_shown(args[0])}"
        )
    return count


def _read_export(args):
    _count(args, "export PANEL PATH (PANEL: phase, configuration, conserved, ... or csv)", 2)
    return args[0], _path(args[1], "export needs a file to write")


def _read_save(args):
    _count(args, "save PATH", 1)
    return _path(args[0], "save needs a file to write")


def _read_did_not_build(args):
    _count(args, "did-not-build [REASON] (after the line whose build failed)", 0, 1)
    return args[0] if args else ""


GRAMMAR: dict[str, Callable[[tuple[str, ...]], Any]] = {
    "open": _read_open,
    "new": _no_arguments("new"),
    "set": _read_set,
    "parameters": _read_parameters,
    "initial": _read_initial,
    "edit": _read_edit,
    "effect": _read_effect,
    "method": _read_method,
    "dt": _read_dt,
    "speed": _read_speed,
    "energy-guard": _read_energy_guard,
    "section": _read_section,
    "pair": _read_pair,
    "launch": _read_launch,
    "delete": _read_delete,
    "clear": _no_arguments("clear"),
    "reset": _no_arguments("reset"),
    "pause": _no_arguments("pause"),
    "play": _no_arguments("play"),
    "step": _no_arguments("step"),
    "run-until": _read_run_until,
    "wait": _read_wait,
    "tab": _read_tab,
    "chaos-map": _no_arguments("chaos-map"),
    "section-fill": _read_section_fill,
    "orbit-diagram": _read_orbit_diagram,
    "export": _read_export,
    "save": _read_save,
    "did-not-build": _read_did_not_build,
}
"""Verb -> the reader of its arguments (returns ``Command.value``, raises ``_Refused``)."""


def parse(text: str, source: str = "<session>") -> list[Command]:
    """The commands of a script; raises ``ScriptError`` at the first line that is wrong.

    Lines are separated by ``\\n`` (a ``\\r`` before it is dropped). Only the grammar is
    checked: the verb, the number and form of its arguments, numbers where numbers
    belong. Never raises anything but ``ScriptError``.
    """
    commands: list[Command] = []
    for number_, raw in enumerate(text.split("\n"), start=1):
        if raw.endswith("\r"):
            raw = raw[:-1]
        try:
            words = split(raw)
        except ValueError as exc:
            raise ScriptError(str(exc), number_, source) from None
        if not words:
            continue
        verb, args = words[0].lower(), tuple(words[1:])
        reader = GRAMMAR.get(verb)
        if reader is None:
            raise ScriptError(_unknown_verb(words[0]), number_, source)
        try:
            value = reader(args)
        except _Refused as exc:
            raise ScriptError(str(exc), number_, source) from None
        if verb == "did-not-build" and (not commands or commands[-1].verb not in BUILDING_VERBS):
            after = f"`{commands[-1].verb}`" if commands else "nothing"
            raise ScriptError(
                f"did-not-build follows the line whose build failed ({', '.join(BUILDING_VERBS)}"
                f"), not {after}",
                number_,
                source,
            )
        if len(commands) == MAX_COMMANDS:
            raise ScriptError(
                f"more than {MAX_COMMANDS:,} commands, the most a script may hold (each "
                "waits for the window: split it into several sessions)",
                number_,
                source,
            )
        commands.append(Command(verb, args, number_, value))
    return commands


def _unknown_verb(word: str) -> str:
    close = difflib.get_close_matches(word.lower()[:SHOWN_CHARACTERS], list(GRAMMAR), n=1)
    hint = f" (did you mean {close[0]!r}?)" if close else f" (commands: {', '.join(GRAMMAR)})"
    return f"unknown command {_shown(word)}{hint}"


def load(path: str | Path, source: str | None = None) -> list[Command]:
    """Read and parse a script file; a file that cannot be read is a ``ScriptError`` too.

    A named pipe, a device or a folder is refused before anything is read, as is a file
    of more than ``MAX_SCRIPT_BYTES`` (``systems.files.read_file``).
    """
    from systems.files import FileTooLarge, read_file

    source = str(path) if source is None else source
    try:
        raw = read_file(path, MAX_SCRIPT_BYTES)
    except FileTooLarge as exc:
        raise ScriptError(
            f"the file is {exc.size:,} bytes; a session script has at most {MAX_SCRIPT_BYTES:,}",
            0,
            source,
        ) from None
    except OSError as exc:
        raise ScriptError(f"cannot read the file: {exc.strerror or exc}", 0, source) from None
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise ScriptError(
            f"not a text file: byte {exc.start} is not UTF-8 text", 0, source
        ) from None
    return parse(text, source)
