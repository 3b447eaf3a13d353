"""Plot helpers in the house style for the Textbook tabs."""

from __future__ import annotations

import pyqtgraph as pg
from PySide6.QtCore import QObject, QSize, Qt
from PySide6.QtWidgets import QDoubleSpinBox, QHBoxLayout, QLabel, QLayout, QVBoxLayout, QWidget

from explorer.panels.curves import style_plot
from explorer.panels.lazy_menu import LazyMenuViewBox

BLUE, RED, GREEN, ORANGE, PURPLE, GREY = (
    "#1f77b4",
    "#d62728",
    "#2ca02c",
    "#ff7f0e",
    "#9467bd",
    "#7f7f7f",
)


def pen(colour: str, width: float = 2.0, dash: bool = False, dot: bool = False):
    style = Qt.PenStyle.SolidLine
    if dash:
        style = Qt.PenStyle.DashLine
    if dot:
        style = Qt.PenStyle.DotLine
    return pg.mkPen(colour, width=width, style=style)


PLOT_HINT = QSize(320, 160)
"""A Textbook plot's preferred size. A tab is laid out at its preferred height inside its
scroll area (word-wrapped notes make the layout height-for-width), so pyqtgraph's own
640 x 480 made the plots taller than the dock and showed only their top."""
NOTES_WIDTH = (260, 460)
"""The least and greatest width of the column of notes beside a tab's plots."""


class TextbookPlot(pg.PlotWidget):
    """A plot widget that prefers ``PLOT_HINT``: the tab's layout stretches it to fit. Its
    view box builds its context menu when first wanted (``LazyMenuViewBox``)."""

    def __init__(self, *args, **kwargs):
        kwargs.setdefault("viewBox", LazyMenuViewBox())
        super().__init__(*args, **kwargs)
        from explorer.inline_math import math_title

        math_title(self.getPlotItem())  # its title's formulas set in type

    def setTitle(self, *args, **kwargs) -> None:  # noqa: N802 - pyqtgraph's name
        self.getPlotItem().setTitle(*args, **kwargs)

    def sizeHint(self) -> QSize:  # noqa: N802 - Qt override
        return QSize(PLOT_HINT)


def beside_notes(plots: QWidget, *notes: QWidget | QLayout) -> QHBoxLayout:
    """``plots`` with a column of ``notes`` (widgets or layouts) on its right.

    The notes sit beside the plots rather than above or below them, so a short bottom
    dock gives its height to the plots.
    """
    column = QWidget()
    column.setMinimumWidth(NOTES_WIDTH[0])
    column.setMaximumWidth(NOTES_WIDTH[1])
    layout = QVBoxLayout(column)
    layout.setContentsMargins(0, 0, 0, 0)
    for note in notes:
        if isinstance(note, QLayout):
            layout.addLayout(note)
        else:
            layout.addWidget(note)
    layout.addStretch(1)
    row = QHBoxLayout()
    row.addWidget(plots, 3)
    row.addWidget(column, 2)
    return row


CORNERS = {"top-right": (-10, 10), "top-left": (10, 10), "bottom-right": (-10, -10)}


def make_plot(title: str, bottom: str, left: str, corner: str = "top-right") -> pg.PlotWidget:
    """A white plot with a grid, axis labels (HTML allowed) and a legend in ``corner``."""
    widget = TextbookPlot(background="w")
    plot = widget.getPlotItem()
    style_plot(plot)
    plot.setTitle(title, color="#222", size="10pt")
    plot.setLabel("bottom", bottom)
    plot.setLabel("left", left)
    from explorer.inline_math import math_legend

    math_legend(  # its entries' formulas set in type
        plot,
        offset=CORNERS[corner],
        labelTextColor="#222",
        brush=pg.mkBrush(255, 255, 255, 190),
        pen=pg.mkPen("#c8c8c8"),
    )
    widget.setMinimumSize(220, 160)
    adopt_menus(widget)
    return widget


def adopt_menus(widget: pg.PlotWidget) -> None:
    """Give the context menus pyqtgraph makes without a Qt parent one: the plot widget.

    Parentless, they are owned by Python alone and die when the garbage collector frees
    them, on whatever thread runs it (the scene builder's, say), where destroying a
    QObject deadlocks against the GUI thread. Owned by the widget, they are destroyed
    with it, on the GUI thread. The window flags are kept, so they still pop up. (A
    ``LazyMenuViewBox`` has no menu yet here, and gives the one it builds the same owner.)
    """
    plot = widget.getPlotItem()
    for menu in (getattr(plot, "ctrlMenu", None), getattr(plot.getViewBox(), "menu", None)):
        if menu is not None and menu.parent() is None:
            menu.setParent(widget, menu.windowFlags())


def clear_plot(widget: pg.PlotWidget) -> None:
    """Remove every item and legend entry, and delete them on the GUI thread.

    A removed pyqtgraph item is left owned by Python only; if it sits in a reference
    cycle, the cyclic garbage collector may free it later on whatever thread happens to
    run it (the scene builder's), and a QObject destroyed there deadlocks against the GUI
    thread. ``deleteLater`` destroys the C++ objects here, deterministically.
    """
    plot = widget.getPlotItem()
    doomed = list(plot.items)
    plot.clear()
    if plot.legend is not None:
        for sample, label in list(plot.legend.items):
            doomed += [sample, label]
        plot.legend.clear()
    for item in doomed:
        if isinstance(item, QObject):
            item.deleteLater()


def note_label(text: str = "") -> QLabel:
    """A wrapped explanatory line of rich text, its formulas set in type
    (``explorer.inline_math.MathLabel``: right-click one to copy it as LaTeX)."""
    from explorer.inline_math import MathLabel

    label = MathLabel(text)
    label.setTextInteractionFlags(
        Qt.TextInteractionFlag.TextSelectableByMouse | Qt.TextInteractionFlag.LinksAccessibleByMouse
    )
    label.setStyleSheet("color: #333; padding: 2px")
    return label


def sub(name: str, index: str) -> str:
    """``name<sub>index</sub>``."""
    return f"{name}<sub>{index}</sub>"


def headroom(plot: pg.PlotItem, low: float, high: float, top: float = 0.5) -> None:
    """A y range over [low, high] with ``top`` of the span free above, for the legend."""
    span = max(high - low, 1e-9 * max(abs(high), abs(low), 1.0))
    plot.setYRange(low - 0.06 * span, high + top * span, padding=0)


def spin_box(low: float, high: float, value: float, step: float, decimals: int = 3):
    """A number field that reports only finished edits (no recomputation per keystroke)."""
    box = QDoubleSpinBox()
    box.setRange(low, high)
    box.setDecimals(decimals)
    box.setSingleStep(step)
    box.setValue(value)
    box.setKeyboardTracking(False)
    return box
