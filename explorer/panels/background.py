"""What the chaos map and the orbit diagram share: a cancellable computing thread that
reports through a queued relay, and a progress bar with its Cancel button."""

from __future__ import annotations

import threading

from PySide6.QtWidgets import QProgressBar, QPushButton


class RelayThread(threading.Thread):
    """A daemon thread whose ``_emit(signal, ...)`` calls ``relay.<signal>.emit(generation,
    ...)`` (queued to the GUI thread) and whose ``cancel`` sets ``stopping`` and joins."""

    def __init__(self, name: str, relay, generation: int):
        super().__init__(name=name, daemon=True)
        self.relay, self.generation = relay, generation
        self.stopping = threading.Event()

    def cancel(self, timeout: float = 1.0) -> None:
        self.stopping.set()
        if self.is_alive() and threading.current_thread() is not self:
            self.join(timeout)

    def _emit(self, signal: str, *values) -> None:
        try:
            getattr(self.relay, signal).emit(self.generation, *values)
        except RuntimeError:  # the relay's C++ side is gone: nobody is left to tell
            pass


class ProgressControls:
    """A progress bar and a Cancel button (calling ``on_cancel``), shown while running."""

    def __init__(self, on_cancel):
        self.progress = QProgressBar()
        self.progress.setMaximumWidth(140)
        self.progress.setVisible(False)
        self.cancel_button = QPushButton("Cancel")
        self.cancel_button.setToolTip("Stop computing (what is already drawn stays)")
        self.cancel_button.setVisible(False)
        self.cancel_button.clicked.connect(on_cancel)

    def show_running(self, running: bool) -> None:
        self.progress.setVisible(running)
        self.cancel_button.setVisible(running)
        if running:
            self.progress.setRange(0, 0)  # busy until the first chunk is done

    def set_progress(self, done: int, total: int) -> None:
        self.progress.setRange(0, total)
        self.progress.setValue(done)
