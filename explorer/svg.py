"""SVG figures through ``QSvgGenerator`` that real renderers draw correctly.

Rendering a pyqtgraph widget straight into a ``QSvgGenerator`` gives curves in data
coordinates under a large scaling transform, with cosmetic pens expressed as
``vector-effect="non-scaling-stroke"`` and without clipping to the plot area (SVG Tiny
has no clip paths): renderers such as librsvg then draw lines hundreds of pixels wide and
data outside the axes. So the widget is rendered without its data items (axes, labels,
legends and titles are drawn in pixel coordinates and come out right), and the data items
are then drawn by this module in pixel coordinates, clipped to their view box: polylines
as paths, scatter points as small vector symbols, images as embedded pictures.

Decimated to the output resolution: a polyline keeps only the vertices needed to stay
within ``TOLERANCE`` output pixels of the original (``simplify``: Douglas–Peucker on a
dyadic grid, vectorised), coordinates are rounded to a tenth of an output pixel, and
scatter points of one style that fall on the same half pixel are drawn once. A long
trajectory (a million samples) so becomes a few thousand vertices, drawn the same.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pyqtgraph as pg
from PySide6.QtCore import QPoint, QPointF, QRect, QRectF, QSize, Qt
from PySide6.QtGui import QBrush, QPainter, QPainterPath, QPen, QTransform
from PySide6.QtWidgets import QWidget

DATA_TYPES = (pg.PlotCurveItem, pg.ScatterPlotItem, pg.ImageItem, pg.TextItem)
TOLERANCE = 0.25
"""How far (output pixels) a simplified polyline may stray from the original."""


def _view_boxes(widget) -> list[pg.ViewBox]:
    views = widget.findChildren(pg.GraphicsView)
    if isinstance(widget, pg.GraphicsView):
        views.append(widget)
    boxes = []
    for view in views:
        boxes += [item for item in view.scene().items() if isinstance(item, pg.ViewBox)]
    return boxes


def _data_items(box: pg.ViewBox) -> list:
    items = []
    for item in box.childGroup.childItems():
        stack = [item]
        while stack:
            current = stack.pop()
            if isinstance(current, DATA_TYPES):
                items.append(current)
            else:
                stack.extend(current.childItems())
    return items


def _to_widget(widget, item) -> QTransform:
    """Transform from ``item``'s coordinates to ``widget``'s pixels."""
    view = item.scene().views()[0]
    transform = item.sceneTransform() * view.viewportTransform()
    offset = view.viewport().mapTo(widget, view.viewport().rect().topLeft())
    return transform * QTransform.fromTranslate(offset.x(), offset.y())


def _box_rect(widget, box: pg.ViewBox) -> QRectF:
    view = box.scene().views()[0]
    polygon = view.mapFromScene(box.sceneBoundingRect())
    offset = view.viewport().mapTo(widget, view.viewport().rect().topLeft())
    return QRectF(polygon.boundingRect()).translated(offset.x(), offset.y())


def _map(transform: QTransform, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    t = transform
    return (
        t.m11() * x + t.m21() * y + t.dx(),
        t.m12() * x + t.m22() * y + t.dy(),
    )


def clip_segments(x: np.ndarray, y: np.ndarray, rect: QRectF):
    """Segments of the polyline (x, y) clipped to ``rect`` (Liang–Barsky), as (x0, y0, x1, y1)."""
    x0, y0, x1, y1 = x[:-1], y[:-1], x[1:], y[1:]
    good = np.isfinite(x0) & np.isfinite(y0) & np.isfinite(x1) & np.isfinite(y1)
    x0, y0, x1, y1 = x0[good], y0[good], x1[good], y1[good]
    dx, dy = x1 - x0, y1 - y0
    lo = np.zeros_like(x0)
    hi = np.ones_like(x0)
    keep = np.ones_like(x0, dtype=bool)
    with np.errstate(divide="ignore", invalid="ignore"):
        for p, q in (
            (-dx, x0 - rect.left()),
            (dx, rect.right() - x0),
            (-dy, y0 - rect.top()),
            (dy, rect.bottom() - y0),
        ):
            parallel = p == 0
            keep &= ~(parallel & (q < 0))
            r = q / p
            entering = (p < 0) & ~parallel
            leaving = (p > 0) & ~parallel
            lo = np.where(entering, np.maximum(lo, r), lo)
            hi = np.where(leaving, np.minimum(hi, r), hi)
    keep &= lo <= hi
    return (
        (x0 + lo * dx)[keep],
        (y0 + lo * dy)[keep],
        (x0 + hi * dx)[keep],
        (y0 + hi * dy)[keep],
    )


def _straight(x, y, starts, stops, width: int, limit: float) -> np.ndarray:
    """Whether every vertex strictly inside each window [start, stop] lies within
    sqrt(``limit``) of the window's chord; windows at most ``width`` long."""
    offsets = np.arange(1, width)
    index = np.minimum(starts[:, None] + offsets[None, :], stops[:, None])
    ax, ay = x[starts][:, None], y[starts][:, None]
    dx, dy = x[stops][:, None] - ax, y[stops][:, None] - ay
    length = dx * dx + dy * dy
    px, py = x[index] - ax, y[index] - ay
    with np.errstate(invalid="ignore", divide="ignore"):
        along = np.where(length > 0, (px * dx + py * dy) / length, 0.0)
    along = np.clip(along, 0.0, 1.0)
    ex, ey = px - along * dx, py - along * dy
    return (ex * ex + ey * ey).max(axis=1) <= limit


