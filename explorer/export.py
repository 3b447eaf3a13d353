"""Figures and data out of the application: PNG, SVG (through ``QSvgGenerator``) and CSV.

pyqtgraph's own SVGExporter is broken on Qt 6.12 (pyqtgraph issue 3485), so an SVG is
made by rendering the panel's widget into a ``QSvgGenerator`` (see ``explorer.svg``):
every curve becomes a vector path in pixel coordinates, clipped to its plot and
simplified to the drawing's resolution.

Sized for use: a figure is drawn at a chosen size in pixels (``size``; the GUI offers
twice the panel's size on screen by default, ``export --width/--height`` on the command
line). The panel keeps its look: it is laid out at the chosen shape, no smaller than on
screen, and scaled up to the chosen size (``figure_layout``), so text and lines grow with
the picture instead of shrinking into a corner. CSV tables can be thinned: one row every
``every`` of simulated time, or ``points`` rows evenly spaced in time (``csv_rows``); the
rows are always states the run passed through, never interpolated.
``explorer.headless`` builds a panel without a main window (for the ``export`` command),
integrates the scene to ``t_end`` and draws it.
"""

from __future__ import annotations

import csv
import errno
import math
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

import numpy as np

FIGURE_SUFFIXES = (".png", ".svg")
FORMATS = ("png", "svg", "csv")
PANELS = ("configuration", "phase", "conserved", "workprecision")
MAX_PIXELS = 12_000
"""The largest width or height a figure may be drawn at."""
GUI_SCALE = 2
"""The GUI's default figure: this many times the panel's size on screen."""


@dataclass(frozen=True)
class ExportOptions:
    """What to write: the format, a figure's size, or a table's thinning.

    Attributes
    ----------
    format : str
        ``"png"``, ``"svg"`` or ``"csv"``.
    width, height : int or None
        A figure's size in pixels (PNG pixels, SVG view box); None: the panel's size.
    every : float or None
        CSV: one row every this much simulated time.
    points : int or None
        CSV: this many rows, evenly spaced in simulated time.
    """

    format: str = "png"
    width: int | None = None
    height: int | None = None
    every: float | None = None
    points: int | None = None

    def __post_init__(self) -> None:
        if self.format not in FORMATS:
            raise ValueError(f"unknown export format {self.format!r}; choose from {FORMATS}")
        for name in ("width", "height"):
            value = getattr(self, name)
            if value is not None and not 1 <= value <= MAX_PIXELS:
                raise ValueError(f"{name} must be between 1 and {MAX_PIXELS} pixels, not {value}")
        check_thinning(self.every, self.points)

    @property
    def size(self) -> tuple[int, int] | None:
        """(width, height), or None when either is not given."""
        if self.width is None or self.height is None:
            return None
        return (self.width, self.height)

    @property
    def suffix(self) -> str:
        return f".{self.format}"

    @property
    def file_filter(self) -> str:
        """For ``QFileDialog``: e.g. ``"PNG image (*.png)"``."""
        return {
            "png": "PNG image (*.png)",
            "svg": "SVG drawing (*.svg)",
            "csv": "CSV table (*.csv)",
        }[self.format]


def check_thinning(every: float | None, points: int | None) -> None:
    """``ValueError`` unless the CSV thinning is one valid choice (or none)."""
    if every is not None and points is not None:
        raise ValueError("choose one row every DT or a number of rows, not both")
    if every is not None and not (math.isfinite(every) and every > 0):
        raise ValueError(f"one row every DT needs a positive time, not {every}")
    if points is not None and not 2 <= points <= 10**7:
        raise ValueError(f"the number of rows must be between 2 and 10000000, not {points}")


def scaled_size(on_screen: tuple[int, int], scale: float = GUI_SCALE) -> tuple[int, int]:
    """A figure size: ``scale`` times a panel's size on screen, within ``MAX_PIXELS``."""
    width, height = on_screen
    return (
        max(1, min(MAX_PIXELS, round(scale * width))),
        max(1, min(MAX_PIXELS, round(scale * height))),
    )


def figure_layout(
    on_screen: tuple[int, int], size: tuple[int, int]
) -> tuple[tuple[int, int], float]:
    """How a panel of size ``on_screen`` is drawn into a figure of ``size`` pixels.

    Returns the size to lay the panel out at and the scale from it to the figure: the
    scale is the figure's size over the panel's in the tighter direction (at least 1, so
    a small figure gets the panel's own text size, not a smaller one), and the layout has
    the figure's shape. Twice the panel's size gives the same layout at scale 2.
    """
    width, height = size
    scale = max(1.0, min(width / max(on_screen[0], 1), height / max(on_screen[1], 1)))
    layout = (max(1, math.ceil(width / scale - 1e-9)), max(1, math.ceil(height / scale - 1e-9)))
    return layout, scale


