"""Plots whose view box builds its context menu on the first right-click.

pyqtgraph builds every ``ViewBox``'s menu ("View All", the X and Y axis pages with their
forms, "Mouse Mode") when the view box is made: 1.6 ms of the GUI thread's time each, and
a window holds about two dozen plots, most of whose menus are never opened.
``LazyMenuViewBox`` builds the same menu when it is first asked for (a right-click on the
plot, or a right-click on an item inside it that adds its parents' menus), so the menu
shown is pyqtgraph's own, with the plot's "Plot Options" and the scene's "Export..." added
as before. ``add_plot`` makes a plot with one; a ``PlotWidget`` takes one as ``viewBox=``.
"""

from __future__ import annotations

import pyqtgraph as pg
from pyqtgraph.graphicsItems.ViewBox.ViewBoxMenu import ViewBoxMenu


class LazyMenuViewBox(pg.ViewBox):
    """A ``pyqtgraph.ViewBox`` whose ``menu`` is None until the menu is first wanted.

    ``menu`` is then pyqtgraph's ``ViewBoxMenu``, owned by the view showing the plot (so it
    is destroyed with that widget, on the GUI thread, never by the garbage collector on
    another thread). Arguments are those of ``pyqtgraph.ViewBox``.
    """

    def __init__(self, *args, enableMenu: bool = True, **kwargs):  # noqa: N803 - pyqtgraph's
        super().__init__(*args, enableMenu=False, **kwargs)
        self.state["enableMenu"] = enableMenu

    def setMenuEnabled(self, enableMenu: bool = True) -> None:  # noqa: N802, N803
        if enableMenu:
            self.state["enableMenu"] = True  # built when first wanted
            self.sigStateChanged.emit(self)
        else:
            super().setMenuEnabled(False)

    def built_menu(self) -> ViewBoxMenu | None:
        """The context menu, built now if it is enabled and not built yet."""
        if self.menu is None and self.menuEnabled():
            menu = ViewBoxMenu(self)
            widget = self.getViewWidget()
            if widget is not None:
                menu.setParent(widget, menu.windowFlags())  # still a pop-up
            self.menu = menu
            self.updateViewLists()  # the link lists pyqtgraph fills as views register
        return self.menu

    def getMenu(self, ev) -> ViewBoxMenu | None:  # noqa: N802 - pyqtgraph's name
        return self.built_menu()

    def getContextMenus(self, event) -> list:  # noqa: N802 - pyqtgraph's name
        self.built_menu()
        return super().getContextMenus(event)


def add_plot(layout: pg.GraphicsLayoutWidget | pg.GraphicsLayout, **kwargs) -> pg.PlotItem:
    """``layout.addPlot(**kwargs)`` with a ``LazyMenuViewBox``.

    Parameters
    ----------
    layout : pyqtgraph.GraphicsLayoutWidget or pyqtgraph.GraphicsLayout
        Where the plot goes.
    **kwargs
        ``addPlot``'s arguments (row, col, axisItems...), other than ``viewBox``.

    Returns
    -------
    pyqtgraph.PlotItem
    """
    return layout.addPlot(viewBox=LazyMenuViewBox(), **kwargs)
