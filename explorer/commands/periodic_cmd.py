"""``periodic SCENE``: a periodic orbit by shooting and Newton, and its Floquet multipliers.

From the scene's initial state or ``--start name=value,...`` (coordinates, ``<q>_dot``
velocities or ``p_<q>`` momenta): for an autonomous system the period is corrected
together with the start (``--period`` is the guess; without it, the first close return
of the orbit); for a periodically driven one the period is the drive's (``--period``
rounds to a multiple of it). Exit status 1 when Newton's method did not converge.
"""

from __future__ import annotations

import argparse
import json

from explorer.commands.errors import UserError, user_errors


def add_parser(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser(
        "periodic",
        help="find a periodic orbit (shooting + Newton) and its Floquet multipliers",
    )
    parser.add_argument("scene", help="a catalogue name (see `list`) or a path to a .toml file")
    parser.add_argument(
        "--start",
        default="",
        help="the start, e.g. x=0,y=0.3,p_x=0,p_y=0 (default: the scene's initial state)",
    )
    parser.add_argument("--period", type=float, default=None, help="a guess of the period")
    parser.add_argument(
        "--t-max",
        type=float,
        default=None,
        help="how long to look for the first close return when no --period is given "
        "(default: the scene's t_end)",
    )
    parser.add_argument("--json", action="store_true", help="print one JSON object")


def _start(text: str) -> dict[str, float]:
    values = {}
    for item in filter(None, (part.strip() for part in text.split(","))):
        name, equals, value = item.partition("=")
        if not equals:
            raise UserError(f"--start: {item!r} is not name=value")
        try:
            values[name.strip()] = float(value)
        except ValueError:
            raise UserError(f"--start: {value.strip()!r} is not a number (for {name})") from None
    return values


def run(args: argparse.Namespace) -> int:
    from systems.mechanics import derive
    from systems.scene import load_scene
    from systems.textbook.periodic_orbits import periodic_orbit

    start = _start(args.start)
    if args.period is not None and not args.period > 0:
        raise UserError("--period must be a positive number")
    with user_errors():
        mechanics = derive(load_scene(args.scene))
    try:
        orbit = periodic_orbit(mechanics, start, period=args.period, t_max=args.t_max)
    except ValueError as exc:
        raise UserError(str(exc)) from exc
    if args.json:
        print(json.dumps(orbit.as_json(), indent=2))
    else:
        print("\n".join(orbit.lines()))
    return 0 if orbit.converged else 1
