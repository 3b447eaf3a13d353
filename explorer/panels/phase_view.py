"""Phase view: trajectories in (q_i, p_i), level sets of H, and the Poincaré section mode."""

from __future__ import annotations

import numpy as np
import pyqtgraph as pg
from PySide6.QtCore import Qt, Signal
from PySide6.QtGui import QColor
from PySide6.QtWidgets import QCheckBox, QComboBox, QHBoxLayout, QLabel, QVBoxLayout, QWidget

from explorer import level_sets, poincare
from explorer.labels import coordinate_label, momentum_label
from explorer.panels.curves import LEGEND_BRUSH, TrailCurve, style_plot
from explorer.panels.ranges import axis_range, phase_ranges

LEVEL_PEN = pg.mkPen("#9aa3ad", width=1)
SEPARATRIX_PEN = pg.mkPen("#e6550d", width=2.5)
FORBIDDEN_RGBA = (120, 120, 120, 90)


def _pen(colour: str, width: float = 1.6, style=Qt.PenStyle.SolidLine):
    return pg.mkPen(colour, width=width, style=style)


def _preferred_index(scene) -> int:
    """The coordinate named first in ``[view] phase`` (default: the first coordinate)."""
    pair = scene.view.get("phase") or []
    for name in pair:
        q = name[2:] if name.startswith("p_") else name
        if q in scene.coordinates:
            return scene.coordinates.index(q)
    return 0