@contextmanager
def laid_out(widget, size: tuple[int, int]) -> Iterator[None]:
    """``widget`` resized to ``size`` while the block runs, then given its size back.

    Nothing is painted in between (only pending layout requests are handled), so a panel
    of the window does not flicker.
    """
    from PySide6.QtCore import QCoreApplication, QEvent

    before = widget.size()
    if (before.width(), before.height()) == tuple(size):
        yield
        return
    widget.resize(*size)
    QCoreApplication.sendPostedEvents(None, QEvent.Type.LayoutRequest)
    try:
        yield
    finally:
        widget.resize(before)
        QCoreApplication.sendPostedEvents(None, QEvent.Type.LayoutRequest)


def render_image(widget, size: tuple[int, int]):
    """``widget`` drawn into a ``QImage`` of ``size`` pixels (``figure_layout``): laid out
    at the figure's shape and rendered at a device pixel ratio, as on a high-DPI screen,
    so text and curves are drawn sharp at the larger size, not scaled up as pixels."""
    from PySide6.QtCore import Qt
    from PySide6.QtGui import QImage
    from PySide6.QtWidgets import QWidget

    layout, scale = figure_layout((widget.width(), widget.height()), size)
    image = QImage(size[0], size[1], QImage.Format.Format_ARGB32)
    image.setDevicePixelRatio(scale)
    image.fill(Qt.GlobalColor.white)
    with laid_out(widget, layout):
        QWidget.render(widget, image)  # QWidget's, not QGraphicsView's (which takes a painter)
    image.setDevicePixelRatio(1.0)
    return image


@contextmanager
def signals_held() -> Iterator[None]:
    """Ctrl+C, SIGTERM and SIGHUP wait for the end of the block, then act as they would.

    Drawing runs Python inside Qt's calls (the paint methods of pyqtgraph's items), where
    the ``KeyboardInterrupt`` of a Ctrl+C was caught and printed as a traceback
    (pyqtgraph's ``warnOnException``) and the drawing went on. Inside the block a signal
    is only noted; when the block ends, outside Qt, it goes to the handler that was in
    place before (the CLI's raise ``KeyboardInterrupt``; the default one ends the
    process). Main thread only; a signal ignored stays ignored.
    """
    import signal
    import threading

    if threading.current_thread() is not threading.main_thread():
        yield
        return
    held: list[int] = []

    def hold(signum: int, _frame) -> None:
        held.append(signum)

    previous = {}
    for signum in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):
        handler = signal.getsignal(signum)
        if handler is not None and handler is not signal.SIG_IGN:
            previous[signum] = signal.signal(signum, hold)
    try:
        yield
    finally:
        for signum, handler in previous.items():
            signal.signal(signum, handler)
        if held:
            handler = previous[held[0]]
            if callable(handler):
                handler(held[0], None)
            else:
                signal.raise_signal(held[0])


def export_widget(widget, path: str | Path, size: tuple[int, int] | None = None) -> Path:
    """Render ``widget`` to ``path``: PNG or SVG by its suffix. Returns the path.

    ``size`` is the figure's size in pixels (``figure_layout``); None: the widget's size
    on screen (a PNG is then the widget's own rendering, ``QWidget.grab``).
    """

    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in FIGURE_SUFFIXES:
        raise ValueError(
            f"cannot export a figure as {suffix or 'a file without suffix'}; use .png or .svg"
        )
    if size is not None:
        size = (int(size[0]), int(size[1]))
        if not all(1 <= side <= MAX_PIXELS for side in size):
            raise ValueError(f"a figure's sides must be 1 to {MAX_PIXELS} pixels, not {size}")
    from systems.files import atomic_path

    # a signal while Qt draws stops the export once the drawing is done, before the
    # temporary file becomes ``path``
    with atomic_path(path) as temporary, signals_held():
        if suffix == ".svg":
            from explorer.svg import write_svg

            title = widget.window().windowTitle() or "Phase Explorer"
            if size is None:
                write_svg(widget, temporary, title=title)
            else:
                layout, _ = figure_layout((widget.width(), widget.height()), size)
                with laid_out(widget, layout):
                    write_svg(widget, temporary, title=title, size=size)
            check_svg(temporary)
        elif size is None:
            save_png(widget.grab(), temporary)
        else:
            save_png(render_image(widget, size), temporary)
    return path


def save_png(image, path: Path) -> None:
    """Write a ``QImage`` or ``QPixmap`` to ``path`` as PNG.

    Encoded in memory and written by Python: Qt's own file writing, on a full disk,
    printed ``libpng error: Write Error`` and only returned False; here the ``OSError``
    says why (``No space left on device``).
    """
    from PySide6.QtCore import QBuffer, QByteArray, QIODevice

    data = QByteArray()
    buffer = QBuffer(data)
    buffer.open(QIODevice.OpenModeFlag.WriteOnly)
    encoded = image.save(buffer, "PNG")
    buffer.close()
    if not encoded:
        raise OSError(
            f"the figure could not be encoded as PNG ({image.width()} x {image.height()})"
        )
    with open(path, "wb") as handle:
        handle.write(data.data())


