"""Presentation mode (View > Presentation, F11): readable from the back of a lecture hall.

The window goes full screen with only the phase plane and the panels chosen under View >
Presentation panels (remembered in the preferences); its widgets' fonts grow by
``FONT_SCALE``, and every plot's curves, axes, titles and legends are drawn large and
thick. Panels rebuild their curves for each new system, and some add items as they run
(a long orbit's frozen parts): the plots are restyled every ``RESTYLE_MS`` while the
mode lasts. Leaving restores the layout, the window's geometry and font, and every pen
and font that was changed.
"""

from __future__ import annotations

import pyqtgraph as pg
from PySide6.QtCore import QObject, Qt, QTimer, Signal
from PySide6.QtGui import QFont
from PySide6.QtWidgets import QMainWindow

FONT_SCALE = 1.6
"""The window's widgets' font, as a multiple of its size outside presentation mode."""
PEN_SCALE = 2.5
PEN_LEAST = 3.0
"""A curve's pen in presentation mode: its width times ``PEN_SCALE``, at least this."""
TICK_POINTS = 15
LABEL_POINTS = 17
TITLE_POINTS = 19
LEGEND_POINTS = 15
TITLE_COLOUR = "#000000"
"""Plot titles in presentation mode: black and bold, legible at the back of a hall."""
RIGHT_SHARE = 0.42
"""The right docks' share of the window's width in presentation mode (no editor on the
left): the configuration's two plots stand side by side there."""
RESTYLE_MS = 400
AXES = ("left", "bottom", "right", "top")


def _relabel(axis: pg.AxisItem) -> None:
    """Draw ``axis``'s label again in its ``labelStyle`` (its text kept)."""
    if axis.labelText or axis.labelUnits:
        axis.setLabel(axis.labelText, axis.labelUnits, axis.labelUnitPrefix)


def _pen_key(pen) -> tuple:
    return (pen.color().name(), round(pen.widthF(), 3), int(pen.style().value))


