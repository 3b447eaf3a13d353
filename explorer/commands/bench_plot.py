"""A minimal headless work-precision figure for ``bench`` (pyqtgraph, PNG or SVG).

Used when ``explorer.export.render_workprecision`` (the GUI panel's renderer) is not
available. Two log-log plots side by side: final-state error and maximum relative energy
error against wall time, one curve per method; the reference is stated in the title.
SVG goes through ``QSvgGenerator`` (pyqtgraph's SVGExporter is broken on Qt 6.12).
"""

from __future__ import annotations

import math
from pathlib import Path

COLOURS = ("#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#8c564b", "#e377c2", "#17becf")
SYMBOLS = ("o", "s", "t", "d", "+", "x", "star", "h")


def render(result, path: str | Path, size=(1100, 520)) -> Path:
    """Draw ``result`` (``systems.workprecision.WorkPrecision``) to ``path`` (.png/.svg)."""
    from explorer.headless import ensure_qt_platform

    ensure_qt_platform()
    import pyqtgraph as pg
    from PySide6.QtCore import QRect, QSize
    from PySide6.QtGui import QPainter
    from PySide6.QtWidgets import QApplication

    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in (".png", ".svg"):
        raise ValueError(f"cannot draw a figure as {suffix or 'a file without suffix'}")
    from explorer.export import check_svg, save_png, signals_held
    from systems.files import atomic_path

    app = QApplication.instance() or QApplication([])
    pg.setConfigOptions(antialias=True, foreground="#222222", background="w")
    with signals_held():  # Qt draws: a signal waits for it (explorer.export)
        widget = _drawn(result, size, app)
    try:
        with atomic_path(path) as temporary, signals_held():
            if suffix == ".svg":
                from PySide6.QtSvg import QSvgGenerator

                generator = QSvgGenerator()
                generator.setFileName(str(temporary))
                generator.setSize(QSize(*size))
                generator.setViewBox(QRect(0, 0, *size))
                generator.setTitle(f"{result.title}: work-precision")
                painter = QPainter(generator)
                try:
                    widget.render(painter)
                finally:
                    painter.end()
                check_svg(temporary)
            else:
                save_png(widget.grab(), temporary)
    finally:  # on a failed write too: a widget left to the interpreter's exit crashed it
        with signals_held():
            widget.close()
            widget.deleteLater()
            app.processEvents()
    return path


def _drawn(result, size: tuple[int, int], app):
    """The figure's widget, laid out and shown (offscreen)."""
    import pyqtgraph as pg

    widget = pg.GraphicsLayoutWidget()
    widget.resize(*size)
    widget.addLabel(
        f"{result.title}: work-precision to t = {result.t_end:.6g}"
        f"<br><small>reference: {result.reference}</small>",
        colspan=2,
    )
    widget.nextRow()
    panels = [("final-state error", "final_error")]
    if any(p.energy_error is not None for p in result.points):
        panels.append(("max relative energy error", "energy_error"))
    plots = []
    for label, attribute in panels:
        plot = widget.addPlot()
        plot.setLogMode(x=True, y=True)
        plot.showGrid(x=True, y=True, alpha=0.3)
        plot.setLabel("bottom", "wall time (s)")
        plot.setLabel("left", label)
        for side in ("bottom", "left"):
            plot.getAxis(side).enableAutoSIPrefix(False)
        legend = plot.addLegend(offset=(-10, 10))
        for i, method in enumerate(result.methods):
            points = [
                (p.wall_s, getattr(p, attribute))
                for p in result.curve(method)
                if getattr(p, attribute) is not None and getattr(p, attribute) > 0
                and math.isfinite(getattr(p, attribute)) and p.wall_s > 0
            ]  # fmt: skip
            if not points:
                continue
            x, y = zip(*points, strict=True)
            colour = COLOURS[i % len(COLOURS)]
            plot.plot(
                x, y, pen=pg.mkPen(colour, width=2), symbol=SYMBOLS[i % len(SYMBOLS)],
                symbolBrush=colour, symbolPen=colour, symbolSize=7, name=method,
            )  # fmt: skip
        del legend
        plots.append(plot)
    widget.show()
    app.processEvents()
    return widget
