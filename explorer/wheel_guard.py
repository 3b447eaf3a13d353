"""The mouse wheel scrolls; it never changes a control that does not have the focus.

Qt sends a wheel event to the widget under the pointer. Scrolling down a long panel, the
pointer passes over combo boxes, spin boxes and sliders, and each one it crosses would
take the scroll as a change of its value ("Given by" switching to H, a parameter slider
moving). ``install_wheel_guard(root)`` stops that for every such control under ``root``,
present or added later: an unfocused control neither takes the focus from the wheel nor
changes, and the scroll goes to the nearest scroll area around it that can still move in
that direction (the editor's page, or a table's rows). Once the user clicks a control
(giving it the focus) the wheel changes it as usual.
"""

from __future__ import annotations

from PySide6.QtCore import QEvent, QObject, Qt
from PySide6.QtGui import QWheelEvent
from PySide6.QtWidgets import (
    QAbstractScrollArea,
    QAbstractSlider,
    QAbstractSpinBox,
    QApplication,
    QComboBox,
    QScrollBar,
    QWidget,
)

GUARDED = (QComboBox, QAbstractSpinBox, QAbstractSlider)
"""The controls whose value the wheel changes; scroll bars (sliders too) are not guarded."""


def is_guarded(widget: QObject) -> bool:
    """Whether ``widget`` is a control the wheel would change (not a scroll bar)."""
    return isinstance(widget, GUARDED) and not isinstance(widget, QScrollBar)


_GUARDED_TYPES: dict[type, bool] = {}
"""``is_guarded`` by the Python class of a widget (the same for every instance)."""


class WheelGuard(QObject):
    """The application event filter behind ``install_wheel_guard``; one per root."""

    def __init__(self, root: QWidget):
        super().__init__(root)
        self._root = root
        self.passed_on = 0  # wheel events handed to a scroll area (for tests and curiosity)
        for widget in root.findChildren(QWidget):
            self._calm(widget)

    def _under_root(self, widget: QObject) -> bool:
        return isinstance(widget, QWidget) and (
            widget is self._root or self._root.isAncestorOf(widget)
        )

    @staticmethod
    def _calm(widget: QObject) -> None:
        """Take ``WheelFocus`` away: the wheel alone no longer gives the control the focus."""
        if is_guarded(widget) and widget.focusPolicy() == Qt.FocusPolicy.WheelFocus:
            widget.setFocusPolicy(Qt.FocusPolicy.StrongFocus)

    def eventFilter(self, watched: QObject, event: QEvent) -> bool:  # noqa: N802 - Qt's name
        # every event of the application passes here: the class test first, since asking
        # an event its type builds a Python enum (a window's start sends some 70 000)
        guarded = _GUARDED_TYPES.get(type(watched))
        if guarded is None:
            guarded = _GUARDED_TYPES[type(watched)] = is_guarded(watched)
        if not guarded:
            return False
        kind = event.type()
        if kind == QEvent.Type.Polish:
            if self._under_root(watched):
                self._calm(watched)
            return False
        if kind != QEvent.Type.Wheel:
            return False
        if watched.hasFocus() or not self._under_root(watched):
            return False
        self._pass_to_scroll_area(watched, event)
        event.accept()
        return True

    def _pass_to_scroll_area(self, control: QWidget, event: QWheelEvent) -> None:
        """Send the scroll to the innermost scroll area around ``control`` that takes it."""
        vertical = abs(event.angleDelta().y()) >= abs(event.angleDelta().x())
        parent = control.parentWidget()
        while parent is not None:
            if isinstance(parent, QAbstractScrollArea):
                bar = parent.verticalScrollBar() if vertical else parent.horizontalScrollBar()
                if bar.maximum() > bar.minimum():
                    viewport = parent.viewport()
                    position = viewport.mapFromGlobal(event.globalPosition())
                    forwarded = QWheelEvent(
                        position,
                        event.globalPosition(),
                        event.pixelDelta(),
                        event.angleDelta(),
                        event.buttons(),
                        event.modifiers(),
                        event.phase(),
                        event.inverted(),
                    )
                    before = bar.value()
                    QApplication.sendEvent(viewport, forwarded)
                    self.passed_on += 1
                    if bar.value() != before:
                        return
            parent = parent.parentWidget()


def install_wheel_guard(root: QWidget) -> WheelGuard:
    """Make the mouse wheel leave every unfocused control under ``root`` alone.

    Combo boxes, spin boxes and sliders (not scroll bars) under ``root``, including those
    created later, stop taking the focus from the wheel; a wheel event over one that does
    not have the focus is handed to the nearest enclosing scroll area that can still
    scroll, and the control keeps its value. Call it once, e.g. on the main window; the
    guard lives as long as ``root``.

    Parameters
    ----------
    root
        The widget whose descendants are guarded.

    Returns
    -------
    WheelGuard
        The installed filter (a child of ``root``).
    """
    existing = root.findChild(WheelGuard, options=Qt.FindChildOption.FindDirectChildrenOnly)
    if existing is not None:
        return existing
    guard = WheelGuard(root)
    app = QApplication.instance()
    if app is None:
        raise RuntimeError("install_wheel_guard needs a QApplication")
    app.installEventFilter(guard)
    root.destroyed.connect(lambda *_: app.removeEventFilter(guard))
    return guard
