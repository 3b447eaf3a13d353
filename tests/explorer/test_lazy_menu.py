"""Plots build their context menus on the first right-click, and those menus are
pyqtgraph's own, as when they were built with the plot."""

from __future__ import annotations

import pyqtgraph as pg
from PySide6.QtCore import QPoint, Qt

from explorer.panels.lazy_menu import LazyMenuViewBox
from tests.explorer.conftest import wait_for_points


def _plots(window) -> dict[str, pg.PlotItem]:
    return {
        "phase": window.phase_view.plot,
        "mechanism": window.configuration_view.mechanism,
        "energy": window.conserved_view.energy_plot,
        "textbook": window.textbook.energy.energy_plot.getPlotItem(),
    }


def _right_click(qtbot, plot: pg.PlotItem):
    """Right-click the middle of ``plot``'s view box; the menu that pops up."""
    box = plot.getViewBox()
    widget = box.getViewWidget()
    pixel = widget.mapFromScene(box.sceneBoundingRect().center())
    qtbot.mouseClick(widget.viewport(), Qt.MouseButton.RightButton, pos=QPoint(pixel))
    qtbot.waitUntil(lambda: box.menu is not None and box.menu.isVisible(), timeout=3000)
    return box.menu


def _texts(menu) -> list[str]:
    return [action.text() for action in menu.actions() if not action.isSeparator()]


def test_a_plot_builds_its_menu_on_the_first_right_click(qtbot, window):
    wait_for_points(qtbot, window, 5)
    window.docks["textbook"].raise_()  # tabbed behind the conserved quantities
    qtbot.waitUntil(lambda: window.docks["textbook"].visibleRegion().isEmpty() is False)
    plots = _plots(window)
    for plot in plots.values():
        assert isinstance(plot.getViewBox(), LazyMenuViewBox)
        assert plot.getViewBox().menu is None  # not built with the plot
    for name, plot in plots.items():
        box = plot.getViewBox()
        menu = _right_click(qtbot, plot)
        texts = _texts(menu)
        # pyqtgraph's view box menu, then the plot's options and the scene's export
        for text in ("View All", "X axis", "Y axis", "Mouse Mode", "Plot Options", "Export..."):
            assert text in texts, (name, texts)
        assert menu.ctrl[0].linkCombo.count() >= 1  # its link lists filled as when built
        # owned by the plot's widget: destroyed with it, on the GUI thread
        assert menu.parent() is box.getViewWidget()
        assert menu.windowFlags() & Qt.WindowType.Popup
        menu.close()
        if name == "textbook":
            continue  # its tab has drawn nothing yet: View All has nothing to show
        # the same menu the next time; View All fits the view to the items again
        box.setRange(xRange=(1e6, 1e6 + 1), yRange=(1e6, 1e6 + 1), padding=0)
        assert _right_click(qtbot, plot) is menu
        view_all = next(a for a in menu.actions() if a.text() == "View All")
        view_all.trigger()
        menu.close()
        (x0, _), (y0, _) = box.viewRange()
        assert x0 < 1e5 and y0 < 1e5, name


def test_a_disabled_menu_is_never_built(qtbot):
    # a right-click on an item inside a plot adds the view box's actions to its menu
    inside = LazyMenuViewBox()
    assert "View All" in [action.text() for action in inside.getContextMenus(None)]
    box = LazyMenuViewBox(enableMenu=False)
    assert not box.menuEnabled() and box.getMenu(None) is None
    box.setMenuEnabled(True)
    assert box.menu is None and box.menuEnabled()  # enabled: built when wanted
    assert box.getMenu(None) is not None
    box.setMenuEnabled(False)
    assert box.menu is None and box.getContextMenus(None) == []