class Presentation(QObject):
    """Presentation mode of a ``MainWindow`` (its ``docks`` and ``preferences``).

    Signals
    -------
    toggled(bool)  the mode was entered (True) or left (False)
    """

    toggled = Signal(bool)

    def __init__(self, window: QMainWindow):
        super().__init__(window)
        self.window = window
        self.active = False
        self._saved: tuple | None = None
        self.timer = QTimer(self)
        self.timer.setInterval(RESTYLE_MS)
        self.timer.timeout.connect(self.restyle)

    @property
    def panels(self) -> tuple[str, ...]:
        """The docks shown beside the phase plane (keys of ``window.docks``)."""
        return self.window.preferences.presentation_panels

    def choose(self, key: str, shown: bool) -> None:
        """Show (or not) the dock ``key`` in presentation mode; applies at once if active."""
        panels = [p for p in self.panels if p != key] + ([key] if shown else [])
        self.window.preferences.set_presentation_panels(panels)
        if self.active:
            self._show_chosen()

    def set_active(self, active: bool) -> None:
        """Enter or leave presentation mode."""
        if active == self.active:
            return
        if active:
            self._enter()
        else:
            self._leave()
        self.toggled.emit(self.active)

    def _enter(self) -> None:
        window = self.window
        self._saved = (
            window.saveState(),
            window.geometry(),
            QFont(window.font())
            if window.testAttribute(Qt.WidgetAttribute.WA_SetFont)
            else QFont(),
            window.isFullScreen(),
            window.isMaximized(),
            dict(getattr(getattr(window, "dock_shares", None), "shares", {})),
        )
        self.active = True
        font = QFont(window.font())
        font.setPointSizeF(font.pointSizeF() * FONT_SCALE)
        window.setFont(font)
        self._show_chosen()
        window.showFullScreen()
        self.restyle()
        self.timer.start()

    def _leave(self) -> None:
        window = self.window
        self.timer.stop()
        self.active = False
        self._unstyle()
        state, geometry, font, full_screen, maximized, shares = self._saved
        self._saved = None
        self._arrange(False)
        window.setFont(font)
        if not full_screen:
            window.showMaximized() if maximized else window.showNormal()
            window.setGeometry(geometry)
        window.restoreState(state)
        if shares:
            window.dock_shares.keep(shares)

    def _show_chosen(self) -> None:
        chosen = self.panels
        for key, dock in self.window.docks.items():
            link = getattr(dock.widget(), "link", None)
            wanted = key in chosen and getattr(link, "offered", True)
            if wanted and dock.isFloating():
                dock.setFloating(False)
            dock.setVisible(wanted)
        self._arrange(self.active)
        shares = getattr(self.window, "dock_shares", None)
        if shares is not None:
            shares.reset()
            if self.active:
                shares.shares[Qt.DockWidgetArea.RightDockWidgetArea] = RIGHT_SHARE
                shares.apply()

    def _arrange(self, presenting: bool) -> None:
        """The configuration's mechanism and path side by side while presenting (stacked
        in the narrow dock, each was a strip under the large type)."""
        panels = getattr(self.window, "panels", {})
        view = panels.get("configuration") if isinstance(panels, dict) else None
        if view is not None and hasattr(view, "set_side_by_side"):
            view.set_side_by_side(presenting)

    # -- the plots --------------------------------------------------------------------------

    def _plots(self) -> list[pg.PlotItem]:
        plots = []
        for view in self.window.findChildren(pg.GraphicsView):
            scene = view.scene()
            if scene is None:
                continue
            plots += [item for item in scene.items() if isinstance(item, pg.PlotItem)]
        return plots

    def restyle(self) -> None:
        """Draw every plot large: thick curves, large ticks, labels, titles and legends."""
        if not self.active:
            return
        for plot in self._plots():
            self._style_plot(plot)

    def _style_plot(self, plot: pg.PlotItem) -> None:
        for name in AXES:
            axis = plot.getAxis(name) if name in plot.axes else None
            if axis is None:
                continue
            if not hasattr(axis, "_presentation"):
                axis._presentation = (axis.style.get("tickFont"), dict(axis.labelStyle))
                tick = QFont(axis.font())
                tick.setPointSizeF(TICK_POINTS)
                axis.setTickFont(tick)
            if axis.labelStyle.get("font-size") != f"{LABEL_POINTS}pt":
                axis.labelStyle = {**axis.labelStyle, "font-size": f"{LABEL_POINTS}pt"}
                _relabel(axis)
        title = plot.titleLabel
        math = getattr(plot, "math_title", None)  # a title with formulas set in type
        if math is not None:
            if math.override.get("size") != f"{TITLE_POINTS}pt":
                math.restyle(size=f"{TITLE_POINTS}pt", color=TITLE_COLOUR, bold=True)
        elif title.opts.get("size") != f"{TITLE_POINTS}pt":
            if not hasattr(title, "_presentation"):
                title._presentation = (
                    title.opts.get("size"),
                    title.opts.get("color"),
                    title.opts.get("bold"),
                )
            title.setText(title.text, size=f"{TITLE_POINTS}pt", color=TITLE_COLOUR, bold=True)
        legend = plot.legend
        if legend is not None and legend.opts.get("labelTextSize") != f"{LEGEND_POINTS}pt":
            if not hasattr(legend, "_presentation"):
                legend._presentation = legend.opts.get("labelTextSize")
            legend.setLabelTextSize(f"{LEGEND_POINTS}pt")
        for item in plot.items:
            opts = getattr(item, "opts", None)
            pen = opts.get("pen") if isinstance(opts, dict) else None
            if pen is None or not hasattr(item, "setPen"):
                continue
            pen = pg.mkPen(pen)
            if getattr(item, "_presentation_set", None) == _pen_key(pen):
                continue
            item._presentation = pen  # the pen a panel gave it
            thick = pg.mkPen(pen)
            thick.setWidthF(max(pen.widthF() * PEN_SCALE, PEN_LEAST))
            thick.setCosmetic(True)
            item.setPen(thick)
            item._presentation_set = _pen_key(thick)

    def _unstyle(self) -> None:
        for plot in self._plots():
            for name in AXES:
                axis = plot.getAxis(name) if name in plot.axes else None
                saved = getattr(axis, "_presentation", None)
                if saved is None:
                    continue
                tick, style = saved
                axis.setTickFont(tick)
                axis.labelStyle = style
                _relabel(axis)
                del axis._presentation
            title = plot.titleLabel
            math = getattr(plot, "math_title", None)
            if math is not None and math.override:
                math.restyle()
            if hasattr(title, "_presentation"):
                size, colour, bold = title._presentation
                for key, value in (("size", size), ("color", colour), ("bold", bold)):
                    if value is None:
                        title.opts.pop(key, None)
                    else:
                        title.opts[key] = value
                title.opts.setdefault("color", None)
                title.setText(title.text)
                del title._presentation
            legend = plot.legend
            if legend is not None and hasattr(legend, "_presentation"):
                legend.setLabelTextSize(legend._presentation)
                del legend._presentation
            for item in plot.items:
                if hasattr(item, "_presentation_set"):
                    item.setPen(item._presentation)
                    del item._presentation, item._presentation_set