def check_svg(path: Path) -> None:
    """``OSError`` unless ``path`` holds a whole SVG document (a full disk cuts it short
    without Qt saying so)."""
    data = path.read_bytes()
    if not data.rstrip().endswith(b"</svg>"):
        raise OSError(errno.ENOSPC, "the SVG came out incomplete (is the disk full?)", str(path))


def csv_header(scene) -> list[str]:
    """Columns as the ``run`` command writes them: t, q, q_dot, p_q, H, and for a scene
    with constraints their multipliers lambda_1 .. lambda_k."""
    from systems.constraints import multiplier_names

    names = ["t", *scene.coordinates, *scene.velocity_names, *scene.momentum_names, "H"]
    return names + multiplier_names(scene)


def csv_rows(t: np.ndarray, every: float | None = None, points: int | None = None) -> np.ndarray:
    """Which samples of times ``t`` (non-decreasing, shape (k,)) a thinned table keeps.

    With ``every``: the first sample at or after each of 0, DT, 2 DT, ... from the first
    time, and the last sample (``run --every`` integrates again and gives rows at exactly
    those times; a window only has the samples it holds). With ``points``: the first
    sample at or after each of ``points`` times evenly spaced from the first time to the
    last. Neither: all. Returns increasing indices, each sample at most once (where
    samples are sparser than the times asked for, as in the thinned past of a long run,
    fewer rows come out).
    """
    t = np.asarray(t, dtype=float)
    check_thinning(every, points)
    if not len(t) or (every is None and points is None):
        return np.arange(len(t))
    start, end = float(t[0]), float(t[-1])
    if every is not None:
        count = (end - start) / every
        if count > 10**7:
            raise ValueError(f"one row every {every:g} asks for {count:.3g} rows; at most 1e7")
        times = start + every * np.arange(math.floor(count) + 1)
    else:
        times = np.linspace(start, end, points)
    index = np.searchsorted(t, times, side="left")
    index = np.append(index[index < len(t)], len(t) - 1)
    return np.unique(index)


def trajectory_table(
    compiled, trajectory, every: float | None = None, points: int | None = None
) -> np.ndarray:
    """Rows (t, q, q_dot, p, H[, lambda]) of one trajectory's states, thinned by
    ``csv_rows``; shape (k, 2 + 3n + c) for c constraints. Gap rows
    (``explorer.trajectories``) are not states: left out."""
    from explorer.trajectories import backfill_energy, is_gap

    n = compiled.n
    real = ~is_gap(trajectory.y.data)
    energy = backfill_energy(trajectory, compiled)[real]
    t = trajectory.t.data[real]
    y = trajectory.y.data[real]
    rows = csv_rows(t, every, points)
    t, y, energy = t[rows], y[rows], energy[rows]
    with np.errstate(all="ignore"):
        qdot = compiled.velocities(t, y)
    columns = [t, y[:, :n], qdot, y[:, n:], energy]
    constraints = compiled.constraints()
    if constraints is not None:
        with np.errstate(all="ignore"):
            columns.append(constraints.multipliers(t, y))
    return np.column_stack(columns)


def write_trajectories_csv(
    compiled,
    trajectories,
    path: str | Path,
    every: float | None = None,
    points: int | None = None,
) -> Path:
    """Write trajectories as CSV; with more than one, an ``orbit`` column comes first.

    ``every`` (one row every DT of simulated time) or ``points`` (rows evenly spaced in
    time) thin each trajectory (``csv_rows``); neither writes every sample kept.
    """
    check_thinning(every, points)
    path = Path(path)
    scene = compiled.mechanics.scene
    header = csv_header(scene)
    many = len(trajectories) > 1
    from systems.files import atomic_path, write_rows

    with atomic_path(path) as temporary, temporary.open("w", newline="", encoding="utf-8") as out:
        csv.writer(out).writerow((["orbit"] if many else []) + header)
        for number, trajectory in enumerate(trajectories, start=1):
            table = trajectory_table(compiled, trajectory, every, points)
            write_rows(out, table, f"{number}," if many else "")
    return path


def render_workprecision(
    result, path: str | Path, size=(1100, 560), image_size: tuple[int, int] | None = None
) -> Path:
    """Draw a work-precision result (``systems.workprecision.WorkPrecision``) to PNG or
    SVG, headless (offscreen Qt unless a platform was chosen), laid out at ``size``, drawn
    at ``image_size`` pixels (``figure_layout``; default ``size``)."""
    from explorer.app import application
    from explorer.headless import ensure_qt_platform

    ensure_qt_platform()
    from explorer.panels.workprecision_view import WorkPrecisionView

    app = application()
    view = WorkPrecisionView()
    try:
        if image_size is not None:
            size, _ = figure_layout(size, image_size)
        with signals_held():
            view.resize(*size)
            view.show_result(result)
            view.show()
            app.processEvents()
        return export_widget(view.export_target(), path, image_size)
    finally:  # on a failed write too: a view left to the interpreter's exit crashed it
        with signals_held():
            view.shutdown()
            view.close()
            view.deleteLater()
            app.processEvents()
