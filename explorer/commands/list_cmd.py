"""``list``: the scene catalogue."""

from __future__ import annotations

import argparse
import json


def add_parser(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser("list", help="list the catalogue of scenes")
    parser.add_argument("--json", action="store_true", help="print JSON instead of a table")


def run(args: argparse.Namespace) -> int:
    from systems.scene import catalogue

    entries = catalogue()
    if args.json:
        rows = [
            {"name": e.name, "title": e.title, "description": e.description, "path": str(e.path)}
            for e in entries
        ]
        print(json.dumps(rows, indent=2))
        return 0
    width = max((len(e.name) for e in entries), default=0)
    for entry in entries:
        print(f"{entry.name:<{width}}  {entry.title}")
    return 0
