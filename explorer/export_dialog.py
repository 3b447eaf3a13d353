"""The Export dialog: format, figure size and CSV thinning, returned as ``ExportOptions``.

The window's Export menu opens it with the panel's size on screen; the figure's size
starts at twice that (``explorer.export.GUI_SCALE``), with the panel's shape kept while
either side is edited unless the box is unticked. A CSV table can keep every stored
sample, one row every Δt of simulated time, or N rows evenly spaced in time. The dialog
only chooses: the caller asks for the file name (``ExportOptions.suffix`` and
``file_filter`` fit a ``QFileDialog``) and writes it (``explorer.export``).

Usage::

    options = ExportDialog.ask(panel.size(), parent=window, title="Export phase view")
    if options is not None:
        ...  # export_widget(target, path, options.size) or write_trajectories_csv(...)
"""

from __future__ import annotations

from PySide6.QtCore import QEvent, QObject, QSize, Qt
from PySide6.QtWidgets import (
    QAbstractSpinBox,
    QButtonGroup,
    QCheckBox,
    QComboBox,
    QDialog,
    QDialogButtonBox,
    QDoubleSpinBox,
    QFormLayout,
    QGroupBox,
    QHBoxLayout,
    QLabel,
    QRadioButton,
    QSpinBox,
    QVBoxLayout,
    QWidget,
)

from explorer.export import FORMATS, GUI_SCALE, MAX_PIXELS, ExportOptions, scaled_size

FORMAT_LABELS = {
    "png": "PNG image",
    "svg": "SVG drawing",
    "csv": "CSV table (every orbit)",
}


class _WheelOnlyWithFocus(QObject):
    """Ignore the mouse wheel over a spin box or combo box that has no keyboard focus, so
    scrolling past the dialog never changes a value."""

    def eventFilter(self, watched: QObject, event: QEvent) -> bool:  # noqa: N802 - Qt override
        if event.type() == QEvent.Type.Wheel and isinstance(watched, QWidget):
            if not watched.hasFocus():
                event.ignore()
                return True
        return super().eventFilter(watched, event)


