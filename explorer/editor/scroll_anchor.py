"""The editor never moves under the hand.

A build that finishes while the user types shows or hides errors, warnings and notes,
and rewrites the classification card: the content above what the user looks at grows
or shrinks, or the page gets shorter than where it is scrolled to, and the field under
the mouse used to move away a second after the edit, so that the next click landed
elsewhere. ``ScrollAnchor`` keeps one widget where it is on screen through every such
change: the focused widget when it is in sight, otherwise the one at the top of the view
(a page scrolled to its top stays there, so a message put at the top is seen). Only the
user moves the anchor (scrolling, or moving the focus).
"""

from __future__ import annotations

from PySide6.QtCore import QEvent, QObject, QPoint, QTimer
from PySide6.QtWidgets import QApplication, QScrollArea, QWidget


class ScrollAnchor(QObject):
    """Keeps what the user looks at in ``area`` in place while its content changes.

    Parameters
    ----------
    area : QScrollArea
        Scrolls a widget (``area.widget()``) that is laid out by a layout.
    """

    def __init__(self, area: QScrollArea):
        super().__init__(area)
        self.area = area
        self.content = area.widget()
        self._anchor: tuple[QWidget, int] | None = None
        self._restoring = False
        self._scheduled = False
        self._held = False  # the content is held taller than it needs (see ``restore``)
        self.bar = area.verticalScrollBar()
        self.bar.valueChanged.connect(self._on_scrolled)
        QApplication.instance().focusChanged.connect(self._on_focus_changed)
        self.content.installEventFilter(self)

    def _top(self, widget: QWidget) -> int:
        return widget.mapTo(self.content, QPoint(0, 0)).y() - self.bar.value()

    def remember(self) -> None:
        """Take the focused widget (if in sight) or the one at the top as the anchor."""
        height = self.area.viewport().height()
        focus = QApplication.focusWidget()
        if focus is not None and self.content.isAncestorOf(focus):
            top = self._top(focus)
            if -focus.height() < top < height:
                self._anchor = (focus, top)
                return
        if self.bar.value() == 0:  # at the top it stays: a message put there is seen
            self._anchor = None
            return
        widget = self.content.childAt(QPoint(12, self.bar.value() + 2))
        self._anchor = None if widget is None else (widget, self._top(widget))

    def restore(self) -> None:
        """Scroll so that the anchor is where it was; a page grown shorter than the
        place it is scrolled to is held tall enough, until the user scrolls."""
        self._scheduled = False
        if self._anchor is None:
            return
        widget, top = self._anchor
        try:
            if not widget.isVisibleTo(self.content):
                return
            delta = self._top(widget) - top
        except RuntimeError:  # the widget was deleted (rows rebuilt)
            self._anchor = None
            return
        if delta == 0:
            return
        wanted = self.bar.value() + delta
        if wanted > self.bar.maximum():
            self.content.setMinimumHeight(self.content.height() + wanted - self.bar.maximum())
            self._held = True
            self.content.resize(self.content.width(), self.content.minimumHeight())
        self._restoring = True
        try:
            self.bar.setValue(max(wanted, 0))
        finally:
            self._restoring = False

    def _on_scrolled(self, _value: int) -> None:
        if self._restoring or self._scheduled:
            return  # ours, or the page grown shorter clamping it: put right by ``restore``
        if self._held:  # the user scrolls: the page may be as short as it is
            self._held = False
            self.content.setMinimumHeight(0)
        self.remember()

    def _on_focus_changed(self, _old, _new) -> None:
        if not self._restoring:
            self.remember()

    def eventFilter(self, watched, event) -> bool:  # noqa: N802 - Qt override
        if watched is self.content and event.type() in (
            QEvent.Type.LayoutRequest,
            QEvent.Type.Resize,
        ):
            if self._anchor is not None and not self._scheduled:
                self._scheduled = True
                QTimer.singleShot(0, self._restore_if_alive)
        return False

    def _restore_if_alive(self) -> None:
        try:
            self.restore()
        except RuntimeError:  # the editor is gone
            pass
