"""The Textbook dock: six tabs that put the theorems of analytical mechanics on screen."""

from __future__ import annotations

from PySide6.QtWidgets import QFrame, QScrollArea, QTabWidget, QVBoxLayout, QWidget

from explorer.textbook.action_angle_view import ActionAngleView
from explorer.textbook.base import TextbookTabView
from explorer.textbook.energy_view import EnergyTheoremView
from explorer.textbook.equilibria_view import EquilibriaView, EquilibriumMarkers
from explorer.textbook.floquet_view import FloquetView
from explorer.textbook.principle_view import PrincipleView
from explorer.textbook.reduction_view import ReductionView
from explorer.textbook.tasks import TaskRunner

MINIMUM_HEIGHT = 120


TABS = (
    EquilibriaView,
    PrincipleView,
    ReductionView,
    ActionAngleView,
    EnergyTheoremView,
    FloquetView,
)
"""The tabs' views, in their order."""


class TextbookPanel(QWidget):
    """Equilibria, Hamilton's principle, reduction, action–angle, the energy theorem and
    Floquet theory.

    ``set_system(compiled)`` shows a system (a new one, or new parameter values). Every
    computation runs in the panel's ``TaskRunner``; a tab computes when it is first shown
    after a change, except the equilibria, which also feed the phase-view markers.

    The tabs other than the equilibria are made when first shown or asked for (their
    attributes, ``views``): nine plots cost a window 60-75 ms of the GUI thread, and most
    windows never show them. A tab made late gets the system shown, and computes as one
    made at the start would when shown.
    """

    def __init__(self, parent: QWidget | None = None):
        super().__init__(parent)
        self.runner = TaskRunner(self)
        self.compiled = None
        self.markers: EquilibriumMarkers | None = None
        self.link = None  # the WindowLink, set by install()
        self.dock = None  # the QDockWidget holding the panel, set by install()
        self.equilibria = EquilibriaView(self.runner)
        self._made: dict[type, TextbookTabView] = {EquilibriaView: self.equilibria}
        self.tabs = QTabWidget()
        self.tabs.setDocumentMode(True)
        self._holders: dict[type, QScrollArea] = {}
        for kind in TABS:
            # each tab scrolls, so the dock can be made short on a small screen
            holder = QScrollArea()
            holder.setFrameShape(QFrame.Shape.NoFrame)
            holder.setWidgetResizable(True)
            holder.setMinimumHeight(MINIMUM_HEIGHT)
            self._holders[kind] = holder
            self.tabs.addTab(holder, kind.title)
        self._holders[EquilibriaView].setWidget(self.equilibria)
        self.tabs.currentChanged.connect(self._on_tabs_current_changed)
        layout = QVBoxLayout(self)
        layout.setContentsMargins(0, 0, 0, 0)
        layout.addWidget(self.tabs)
        self.equilibria.equilibria_found.connect(self._on_equilibria_found)

    @property
    def principle(self) -> PrincipleView:
        return self._view(PrincipleView)

    @property
    def reduction(self) -> ReductionView:
        return self._view(ReductionView)

    @property
    def action_angle(self) -> ActionAngleView:
        return self._view(ActionAngleView)

    @property
    def energy(self) -> EnergyTheoremView:
        return self._view(EnergyTheoremView)

    @property
    def floquet(self) -> FloquetView:
        return self._view(FloquetView)

    @property
    def views(self) -> tuple:
        """Every tab's view, in order (those not made yet are made now)."""
        return tuple(self._view(kind) for kind in TABS)

    @property
    def made_views(self) -> tuple:
        """The views made so far, in the order they were made (the equilibria first)."""
        return tuple(self._made.values())

    def _view(self, kind: type) -> TextbookTabView:
        """The tab ``kind``'s view, made now if it was not: it gets the system shown, and
        computes when shown (at once, if its tab is in front)."""
        view = self._made.get(kind)
        if view is None:
            view = self._made[kind] = kind(self.runner)
            if self.compiled is not None:
                view.set_system(self.compiled)
            self._holders[kind].setWidget(view)
            if self.link is not None:
                self.link.view_made()
        return view

    def _on_tabs_current_changed(self, index: int) -> None:
        for kind, holder in self._holders.items():
            if self.tabs.indexOf(holder) == index:
                self._view(kind)

    def attach_markers(self, markers: EquilibriumMarkers) -> None:
        """Draw the equilibria found into the phase view through ``markers``."""
        self.markers = markers

    def set_system(self, compiled) -> None:
        """Show ``compiled``: every tab is stale; the visible one and the equilibria compute."""
        self.compiled = compiled
        for view in self._made.values():
            view.set_system(compiled)

    def show_tab(self, view: QWidget) -> None:
        """Bring ``view`` (one of ``views``) to the front."""
        self.tabs.setCurrentWidget(self._holders[type(view)])

    def _on_equilibria_found(self, result) -> None:
        if self.markers is not None:
            self.markers.show_result(result)

    def shutdown(self) -> None:
        """End the computations' worker processes, take the markers away."""
        self.runner.shutdown()
        if self.markers is not None:
            self.markers.remove()
            self.markers = None
