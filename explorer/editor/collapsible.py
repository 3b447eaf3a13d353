"""A section of the editor that folds to its title line (constraints, symmetries).

Folded, it takes one line of the editor's page; its title says how many entries it holds,
so a folded section with content is not overlooked. A problem shown inside unfolds it.
"""

from __future__ import annotations

from PySide6.QtCore import Qt
from PySide6.QtWidgets import QFrame, QSizePolicy, QToolButton, QVBoxLayout, QWidget


class CollapsibleSection(QFrame):
    """A title button that folds and unfolds ``body`` (lay the section out in ``content``)."""

    def __init__(self, title: str, parent: QWidget | None = None):
        super().__init__(parent)
        self.setFrameShape(QFrame.Shape.StyledPanel)
        self.title = title
        self.toggle = QToolButton()
        self.toggle.setCheckable(True)
        self.toggle.setToolButtonStyle(Qt.ToolButtonStyle.ToolButtonTextBesideIcon)
        self.toggle.setStyleSheet("QToolButton { border: none; font-weight: bold; }")
        self.toggle.setSizePolicy(QSizePolicy.Policy.Expanding, QSizePolicy.Policy.Fixed)
        self.toggle.toggled.connect(self._on_toggle_toggled)
        self.body = QWidget()
        self.content = QVBoxLayout(self.body)
        self.content.setContentsMargins(4, 0, 4, 4)
        outer = QVBoxLayout(self)
        outer.setContentsMargins(2, 2, 2, 2)
        outer.setSpacing(2)
        outer.addWidget(self.toggle)
        outer.addWidget(self.body)
        self.set_summary("")
        self.set_expanded(False)

    @property
    def expanded(self) -> bool:
        """Whether the body is shown."""
        return self.toggle.isChecked()

    def set_expanded(self, expanded: bool) -> None:
        """Unfold (True) or fold the section."""
        self.toggle.setChecked(expanded)
        self._on_toggle_toggled(expanded)

    def set_summary(self, summary: str) -> None:
        """Say what the section holds after its title (``""``: nothing)."""
        self.toggle.setText(f"{self.title} — {summary}" if summary else self.title)

    def _on_toggle_toggled(self, expanded: bool) -> None:
        self.toggle.setArrowType(Qt.ArrowType.DownArrow if expanded else Qt.ArrowType.RightArrow)
        self.body.setVisible(expanded)
