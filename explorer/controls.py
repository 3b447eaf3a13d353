"""Run controls: method, step or tolerance, speed, play/pause, single step, reset, clear."""

from __future__ import annotations

import math

from PySide6.QtCore import Signal
from PySide6.QtGui import QDoubleValidator
from PySide6.QtWidgets import (
    QComboBox,
    QHBoxLayout,
    QLabel,
    QLineEdit,
    QPushButton,
    QStyle,
    QWidget,
)

SPEEDS = (
    ("0.1×", 0.1),
    ("0.25×", 0.25),
    ("0.5×", 0.5),
    ("1×", 1.0),
    ("2×", 2.0),
    ("5×", 5.0),
    ("20×", 20.0),
    ("100×", 100.0),
    ("max", math.inf),
)
AUTOMATIC = "automatic"


class ControlsPanel(QWidget):
    """The toolbar's widgets; emits what the user asked for, the window applies it.

    Signals
    -------
    method_changed(object)   stepper name, or None for the automatic choice
    step_changed(object)     dt or tolerance (float), or None for the method's default
    speed_changed(float)     simulated time per wall second (``inf``: as fast as possible)
    play_toggled(bool)       True: running
    single_step_requested()
    reset_requested()
    clear_requested()        forget launched trajectories
    """

    method_changed = Signal(object)
    step_changed = Signal(object)
    speed_changed = Signal(float)
    play_toggled = Signal(bool)
    single_step_requested = Signal()
    reset_requested = Signal()
    clear_requested = Signal()

    def __init__(self, parent: QWidget | None = None):
        super().__init__(parent)
        style = self.style()
        self.method_combo = QComboBox()
        self.method_combo.setMinimumContentsLength(24)
        self.method_combo.setSizeAdjustPolicy(QComboBox.SizeAdjustPolicy.AdjustToContents)
        self.method_combo.currentIndexChanged.connect(self._on_method_index_changed)
        self.reason_label = QLabel("")
        self.reason_label.setStyleSheet("color: #555")
        self.step_edit = QLineEdit()
        self.step_edit.setPlaceholderText("auto")
        self.step_edit.setMaximumWidth(80)
        validator = QDoubleValidator(1e-15, 1e3, 15)
        validator.setNotation(QDoubleValidator.Notation.ScientificNotation)
        self.step_edit.setValidator(validator)
        self.step_edit.editingFinished.connect(self._on_step_edit_finished)
        self.step_label = QLabel("dt:")
        self.speed_combo = QComboBox()
        for label, _ in SPEEDS:
            self.speed_combo.addItem(label)
        self.speed_combo.setCurrentIndex(3)
        self.speed_combo.currentIndexChanged.connect(self._on_speed_index_changed)
        self.play_button = QPushButton()
        self.play_button.setCheckable(True)
        self.play_button.setChecked(True)
        self.play_button.toggled.connect(self._on_play_button_toggled)
        self.step_button = QPushButton(
            style.standardIcon(QStyle.StandardPixmap.SP_MediaSeekForward), ""
        )
        self.step_button.setToolTip("Single step (one frame) while paused")
        self.step_button.clicked.connect(self.single_step_requested)
        self.reset_button = QPushButton(
            style.standardIcon(QStyle.StandardPixmap.SP_MediaSkipBackward), ""
        )
        self.reset_button.setToolTip("Reset to the initial conditions")
        self.reset_button.clicked.connect(self.reset_requested)
        self.clear_button = QPushButton("Clear orbits")
        self.clear_button.setToolTip("Remove the trajectories launched by clicking")
        self.clear_button.clicked.connect(self.clear_requested)
        layout = QHBoxLayout(self)
        layout.setContentsMargins(4, 0, 4, 0)
        for widget in (
            QLabel("Method:"),
            self.method_combo,
            self.reason_label,
            self.step_label,
            self.step_edit,
            QLabel("Speed:"),
            self.speed_combo,
            self.play_button,
            self.step_button,
            self.reset_button,
            self.clear_button,
        ):
            layout.addWidget(widget)
        self._steppers: dict = {}
        self._update_play_button(True)

    # -- configuration from the window -------------------------------------------------------

    def set_methods(self, steppers: dict, separable: bool, automatic: str, reason: str) -> None:
        """Offer ``automatic`` plus every stepper the system's structure allows."""
        self._steppers = steppers
        self.method_combo.blockSignals(True)
        self.method_combo.clear()
        label = f"{AUTOMATIC} ({automatic})" if automatic else AUTOMATIC
        self.method_combo.addItem(label, None)
        self.method_combo.setItemData(0, reason, role=3)  # Qt.ToolTipRole
        for name, stepper in steppers.items():
            if stepper.needs_separable and not separable:
                continue
            self.method_combo.addItem(name, name)
            index = self.method_combo.count() - 1
            self.method_combo.setItemData(index, stepper.description, role=3)
        self.method_combo.setCurrentIndex(0)
        self.method_combo.blockSignals(False)
        self.automatic = automatic
        self.reason_label.setText(reason)
        self.reason_label.setToolTip(reason)
        self._update_step_label(automatic)

    @property
    def method(self) -> str | None:
        return self.method_combo.currentData()

    @property
    def speed(self) -> float:
        return SPEEDS[self.speed_combo.currentIndex()][1]

    @property
    def step_value(self) -> float | None:
        text = self.step_edit.text().strip()
        try:
            value = float(text)
        except ValueError:
            return None
        return value if value > 0 else None

    @property
    def playing(self) -> bool:
        return self.play_button.isChecked()

    def _update_step_label(self, name: str | None) -> None:
        stepper = self._steppers.get(name or getattr(self, "automatic", ""))
        adaptive = bool(stepper and stepper.adaptive)
        self.step_label.setText("tol:" if adaptive else "dt:")
        self.step_edit.setToolTip(
            "relative tolerance (empty: default)" if adaptive else "time step (empty: default)"
        )

    def is_adaptive(self) -> bool:
        stepper = self._steppers.get(self.method or getattr(self, "automatic", ""))
        return bool(stepper and stepper.adaptive)

    def _update_play_button(self, playing: bool) -> None:
        pixmap = (
            QStyle.StandardPixmap.SP_MediaPause if playing else QStyle.StandardPixmap.SP_MediaPlay
        )
        self.play_button.setIcon(self.style().standardIcon(pixmap))
        self.play_button.setText("Pause" if playing else "Play")
        self.step_button.setEnabled(not playing)

    # -- slots -------------------------------------------------------------------------------

    def _on_method_index_changed(self, _index: int) -> None:
        self._update_step_label(self.method)
        self.method_changed.emit(self.method)

    def _on_step_edit_finished(self) -> None:
        self.step_changed.emit(self.step_value)

    def _on_speed_index_changed(self, _index: int) -> None:
        self.speed_changed.emit(self.speed)

    def _on_play_button_toggled(self, checked: bool) -> None:
        self._update_play_button(checked)
        self.play_toggled.emit(checked)
