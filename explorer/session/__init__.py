"""Session scripts: a window's user actions recorded as text, and replayed.

See docs/sessions.md for the language. ``parse``, ``load``, ``Command``, ``ScriptError``,
``line``, ``quote`` and ``number`` (``explorer.session.script``) need no Qt;
``Player`` and ``Recorder`` (``explorer.session.player``, ``.recorder``) are imported on
first use, so that reading a script does not start Qt.
"""

from __future__ import annotations

from typing import Any

from explorer.session.script import (
    Command,
    ScriptError,
    line,
    load,
    number,
    parse,
    quote,
    split,
    time_mark,
)

__all__ = [
    "Command",
    "Player",
    "Recorder",
    "ScriptError",
    "line",
    "load",
    "number",
    "parse",
    "quote",
    "split",
    "time_mark",
]


def __getattr__(name: str) -> Any:
    if name == "Player":
        from explorer.session.player import Player

        return Player
    if name == "Recorder":
        from explorer.session.recorder import Recorder

        return Recorder
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
