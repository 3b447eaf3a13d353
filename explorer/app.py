"""Application setup: the display check, the ``QApplication``, the main window."""

from __future__ import annotations

import os
import sys

NO_DISPLAY_MESSAGE = (
    "Phase Explorer needs a display to open its window, and none was found "
    "(DISPLAY and WAYLAND_DISPLAY are not set).\n"
    "  - To integrate or derive headless, use `python main.py run SCENE` or "
    "`python main.py derive SCENE`.\n"
    "  - To render a figure headless, use `python main.py export SCENE --panel phase --out "
    "phase.png`.\n"
    "  - To run the window without a screen, set QT_QPA_PLATFORM=offscreen, or start it "
    "under Xvfb: `xvfb-run python main.py`."
)


def display_available(environ=None) -> bool:
    """Whether Qt can open a window: a platform was chosen, or an X/Wayland display is set."""
    environ = os.environ if environ is None else environ
    if not sys.platform.startswith("linux"):
        return True
    return any(environ.get(key) for key in ("QT_QPA_PLATFORM", "DISPLAY", "WAYLAND_DISPLAY"))


def application():
    """The running ``QApplication``, created (with pyqtgraph's options) if needed."""
    import pyqtgraph as pg
    from PySide6.QtWidgets import QApplication

    pg.setConfigOptions(antialias=True, foreground="#222222", background="w")
    app = QApplication.instance()
    if app is None:
        app = QApplication(sys.argv[:1])
        app.setApplicationName("Phase Explorer")
        app.setOrganizationName("phase-explorer")
    return app


def create_window(scene="simple_pendulum", runs=None):
    """A ``MainWindow`` opened on ``scene`` (a catalogue name, path or ``Scene``)."""
    application()
    from explorer.main_window import MainWindow

    window = MainWindow(runs=runs)
    window.open_scene(scene)
    return window


def run(scene="simple_pendulum") -> int:
    """Open the window and run the event loop; returns the exit status."""
    app = application()
    window = create_window(scene)
    window.show()
    return app.exec()
