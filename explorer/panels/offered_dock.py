"""A panel's dock offered only where the panel means something.

The normal-mode energies and the constraint forces each live in a dock tabbed with the
conserved quantities. ``OfferedDockLink`` keeps the dock's View-menu action enabled
where the panel applies (or while the dock is still open), with a status tip saying why
not, and shuts the view's background work down when the window closes. ``wanted`` says
whether the dock is shown for the running system: View > Reset layout shows it only then.
"""

from __future__ import annotations

from PySide6.QtCore import QEvent, QObject


class OfferedDockLink(QObject):
    """Ties ``view``'s ``dock`` to ``window``: subclasses decide when it is offered.

    Parameters
    ----------
    window : QMainWindow
    view : QWidget
        Has ``shutdown()``, called when the window closes.
    dock : QDockWidget
    offered_tip : str
        The View-menu action's status tip where the panel applies.
    refused_tip : str
        Where it does not, with ``{why}`` for the reason.
    """

    def __init__(self, window, view, dock, offered_tip: str, refused_tip: str):
        super().__init__(window)
        self.window = window
        self.view = view
        self.dock = dock
        self.offered = False
        self.wanted = False  # whether opening the system shows the dock (and Reset layout)
        self._tips = (offered_tip, refused_tip)
        dock.visibilityChanged.connect(self._on_dock_visibility_changed)
        window.installEventFilter(self)
        self._offer(False, "no system yet")

    def _offer(self, offered: bool, why: str) -> None:
        action = self.dock.toggleViewAction()
        self.offered = offered
        action.setEnabled(offered or not self.dock.isHidden())
        offered_tip, refused_tip = self._tips
        action.setStatusTip(offered_tip if offered else refused_tip.format(why=why))

    def _on_dock_visibility_changed(self, _visible: bool) -> None:
        action = self.dock.toggleViewAction()
        action.setEnabled(self.offered or not self.dock.isHidden())

    def eventFilter(self, watched, event) -> bool:  # noqa: N802 - Qt override
        if watched is self.window and event.type() == QEvent.Type.Close:
            self.view.shutdown()
        return False


def attach_hidden(window, key: str, title: str, view, link_class):
    """Add ``view`` to ``window`` (a ``MainWindow``) as the dock ``key`` titled ``title``,
    tabbed with the conserved quantities and hidden until offered or asked for, linked by
    ``link_class(window, view, dock)``; returns the view."""
    from PySide6.QtCore import Qt

    dock = window._add_dock(key, title, view, Qt.DockWidgetArea.BottomDockWidgetArea)
    bottom = window.docks.get("conserved")
    if bottom is not None:
        window.tabifyDockWidget(bottom, dock)
        bottom.raise_()
    window.panels[key] = view
    dock.hide()
    view.link = link_class(window, view, dock)
    return view
