"""Application setup: the display check, the ``QApplication``, the main window."""

from __future__ import annotations

import os
import sys
from collections.abc import Callable, Iterator
from contextlib import contextmanager

SIGNAL_POLL_MS = 100
"""How often a replaying window lets Python look for a signal (``run_session``)."""

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


def run_session(
    commands: list,
    *,
    source: str,
    folder: str | os.PathLike | None = None,
    scene: str = "simple_pendulum",
    exit_when_done: bool = False,
) -> int:
    """Replay a parsed session script in a new window (``open --session FILE``).

    Parameters
    ----------
    commands : list of explorer.session.Command
        The script, parsed (its grammar already checked).
    source : str
        The script's name for messages.
    folder : path, optional
        Where the script's relative paths start (its folder).
    scene : str
        The scene to open first when the script does not begin with ``open`` or ``new``.
    exit_when_done : bool
        Close the window when the replay ends and return its outcome.

    Returns
    -------
    int
        With ``exit_when_done``: 0 when the script ran through, 1 when the application
        raised an exception meanwhile (its traceback is on stderr), 2 for a script error
        (``source:line: reason`` on stderr). Otherwise the event loop's status, once the
        user closes the window. Ctrl+C, SIGTERM or SIGHUP close the window and give
        128 + the signal (130 for Ctrl+C), with ``stopped (Ctrl+C) at source:line``.
    """
    import signal

    from PySide6.QtCore import QTimer

    from explorer.session import Player

    app = application()
    from explorer.main_window import MainWindow

    window = MainWindow()
    if not commands or commands[0].verb not in ("open", "new"):
        window.open_scene(scene)
    window.show()
    player = Player(window, commands, source=source, folder=folder)
    outcome: list[int] = []

    def on_noted(message: str) -> None:
        print(message, file=sys.stderr)

    def on_finished(status: int) -> None:
        if stopped:
            return  # the window closed because of the signal: no failure of the script
        outcome.append(status)
        if player.message:
            print(player.message, file=sys.stderr)
        if exit_when_done:
            QTimer.singleShot(0, window, lambda: _close(app, window, status))

    def on_signal(signum: int) -> None:
        stopped.append(signum)
        player.stop()
        _close(app, window, 128 + signum)

    stopped: list[int] = []
    player.noted.connect(on_noted)
    player.finished.connect(on_finished)
    player.start()
    with _signals_close(window, on_signal):
        status = app.exec()
    if stopped:
        command = player.command
        where = f"{source}:{command.line}" if command is not None and command.line else source
        name = "Ctrl+C" if stopped[0] == signal.SIGINT else signal.Signals(stopped[0]).name
        print(f"stopped ({name}) at {where}", file=sys.stderr)
        return 128 + stopped[0]
    if exit_when_done:
        return outcome[0] if outcome else 1
    return status


@contextmanager
def _signals_close(window, stop: Callable[[int], None]) -> Iterator[None]:
    """Inside the block Ctrl+C, SIGTERM and SIGHUP call ``stop(signum)`` once, from the
    event loop.

    Python runs a signal handler only between bytecodes: left to the default, Ctrl+C
    raised ``KeyboardInterrupt`` inside whatever slot ran next (the error reporter then
    called it a failure of the application) and the loop ran on. Here the handler only
    queues ``stop``, and a timer runs a little Python every ``SIGNAL_POLL_MS`` so that
    the handler is not kept waiting while the loop is idle. A signal the process was
    started with ignored stays ignored; outside the main thread nothing is changed.
    """
    import signal
    import threading

    from PySide6.QtCore import QTimer

    if threading.current_thread() is not threading.main_thread():
        yield
        return
    received: list[int] = []

    def handler(signum: int, _frame) -> None:
        if not received:
            received.append(signum)
            QTimer.singleShot(0, window, lambda: stop(signum))

    previous = {}
    for signum in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):
        if signal.getsignal(signum) is not signal.SIG_IGN:
            previous[signum] = signal.signal(signum, handler)
    poll = QTimer(window)
    poll.setInterval(SIGNAL_POLL_MS)
    poll.timeout.connect(lambda: None)
    poll.start()
    try:
        yield
    finally:
        try:
            poll.stop()
        except RuntimeError:  # deleted with the window
            pass
        for signum, before in previous.items():
            signal.signal(signum, signal.SIG_DFL if before is None else before)


def _close(app, window, status: int) -> None:
    """Close the replaying window and end the event loop with ``status``."""
    window.close()
    app.exit(status)
