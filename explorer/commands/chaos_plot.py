"""Headless figures of ``chaosmap`` and ``bifurcation`` (pyqtgraph, PNG), drawn as
``bench_plot`` draws the work-precision figure: a widget laid out offscreen and grabbed."""

from __future__ import annotations

from pathlib import Path

import numpy as np

NO_VALUE = (0.85, 0.85, 0.85, 1.0)
"""Light grey: a pixel with no value (no state there, or the orbit stopped)."""


def render_map(
    values: np.ndarray,
    xs: np.ndarray,
    ys: np.ndarray,
    *,
    title: str,
    labels: tuple[str, str],
    colour_label: str,
    levels: tuple[float, float],
    path: str | Path,
    size: tuple[int, int] = (820, 700),
) -> Path:
    """A map ``values`` (ny, nx) over ``xs`` (nx,), ``ys`` (ny,) as a PNG, colours from
    viridis over ``levels``, NaN light grey, with a colour bar."""
    import pyqtgraph as pg

    lo, hi = levels
    cmap = pg.colormap.get("viridis")
    scaled = np.clip((values - lo) / (hi - lo if hi > lo else 1.0), 0.0, 1.0)
    rgba = cmap.map(np.nan_to_num(scaled), mode="float")
    rgba = rgba.reshape(*values.shape, 4)
    rgba[~np.isfinite(values)] = NO_VALUE

    def draw(widget):
        plot = widget.addPlot()
        image = pg.ImageItem((rgba * 255).astype(np.uint8).transpose(1, 0, 2))
        dx = (xs[-1] - xs[0]) / max(len(xs) - 1, 1)
        dy = (ys[-1] - ys[0]) / max(len(ys) - 1, 1)
        image.setRect(xs[0] - dx / 2, ys[0] - dy / 2, xs[-1] - xs[0] + dx, ys[-1] - ys[0] + dy)
        plot.addItem(image)
        _label(plot, labels)
        plot.getViewBox().autoRange(padding=0)
        bar = pg.ColorBarItem(values=(lo, hi), colorMap=cmap, interactive=False, label=colour_label)
        widget.addItem(bar)

    return _render(draw, title, path, size)


def render_points(
    x: np.ndarray,
    y: np.ndarray,
    *,
    title: str,
    labels: tuple[str, str],
    path: str | Path,
    size: tuple[int, int] = (1000, 640),
) -> Path:
    """A scatter of small dots (x, y) (an orbit diagram) as a PNG."""
    import pyqtgraph as pg

    def draw(widget):
        plot = widget.addPlot()
        plot.plot(
            x, y, pen=None, symbol="o", symbolSize=1.5, symbolPen=None,
            symbolBrush=pg.mkBrush(20, 20, 90, 160),
        )  # fmt: skip
        _label(plot, labels)
        plot.showGrid(x=True, y=True, alpha=0.2)

    return _render(draw, title, path, size)


def _label(plot, labels: tuple[str, str]) -> None:
    for side, label in zip(("bottom", "left"), labels, strict=True):
        plot.setLabel(side, label)
        plot.getAxis(side).enableAutoSIPrefix(False)


def _render(draw, title: str, path: str | Path, size: tuple[int, int]) -> Path:
    from explorer.headless import ensure_qt_platform

    ensure_qt_platform()
    import pyqtgraph as pg
    from PySide6.QtWidgets import QApplication

    from explorer.export import save_png, signals_held
    from systems.files import atomic_path

    path = Path(path)
    app = QApplication.instance() or QApplication([])
    pg.setConfigOptions(antialias=True, foreground="#222222", background="w")
    with signals_held():
        widget = pg.GraphicsLayoutWidget()
        widget.resize(*size)
        widget.addLabel(title, colspan=2)
        widget.nextRow()
        draw(widget)
        widget.show()
        app.processEvents()
    try:
        with atomic_path(path) as temporary, signals_held():
            save_png(widget.grab(), temporary)
    finally:  # on a failed write too: a widget left to the interpreter's exit crashed it
        with signals_held():
            widget.close()
            widget.deleteLater()
            app.processEvents()
    return path
