"""Everything the Textbook dock knows about the main window, in one place.

It uses: ``window.system_started(Built)`` (``Built.compiled``), ``window.compiled`` (after
a parameter change), ``window.editor.parameters_changed`` (optional), ``window.docks``
and ``window._add_dock`` (optional), ``window.phase_view.plot`` / ``.index`` / ``.mode``
/ ``.pair_combo`` / ``.mode_changed``, and the window's close event.
"""

from __future__ import annotations

from PySide6.QtCore import QEvent, QObject, Qt
from PySide6.QtWidgets import QDockWidget, QMainWindow

from explorer.textbook.equilibria_view import EquilibriumMarkers
from explorer.textbook.panel import TextbookPanel

DOCK_KEY = "textbook"


class WindowLink(QObject):
    """Connects a ``TextbookPanel`` to a main window and its phase view."""

    def __init__(self, window: QMainWindow, panel: TextbookPanel):
        super().__init__(panel)
        self.window = window
        self.panel = panel
        self.phase_view = getattr(window, "phase_view", None)
        self.markers: EquilibriumMarkers | None = None
        if self.phase_view is not None:
            self.markers = EquilibriumMarkers(self.phase_view.plot)
            panel.attach_markers(self.markers)
            self.phase_view.pair_combo.currentIndexChanged.connect(self._on_pair_changed)
            self.phase_view.mode_changed.connect(self._on_mode_changed)
        window.system_started.connect(self._on_system_started)
        editor = getattr(window, "editor", None)
        if editor is not None and hasattr(editor, "parameters_changed"):
            editor.parameters_changed.connect(self._on_parameters_changed)
        window.installEventFilter(self)

    def _on_system_started(self, built) -> None:
        self._sync_pair()
        self.panel.set_system(built.compiled)

    def _on_parameters_changed(self, _values) -> None:
        compiled = getattr(self.window, "compiled", None)  # the window rebuilt it already
        if compiled is not None and compiled is not self.panel.compiled:
            self.panel.set_system(compiled)

    def _on_pair_changed(self, _index: int) -> None:
        self._sync_pair()

    def _on_mode_changed(self, _mode: str) -> None:
        self._sync_pair()

    def _sync_pair(self) -> None:
        if self.markers is not None:
            view = self.phase_view
            self.markers.set_pair(int(view.index), getattr(view, "mode", "phase") == "phase")

    def eventFilter(self, watched, event) -> bool:  # noqa: N802 - Qt override
        if watched is self.window and event.type() == QEvent.Type.Close:
            self.panel.shutdown()
        return False


def install(window: QMainWindow) -> TextbookPanel:
    """Add the Textbook dock to ``window`` and follow its systems; returns the panel.

    The dock is tabified with the bottom dock ("Conserved quantities") when there is one,
    else put on the right. If a system is already running it is shown at once.
    """
    panel = TextbookPanel()
    docks = getattr(window, "docks", None)
    add_dock = getattr(window, "_add_dock", None)
    area = Qt.DockWidgetArea.BottomDockWidgetArea
    bottom = docks.get("conserved") if isinstance(docks, dict) else None
    if bottom is None:
        area = Qt.DockWidgetArea.RightDockWidgetArea
    if callable(add_dock):
        dock = add_dock(DOCK_KEY, "Textbook", panel, area)
    else:
        dock = QDockWidget("Textbook", window)
        dock.setObjectName(f"dock-{DOCK_KEY}")
        dock.setWidget(panel)
        window.addDockWidget(area, dock)
        if isinstance(docks, dict):
            docks[DOCK_KEY] = dock
    if bottom is not None:
        window.tabifyDockWidget(bottom, dock)
        bottom.raise_()
    _add_to_view_menu(window, dock)
    panel.link = WindowLink(window, panel)
    panel.dock = dock
    compiled = getattr(window, "compiled", None)
    if compiled is not None:
        panel.link._sync_pair()
        panel.set_system(compiled)
    return panel


def _add_to_view_menu(window: QMainWindow, dock: QDockWidget) -> None:
    for action in window.menuBar().actions():
        menu = action.menu()
        if menu is not None and action.text().replace("&", "") == "View":
            menu.addAction(dock.toggleViewAction())
            return