class PhaseView(QWidget):
    """Trajectories in the phase plane of one coordinate; clicks launch new ones.

    Signals
    -------
    launch_requested(object)
        A full canonical state ``y0`` (shape (2n,)) to start a trajectory from.
    launch_refused(str)
        A click that cannot start an orbit (forbidden region of the section).
    mode_changed(str)
        ``"phase"`` or ``"poincare"``.
    """

    launch_requested = Signal(object)
    launch_refused = Signal(str)
    mode_changed = Signal(str)

    def __init__(self, parent: QWidget | None = None):
        super().__init__(parent)
        self.compiled = None
        self.scene = None
        self.mode = "phase"
        self.index = 0
        self.section: poincare.Section | None = None
        self.section_energy = 0.0
        self.grid: level_sets.EnergyGrid | None = None
        self.saddles: list[level_sets.Saddle] = []
        self._curves: dict[int, TrailCurve] = {}
        self._heads: dict[int, pg.ScatterPlotItem] = {}
        self._energy_items: dict[int, pg.PlotDataItem] = {}
        self._section_points: dict[int, np.ndarray] = {}
        self._section_scatter: dict[int, pg.ScatterPlotItem] = {}
        self._static: list = []
        self._generation = -1

        self.plot_widget = pg.PlotWidget(background="w")
        self.plot = self.plot_widget.getPlotItem()
        style_plot(self.plot)
        self.legend = self.plot.addLegend(
            offset=(-10, 10), labelTextColor="#222", brush=LEGEND_BRUSH
        )
        self.plot.scene().sigMouseClicked.connect(self._on_scene_clicked)

        self.pair_combo = QComboBox()
        self.pair_combo.currentIndexChanged.connect(self._on_pair_changed)
        self.poincare_box = QCheckBox("Poincaré section")
        self.poincare_box.toggled.connect(self._on_poincare_toggled)
        self.hint = QLabel("Click to launch a trajectory.")
        self.hint.setStyleSheet("color: #555")
        header = QHBoxLayout()
        header.addWidget(QLabel("Pair:"))
        header.addWidget(self.pair_combo)
        header.addWidget(self.poincare_box)
        header.addStretch(1)
        header.addWidget(self.hint)
        layout = QVBoxLayout(self)
        layout.setContentsMargins(2, 2, 2, 2)
        layout.addLayout(header)
        layout.addWidget(self.plot_widget)

    # -- setup ---------------------------------------------------------------------------

    @property
    def level_sets_available(self) -> bool:
        """Autonomous one-degree systems get level sets of H."""
        if self.compiled is None:
            return False
        cls = self.compiled.mechanics.classification
        return self.compiled.n == 1 and not cls.time_dependent

    @property
    def poincare_available(self) -> bool:
        """Autonomous conservative two-degree systems get a Poincaré section."""
        if self.compiled is None:
            return False
        cls = self.compiled.mechanics.classification
        return self.compiled.n == 2 and not cls.time_dependent and cls.hamiltonian_conserved

    def set_system(self, compiled, y0: np.ndarray) -> None:
        """Show a newly compiled system whose main trajectory starts at ``y0``."""
        self.compiled = compiled
        self.scene = compiled.mechanics.scene
        self.y0 = np.asarray(y0, dtype=float)
        self.pair_combo.blockSignals(True)
        self.pair_combo.clear()
        for q in self.scene.coordinates:
            self.pair_combo.addItem(f"{coordinate_label(q)}, p_{coordinate_label(q)}")
        self.index = _preferred_index(self.scene)
        self.pair_combo.setCurrentIndex(self.index)
        self.pair_combo.blockSignals(False)
        self.pair_combo.setEnabled(compiled.n > 1)
        self.poincare_box.blockSignals(True)
        self.poincare_box.setEnabled(self.poincare_available)
        if not self.poincare_available:
            self.poincare_box.setChecked(False)
            self.mode = "phase"
        self.poincare_box.blockSignals(False)
        self.section = poincare.Section.from_scene(self.scene) if self.poincare_available else None
        self.section_energy = float(compiled.hamiltonian(0.0, self.y0[None, :])[0])
        self._rebuild()

    def _rebuild(self) -> None:
        """Redraw everything static (axes, level sets, forbidden region) and forget curves."""
        self._clear_dynamic()
        for item in self._static:
            self.plot.removeItem(item)
        self._static.clear()
        self.legend.clear()
        self.grid = None
        self.saddles = []
        if self.compiled is None:
            return
        if self.mode == "poincare":
            self._setup_section()
        else:
            self._setup_phase()

    def _setup_phase(self) -> None:
        scene, i = self.scene, self.index
        q = scene.coordinates[i]
        self.plot.setLabel("bottom", coordinate_label(q))
        self.plot.setLabel("left", momentum_label(q))
        self.plot.setTitle(f"Phase plane ({coordinate_label(q)}, {momentum_label(q)})")
        q_range, p_range = phase_ranges(scene, self.y0, i)
        self.plot.setXRange(*q_range, padding=0)
        self.plot.setYRange(*p_range, padding=0)
        if not self.level_sets_available:
            self.hint.setText("Click to launch a trajectory.")
            return
        self.grid = level_sets.energy_grid(self.compiled, q_range, p_range)
        self.saddles = level_sets.find_saddles(self.compiled, self.grid)
        first = True
        for level in level_sets.spread_levels(self.grid):
            x, y = level_sets.contour(self.grid, level)
            item = pg.PlotDataItem(x, y, pen=LEVEL_PEN, connect="finite")
            item.setZValue(-10)
            self.plot.addItem(item)
            self._static.append(item)
            if first:
                self.legend.addItem(item, "level sets of H")
                first = False
        energies = sorted({round(s.energy, 12) for s in self.saddles})
        for k, energy in enumerate(energies):
            x, y = level_sets.contour(self.grid, energy)
            item = pg.PlotDataItem(x, y, pen=SEPARATRIX_PEN, connect="finite")
            item.setZValue(-5)
            self.plot.addItem(item)
            self._static.append(item)
            if k == 0:
                self.legend.addItem(item, f"separatrix (H = {energy:.4g})")
        if self.saddles:
            marks = pg.ScatterPlotItem(
                [s.q for s in self.saddles],
                [s.p for s in self.saddles],
                symbol="x",
                size=12,
                pen=pg.mkPen("#e6550d", width=2),
            )
            self.plot.addItem(marks)
            self._static.append(marks)
        self.hint.setText("Click to launch a trajectory.")

    def _setup_section(self) -> None:
        scene, section = self.scene, self.section
        shown = scene.coordinates[section.shown]
        cut = scene.coordinates[section.coordinate]
        self.plot.setLabel("bottom", coordinate_label(shown))
        self.plot.setLabel("left", momentum_label(shown))
        self.plot.setTitle(
            f"Poincaré section {coordinate_label(cut)} = {section.value:g}, "
            f"{momentum_label(cut)} > 0, at H = {self.section_energy:.4g}"
        )
        q_range = axis_range(scene, shown, float(self.y0[section.shown]))
        p_range = axis_range(scene, f"p_{shown}", float(self.y0[self.compiled.n + section.shown]))
        self.plot.setXRange(*q_range, padding=0)
        self.plot.setYRange(*p_range, padding=0)
        size = 241
        qs = np.linspace(*q_range, size)
        ps = np.linspace(*p_range, size)
        Q, P = np.meshgrid(qs, ps, indexing="ij")
        mask = poincare.forbidden(
            self.compiled, section, self.section_energy, Q.ravel(), P.ravel()
        ).reshape(Q.shape)
        rgba = np.zeros((size, size, 4), dtype=np.ubyte)
        rgba[mask] = FORBIDDEN_RGBA
        image = pg.ImageItem(rgba, levels=(0, 255))
        image.setRect(q_range[0], p_range[0], q_range[1] - q_range[0], p_range[1] - p_range[0])
        image.setZValue(-20)
        self.plot.addItem(image)
        self._static.append(image)
        swatch = pg.BarGraphItem(x=[0], height=[0], width=0, brush=QColor(*FORBIDDEN_RGBA))
        self.legend.addItem(swatch, "energetically forbidden")
        self.hint.setText("Click in the allowed region to start an orbit at this energy.")

    def _clear_dynamic(self) -> None:
        for curve in self._curves.values():
            curve.remove()
        for item in (
            *self._heads.values(),
            *self._energy_items.values(),
            *self._section_scatter.values(),
        ):
            self.plot.removeItem(item)
        self._curves.clear()
        self._heads.clear()
        self._energy_items.clear()
        self._section_scatter.clear()
        self._section_points.clear()

    # -- drawing -------------------------------------------------------------------------

    def refresh(self, store) -> None:
        """Bring the plot up to date with ``store`` (called by the redraw timer)."""
        if self.compiled is None:
            return
        if store.generation != self._generation:
            self._generation = store.generation
            self._clear_dynamic()
        for key in [k for k in self._curves if k not in store.trajectories]:
            self._forget(key)
        for key in [k for k in self._section_scatter if k not in store.trajectories]:
            self._forget(key)
        for trajectory in store:
            if self.mode == "poincare":
                self._refresh_section(trajectory)
            else:
                self._refresh_phase(trajectory)

    def _forget(self, key: int) -> None:
        curve = self._curves.pop(key, None)
        if curve is not None:
            curve.remove()
        for table in (self._heads, self._energy_items, self._section_scatter):
            item = table.pop(key, None)
            if item is not None:
                self.plot.removeItem(item)
        self._section_points.pop(key, None)

    def _refresh_phase(self, trajectory) -> None:
        n, i, key = self.compiled.n, self.index, trajectory.key
        if key not in self._curves:
            label = "orbit" if key == 0 else f"orbit {key + 1}"
            self._curves[key] = TrailCurve(self.plot, _pen(trajectory.colour), name=label)
            head = pg.ScatterPlotItem(size=9, brush=pg.mkBrush(trajectory.colour), pen="w")
            self.plot.addItem(head)
            self._heads[key] = head
            if self.grid is not None:
                energy = float(self.compiled.hamiltonian(trajectory.t0, trajectory.y0[None])[0])
                x, y = level_sets.contour(self.grid, energy)
                style = Qt.PenStyle.DashLine
                item = pg.PlotDataItem(x, y, pen=_pen(trajectory.colour, 1.0, style))
                item.setZValue(-4)
                self.plot.addItem(item)
                self._energy_items[key] = item
        y = trajectory.y.data
        self._curves[key].update(y[:, i], y[:, n + i])
        self._heads[key].setData([y[-1, i]], [y[-1, n + i]])

    def _refresh_section(self, trajectory) -> None:
        key = trajectory.key
        if key not in self._section_scatter:
            scatter = pg.ScatterPlotItem(size=3, pen=None, brush=pg.mkBrush(trajectory.colour))
            self.plot.addItem(scatter)
            self._section_scatter[key] = scatter
        self._section_points[key] = trajectory.events.data
        points = self._section_points[key]
        n, s = self.compiled.n, self.section.shown
        self._section_scatter[key].setData(points[:, s], points[:, n + s])

    def section_points(self, key: int) -> np.ndarray:
        """The section crossings found so far for trajectory ``key``, shape (m, 2n)."""
        points = self._section_points.get(key)
        if points is None:
            return np.empty((0, 2 * (self.compiled.n if self.compiled else 1)))
        return points

    # -- interaction -----------------------------------------------------------------------

    def launch_at(self, x: float, y: float) -> None:
        """Start a trajectory at the plot point (x, y): (q_i, p_i) or a section point."""
        if self.compiled is None:
            return
        n = self.compiled.n
        if self.mode == "poincare":
            state = poincare.state_on_section(
                self.compiled, self.section, self.section_energy, x, y
            )
            if state is None:
                self.launch_refused.emit(
                    f"({x:.3g}, {y:.3g}) is energetically forbidden at H = "
                    f"{self.section_energy:.4g}"
                )
                return
        else:
            state = self.y0.copy()
            state[self.index] = x
            state[n + self.index] = y
        self.launch_requested.emit(state)

    def _on_scene_clicked(self, event) -> None:
        if event.button() != Qt.MouseButton.LeftButton or event.double():
            return
        view = self.plot.getViewBox()
        if not view.sceneBoundingRect().contains(event.scenePos()):
            return
        point = view.mapSceneToView(event.scenePos())
        self.launch_at(point.x(), point.y())

    def _on_pair_changed(self, index: int) -> None:
        if index >= 0 and index != self.index:
            self.index = index
            self._rebuild()

    def _on_poincare_toggled(self, checked: bool) -> None:
        self.set_mode("poincare" if checked else "phase")

    def set_mode(self, mode: str) -> None:
        """``"phase"`` or ``"poincare"`` (the latter only where ``poincare_available``)."""
        if mode == "poincare" and not self.poincare_available:
            mode = "phase"
        if mode == self.mode:
            return
        self.mode = mode
        self.poincare_box.blockSignals(True)
        self.poincare_box.setChecked(mode == "poincare")
        self.poincare_box.blockSignals(False)
        self.pair_combo.setEnabled(
            mode == "phase" and self.compiled is not None and self.compiled.n > 1
        )
        self._rebuild()
        self.mode_changed.emit(mode)

    def export_target(self) -> QWidget:
        """The widget that figure exports render."""
        return self.plot_widget
