"""The common part of a Textbook tab: the current system, staleness, lazy computation."""

from __future__ import annotations

from PySide6.QtWidgets import QWidget

from explorer.textbook.tasks import TaskRunner


class TextbookTabView(QWidget):
    """A tab that recomputes for a new system only when it is shown.

    Subclasses implement ``_clear()`` (forget what is drawn) and ``_start()`` (submit the
    computation for ``self.compiled``).
    """

    title = ""

    def __init__(self, runner: TaskRunner, parent: QWidget | None = None):
        super().__init__(parent)
        self.runner = runner
        self.compiled = None
        self.stale = False
        self.generation = 0

    def set_system(self, compiled) -> None:
        """Show ``compiled`` (a new system, or new parameter values of the same one)."""
        self.compiled = compiled
        self.generation += 1
        self.stale = True
        self.runner.cancel(self.key)
        self._clear()
        if self.isVisible():
            self.refresh()

    @property
    def key(self) -> str:
        return type(self).__name__

    def refresh(self) -> None:
        """Compute now if stale."""
        if self.compiled is None or not self.stale:
            return
        self.stale = False
        self._start()

    def showEvent(self, event) -> None:  # noqa: N802 - Qt override
        super().showEvent(event)
        self.refresh()

    def _clear(self) -> None:
        raise NotImplementedError

    def _start(self) -> None:
        raise NotImplementedError
