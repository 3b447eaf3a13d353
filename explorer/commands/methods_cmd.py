"""``methods [SCENE]``: the integration methods, what each takes, and which apply."""

from __future__ import annotations

import argparse
import json

from explorer.commands.errors import user_errors


def add_parser(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser(
        "methods", help="list the integration methods (for a scene: which apply, and why not)"
    )
    parser.add_argument("scene", nargs="?", help="a catalogue name or a .toml file")
    parser.add_argument("--json", action="store_true", help="print JSON instead of a table")


def run(args: argparse.Namespace) -> int:
    from systems.integrators import STEPPERS

    refusals = dict.fromkeys(STEPPERS)
    chosen = None
    if args.scene:
        from explorer.commands.run_cmd import prepare
        from systems.mechanics import derive
        from systems.scene import load_scene

        with user_errors():
            mechanics = derive(load_scene(args.scene))
        refusals = {name: s.applies_to(mechanics) for name, s in STEPPERS.items()}
        # what `run` and the window take: the choice measured on the compiled system
        _, _, chosen, why, _ = prepare(args.scene, None, extra_wants=())
    rows = [
        {
            "method": name,
            "family": s.family.name,
            "order": s.order,
            "takes": s.setting,
            "symplectic": s.symplectic,
            "description": s.description,
            "applies": refusals[name] is None,
            "why_not": refusals[name],
        }
        for name, s in STEPPERS.items()
    ]
    if args.json:
        print(json.dumps({"automatic": chosen, "methods": rows}, indent=2))
        return 0
    for row in rows:
        mark = "*" if row["method"] == chosen else " "
        flag = "" if row["applies"] else "  (not for this system)"
        line = f"{mark} {row['method']:<20} order {row['order']:<2} takes {row['takes']:<4}"
        print(f"{line} {row['description']}{flag}")
        if row["why_not"]:
            print(f"      {row['why_not']}")
    if chosen:
        print(f"* automatic choice: {chosen}: {why}")
    return 0
