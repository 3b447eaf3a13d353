"""``warm``: compile every method's stepping loop once, ahead of the first scene."""

from __future__ import annotations

import argparse
import sys


def add_parser(sub: argparse._SubParsersAction) -> None:
    sub.add_parser(
        "warm",
        help="compile the integrators' stepping loops once (make run does it); afterwards "
        "a new scene compiles only its own functions",
    )


def run(args: argparse.Namespace) -> int:
    from systems.integrators.warmup import drivers_warmed, warm_drivers

    if drivers_warmed():
        print("the stepping loops are compiled already", file=sys.stderr)
        return 0

    def progress(family: str) -> None:
        print(f"  {family}", file=sys.stderr, flush=True)

    print("compiling the stepping loops (once per installation):", file=sys.stderr, flush=True)
    seconds = warm_drivers(progress)
    print(f"done in {seconds:.1f} s", file=sys.stderr)
    return 0
