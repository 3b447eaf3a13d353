"""``derive SCENE``: Lagrange's and Hamilton's equations, for a person or as JSON.

The text and the data come from ``systems.report``, which the window uses too.
"""

from __future__ import annotations

import argparse
import json

from explorer.commands.errors import user_errors


def add_parser(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser(
        "derive", help="derive the equations of motion of a scene (catalogue name or .toml)"
    )
    parser.add_argument("scene", help="a catalogue name (see `list`) or a path to a .toml file")
    parser.add_argument("--json", action="store_true", help="print one JSON object")


def run(args: argparse.Namespace) -> int:
    from systems.mechanics import derive
    from systems.report import derivation_json, readable
    from systems.scene import load_scene

    with user_errors():
        scene = load_scene(args.scene)
        mechanics = derive(scene)
        if args.json:  # the report searches the equilibria too: only when it is printed
            print(json.dumps(derivation_json(mechanics), indent=2))
        else:
            print(readable(mechanics))
    return 0
