"""The Textbook dock: the theorems of analytical mechanics on the system being explored.

``install(window)`` adds it to a ``MainWindow``. All coupling to the window is in
``WindowLink`` (explorer/textbook/link.py); the tabs only see compiled systems.
"""

from __future__ import annotations

from explorer.textbook.link import WindowLink, install
from explorer.textbook.panel import TextbookPanel

__all__ = ["TextbookPanel", "WindowLink", "install"]