class ExportDialog(QDialog):
    """Choose how to export: format, a figure's size in pixels, a table's rows.

    Parameters
    ----------
    panel_size : QSize or (int, int)
        The panel's size on screen; the figure's size starts at ``GUI_SCALE`` times it.
    parent : QWidget, optional
    formats : sequence of str
        Which of ``"png"``, ``"svg"``, ``"csv"`` to offer, in that order of the list.
    format : str
        The one chosen at first.
    title : str
    """

    def __init__(
        self,
        panel_size: QSize | tuple[int, int],
        parent: QWidget | None = None,
        *,
        formats: tuple[str, ...] = FORMATS,
        format: str = "png",  # noqa: A002 - the option's name
        title: str = "Export",
    ):
        super().__init__(parent)
        self.setWindowTitle(title)
        if isinstance(panel_size, QSize):
            panel_size = (panel_size.width(), panel_size.height())
        self.panel_size = (max(int(panel_size[0]), 1), max(int(panel_size[1]), 1))
        formats = tuple(f for f in FORMATS if f in formats)
        if not formats:
            raise ValueError(f"no format to offer; choose among {FORMATS}")
        self._wheel = _WheelOnlyWithFocus(self)

        self.format_combo = QComboBox()
        for name in formats:
            self.format_combo.addItem(FORMAT_LABELS[name], name)
        self.format_combo.setToolTip(
            "PNG: a picture of the panel; SVG: a drawing whose curves stay sharp at any "
            "zoom; CSV: the orbits' t, q, q_dot, p and H, one row per sample"
        )
        self.format_combo.setCurrentIndex(max(self.format_combo.findData(format), 0))

        width, height = scaled_size(self.panel_size)
        self.width_box = self._pixels(width, "Width of the picture in pixels")
        self.height_box = self._pixels(height, "Height of the picture in pixels")
        self.keep_shape = QCheckBox("Keep the panel's shape")
        self.keep_shape.setChecked(True)
        self.keep_shape.setToolTip(
            "Change the height with the width (and back) so the figure has the panel's shape"
        )
        self.size_note = QLabel()
        self.size_note.setWordWrap(True)
        self.width_box.valueChanged.connect(self._on_width_changed)
        self.height_box.valueChanged.connect(self._on_height_changed)
        figure = QGroupBox("Figure")
        form = QFormLayout(figure)
        form.addRow("Width (px)", self.width_box)
        form.addRow("Height (px)", self.height_box)
        form.addRow(self.keep_shape)
        form.addRow(self.size_note)
        self.figure_group = figure

        self.all_rows = QRadioButton("Every sample kept")
        self.all_rows.setToolTip("One row per sample the window holds (recent ones are dense)")
        self.every_rows = QRadioButton("One row every Δt of simulated time")
        self.every_rows.setToolTip(
            "The first sample the window holds at or after 0, Δt, 2Δt, ... and the last one "
            "(run --every and export --every integrate again for rows at exactly those times)"
        )
        self.points_rows = QRadioButton("A number of rows evenly spaced in time")
        self.points_rows.setToolTip("The first sample at or after each of N evenly spaced times")
        self.rows_group = QButtonGroup(self)
        for button in (self.all_rows, self.every_rows, self.points_rows):
            self.rows_group.addButton(button)
        self.all_rows.setChecked(True)
        self.every_box = QDoubleSpinBox()
        self.every_box.setDecimals(6)
        self.every_box.setRange(1e-6, 1e9)
        self.every_box.setValue(0.1)
        self.every_box.setToolTip("Δt: simulated time between rows")
        self.points_box = QSpinBox()
        self.points_box.setRange(2, 10**7)
        self.points_box.setValue(1000)
        self.points_box.setToolTip("N: rows per orbit")
        for box in (self.every_box, self.points_box):
            box.setFocusPolicy(Qt.FocusPolicy.StrongFocus)
            box.installEventFilter(self._wheel)
        table = QGroupBox("Table rows")
        rows = QVBoxLayout(table)
        rows.addWidget(self.all_rows)
        line = QHBoxLayout()
        line.addWidget(self.every_rows)
        line.addWidget(self.every_box)
        rows.addLayout(line)
        line = QHBoxLayout()
        line.addWidget(self.points_rows)
        line.addWidget(self.points_box)
        rows.addLayout(line)
        self.table_group = table
        self.rows_group.buttonToggled.connect(self._update)

        buttons = QDialogButtonBox(
            QDialogButtonBox.StandardButton.Ok | QDialogButtonBox.StandardButton.Cancel
        )
        buttons.accepted.connect(self.accept)
        buttons.rejected.connect(self.reject)
        self.buttons = buttons

        layout = QVBoxLayout(self)
        top = QFormLayout()
        top.addRow("Format", self.format_combo)
        layout.addLayout(top)
        layout.addWidget(figure)
        layout.addWidget(table)
        layout.addWidget(buttons)
        self.format_combo.installEventFilter(self._wheel)
        self.format_combo.currentIndexChanged.connect(self._update)
        self._update()

    def _pixels(self, value: int, tip: str) -> QSpinBox:
        box = QSpinBox()
        box.setRange(1, MAX_PIXELS)
        box.setValue(value)
        box.setToolTip(tip)
        box.setFocusPolicy(Qt.FocusPolicy.StrongFocus)
        box.setButtonSymbols(QAbstractSpinBox.ButtonSymbols.UpDownArrows)
        box.installEventFilter(self._wheel)
        return box

    # -- keeping the shape -----------------------------------------------------------------

    def _on_width_changed(self, width: int) -> None:
        if self.keep_shape.isChecked():
            height = round(width * self.panel_size[1] / self.panel_size[0])
            self.height_box.blockSignals(True)
            self.height_box.setValue(max(1, min(MAX_PIXELS, height)))
            self.height_box.blockSignals(False)
        self._update()

    def _on_height_changed(self, height: int) -> None:
        if self.keep_shape.isChecked():
            width = round(height * self.panel_size[0] / self.panel_size[1])
            self.width_box.blockSignals(True)
            self.width_box.setValue(max(1, min(MAX_PIXELS, width)))
            self.width_box.blockSignals(False)
        self._update()

    def _update(self, *_args) -> None:
        table = self.format == "csv"
        self.figure_group.setEnabled(not table)
        self.table_group.setEnabled(table)
        self.every_box.setEnabled(table and self.every_rows.isChecked())
        self.points_box.setEnabled(table and self.points_rows.isChecked())
        w, h = self.panel_size
        scale = self.width_box.value() / w
        self.size_note.setText(
            f"The panel is {w} × {h} on screen; the figure is {scale:.3g} × that "
            f"(default {GUI_SCALE} ×): text and lines are scaled with it."
        )

    # -- the answer ----------------------------------------------------------------------------

    @property
    def format(self) -> str:
        return self.format_combo.currentData()

    def options(self) -> ExportOptions:
        """The choices as ``ExportOptions`` (a figure's size, or a table's thinning)."""
        if self.format == "csv":
            every = self.every_box.value() if self.every_rows.isChecked() else None
            points = self.points_box.value() if self.points_rows.isChecked() else None
            return ExportOptions("csv", every=every, points=points)
        return ExportOptions(
            self.format, width=self.width_box.value(), height=self.height_box.value()
        )

    @classmethod
    def ask(
        cls,
        panel_size: QSize | tuple[int, int],
        parent: QWidget | None = None,
        **options,
    ) -> ExportOptions | None:
        """Show the dialog (modal); the options chosen, or None if it was cancelled.
        ``options`` are those of the constructor (``formats``, ``format``, ``title``)."""
        dialog = cls(panel_size, parent, **options)
        try:
            if dialog.exec() != QDialog.DialogCode.Accepted:
                return None
            return dialog.options()
        finally:
            dialog.deleteLater()
