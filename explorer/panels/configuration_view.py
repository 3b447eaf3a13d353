"""Configuration view: the mechanism animated from the scene's drawing, and the path in (q1, q2).

The mechanism's plot has its aspect locked (a circle stays round) and keeps a box in view:
the drawing's reach at the start (or ``[view] ranges`` x and y), grown whenever a point or
trace leaves it. The box is set on both axes at once and again whenever the plot changes
shape (a dock resized, an export at another size), so the whole mechanism stays visible;
panning or zooming by hand stops that until the next system.

Bodies are discs: in a scene given by particles, the particles with a mass (``systems.sketch``),
their area in proportion to the mass; in a scene that gives T itself, the points a coordinate
or t moves. Every other point (a pulley's rim, a hoop, a massless pivot, a support) is a small
grey dot. A scene of particles whose drawing has no links of its own gets the rods of its
sketch: to the supports, and between particles whose distance the transformation keeps or
a constraint fixes.

The path plot wraps angle coordinates to (-pi, pi] like the phase view; its aspect is locked
(a circle stays round) when both coordinates are angles or neither is.
"""

from __future__ import annotations

import numpy as np
import pyqtgraph as pg
import sympy
from PySide6.QtWidgets import QVBoxLayout, QWidget

from explorer.labels import coordinate_label
from explorer.panels.curves import (
    ANGLE_RANGE,
    PacedLayoutWidget,
    RangeKeeper,
    TrailCurve,
    WrappedSeries,
    set_title,
    style_plot,
)
from explorer.panels.lazy_menu import add_plot
from explorer.trajectories import backfill_points
from systems.angles import angle_flags, wrap
from systems.sketch import Sketch, sketch

REPAINT_GAP_SECONDS = 0.015
"""Time left free after each paint: the mechanism is animated at every redraw (a paint
costs a few ms), bursts of changes are gathered."""
ROD_PEN = pg.mkPen("#333333", width=3)
TRACE_POINTS = 4000
BODY_PIXELS = 18.0
"""Diameter of the heaviest body's disc; a lighter one's area is in proportion to its mass."""
SMALLEST_BODY_PIXELS = 7.0
POINT_PIXELS = 12.0
"""Diameter of a moving point of a scene without particles (no mass to size it by)."""
FIXED_BRUSH = pg.mkBrush("#8c8c8c")


def moving_points(scene) -> np.ndarray:
    """Which drawing points move (depend on a coordinate or on t): in a scene without
    particles, drawn as bodies; the fixed ones (walls, ceilings) as small grey dots."""
    names = set(scene.coordinates) | {"t"}
    flags = []
    for name, _, _ in scene.drawing.points:
        symbols = set()
        for axis in ("x", "y"):
            symbols |= {
                s.name for s in scene.expression(f"drawing.points.{name}.{axis}").free_symbols
            }
        flags.append(bool(symbols & names))
    return np.array(flags, dtype=bool)


def body_points(scene, sketched: Sketch) -> np.ndarray:
    """Which drawing points are bodies (discs): the particles with a mass where the scene
    has particles, else the points that move."""
    if not scene.particles:
        return moving_points(scene)
    return np.array([name in sketched.bodies for name, _, _ in scene.drawing.points], dtype=bool)


def disc_sizes(masses: np.ndarray) -> np.ndarray:
    """Disc diameters in pixels: area in proportion to the mass, the heaviest
    ``BODY_PIXELS``, none below ``SMALLEST_BODY_PIXELS`` (a mass that is not a positive
    number: the heaviest's size)."""
    masses = np.asarray(masses, dtype=float)
    good = np.isfinite(masses) & (masses > 0)
    if not good.any():
        return np.full(len(masses), BODY_PIXELS)
    ratio = np.where(good, masses / masses[good].max(), 1.0)
    return np.maximum(BODY_PIXELS * np.sqrt(ratio), SMALLEST_BODY_PIXELS)


def path_aspect_locked(angles) -> bool:
    """The path plot keeps one scale on both axes when its coordinates are alike: both
    angles or neither (x and y, two lengths): a circle is drawn round."""
    return bool(angles[0]) == bool(angles[1])


