"""The Textbook dock: six tabs that put the theorems of analytical mechanics on screen."""

from __future__ import annotations

from PySide6.QtWidgets import QFrame, QScrollArea, QTabWidget, QVBoxLayout, QWidget

from explorer.textbook.action_angle_view import ActionAngleView
from explorer.textbook.energy_view import EnergyTheoremView
from explorer.textbook.equilibria_view import EquilibriaView, EquilibriumMarkers
from explorer.textbook.floquet_view import FloquetView
from explorer.textbook.principle_view import PrincipleView
from explorer.textbook.reduction_view import ReductionView
from explorer.textbook.tasks import TaskRunner

MINIMUM_HEIGHT = 120


class TextbookPanel(QWidget):
    """Equilibria, Hamilton's principle, reduction, action–angle, the energy theorem and
    Floquet theory.

    ``set_system(compiled)`` shows a system (a new one, or new parameter values). Every
    computation runs in the panel's ``TaskRunner``; a tab computes when it is first shown
    after a change, except the equilibria, which also feed the phase-view markers.
    """

    def __init__(self, parent: QWidget | None = None):
        super().__init__(parent)
        self.runner = TaskRunner(self)
        self.compiled = None
        self.markers: EquilibriumMarkers | None = None
        self.link = None  # the WindowLink, set by install()
        self.dock = None  # the QDockWidget holding the panel, set by install()
        self.equilibria = EquilibriaView(self.runner)
        self.principle = PrincipleView(self.runner)
        self.reduction = ReductionView(self.runner)
        self.action_angle = ActionAngleView(self.runner)
        self.energy = EnergyTheoremView(self.runner)
        self.floquet = FloquetView(self.runner)
        self.tabs = QTabWidget()
        self.tabs.setDocumentMode(True)
        self._holders: dict = {}
        for view in self.views:
            # each tab scrolls, so the dock can be made short on a small screen
            holder = QScrollArea()
            holder.setFrameShape(QFrame.Shape.NoFrame)
            holder.setWidgetResizable(True)
            holder.setWidget(view)
            holder.setMinimumHeight(MINIMUM_HEIGHT)
            self._holders[view] = holder
            self.tabs.addTab(holder, view.title)
        layout = QVBoxLayout(self)
        layout.setContentsMargins(0, 0, 0, 0)
        layout.addWidget(self.tabs)
        self.equilibria.equilibria_found.connect(self._on_equilibria_found)

    @property
    def views(self) -> tuple:
        return (
            self.equilibria,
            self.principle,
            self.reduction,
            self.action_angle,
            self.energy,
            self.floquet,
        )

    def attach_markers(self, markers: EquilibriumMarkers) -> None:
        """Draw the equilibria found into the phase view through ``markers``."""
        self.markers = markers

    def set_system(self, compiled) -> None:
        """Show ``compiled``: every tab is stale; the visible one and the equilibria compute."""
        self.compiled = compiled
        for view in self.views:
            view.set_system(compiled)

    def show_tab(self, view: QWidget) -> None:
        """Bring ``view`` (one of ``views``) to the front."""
        self.tabs.setCurrentWidget(self._holders[view])

    def _on_equilibria_found(self, result) -> None:
        if self.markers is not None:
            self.markers.show_result(result)

    def shutdown(self) -> None:
        """End the computations' worker processes, take the markers away."""
        self.runner.shutdown()
        if self.markers is not None:
            self.markers.remove()
            self.markers = None