def simplify(x: np.ndarray, y: np.ndarray, tolerance: float) -> np.ndarray:
    """Which vertices of the polyline (x, y) to keep so that it strays by at most
    ``tolerance`` from the original.

    Douglas–Peucker on a dyadic grid: a window of vertices is replaced by its chord when
    every vertex in it lies within ``tolerance`` of the chord, otherwise it is halved;
    all windows of one size are tested at once. Non-finite vertices break the line:
    they are kept, and each finite stretch is simplified on its own.

    Parameters
    ----------
    x, y : ndarray, shape (k,)
    tolerance : float
        In the units of x and y; 0 keeps every vertex.

    Returns
    -------
    ndarray of bool, shape (k,)
    """
    x = np.asarray(x, dtype=float)
    y = np.asarray(y, dtype=float)
    k = len(x)
    keep = np.ones(k, dtype=bool)
    if k < 3 or not tolerance > 0:
        return keep
    finite = np.isfinite(x) & np.isfinite(y)
    # windows never span a break: the vertices next to one are window ends
    ends = np.flatnonzero(~finite)
    bounds = np.unique(np.concatenate([[0, k - 1], ends, ends - 1, ends + 1]))
    bounds = bounds[(bounds >= 0) & (bounds < k)]
    keep[:] = False
    keep[bounds] = True
    starts = bounds[:-1][finite[bounds[:-1]] & finite[bounds[1:]]]
    stops = bounds[1:][finite[bounds[:-1]] & finite[bounds[1:]]]
    starts, stops = starts[stops - starts > 1], stops[stops - starts > 1]
    limit = tolerance * tolerance
    while len(starts):
        # windows of like sizes together, so padding never more than doubles the work
        size_class = np.ceil(np.log2(stops - starts)).astype(int)
        bent = np.zeros(len(starts), dtype=bool)
        for cls in np.unique(size_class):
            chosen = np.flatnonzero(size_class == cls)
            bent[chosen] = ~_straight(x, y, starts[chosen], stops[chosen], 1 << cls, limit)
        bent_starts, bent_stops = starts[bent], stops[bent]
        middle = (bent_starts + bent_stops) // 2
        keep[middle] = True
        starts = np.concatenate([bent_starts, middle])
        stops = np.concatenate([middle, bent_stops])
        starts, stops = starts[stops - starts > 1], stops[stops - starts > 1]
    return keep


def _polyline_path(segments) -> QPainterPath:
    sx0, sy0, sx1, sy1 = segments
    path = QPainterPath()
    last = None
    for a, b, c, d in zip(sx0.tolist(), sy0.tolist(), sx1.tolist(), sy1.tolist(), strict=True):
        if last is None or abs(last[0] - a) > 1e-9 or abs(last[1] - b) > 1e-9:
            path.moveTo(a, b)
        path.lineTo(c, d)
        last = (c, d)
    return path


