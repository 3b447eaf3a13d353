"""Python's cyclic garbage collection, run only on the GUI thread while a window lives.

The cyclic collector runs in whichever thread happens to allocate when a threshold is
crossed: with worker threads that is often not the GUI thread. Freeing a Qt object there
(pyqtgraph creates its context menus without a Qt parent, so only Python owns them) can
deadlock against the GUI thread or crash. So while a window is open, automatic collection
is off and a timer on the GUI thread collects instead, generation by generation, when the
allocation counts pass the usual thresholds (what ``pyqtgraph.util.GarbageCollector``
does, but stoppable, so closing the last window restores the interpreter's own
collection, after a full one on the GUI thread).
"""

from __future__ import annotations

import gc

from PySide6.QtCore import QObject, QTimer

_active = 0


class GuiThreadCollector(QObject):
    """Collects cyclic garbage from a GUI-thread timer; ``stop`` restores automatic gc."""

    def __init__(self, parent: QObject | None = None, interval_ms: int = 500):
        super().__init__(parent)
        self.threshold = gc.get_threshold()
        self.timer = QTimer(self)
        self.timer.setInterval(interval_ms)
        self.timer.timeout.connect(self._on_timer_timeout)
        self.running = False

    def start(self) -> None:
        global _active
        if self.running:
            return
        self.running = True
        _active += 1
        gc.disable()
        self.timer.start()

    def stop(self) -> None:
        global _active
        if not self.running:
            return
        self.running = False
        self.timer.stop()
        _active -= 1
        if _active == 0:
            # what is left in cycles is freed here, on the GUI thread: once the
            # interpreter collects again, any thread allocating past a threshold would
            # free it, a window's thread not yet ended at close (a section fill's, joined
            # for a second at most) among them, and a Qt object freed there deadlocks
            gc.collect()
            gc.enable()

    def _on_timer_timeout(self) -> None:
        self.collect_due()

    def collect_due(self) -> None:
        """Collect the generations whose allocation counts passed their thresholds, as
        the interpreter would, in this (the GUI) thread."""
        first, second, third = gc.get_count()
        if first > self.threshold[0]:
            gc.collect(0)
            if second > self.threshold[1]:
                gc.collect(1)
                if third > self.threshold[2]:
                    gc.collect(2)
