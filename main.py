"""Phase Explorer: ``python main.py [COMMAND]``; with no command, the application opens."""

import sys

if __name__ == "__main__":
    try:
        from explorer.cli import entry
    except KeyboardInterrupt:  # Ctrl+C while the program was still being loaded
        print("stopped (Ctrl+C)", file=sys.stderr)
        sys.exit(130)
    entry()