class ConfigurationView(QWidget):
    """The main trajectory's mechanism (rods, bobs, traces) and, for n >= 2, its (q1, q2) path."""

    def __init__(self, parent: QWidget | None = None):
        super().__init__(parent)
        self.compiled = None
        self.layout_widget = PacedLayoutWidget(gap=REPAINT_GAP_SECONDS)
        self.layout_widget.setBackground("w")
        layout = QVBoxLayout(self)
        layout.setContentsMargins(2, 2, 2, 2)
        layout.addWidget(self.layout_widget)
        self.mechanism = add_plot(self.layout_widget, row=0, col=0)
        self.mechanism.setAspectLocked(True)
        style_plot(self.mechanism)
        self.mechanism.setLabel("bottom", "x")
        self.mechanism.setLabel("left", "y")
        self.path_plot: pg.PlotItem | None = None
        # the path plot is made once and kept (out of the layout while a scene has one
        # coordinate): a PlotItem removed from the layout and deleted crashed Qt's next
        # paint of the view, within a few dozen scene switches
        self._path_plot: pg.PlotItem | None = None
        self._path_keeper: RangeKeeper | None = None
        self._rods = pg.PlotDataItem(pen=ROD_PEN, connect="pairs")
        self._bobs = pg.ScatterPlotItem(
            size=BODY_PIXELS, pen=pg.mkPen("#222"), brush=pg.mkBrush("#1f77b4")
        )
        self._fixed = pg.ScatterPlotItem(size=6, pen=None, brush=FIXED_BRUSH)
        self._moving = np.zeros(0, dtype=bool)
        self._pivot = pg.ScatterPlotItem(
            [0], [0], size=9, symbol="s", pen=pg.mkPen("#555"), brush=FIXED_BRUSH
        )
        self.sketch = Sketch()
        self.links: tuple[tuple[str, str], ...] = ()
        """The rods drawn: the drawing's links, or the sketch's where it has none."""
        self._support_at = None  # (t, P) -> (supports, 2)
        self._body_masses = None  # P -> (bodies,)
        self._traces: list[pg.PlotDataItem] = []
        self._path: TrailCurve | None = None
        self._head: pg.ScatterPlotItem | None = None
        self._message = pg.TextItem("", color="#555", anchor=(0.5, 0.5))
        self._trace_from = 0
        self.fit = RangeKeeper(self.mechanism, margin=0.1)
        self.mechanism.getViewBox().sigResized.connect(self._on_mechanism_resized)
        self._path_series: WrappedSeries | None = None
        self._path_angles = np.zeros(2, dtype=bool)
        self._store = None
        self.side_by_side = False
        """The path plot stands right of the mechanism, not below it (presentation)."""

    def _path_cell(self) -> dict:
        return {"row": 0, "col": 1} if self.side_by_side else {"row": 1, "col": 0}

    def set_side_by_side(self, side_by_side: bool) -> None:
        """Put the path plot beside the mechanism (True) or below it (False)."""
        if side_by_side == self.side_by_side:
            return
        self.side_by_side = side_by_side
        if self.path_plot is not None:
            # moved within the layout, never deleted (see ``_path_plot``)
            self.layout_widget.removeItem(self.path_plot)
            self.layout_widget.addItem(self.path_plot, **self._path_cell())
        grid = self.layout_widget.ci.layout
        for column in (0, 1):  # side by side: half the width each
            grid.setColumnStretchFactor(column, 1 if side_by_side else 0)

    def set_system(self, compiled) -> None:
        """Show a newly compiled system (its drawing and coordinates)."""
        self.compiled = compiled
        scene = compiled.mechanics.scene
        self.mechanism.clear()
        self._traces.clear()
        drawing = scene.drawing
        set_title(self.mechanism, scene.title)  # the dock says "Configuration"
        self.sketch = sketch(scene)
        self._set_sketch(scene)
        if drawing is None or not drawing.points:
            self._message.setText("This scene has no [drawing] table.")
            self.mechanism.addItem(self._message)
        else:
            self.mechanism.addItem(self._rods)
            if self.sketch.supports or any("origin" in link for link in self.links):
                self.mechanism.addItem(self._pivot)
            self.mechanism.addItem(self._fixed)
            self.mechanism.addItem(self._bobs)
            self._moving = body_points(scene, self.sketch)
            for name in drawing.trace:
                item = pg.PlotDataItem(pen=pg.mkPen("#d62728", width=1), name=f"trace of {name}")
                item.setZValue(-5)
                self.mechanism.addItem(item)
                self._traces.append(item)
        if self.path_plot is not None:
            self.path_plot.clear()  # the last scene's path and head
            if compiled.n < 2:
                self.layout_widget.removeItem(self.path_plot)  # kept in _path_plot
                self.path_plot = None
        self._path = None
        self._head = None
        self._path_series = None
        self._store = None
        if compiled.n >= 2:
            self._add_path_plot(compiled)
        self._fit_range(compiled)

    def _set_sketch(self, scene) -> None:
        """The rods to draw and the functions of the supports' places and the bodies'
        masses (in t and the parameters)."""
        drawing = scene.drawing
        own = drawing.links if drawing is not None else ()
        automatic = bool(scene.particles) and not own
        self.links = self.sketch.links if automatic else tuple(own)
        symbols = scene.symbols
        parameters = [symbols[name] for name, _ in scene.parameters]
        supports = self.sketch.supports if automatic else ()
        self._support_names = [name for name, _, _ in supports]
        self._support_at = None
        if supports:
            places = sympy.lambdify(
                [symbols["t"], parameters], [[x, y] for _, x, y in supports], modules="numpy"
            )
            self._support_at = lambda t, P: np.array(places(t, list(P)), dtype=float)
        self._body_masses = None
        if self.sketch.masses:
            masses = sympy.lambdify([parameters], list(self.sketch.masses), modules="numpy")
            self._body_masses = lambda P: np.array(masses(list(P)), dtype=float)

    def _add_path_plot(self, compiled) -> None:
        scene = compiled.mechanics.scene
        q1, q2 = scene.coordinates[:2]
        if self._path_plot is None:
            self._path_plot = add_plot(self.layout_widget, **self._path_cell())
            style_plot(self._path_plot)
            self._path_keeper = RangeKeeper(self._path_plot)
            self._path_plot.getViewBox().sigResized.connect(self._on_path_resized)
        elif self.path_plot is None:
            self.layout_widget.addItem(self._path_plot, **self._path_cell())
        self.path_plot = self._path_plot
        set_title(self.path_plot, f"Path in ({coordinate_label(q1)}, {coordinate_label(q2)})")
        self.path_plot.setLabel("bottom", coordinate_label(q1))
        self.path_plot.setLabel("left", coordinate_label(q2))
        keeper = self._path_keeper
        keeper.reset()
        self._path_angles = angle_flags(compiled.mechanics)[:2]
        if self._path_angles.any():
            self._path_series = WrappedSeries(self._path_angles)
            keeper.reset(
                ANGLE_RANGE if self._path_angles[0] else None,
                ANGLE_RANGE if self._path_angles[1] else None,
                fixed=tuple(a for a, f in zip("xy", self._path_angles, strict=True) if f),
            )
        # x and y, or two angles, on one scale: the rolling disk's circle is round
        self.path_plot.setAspectLocked(path_aspect_locked(self._path_angles))
        self._path = TrailCurve(self.path_plot, pg.mkPen("#1f77b4", width=1.2), ranges=keeper)
        self._head = pg.ScatterPlotItem(size=9, brush=pg.mkBrush("#1f77b4"), pen="w")
        self.path_plot.addItem(self._head)

    def _fit_range(self, compiled) -> None:
        """The first box to keep in view: declared x and y ranges (kept), else a square
        around the origin that holds the drawing at the start (grown by the motion)."""
        scene = compiled.mechanics.scene
        if scene.drawing is None or not scene.drawing.points:
            self.fit.reset((-1.0, 1.0), (-1.0, 1.0), fixed=("x", "y"))
            return
        ranges = dict(scene.view.get("ranges", {}) or {})
        if "x" in ranges and "y" in ranges and "x" not in scene.coordinates:
            self.fit.reset(tuple(ranges["x"]), tuple(ranges["y"]), fixed=("x", "y"))
            return
        y0 = compiled.initial_state()
        with np.errstate(all="ignore"):
            points = compiled.drawing(0.0, y0[None, :])[0]
        finite = np.isfinite(points)
        reach = float(np.abs(points[finite]).max()) if finite.any() else 1.0
        reach = 1.15 * max(reach, 1e-3)
        self.fit.reset((-reach, reach), (-reach, reach))

    def _on_mechanism_resized(self) -> None:
        # pyqtgraph keeps the requested box visible on resize only if both axes were set
        # together; setting it again also restores it after a squeeze that hid part of it
        if not self.fit.manual:
            self.fit.apply()

    def _on_path_resized(self) -> None:
        # an aspect-locked path plot keeps its whole box in view, as the mechanism does
        keeper = self._path_keeper
        if self.path_plot is not None and keeper is not None and not keeper.manual:
            keeper.apply()

    def _keep_in_view(self, points: np.ndarray) -> None:
        """Grow the kept box when the mechanism leaves it; never shrink it.

        Parameters
        ----------
        points : ndarray, shape (..., 2)
        """
        points = points.reshape(-1, 2)
        self.fit.include(points[:, 0], points[:, 1])

    def refresh(self, store) -> None:
        """Draw the main trajectory's current configuration and traces."""
        trajectory = store.main
        if self.compiled is None or trajectory is None:
            return
        if trajectory.y.data.shape[1] != 2 * self.compiled.n:
            return  # a trajectory of another system: the store is about to be replaced
        if store is not self._store:  # a restart: the path starts again
            self._store = store
            if self._path is not None:
                self._path.reset()
            if self._path_series is not None:
                self._path_series.reset()
        scene = self.compiled.mechanics.scene
        drawing = scene.drawing
        total = len(trajectory.t)
        if drawing is not None and drawing.points:
            start = max(total - TRACE_POINTS, 0) if drawing.trace else total - 1
            window = backfill_points(trajectory, self.compiled, start)
            current = window[-1]
            names = list(self.compiled.point_names)
            where = {name: current[k] for k, name in enumerate(names)}
            where["origin"] = np.zeros(2)
            fixed_points = [np.zeros((0, 2))]
            if self._support_at is not None:
                with np.errstate(all="ignore"):
                    at = self._support_at(float(trajectory.t.data[-1]), self.compiled.parameters)
                where.update(zip(self._support_names, at, strict=True))
                fixed_points.append(at)
            if any("origin" in link for link in self.links):
                fixed_points.append(np.zeros((1, 2)))
            pivots = np.concatenate(fixed_points)
            self._pivot.setData(pivots[:, 0], pivots[:, 1])
            segments = np.array([[where[a], where[b]] for a, b in self.links]).reshape(-1, 2)
            if len(segments):
                self._rods.setData(segments[:, 0], segments[:, 1])
            else:
                self._rods.setData([], [])
            moving = self._moving
            sizes = POINT_PIXELS
            if self._body_masses is not None:
                with np.errstate(all="ignore"):
                    sizes = disc_sizes(self._body_masses(self.compiled.parameters))
            self._bobs.setData(current[moving, 0], current[moving, 1], size=sizes)
            self._fixed.setData(current[~moving, 0], current[~moving, 1])
            self._keep_in_view(window if drawing.trace else current[None])
            if len(pivots):
                self._keep_in_view(pivots)
            for item, name in zip(self._traces, drawing.trace, strict=True):
                if name == "origin":
                    continue
                k = names.index(name)
                item.setData(window[:, k, 0], window[:, k, 1])
        if self._path is not None:
            y = trajectory.y.data
            q1, q2 = y[:, 0], y[:, 1]
            if self._path_series is not None:
                q1, q2 = self._path_series.feed(q1, q2)
            self._path.update(q1, q2)
            head = [wrap(v) if a else v for v, a in zip(y[-1, :2], self._path_angles, strict=True)]
            self._head.setData([head[0]], [head[1]])

    def export_target(self) -> QWidget:
        return self.layout_widget