def _pixel_pen(pen: QPen) -> QPen:
    pen = QPen(pen)
    pen.setCosmetic(False)
    pen.setWidthF(max(pen.widthF(), 1.0))
    return pen


def _draw_curve(
    painter, widget, item: pg.PlotCurveItem, rect: QRectF, tolerance: float = 0.0
) -> int:
    """Draw a curve simplified to ``tolerance`` (widget pixels), rounded to a tenth of it;
    returns the segments drawn."""
    x, y = item.getData()
    if x is None or len(x) < 2:
        return 0
    x, y = _map(_to_widget(widget, item), np.asarray(x, float), np.asarray(y, float))
    connect = item.opts.get("connect", "all")
    if isinstance(connect, str) and connect == "pairs":
        x = np.insert(x, np.arange(2, len(x), 2), np.nan)
        y = np.insert(y, np.arange(2, len(y), 2), np.nan)
    elif tolerance > 0:
        keep = simplify(x, y, tolerance)
        x, y = x[keep], y[keep]
    if tolerance > 0:
        quantum = 0.4 * tolerance
        x, y = np.round(x / quantum) * quantum, np.round(y / quantum) * quantum
    segments = clip_segments(x, y, rect)
    if not len(segments[0]):
        return 0
    painter.setPen(_pixel_pen(pg.mkPen(item.opts["pen"])))
    painter.setBrush(QBrush())
    painter.drawPath(_polyline_path(segments))
    return len(segments[0])


def _draw_scatter(
    painter, widget, item: pg.ScatterPlotItem, rect: QRectF, tolerance: float = 0.0
) -> int:
    """Draw scatter points as vector symbols; points of one style closer than
    ``2 * tolerance`` (on one cell of that size) are drawn once. Returns the count."""
    data = item.data
    if not len(data):
        return 0
    x, y = _map(_to_widget(widget, item), data["x"].astype(float), data["y"].astype(float))
    count = 0
    shown = np.flatnonzero(np.isfinite(x) & np.isfinite(y))
    uniform = all(
        all(value is None for value in data[column]) for column in ("pen", "brush", "symbol")
    ) and bool(np.all(data["size"] == data["size"][0]))
    if tolerance > 0 and uniform and len(shown) > 1:
        cells = np.floor(np.column_stack([x[shown], y[shown]]) / (2 * tolerance))
        _, first = np.unique(cells, axis=0, return_index=True)
        shown = shown[np.sort(first)]
    for k in shown:
        point = QPointF(x[k], y[k])
        if not rect.contains(point):
            continue
        size = float(data["size"][k]) if data["size"][k] >= 0 else float(item.opts["size"])
        pen = data["pen"][k] if data["pen"][k] is not None else pg.mkPen(item.opts["pen"])
        brush = data["brush"][k] if data["brush"][k] is not None else pg.mkBrush(item.opts["brush"])
        painter.setPen(_pixel_pen(pg.mkPen(pen)))
        painter.setBrush(pg.mkBrush(brush))
        symbol = data["symbol"][k] if data["symbol"][k] is not None else item.opts["symbol"]
        half = size / 2
        if symbol in ("s",):
            painter.drawRect(QRectF(x[k] - half, y[k] - half, size, size))
        elif symbol == "x":
            painter.drawLine(QPointF(x[k] - half, y[k] - half), QPointF(x[k] + half, y[k] + half))
            painter.drawLine(QPointF(x[k] - half, y[k] + half), QPointF(x[k] + half, y[k] - half))
        else:
            painter.drawEllipse(point, half, half)
        count += 1
    return count


