"""Run controls: method, step or tolerance, speed, play/pause, single step, reset, clear."""

from __future__ import annotations

import math

from PySide6.QtCore import QPoint, Qt, Signal
from PySide6.QtGui import QDoubleValidator
from PySide6.QtWidgets import (
    QComboBox,
    QHBoxLayout,
    QLabel,
    QLineEdit,
    QPushButton,
    QStyle,
    QToolTip,
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
DEFAULT_SPEED_INDEX = 3
AUTOMATIC = "automatic"
METHOD_TIP = (
    "The integration method. Automatic picks one for this system (why: below); methods "
    "that would drop an effect of the system are listed but disabled."
)
HIGHEST_ACCURACY = "taylor"
"""The method the Max accuracy button switches to, at ``HIGHEST_ACCURACY_TOL``."""
HIGHEST_ACCURACY_TOL = 1e-16
"""Its tolerance: below machine epsilon, so Taylor series of order 20 from the derivation
with the state and the series' first two orders in double-double
(``systems.taylor.double``): Kepler's 100 periods to 5.5e-14 instead of 3.7e-12 at
machine epsilon, for 1.1-1.4x the integration time of the default tolerance (measured
on eight scenes, docs/internals.md: within the 1.5x this button may cost)."""
HIGHEST_ACCURACY_TIP = (
    "Max accuracy: run this system with taylor, Taylor series of order 20 from its "
    f"derivation at tolerance {HIGHEST_ACCURACY_TOL:g}, below machine epsilon: the state "
    "and the series' first orders carried in double-double (about 1.1-1.4x the time of "
    "its default). Choose a method in the list to go back."
)


class ControlsPanel(QWidget):
    """The toolbar's widgets; emits what the user asked for, the window applies it.

    Signals
    -------
    method_changed(object)   stepper name, or None for the automatic choice
    notice_posted(str)       a message for the status bar (what Max accuracy did,
                             or why it could not)
    step_changed(object)     dt or tolerance (float), or None for the method's default
    speed_changed(float)     simulated time per wall second (``inf``: as fast as possible)
    play_toggled(bool)       True: running
    single_step_requested()
    reset_requested()
    clear_requested()        forget launched trajectories
    """

    method_changed = Signal(object)
    notice_posted = Signal(str)
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
        # as wide as the entry shown ("automatic (gauss_legendre6)" was cut), in
        # presentation mode's large type too (``_fit_method_combo``)
        self.method_combo.setMinimumContentsLength(16)
        self.method_combo.setSizeAdjustPolicy(
            QComboBox.SizeAdjustPolicy.AdjustToMinimumContentsLengthWithIcon
        )
        self.method_combo.setToolTip(METHOD_TIP)
        self.method_combo.currentIndexChanged.connect(self._on_method_index_changed)
        self.reason = ""  # why the automatic choice chose what it did (in the tooltip)
        # (the label "Highest accuracy" cut the method box at 1280 x 720 in presentation
        # mode's large type)
        self.accuracy_button = QPushButton("Max accuracy")
        self._accuracy_text: str | None = None  # the tolerance the button typed
        self.accuracy_button.setToolTip(HIGHEST_ACCURACY_TIP)
        self.accuracy_button.clicked.connect(self._on_accuracy_button_clicked)
        self.step_edit = QLineEdit()
        self.step_edit.setPlaceholderText("auto")
        self.step_edit.setMaximumWidth(110)
        validator = QDoubleValidator(1e-15, 1e3, 15)
        validator.setNotation(QDoubleValidator.Notation.ScientificNotation)
        self.step_edit.setValidator(validator)
        self.step_edit.editingFinished.connect(self._on_step_edit_finished)
        # an empty field is not "acceptable" to the validator, so editingFinished does
        # not fire for it: emptied is automatic again at once
        self.step_edit.textChanged.connect(self._on_step_text_changed)
        self.step_label = QLabel("dt:")
        self.speed_combo = QComboBox()
        for label, _ in SPEEDS:
            self.speed_combo.addItem(label)
        self.speed_combo.setCurrentIndex(DEFAULT_SPEED_INDEX)
        self.speed_combo.setToolTip(
            "Simulated time per second of wall time; max: as fast as the machine goes "
            "(the states are those of a full-speed run at every speed)"
        )
        self.speed_combo.currentIndexChanged.connect(self._on_speed_index_changed)
        self.play_button = QPushButton()
        self.play_button.setCheckable(True)
        self.play_button.setChecked(True)
        self.play_button.toggled.connect(self._on_play_button_toggled)
        self.step_button = QPushButton(
            style.standardIcon(QStyle.StandardPixmap.SP_MediaSeekForward), ""
        )
        self.step_button.setToolTip(
            "Single step: advance one frame while paused; at max speed, one frame of 1× (Ctrl+.)"
        )
        self.step_button.clicked.connect(self.single_step_requested)
        self.reset_button = QPushButton(
            style.standardIcon(QStyle.StandardPixmap.SP_MediaSkipBackward), ""
        )
        self.reset_button.setToolTip(
            "Reset: start every orbit again from its initial state (Ctrl+R)"
        )
        self.reset_button.clicked.connect(self.reset_requested)
        self.clear_button = QPushButton("Clear orbits")
        self.clear_button.setToolTip(
            "Remove the orbits launched by clicking in the phase view (Ctrl+Shift+K); "
            "right-click an orbit to delete only that one"
        )
        self.clear_button.clicked.connect(self.clear_requested)
        layout = QHBoxLayout(self)
        layout.setContentsMargins(4, 0, 4, 0)
        for widget in (
            QLabel("Method:"),
            self.method_combo,
            self.accuracy_button,
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

    def set_methods(
        self, steppers: dict, mechanics, automatic: str, reason: str, keep: bool = False
    ) -> None:
        """Offer ``automatic`` plus every method of the registry ``steppers``.

        A method that does not apply to ``mechanics`` (it would drop an effect, needs a
        separable H, ...) is listed disabled, with the reason as its tooltip. With ``keep``
        (the same system rebuilt after an edit) a chosen method that still applies stays
        chosen with its step; otherwise (a new system) the choice goes back to automatic
        and the step field is cleared, since a step typed for one system is no step for
        another.
        """
        previous = self.method if keep else None
        step_text = self.step_edit.text() if keep else ""
        self._steppers = steppers
        self.method_combo.blockSignals(True)
        self.method_combo.clear()
        label = f"{AUTOMATIC} ({automatic})" if automatic else AUTOMATIC
        self.method_combo.addItem(label, None)
        self.method_combo.setItemData(0, reason, Qt.ItemDataRole.ToolTipRole)
        model = self.method_combo.model()
        chosen = 0
        for name, stepper in steppers.items():
            refusal = stepper.applies_to(mechanics)
            label = name if refusal is None else f"{name} (not for this system)"
            self.method_combo.addItem(label, name)
            index = self.method_combo.count() - 1
            tip = f"{stepper.description}; order {stepper.order}; takes {stepper.setting}"
            self.method_combo.setItemData(index, refusal or tip, Qt.ItemDataRole.ToolTipRole)
            if refusal is not None:
                model.item(index).setEnabled(False)
            elif name == previous:
                chosen = index
        self.method_combo.setCurrentIndex(chosen)
        self.method_combo.blockSignals(False)
        self._fit_method_combo()
        self.automatic = automatic
        self.reason = reason
        self.method_combo.setToolTip(f"{METHOD_TIP}\n\nAutomatic choice: {reason}")
        refusal = self.refusal(HIGHEST_ACCURACY) if HIGHEST_ACCURACY in steppers else None
        self.accuracy_button.setToolTip(
            HIGHEST_ACCURACY_TIP
            if refusal is None
            else f"{HIGHEST_ACCURACY_TIP}\n\nNot for this system: {refusal}"
        )
        self._setting = None
        self.step_edit.blockSignals(True)  # the window applies the new settings itself
        self._update_step_label(self.method)
        self.step_edit.setText(step_text if chosen else "")
        self.step_edit.blockSignals(False)

    def refusal(self, name: str) -> str | None:
        """The tooltip of a disabled method (why it does not apply), else None."""
        for index in range(self.method_combo.count()):
            if self.method_combo.itemData(index) == name:
                if self.method_combo.model().item(index).isEnabled():
                    return None
                return self.method_combo.itemData(index, Qt.ItemDataRole.ToolTipRole)
        return None

    def choose_highest_accuracy(self) -> bool:
        """Switch the run to ``HIGHEST_ACCURACY`` at ``HIGHEST_ACCURACY_TOL``, as choosing
        it in the method list and typing the tolerance in the step field would;
        where the system does not allow it, change nothing and say why. Either way the
        message goes out by ``notice_posted``. Returns whether the method is now the one
        asked for.
        """
        switched, message = self._switch_to_highest_accuracy()
        self.notice_posted.emit(message)
        return switched

    def _switch_to_highest_accuracy(self) -> tuple[bool, str]:
        index = self.method_combo.findData(HIGHEST_ACCURACY)
        if index <= 0:
            return False, (
                f"Max accuracy is not available: no method {HIGHEST_ACCURACY!r} is offered"
            )
        refusal = self.refusal(HIGHEST_ACCURACY)
        if refusal is not None:
            return False, f"Max accuracy is not available here: {refusal}"
        previous = self.method_combo.currentText()
        tol = HIGHEST_ACCURACY_TOL
        if self.method == HIGHEST_ACCURACY and self.step_value == tol:
            return True, f"Already at max accuracy: {HIGHEST_ACCURACY} at tolerance {tol:g}"
        # a tolerance typed for the method before goes first, so that taylor never runs
        # with it (a session records "dt auto", "method taylor", then "dt 1e-16")
        self.step_edit.clear()
        self.method_combo.setCurrentIndex(index)
        self._accuracy_text = f"{tol:g}"
        self.step_edit.setText(self._accuracy_text)
        self.step_changed.emit(tol)
        return True, (
            f"Max accuracy: {HIGHEST_ACCURACY} (Taylor series of order 20 at tolerance "
            f"{tol:g}: the state and the first orders in double-double); choose "
            f"{previous} in the method list to go back"
        )

    def show_setting_in_use(self, setting: str, value: float) -> None:
        """Show the step or tolerance the run uses when the field is left on automatic."""
        if setting and math.isfinite(value):
            self.step_edit.setPlaceholderText(f"auto: {value:.3g}")
        else:
            self.step_edit.setPlaceholderText("auto")
        self._fit_step_edit()

    def _fit_step_edit(self) -> None:
        """Room for "auto: 1e-12" in the font shown (presentation mode's large type)."""
        advance = self.step_edit.fontMetrics().horizontalAdvance("auto: 0.00000")
        self.step_edit.setMaximumWidth(max(110, advance + 16))

    def changeEvent(self, event) -> None:  # noqa: N802 - Qt override
        super().changeEvent(event)
        if event.type() == event.Type.FontChange:
            self._fit_step_edit()
            self._fit_method_combo()

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
        setting = stepper.setting if stepper else "dt"
        if setting != getattr(self, "_setting", setting):
            self.step_edit.clear()  # a step typed for one method is no tolerance for another
        self._setting = setting
        self.step_label.setText(f"{setting}:")
        self.step_edit.setToolTip(
            {
                "tol": "Relative tolerance of the adaptive method; empty: its default "
                "(shown greyed). Press Enter to apply.",
                "ds": "Step in the method's fictitious time; empty: its default "
                "(shown greyed). Press Enter to apply.",
            }.get(
                setting,
                "Time step of the fixed-step method; empty: the default (shown greyed). "
                "Press Enter to apply.",
            )
        )

    def is_adaptive(self) -> bool:
        stepper = self._steppers.get(self.method or getattr(self, "automatic", ""))
        return bool(stepper and stepper.adaptive)

    def refresh_play_button(self) -> None:
        """Show the play button's state after it was set with its signals blocked."""
        self._update_play_button(self.playing)

    def _update_play_button(self, playing: bool) -> None:
        pixmap = (
            QStyle.StandardPixmap.SP_MediaPause if playing else QStyle.StandardPixmap.SP_MediaPlay
        )
        self.play_button.setIcon(self.style().standardIcon(pixmap))
        self.play_button.setText("Pause" if playing else "Play")
        self.play_button.setToolTip(
            "Pause the simulation (Space)" if playing else "Run the simulation (Space)"
        )
        self.step_button.setEnabled(not playing)

    # -- slots -------------------------------------------------------------------------------

    def _fit_method_combo(self) -> None:
        """Room for the entry shown, at least 16 characters."""
        self.method_combo.setMinimumContentsLength(max(16, len(self.method_combo.currentText())))

    def _on_accuracy_button_clicked(self) -> None:
        switched, message = self._switch_to_highest_accuracy()
        self.notice_posted.emit(message)
        if not switched:
            # the reason is longer than the status bar shows beside its readouts: in full
            # at the button too
            button = self.accuracy_button
            QToolTip.showText(button.mapToGlobal(QPoint(0, button.height())), message, button)

    def _on_method_index_changed(self, _index: int) -> None:
        if self.method != HIGHEST_ACCURACY and self._accuracy_text is not None:
            # the tolerance Max accuracy typed is taylor's double-double: another method
            # chosen in the list starts at its own default ("dt auto" first)
            if self.step_edit.text() == self._accuracy_text:
                self.step_edit.clear()
            self._accuracy_text = None
        self._fit_method_combo()
        self._update_step_label(self.method)
        self.method_changed.emit(self.method)

    def _on_step_edit_finished(self) -> None:
        self.step_changed.emit(self.step_value)

    def _on_step_text_changed(self, text: str) -> None:
        if not text.strip():
            self.step_changed.emit(None)

    def _on_speed_index_changed(self, _index: int) -> None:
        self.speed_changed.emit(self.speed)

    def _on_play_button_toggled(self, checked: bool) -> None:
        self._update_play_button(checked)
        self.play_toggled.emit(checked)
