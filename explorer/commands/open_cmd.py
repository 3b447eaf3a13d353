"""``open [SCENE] [--session FILE [--offscreen] [--exit]]``: the application window.

The default command of ``python main.py``. With ``--session`` the window replays a
session script (docs/sessions.md); a script with a grammar error is refused (status 2)
before any window opens.
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

from explorer.commands.errors import user_errors


def add_parser(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser("open", help="open the application window on a scene")
    parser.add_argument(
        "scene",
        nargs="?",
        default="simple_pendulum",
        help="a catalogue name (see `list`) or a path to a .toml file (default: simple_pendulum)",
    )
    parser.add_argument(
        "--session",
        metavar="FILE",
        help="replay a session script (docs/sessions.md), e.g. one written by File > Save "
        "session; its grammar is checked before the window opens",
    )
    parser.add_argument(
        "--offscreen",
        action="store_true",
        help="with --session: run the window without showing it (QT_QPA_PLATFORM=offscreen)",
    )
    parser.add_argument(
        "--exit",
        action="store_true",
        help="with --session: close when the script ends; exit status 0 when it ran "
        "through, 1 when the application raised an exception or a build failed that the "
        "script expects to build (the replay stops there), 2 for a script error",
    )


def run(args: argparse.Namespace) -> int:
    session = getattr(args, "session", None)
    if session is None and (getattr(args, "offscreen", False) or getattr(args, "exit", False)):
        print("error: --offscreen and --exit go with --session FILE", file=sys.stderr)
        return 2
    commands = None
    if session is not None:
        from explorer.session import ScriptError, load

        try:
            commands = load(session)
        except ScriptError as exc:
            print(exc, file=sys.stderr)
            return 2
    if getattr(args, "offscreen", False):
        os.environ["QT_QPA_PLATFORM"] = "offscreen"
    from explorer.app import NO_DISPLAY_MESSAGE, display_available

    if not display_available():
        print(NO_DISPLAY_MESSAGE, file=sys.stderr)
        return 2
    from systems.scene import load_scene

    with user_errors():
        load_scene(args.scene)  # a bad scene is one message and status 2, before any window
    if commands is not None:
        from explorer.app import run_session

        return run_session(
            commands,
            source=session,
            folder=Path(session).resolve().parent,
            scene=args.scene,
            exit_when_done=args.exit,
        )
    from explorer.app import run as run_app

    return run_app(args.scene)  # by name, so that a recorded session begins with `open`
