"""Phase Explorer: ``python main.py [COMMAND]``; with no command, the application opens."""

import sys

from explorer.cli import main

if __name__ == "__main__":
    sys.exit(main())
