"""The main window's size on screen and its docks' shares of it.

The window opens filling the screen's available geometry (``fit_window``), with the side
docks and the bottom dock given a share of it (``default_shares``). ``DockShares`` keeps
those shares as the window is resized: Qt gives every pixel a window gains or loses to
the central widget, so a window made small and large again kept its side panels narrow
(with a horizontal scroll bar) and its phase plane a strip. A separator the user drags
sets the share of that side from then on.

Plots keep a readable size: every panel with a plot has a minimum size (``PLOT_MINIMUM``
for its plot area), so the window cannot be made small enough to crush one; its minimum
size fits a 1280 x 720 screen.
"""

from __future__ import annotations

from PySide6.QtCore import QEvent, QObject, QRect, QSize, Qt, QTimer
from PySide6.QtWidgets import QDockWidget, QMainWindow, QStyle

PLOT_MINIMUM = QSize(200, 150)
"""The least size of a plot area on screen, in pixels."""
SIDE_SHARE = {
    Qt.DockWidgetArea.LeftDockWidgetArea: 0.3,
    Qt.DockWidgetArea.RightDockWidgetArea: 0.27,
}
"""The width of the side docks by default, as a share of the window's width."""
SIDE_WIDTH = (300, 480)
"""The least and greatest default width of a side dock."""
BOTTOM_SHARE = 0.42
BOTTOM_HEIGHT = (280, 380)
"""The bottom dock's default height: its share of the window's height, and its bounds."""
HORIZONTAL = (Qt.DockWidgetArea.LeftDockWidgetArea, Qt.DockWidgetArea.RightDockWidgetArea)


def fit_window(window: QMainWindow, available: QRect) -> None:
    """Size and place ``window`` (frame included) within ``available`` (a screen's
    available geometry), never below its minimum size.

    Before the window is shown its frame is not known: a title bar and borders are
    assumed from the style.
    """
    frame = window.frameGeometry()
    inner = window.geometry()
    extra_w = frame.width() - inner.width()
    extra_h = frame.height() - inner.height()
    if extra_w <= 0 and extra_h <= 0:  # not shown yet: estimate the frame
        border = window.style().pixelMetric(QStyle.PixelMetric.PM_DefaultFrameWidth)
        extra_w = 2 * border
        extra_h = window.style().pixelMetric(QStyle.PixelMetric.PM_TitleBarHeight) + 2 * border
    window.resize(available.width() - extra_w, available.height() - extra_h)
    window.move(available.topLeft())


def default_shares(size: QSize) -> dict:
    """The docks' default shares of a window of ``size``: side widths and the bottom height,
    as fractions of the window's width and height."""
    shares = {}
    for area, share in SIDE_SHARE.items():
        width = min(max(share * size.width(), SIDE_WIDTH[0]), SIDE_WIDTH[1])
        shares[area] = width / max(size.width(), 1)
    height = min(max(BOTTOM_SHARE * size.height(), BOTTOM_HEIGHT[0]), BOTTOM_HEIGHT[1])
    shares[Qt.DockWidgetArea.BottomDockWidgetArea] = height / max(size.height(), 1)
    return shares


class DockShares(QObject):
    """Keeps the docks of each area of ``window`` at a share of the window's size.

    Parameters
    ----------
    window : QMainWindow
        Its docks are found when needed (``findChildren``), so docks added later count.
    """

    def __init__(self, window: QMainWindow):
        super().__init__(window)
        self.window = window
        self.shares: dict = default_shares(window.size())
        self._settled = QSize()  # the window size the shares were last applied at
        self._applying = False
        self._pending = False
        self._available: QRect | None = None  # the screen area fitted to, until shown
        window.installEventFilter(self)
        for dock in window.findChildren(QDockWidget):
            dock.installEventFilter(self)

    def fit(self, available: QRect) -> None:
        """Fit the window to ``available`` (``fit_window``) and give the docks their
        default shares; once shown, the window's real frame is checked against it."""
        self._available = QRect(available)
        fit_window(self.window, available)
        self.reset()

    def reset(self) -> None:
        """Back to the default shares for the window's size, applied now."""
        self.shares = default_shares(self.window.size())
        self.apply()

    def docks(self, area) -> list[QDockWidget]:
        """The docks in ``area`` that take room: shown and not floating."""
        return [
            dock
            for dock in self.window.findChildren(QDockWidget)
            if not dock.isHidden()
            and not dock.isFloating()
            and self.window.dockWidgetArea(dock) == area
        ]

    def apply(self) -> None:
        """Give each area its share of the window now."""
        self._pending = False
        size = self.window.size()
        self._applying = True
        try:
            for area, share in self.shares.items():
                docks = self.docks(area)
                if not docks:
                    continue
                horizontal = area in HORIZONTAL
                length = round(share * (size.width() if horizontal else size.height()))
                orientation = Qt.Orientation.Horizontal if horizontal else Qt.Orientation.Vertical
                self.window.resizeDocks(docks, [length] * len(docks), orientation)
            layout = self.window.layout()
            if layout is not None:
                layout.activate()
        finally:
            self._applying = False
        self._settled = size

    def _schedule(self) -> None:
        if not self._pending:
            self._pending = True
            QTimer.singleShot(0, self._apply_if_alive)

    def _apply_if_alive(self) -> None:
        try:
            if self.window.size() != self._settled:
                self.apply()
            self._pending = False
        except RuntimeError:  # the window is gone
            pass

    def keep(self, shares: dict) -> None:
        """Take ``shares`` as they are now on screen (a layout restored as it was)."""
        self.shares = dict(shares)
        self._settled = self.window.size()

    def remember(self) -> None:
        """Take the docks' present sizes as their shares (after the user moved a separator)."""
        size = self.window.size()
        for area in self.shares:
            docks = [d for d in self.docks(area) if d.geometry().intersects(self.window.rect())]
            if not docks:
                continue
            if area in HORIZONTAL:
                self.shares[area] = docks[0].width() / max(size.width(), 1)
            else:
                self.shares[area] = docks[0].height() / max(size.height(), 1)

    def eventFilter(self, watched, event) -> bool:  # noqa: N802 - Qt override
        if watched is self.window:
            kind = event.type()
            if kind == QEvent.Type.Resize and self.window.size() != self._settled:
                self._schedule()
            elif kind == QEvent.Type.Show and self._available is not None:
                available, self._available = self._available, None
                if not available.contains(self.window.frameGeometry()):
                    fit_window(self.window, available)  # the frame is known now
            elif kind == QEvent.Type.ChildAdded and isinstance(event.child(), QDockWidget):
                event.child().installEventFilter(self)
        elif (
            isinstance(watched, QDockWidget)
            and event.type() == QEvent.Type.Resize
            and not self._applying
            and not self._pending
            and self.window.size() == self._settled
            and self.window.isVisible()
        ):
            self.remember()  # the window kept its size: the user moved a separator
        return False


def keep_plots_readable(panel) -> None:
    """Give every plot area in ``panel`` at least ``PLOT_MINIMUM``: docks are then
    tabbed or scrolled, never crushed, and the window cannot shrink below it."""
    import pyqtgraph as pg

    for view in panel.findChildren(pg.GraphicsView):
        view.setMinimumSize(view.minimumSize().expandedTo(PLOT_MINIMUM))
