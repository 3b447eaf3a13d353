"""Run a command beside busy loops that saturate the machine: ``make test-under-load``.

``python tests/under_load.py --busy 2 -- make test`` starts two processes that spin for
ever, runs the command, ends the spinners however the command ends, and exits with the
command's status. The suite must pass so: no test may decide anything from a wall clock.
"""

from __future__ import annotations

import argparse
import subprocess
import sys

SPIN = "while True:\n    pass\n"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--busy", type=int, default=2, help="busy loops to start (default 2)")
    parser.add_argument("command", nargs=argparse.REMAINDER, help="-- COMMAND [ARGS...]")
    args = parser.parse_args(argv)
    command = args.command[1:] if args.command[:1] == ["--"] else args.command
    if not command:
        parser.error("give the command to run after --")
    spinners = [subprocess.Popen([sys.executable, "-c", SPIN]) for _ in range(args.busy)]
    try:
        return subprocess.call(command)
    except KeyboardInterrupt:
        return 130
    finally:
        for spinner in spinners:
            spinner.kill()
        for spinner in spinners:
            spinner.wait()


if __name__ == "__main__":
    sys.exit(main())
