"""Everything the Textbook dock knows about the main window, in one place.

It uses: ``window.system_started(Built)`` (``Built.compiled``), ``window.compiled`` (at
install), ``window.editor.parameters_changed(dict)`` (optional), ``window.docks``
and ``window._add_dock`` (optional), ``window.phase_view.plot`` / ``.index`` / ``.mode``
/ ``.pair_combo`` / ``.mode_changed``, ``window.presentation.restyle()`` (optional), and
the window's close event.
"""

from __future__ import annotations

import weakref

from PySide6.QtCore import QEvent, QObject, Qt
from PySide6.QtWidgets import QDockWidget, QMainWindow

from explorer.textbook.equilibria_view import EquilibriumMarkers
from explorer.textbook.panel import TextbookPanel

DOCK_KEY = "textbook"


class WindowLink(QObject):
    """Connects a ``TextbookPanel`` to a main window and its phase view."""

    def __init__(self, window: QMainWindow, panel: TextbookPanel):
        super().__init__(panel)
        self._window = weakref.ref(window)  # the window holds the panel: no reference cycle
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

    @property
    def window(self) -> QMainWindow | None:
        return self._window()

    def _on_parameters_changed(self, values) -> None:
        # The same kernels with the new values (no recompilation); independent of when the
        # window itself restarts its worker (it may debounce the sliders).
        base = self.panel.compiled
        if base is None or not isinstance(values, dict):
            return
        known = {k: float(v) for k, v in values.items() if k in base.parameter_names}
        current = dict(zip(base.parameter_names, base.parameters, strict=True))
        if all(current[k] == v for k, v in known.items()):
            return
        self.panel.set_system(base.with_parameters(known))

    def view_made(self) -> None:
        """A tab's view was made (on first showing it): in presentation mode its plots
        are drawn large at once, as those made with the panel were."""
        presentation = getattr(self.window, "presentation", None)
        if presentation is not None:
            presentation.restyle()

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
    else put on the right. If a system is already running it is shown at once. A window
    that has its panel already (``MainWindow`` installs one) gets that panel back.
    """
    existing = getattr(window, "textbook", None)
    if isinstance(existing, TextbookPanel):
        return existing
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
