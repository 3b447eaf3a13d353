"""Why the run stopped, above the plots, with the energy guard that stopped it at hand.

The one place a run's stop is reported in the window (the status bar keeps the time and
the energy error readouts, and short notes): the reason in words, wrapped, and where the
energy guard made the stop (an energy error, an unbounded motion, an unstable step) its
value, editable, with "Raise ×10" and "Turn guard off" that continue the run from where
it stopped. The window hides it whenever a run starts (a rebuild, a reset, a new scene).
"""

from __future__ import annotations

from PySide6.QtCore import Signal
from PySide6.QtWidgets import (
    QFrame,
    QHBoxLayout,
    QLabel,
    QLineEdit,
    QPushButton,
    QSizePolicy,
    QToolButton,
    QVBoxLayout,
    QWidget,
)

TITLES = {
    "unbounded": "The motion is unbounded",
    "energy_error": "Stopped by the energy guard",
    "unstable": "The step is unstable",
    "non_finite": "The state became non-finite",
    "singular": "The equations are singular",
    "stalled": "The method gave up",
    "budget": "The step budget ran out",
}
GUARDED = ("unbounded", "energy_error", "unstable")
"""Stops the energy guard makes: the banner offers its value there."""
GUARD_TIP = (
    "The energy guard stops a run whose relative energy error |H - H0|/|H0| exceeds this "
    "(measured against the size of the energy's terms once they have grown tenfold), or "
    "whose motion grows without bound. A number such as 0.01, or off. Also: Run > Energy "
    "guard…"
)


def guard_text(value: float | None) -> str:
    return "off" if value is None else f"{value:g}"


class StopBanner(QFrame):
    """A strip above the plots saying why the run stopped, hidden while it runs.

    Signals
    -------
    guard_changed(object)   the energy guard the user set here (float, or None: off)
    restart_requested()     "Start over": the run again from its start
    """

    guard_changed = Signal(object)
    restart_requested = Signal()

    def __init__(self, parent: QWidget | None = None):
        super().__init__(parent)
        self.setObjectName("stop-banner")
        self.setFrameShape(QFrame.Shape.StyledPanel)
        self.setStyleSheet(
            "#stop-banner { background: #fff4d6; border: 1px solid #d9a400; border-radius: 3px; }"
        )
        self.status = ""
        self.title = QLabel()
        self.title.setStyleSheet("font-weight: bold;")
        self.message = QLabel()
        self.message.setWordWrap(True)
        self.message.setSizePolicy(QSizePolicy.Policy.Ignored, QSizePolicy.Policy.Preferred)
        self.message.setTextInteractionFlags(self.message.textInteractionFlags() | _selectable())
        self.guard_label = QLabel("Energy guard:")
        self.guard_edit = QLineEdit()
        self.guard_edit.setFixedWidth(
            self.guard_edit.fontMetrics().horizontalAdvance("0.0001e-10") + 12
        )
        self.guard_edit.setToolTip(GUARD_TIP)
        self.guard_edit.returnPressed.connect(self._on_guard_edit_return_pressed)
        self.raise_button = QPushButton("Raise ×10")
        self.raise_button.setToolTip("Allow ten times the energy error and go on from here")
        self.raise_button.clicked.connect(self._on_raise_button_clicked)
        self.off_button = QPushButton("Turn guard off")
        self.off_button.setToolTip(
            "Go on from here with no energy guard: the run stops only where the numbers overflow"
        )
        self.off_button.clicked.connect(lambda: self.guard_changed.emit(None))
        self.restart_button = QPushButton("Start over")
        self.restart_button.setToolTip("Run again from the initial state (Ctrl+R)")
        self.restart_button.clicked.connect(self.restart_requested)
        self.close_button = QToolButton()
        self.close_button.setText("×")
        self.close_button.setToolTip("Hide this message")
        self.close_button.setAutoRaise(True)
        self.close_button.clicked.connect(self.hide)
        self.guard_widgets = (self.guard_label, self.guard_edit, self.raise_button, self.off_button)
        top = QHBoxLayout()
        top.setContentsMargins(0, 0, 0, 0)
        top.addWidget(self.title)
        top.addStretch(1)
        for widget in (*self.guard_widgets, self.restart_button, self.close_button):
            top.addWidget(widget)
        layout = QVBoxLayout(self)
        layout.setContentsMargins(8, 4, 4, 6)
        layout.setSpacing(2)
        layout.addLayout(top)
        layout.addWidget(self.message)
        self._guard: float | None = None
        self.hide()

    def show_stop(self, status: str, message: str, guard: float | None) -> None:
        """Say why the run stopped (a status of ``systems.simulation.PROBLEMS``)."""
        self.status = status
        self.title.setText(TITLES.get(status, f"Stopped: {status}"))
        self.message.setText(message)
        self.message.setToolTip(message)
        self.set_guard(guard)
        for widget in self.guard_widgets:
            widget.setVisible(status in GUARDED)
        self.show()

    def set_guard(self, value: float | None) -> None:
        self._guard = value
        self.guard_edit.setText(guard_text(value))
        self.raise_button.setEnabled(value is not None)
        self.off_button.setEnabled(value is not None)

    def clear(self) -> None:
        self.status = ""
        self.hide()

    def _on_raise_button_clicked(self) -> None:
        if self._guard is not None:
            self.guard_changed.emit(self._guard * 10.0)

    def _on_guard_edit_return_pressed(self) -> None:
        from systems.simulation import parse_energy_tolerance

        try:
            value = parse_energy_tolerance(self.guard_edit.text())
        except ValueError as exc:
            self.guard_edit.setToolTip(f"{exc}\n\n{GUARD_TIP}")
            self.guard_edit.selectAll()
            return
        self.guard_edit.setToolTip(GUARD_TIP)
        self.guard_changed.emit(value)


def _selectable():
    from PySide6.QtCore import Qt

    return Qt.TextInteractionFlag.TextSelectableByMouse
