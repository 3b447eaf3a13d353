"""Figures that display themselves in Jupyter: matplotlib's Agg canvas, no pyplot, no Qt."""

from __future__ import annotations

import io
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    import matplotlib.axes
    import matplotlib.figure

NO_VALUE = (0.85, 0.85, 0.85, 1.0)
"""Light grey: a pixel of a map with no value (no state there, or the orbit stopped)."""


class Figure:
    """A finished picture: shown by Jupyter as a PNG (``_repr_png_``), written by ``save``.

    Attributes
    ----------
    figure : matplotlib.figure.Figure
        The matplotlib figure itself, to change before showing or saving it.
    """

    def __init__(self, figure: matplotlib.figure.Figure) -> None:
        self.figure = figure

    @property
    def axes(self) -> matplotlib.axes.Axes:
        """The figure's first axes (``matplotlib.axes.Axes``)."""
        return self.figure.axes[0]

    def png(self, dpi: int = 100) -> bytes:
        """The figure as PNG bytes."""
        buffer = io.BytesIO()
        self.figure.savefig(buffer, format="png", dpi=dpi)
        return buffer.getvalue()

    def _repr_png_(self) -> bytes:
        return self.png()

    def save(self, path: str | Path, dpi: int = 100) -> Path:
        """Write the figure to ``path`` (.png, .svg, .pdf: matplotlib's formats)."""
        path = Path(path)
        self.figure.savefig(path, dpi=dpi)
        return path


def new_figure(size: tuple[float, float] = (7.0, 4.5)) -> matplotlib.figure.Figure:
    """A matplotlib figure on the Agg canvas (no pyplot: nothing global, no window)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure as MplFigure

    figure = MplFigure(figsize=size, layout="constrained")
    FigureCanvasAgg(figure)
    return figure


def lines(
    x: np.ndarray,
    ys: dict[str, np.ndarray],
    *,
    xlabel: str,
    ylabel: str = "",
    title: str = "",
    logy: bool = False,
) -> Figure:
    """Curves ``ys`` (name -> (k,)) against ``x`` (k,), with a legend of their names."""
    figure = new_figure()
    axes = figure.add_subplot()
    for name, y in ys.items():
        axes.plot(x, y, label=name, linewidth=1.0)
    if logy:
        axes.set_yscale("log")
    axes.set_xlabel(xlabel)
    axes.set_ylabel(ylabel)
    axes.set_title(title, fontsize=10)
    if len(ys) > 1:
        axes.legend(fontsize=8)
    axes.grid(alpha=0.2)
    return Figure(figure)


def points(
    x: np.ndarray,
    y: np.ndarray,
    *,
    labels: tuple[str, str],
    title: str = "",
    size: float = 1.0,
) -> Figure:
    """A scatter of small dots (a Poincaré section, an orbit diagram)."""
    figure = new_figure((7.0, 5.0))
    axes = figure.add_subplot()
    axes.scatter(x, y, s=size, c="#14145a", linewidths=0, alpha=0.7)
    axes.set_xlabel(labels[0])
    axes.set_ylabel(labels[1])
    axes.set_title(title, fontsize=10)
    axes.grid(alpha=0.2)
    return Figure(figure)


def image(
    values: np.ndarray,
    xs: np.ndarray,
    ys: np.ndarray,
    *,
    labels: tuple[str, str],
    colour_label: str,
    levels: tuple[float, float],
    title: str = "",
) -> Figure:
    """A map ``values`` (ny, nx) over ``xs`` (nx,), ``ys`` (ny,): viridis over ``levels``,
    NaN light grey, with a colour bar."""
    import matplotlib as mpl

    figure = new_figure((6.5, 5.2))
    axes = figure.add_subplot()
    axes.set_facecolor(NO_VALUE)
    dx = (xs[-1] - xs[0]) / max(len(xs) - 1, 1)
    dy = (ys[-1] - ys[0]) / max(len(ys) - 1, 1)
    extent = (xs[0] - dx / 2, xs[-1] + dx / 2, ys[0] - dy / 2, ys[-1] + dy / 2)
    shown = axes.imshow(
        np.ma.masked_invalid(values), origin="lower", extent=extent, aspect="auto",
        cmap=mpl.colormaps["viridis"], vmin=levels[0], vmax=levels[1], interpolation="nearest",
    )  # fmt: skip
    figure.colorbar(shown, ax=axes, label=colour_label)
    axes.set_xlabel(labels[0])
    axes.set_ylabel(labels[1])
    axes.set_title(title, fontsize=10)
    return Figure(figure)
