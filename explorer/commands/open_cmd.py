"""``open [SCENE]``: the application window (the default command of ``python main.py``)."""

from __future__ import annotations

import argparse
import sys

from explorer.commands.errors import user_errors


def add_parser(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser("open", help="open the application window on a scene")
    parser.add_argument(
        "scene",
        nargs="?",
        default="simple_pendulum",
        help="a catalogue name (see `list`) or a path to a .toml file (default: simple_pendulum)",
    )


def run(args: argparse.Namespace) -> int:
    from explorer.app import NO_DISPLAY_MESSAGE, display_available

    if not display_available():
        print(NO_DISPLAY_MESSAGE, file=sys.stderr)
        return 2
    from systems.scene import load_scene

    with user_errors():
        scene = load_scene(args.scene)
    from explorer.app import run as run_app

    return run_app(scene)
