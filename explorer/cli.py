"""Command-line entry point: ``phase-explorer [COMMAND] ...`` or ``python main.py ...``.

Each command lives in its own module under ``explorer.commands`` exposing
``add_parser(subparsers)`` and ``run(args) -> int``. A user error exits with status 2
and one message naming the file, the field and the position. Ctrl+C, SIGTERM and SIGHUP
stop a command alike (``explorer.commands.stopping``), with status 128 + the signal.
"""

from __future__ import annotations

import argparse
import importlib
import sys
from contextlib import nullcontext

COMMANDS = ("list", "derive", "run", "bench", "methods", "open", "export", "warm")


def _load(name: str):
    return importlib.import_module(f"explorer.commands.{name}_cmd")


def build_parser() -> argparse.ArgumentParser:
    """The argument parser with one subcommand per available command module."""
    parser = argparse.ArgumentParser(
        prog="phase-explorer",
        description="Lagrangian and Hamiltonian mechanics, derived and explored live. "
        "With no command, the application opens on the simple pendulum.",
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name in COMMANDS:
        try:
            module = _load(name)
        except ModuleNotFoundError as exc:
            if exc.name != f"explorer.commands.{name}_cmd":
                raise
            continue
        module.add_parser(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Parse ``argv`` and run the command; return the process exit status."""
    parser = build_parser()
    args = parser.parse_args(argv)
    command = args.command or "open"
    try:
        module = _load(command)
    except ModuleNotFoundError:
        parser.error(f"the command {command!r} is not available in this build")
    if args.command is None:
        args = parser.parse_args(["open"])
    from explorer.commands import stopping
    from explorer.commands.errors import UserError

    # the window's event loop runs no Python between events: a signal raised there would
    # land in whatever slot ran next, so only the other commands stop on SIGTERM this way
    signals = nullcontext() if command == "open" else stopping.stop_signals()
    try:
        with signals:
            return int(module.run(args) or 0)
    except UserError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"stopped ({stopping.cause()})", file=sys.stderr)
        return stopping.status()