def _draw_image(painter, widget, item: pg.ImageItem, rect: QRectF) -> int:
    if item.image is None:
        return 0
    item.render()
    qimage = item.qimage
    if qimage is None:
        return 0
    bounds = _to_widget(widget, item).mapRect(item.boundingRect())
    target = bounds.intersected(rect)
    if target.isEmpty():
        return 0
    sx = qimage.width() / bounds.width()
    sy = qimage.height() / bounds.height()
    source = QRectF(
        (target.left() - bounds.left()) * sx,
        (target.top() - bounds.top()) * sy,
        target.width() * sx,
        target.height() * sy,
    )
    flipped = _to_widget(widget, item).m22() < 0
    image = _upside_down(qimage) if flipped else qimage
    if flipped:
        source.moveTop(qimage.height() - source.bottom())
    painter.drawImage(target, image, source)
    return 1


def _upside_down(image):
    """``image`` flipped top to bottom: ``QImage.flipped`` from Qt 6.9, where
    ``mirrored`` is deprecated (and warns), ``mirrored`` before."""
    flip = getattr(image, "flipped", None)
    return flip(Qt.Orientation.Vertical) if flip is not None else image.mirrored(False, True)


def write_svg(
    widget,
    path: str | Path,
    title: str = "Phase Explorer",
    size: tuple[int, int] | None = None,
    tolerance: float = TOLERANCE,
) -> dict[str, int]:
    """Render ``widget`` (pyqtgraph plots inside) to ``path``; returns counts of drawn items.

    Parameters
    ----------
    widget : QWidget
        Laid out at the size it is to be drawn at (``explorer.export`` does that).
    path : str or Path
    title : str
    size : (int, int), optional
        The drawing's size in pixels; the view box is the widget's size, scaled to it by
        the viewer. Default: the widget's size.
    tolerance : float
        How far (drawing pixels) simplified curves may stray from the data; 0 keeps every
        vertex.

    Returns
    -------
    dict
        ``curves`` (curves drawn), ``segments`` (their segments), ``points``, ``images``.
    """
    from PySide6.QtSvg import QSvgGenerator

    logical = widget.size()
    width, height = size if size is not None else (logical.width(), logical.height())
    scale = min(width / max(logical.width(), 1), height / max(logical.height(), 1))
    generator = QSvgGenerator()
    generator.setFileName(str(path))
    generator.setSize(QSize(width, height))
    generator.setViewBox(QRect(0, 0, logical.width(), logical.height()))  # scaled by viewers
    generator.setTitle(title)
    generator.setResolution(widget.logicalDpiX())
    boxes = [box for box in _view_boxes(widget) if box.isVisible()]
    items = {box: [i for i in _data_items(box) if i.isVisible()] for box in boxes}
    counts = {"curves": 0, "segments": 0, "points": 0, "images": 0}
    for group in items.values():
        for item in group:
            item.setVisible(False)
    painter = QPainter(generator)
    try:
        # QWidget's render, not QGraphicsView's (which would fill the device's size)
        QWidget.render(widget, painter, QPoint(0, 0))
        painter.setRenderHint(QPainter.RenderHint.Antialiasing)
        fine = tolerance / scale
        for box, group in items.items():
            rect = _box_rect(widget, box)
            for item in sorted(group, key=lambda i: i.zValue()):
                if isinstance(item, pg.ImageItem):
                    counts["images"] += _draw_image(painter, widget, item, rect)
                elif isinstance(item, pg.PlotCurveItem):
                    drawn = _draw_curve(painter, widget, item, rect, fine)
                    counts["curves"] += bool(drawn)
                    counts["segments"] += drawn
                elif isinstance(item, pg.ScatterPlotItem):
                    counts["points"] += _draw_scatter(painter, widget, item, rect, fine)
    finally:
        painter.end()
        for group in items.values():
            for item in group:
                item.setVisible(True)
    _size_in_pixels(Path(path), width, height)
    return counts


def _size_in_pixels(path: Path, width: int, height: int) -> None:
    """Give the drawing its size in pixels, not the millimetres QSvgGenerator writes.

    Converted back at 96 dpi, the millimetres come out a hair above the whole pixel count
    (1008.0000001), and renderers round that up: a last row and column left transparent.
    """
    import re

    text = path.read_text(encoding="utf-8")
    text = re.sub(
        r'<svg width="[^"]*" height="[^"]*"',
        f'<svg width="{width}" height="{height}"',
        text,
        count=1,
    )
    path.write_text(text, encoding="utf-8")
