"""Phase view: trajectories in (q_i, p_i), level sets of H, and the Poincaré section mode.

Every ``set_system`` starts from nothing: labels, pair list, section, level sets,
equilibria, legend, ranges and curves come from the new system only.

Ranges: a ``[view] ranges`` entry is kept as given. Otherwise an angle coordinate (see
``systems.angles``) shows (-pi, pi], its curves wrapped and broken at the edges, and the
other axes start from a window that fits the main orbit's level set, the separatrix and
the equilibria (one-degree systems) or the allowed region of the section, then grow with
the orbits by a margin (``RangeKeeper``), never shrinking. Panning or zooming with the
mouse stops the growing until the next system or pair.

A right-click on or near an orbit puts "Delete this orbit" at the top of pyqtgraph's
context menu (added once pyqtgraph has opened it, so its own entries stay as they are);
the panel emits ``orbit_delete_requested(key)`` and the owner removes it.
"""

from __future__ import annotations

import functools
import math

import numpy as np
import pyqtgraph as pg
from PySide6.QtCore import QSize, Qt, Signal
from PySide6.QtGui import QAction, QColor, QPainter
from PySide6.QtWidgets import (
    QCheckBox,
    QComboBox,
    QCompleter,
    QGraphicsItem,
    QHBoxLayout,
    QLabel,
    QVBoxLayout,
    QWidget,
)

from explorer import level_sets, poincare
from explorer.labels import coordinate_label, momentum_label
from explorer.panels.chaos_map_layer import ChaosMapLayer
from explorer.panels.curves import (
    ANGLE_RANGE,
    PacedLayoutWidget,
    RangeKeeper,
    TrailCurve,
    WrappedSeries,
    add_outside_legend,
    legend_orbit_names,
    nearest_distance,
    set_title,
    style_plot,
)
from explorer.panels.lazy_menu import add_plot
from explorer.panels.ranges import axis_range
from explorer.panels.section_fill_layer import SectionFillLayer
from systems.angles import angle_flags, wrap

LEVEL_PEN = pg.mkPen("#9aa3ad", width=1)
SEPARATRIX_PEN = pg.mkPen("#e6550d", width=2.5)
FORBIDDEN_RGBA = (120, 120, 120, 90)
SEARCHABLE_PAIRS = 8
"""With more coordinates than this the pair list is a searchable field."""
PICK_PIXELS = 8.0
"""How close (in pixels) a right-click must be to an orbit to offer deleting it."""
REPAINT_GAP_SECONDS = 0.04
"""Time left free after each paint: at full speed a paint costs about ten ms, and twenty
paints a second show the orbits growing as well as forty."""
FIT_GRID = 121
FIT_MARGIN = 0.12
PAIR_TIP = (
    "Which coordinate's phase plane (q, p_q) to show. Clicking in the plane starts an "
    "orbit there, with the other coordinates as at the start."
)
POINCARE_TIP = (
    "Instead of the phase plane, show where orbits cross the section {cut} = {value:g} "
    "upwards ({p_cut} > 0), plotted in ({shown}, {p_shown}): a closed curve for a regular "
    "orbit, a scattered cloud for a chaotic one. All orbits share the energy of the start; "
    "a click starts a new one there. Runs at full speed."
)


def _pen(colour: str, width: float = 1.6, style=Qt.PenStyle.SolidLine):
    return pg.mkPen(colour, width=width, style=style)


@functools.cache
def _brush(colour: str):
    """``pg.mkBrush(colour)``, made once per colour (it parses the colour: most of a ms)."""
    return pg.mkBrush(colour)


def _preferred_index(scene) -> int:
    """The coordinate named first in ``[view] phase`` (default: the first coordinate)."""
    pair = scene.view.get("phase") or []
    for name in pair:
        q = name[2:] if name.startswith("p_") else name
        if q in scene.coordinates:
            return scene.coordinates.index(q)
    return 0


def _declared(scene, name: str) -> bool:
    return name in dict(scene.view.get("ranges", {}) or {})


def _pair_text(q: str) -> str:
    """``θ₁, p_θ₁ (theta1)``: the pretty pair, and the scene's name to search by."""
    pretty = coordinate_label(q)
    text = f"{pretty}, {momentum_label(q, html=False)}"
    return text if pretty == q else f"{text}  ({q})"


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
    orbit_delete_requested(int)
        The user asked to delete the launched orbit with this key (never 0, the main one).
    """

    launch_requested = Signal(object)
    launch_refused = Signal(str)
    mode_changed = Signal(str)
    orbit_delete_requested = Signal(int)

    def __init__(self, parent: QWidget | None = None):
        super().__init__(parent)
        self.compiled = None
        self.scene = None
        self.mode = "phase"
        self.index = 0
        self.y0 = np.zeros(2)
        self.angles = np.zeros(0, dtype=bool)
        self.section: poincare.Section | None = None
        self.strobe_period: float | None = None  # a periodic drive's: the stroboscopic section
        self.section_energy = 0.0
        self.grid: level_sets.EnergyGrid | None = None
        self.saddles: list[level_sets.Saddle] = []
        self.centres: list[tuple[float, float]] = []
        self._curves: dict[int, TrailCurve] = {}
        self._series: dict[int, WrappedSeries] = {}
        self._shown: dict[int, tuple[np.ndarray, np.ndarray]] = {}
        self._heads: dict[int, tuple[float, float]] = {}  # each orbit's last point
        self._energy_items: dict[int, pg.PlotDataItem] = {}
        self._section_points: dict[int, np.ndarray] = {}
        self._section_scatter: dict[int, pg.ScatterPlotItem] = {}
        self._colours: dict[int, str] = {}
        self._orbit_energies: dict[int, float] = {}
        self._static: list = []
        self._legend_static: list[tuple[object, str]] = []
        # the layers' keys (the chaos map's colours, the section fill's orbits) by layer
        self._legend_layers: dict[str, list[tuple[object, str]]] = {}
        self._static_stale = False
        self._store = None
        self._generation = -1

        self.plot_widget = PacedLayoutWidget(gap=REPAINT_GAP_SECONDS)
        self.plot_widget.setBackground("w")
        self.plot = add_plot(self.plot_widget, row=0, col=0)
        self.view_box = self.plot.getViewBox()
        self.last_menu = None  # the context menu shown last (for tests)
        self._menu_actions: list[QAction] = []
        self._delete_key: int | None = None
        self._delete_action = QAction(self)
        self._delete_action.setToolTip("Stop integrating this orbit and remove it from every plot")
        self._delete_action.triggered.connect(self._on_delete_triggered)
        style_plot(self.plot)
        self.legend = add_outside_legend(self.plot_widget.ci, row=1, col=0, columns=4)
        self.ranges = RangeKeeper(self.plot, margin=0.15, on_grow=self._on_ranges_grown)
        # every orbit's head in one item (a scatter item costs most of a ms to draw)
        self._head_item = pg.ScatterPlotItem(size=9, pen="w")
        self._head_item.setZValue(5)
        self.plot.addItem(self._head_item)
        self.plot.scene().sigMouseClicked.connect(self._on_scene_clicked)

        self.pair_combo = QComboBox()
        self._pair_edit = None
        self.pair_combo.setInsertPolicy(QComboBox.InsertPolicy.NoInsert)
        self.pair_combo.setMaxVisibleItems(20)
        self.pair_combo.setSizeAdjustPolicy(QComboBox.SizeAdjustPolicy.AdjustToContents)
        self.pair_combo.setToolTip(PAIR_TIP)
        self.pair_combo.currentIndexChanged.connect(self._on_pair_changed)
        self.poincare_box = QCheckBox("Poincaré section")
        self.poincare_box.setToolTip("Poincaré sections need a system to be loaded.")
        self.poincare_box.toggled.connect(self._on_poincare_toggled)
        self.hint = _ElidedLabel("Click to launch a trajectory.")
        self.hint.setStyleSheet("color: #555")
        self.hint.setToolTip(
            "Left click: start an orbit there. Right click on an orbit: delete it. "
            "Drag or scroll to pan and zoom."
        )
        header = QHBoxLayout()
        header.addWidget(QLabel("Pair:"))
        header.addWidget(self.pair_combo)
        header.addWidget(self.poincare_box)
        self.map_layer = ChaosMapLayer(self)  # a MEGNO map under the section
        for widget in self.map_layer.widgets():
            header.addWidget(widget)
        self.fill_layer = SectionFillLayer(self)  # many orbits' crossings at the energy
        for widget in self.fill_layer.widgets():
            header.addWidget(widget)
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
        """Autonomous conservative two-degree systems get a Poincaré section, periodically
        driven ones a stroboscopic section (the state once per period of the drive)."""
        if self.compiled is None:
            return False
        if self.strobe_period is not None:
            return True
        cls = self.compiled.mechanics.classification
        return self.compiled.n == 2 and not cls.time_dependent and cls.hamiltonian_conserved

    def _poincare_refusal(self) -> str:
        """Why this system has no Poincaré section (a tooltip)."""
        n = self.compiled.n
        cls = self.compiled.mechanics.classification
        if n != 2:
            return (
                f"A Poincaré section needs two degrees of freedom; this system has {n}. "
                "(With one, the phase plane already shows whole orbits.)"
            )
        if cls.time_dependent:
            return (
                "A Poincaré section needs an autonomous system, or a periodic drive (then "
                "it is stroboscopic); this one depends on t otherwise."
            )
        return "A Poincaré section needs a conserved H (no dissipation or driving force)."

    def set_system(self, compiled, y0: np.ndarray) -> None:
        """Show a newly compiled system whose main trajectory starts at ``y0``.

        Everything shown is rebuilt from ``compiled`` alone (a clean start); the mode
        stays Poincaré only if the new system has a section.
        """
        self._clear_dynamic()
        self.compiled = compiled
        self.scene = compiled.mechanics.scene
        self.y0 = np.asarray(y0, dtype=float).copy()
        self.angles = angle_flags(compiled.mechanics)
        n = compiled.n
        self.index = _preferred_index(self.scene)
        self._fill_pairs()
        self.strobe_period = None
        if compiled.mechanics.classification.time_dependent:
            from systems.chaos.bifurcation import drive_period

            self.strobe_period = drive_period(compiled)
        available = self.poincare_available
        if not available:
            self.mode = "phase"
        self.section = None
        if available and self.strobe_period is None:
            angles = tuple(q for q, a in zip(self.scene.coordinates, self.angles, strict=True) if a)
            self.section = poincare.Section.from_scene(
                self.scene, angles, tuple(compiled.mechanics.cyclic)
            )
        with np.errstate(all="ignore"):
            energy = compiled.hamiltonian(0.0, self.y0[None, :])[0]
        self.section_energy = float(energy)
        self.poincare_box.blockSignals(True)
        self.poincare_box.setEnabled(available)
        self.poincare_box.setChecked(self.mode == "poincare")
        self.poincare_box.blockSignals(False)
        self._update_tips()
        self.pair_combo.setEnabled(self.mode == "phase" and n > 1)
        self._rebuild()

    def _fill_pairs(self) -> None:
        combo, scene = self.pair_combo, self.scene
        combo.blockSignals(True)
        combo.clear()
        searchable = len(scene.coordinates) > SEARCHABLE_PAIRS
        combo.setEditable(searchable)
        for q in scene.coordinates:
            combo.addItem(_pair_text(q))
        if searchable:
            completer = QCompleter(combo.model(), combo)
            completer.setFilterMode(Qt.MatchFlag.MatchContains)
            completer.setCaseSensitivity(Qt.CaseSensitivity.CaseInsensitive)
            completer.setCompletionMode(QCompleter.CompletionMode.PopupCompletion)
            completer.setMaxVisibleItems(15)
            combo.setCompleter(completer)
            edit = combo.lineEdit()
            edit.setPlaceholderText("type a coordinate")
            if edit is not self._pair_edit:  # the same field stays while it is editable
                edit.editingFinished.connect(self._on_pair_text_finished)
                self._pair_edit = edit
        combo.setCurrentIndex(self.index)
        combo.blockSignals(False)

    def _update_tips(self) -> None:
        n = self.compiled.n
        tip = PAIR_TIP
        if n > SEARCHABLE_PAIRS:
            tip += f" Type part of a name to search the {n} coordinates."
        elif n == 1:
            tip += " This system has one coordinate."
        self.pair_combo.setToolTip(tip)
        if self.section is not None:
            names = self.scene.coordinates
            cut, shown = names[self.section.coordinate], names[self.section.shown]
            text = POINCARE_TIP.format(
                cut=coordinate_label(cut),
                value=self.section.value,
                p_cut=momentum_label(cut, html=False),
                shown=coordinate_label(shown),
                p_shown=momentum_label(shown, html=False),
            )
            if self.angles[self.section.coordinate]:
                text += f" {coordinate_label(cut)} is an angle: every turn crosses the section."
            self.poincare_box.setToolTip(text)
        elif self.strobe_period is not None:
            self.poincare_box.setToolTip(
                "Stroboscopic section: the drive is periodic, so the section is the state "
                f"once per period T = {self.strobe_period:.6g} (t = T, 2T, ...), in the "
                "pair's plane."
            )
        else:
            self.poincare_box.setToolTip(self._poincare_refusal())

    def _rebuild(self) -> None:
        """Redraw everything static (axes, level sets, forbidden region) and forget curves."""
        self._clear_dynamic()
        self._remove_static()
        self.grid = None
        self.saddles = []
        self.centres = []
        if self.compiled is None:
            self._update_legend()
            self.map_layer.clear()
            self.fill_layer.clear()
            return
        if self.mode == "poincare":
            self._setup_section()
        else:
            self._setup_phase()
        self._update_legend()
        self.map_layer.clear()  # drawn for another system, mode or energy
        self.fill_layer.clear()

    def _axis(self, name: str, value: float, angle: bool) -> tuple[tuple[float, float], bool]:
        """(range, fixed) of one axis: declared, an angle's, or a guess that may grow."""
        if _declared(self.scene, name):
            lo, hi = axis_range(self.scene, name, value)
            if not (angle and hi - lo > 2 * math.pi + 1.0):  # unwrapped ranges do not apply
                return (lo, hi), True
        if angle:
            return ANGLE_RANGE, True
        return axis_range(self.scene, name, value), False

    def _setup_phase(self) -> None:
        scene, i, n = self.scene, self.index, self.compiled.n
        q = scene.coordinates[i]
        self.plot.setLabel("bottom", coordinate_label(q))
        self.plot.setLabel("left", momentum_label(q))
        set_title(self.plot, f"Phase plane ({coordinate_label(q)}, {momentum_label(q)})")
        angle = bool(self.angles[i])
        q_range, q_fixed = self._axis(q, float(self.y0[i]), angle)
        p_range, p_fixed = self._axis(f"p_{q}", float(self.y0[n + i]), False)
        if self.level_sets_available and not (q_fixed and p_fixed):
            q_range, p_range = self._fit_level_sets(q_range, p_range, q_fixed, p_fixed)
        fixed = tuple(axis for axis, f in (("x", q_fixed), ("y", p_fixed)) if f)
        self.ranges.reset(q_range, p_range, fixed)
        self._draw_static()
        self.hint.setText("Click to launch a trajectory.")

    def _fit_level_sets(self, q_range, p_range, q_fixed, p_fixed):
        """Ranges around the main orbit's level set, the separatrix and the equilibria."""
        compiled, y0 = self.compiled, self.y0
        with np.errstate(all="ignore"):
            energy = float(compiled.hamiltonian(0.0, y0[None, :])[0])

        def features(qr, pr):
            grid = level_sets.energy_grid(compiled, qr, pr, size=FIT_GRID)
            saddles, centres = level_sets.find_stationary(compiled, grid)
            masks = [level_sets.level_mask(grid, energy)] if math.isfinite(energy) else []
            masks += [level_sets.level_mask(grid, s.energy) for s in saddles]
            points = np.zeros(grid.values.shape, dtype=bool)
            for q, p in [(s.q, s.p) for s in saddles] + centres + [(y0[0], y0[1])]:
                a = int(np.clip(np.searchsorted(grid.qs, q), 0, len(grid.qs) - 1))
                b = int(np.clip(np.searchsorted(grid.ps, p), 0, len(grid.ps) - 1))
                points[a, b] = True
            masks.append(points)
            return grid.qs, grid.ps, masks

        fitted = level_sets.fit_window(features, q_range, p_range, q_fixed=q_fixed, p_fixed=p_fixed)
        if fitted is None:
            return q_range, p_range
        (q_lo, q_hi), (p_lo, p_hi) = fitted
        if not q_fixed:
            q_range = _with_margin(q_lo, q_hi)
        if not p_fixed:
            p_range = _with_margin(p_lo, p_hi)
        return q_range, p_range

    def _setup_section(self) -> None:
        if self.section is None:
            self._setup_strobe()
            return
        scene, section, n = self.scene, self.section, self.compiled.n
        shown = scene.coordinates[section.shown]
        cut = scene.coordinates[section.coordinate]
        self.plot.setLabel("bottom", coordinate_label(shown))
        self.plot.setLabel("left", momentum_label(shown))
        set_title(
            self.plot,
            f"Poincaré section {coordinate_label(cut)} = {section.value:g}, "
            f"{momentum_label(cut)} > 0, at H = {self.section_energy:.4g}",
        )
        angle = bool(self.angles[section.shown])
        q_range, q_fixed = self._axis(shown, float(self.y0[section.shown]), angle)
        p_range, p_fixed = self._axis(f"p_{shown}", float(self.y0[n + section.shown]), False)
        if not (q_fixed and p_fixed):

            def features(qr, pr):
                qs, ps = np.linspace(*qr, FIT_GRID), np.linspace(*pr, FIT_GRID)
                return qs, ps, [~self._forbidden_mask(qs, ps)]

            fitted = level_sets.fit_window(
                features, q_range, p_range, q_fixed=q_fixed, p_fixed=p_fixed
            )
            if fitted is not None:
                (q_lo, q_hi), (p_lo, p_hi) = fitted
                q_range = q_range if q_fixed else _with_margin(q_lo, q_hi)
                p_range = p_range if p_fixed else _with_margin(p_lo, p_hi)
        fixed = tuple(axis for axis, f in (("x", q_fixed), ("y", p_fixed)) if f)
        self.ranges.reset(q_range, p_range, fixed)
        self._draw_static()
        self.hint.setText("Click in the allowed region to start an orbit at this energy.")

    def _setup_strobe(self) -> None:
        """The stroboscopic section of a periodically driven system, in the pair's plane."""
        scene, i, n = self.scene, self.index, self.compiled.n
        q = scene.coordinates[i]
        self.plot.setLabel("bottom", coordinate_label(q))
        self.plot.setLabel("left", momentum_label(q))
        set_title(
            self.plot,
            f"Stroboscopic section: t = k·{self.strobe_period:.4g}, the drive's period",
        )
        q_range, q_fixed = self._axis(q, float(self.y0[i]), bool(self.angles[i]))
        p_range, p_fixed = self._axis(f"p_{q}", float(self.y0[n + i]), False)
        fixed = tuple(axis for axis, f in (("x", q_fixed), ("y", p_fixed)) if f)
        self.ranges.reset(q_range, p_range, fixed)
        self._draw_static()
        self.hint.setText("Click to start an orbit there at t = 0: one point per period.")

    def _forbidden_mask(self, qs: np.ndarray, ps: np.ndarray) -> np.ndarray:
        """``mask[a, b]``: (qs[a], ps[b]) is energetically forbidden; shape (len(qs), len(ps))."""
        Q, P = np.meshgrid(qs, ps, indexing="ij")
        return poincare.forbidden(
            self.compiled, self.section, self.section_energy, Q.ravel(), P.ravel()
        ).reshape(Q.shape)

    # -- static items (redrawn when the ranges grow) ------------------------------------------

    def _remove_static(self) -> None:
        for item in self._static:
            self.plot.removeItem(item)
        self._static.clear()
        self._legend_static.clear()

    def _add_static(self, item, legend: str | None = None) -> None:
        self.plot.addItem(item)
        self._static.append(item)
        if legend is not None:
            self._legend_static.append((item, legend))

    def _draw_static(self) -> None:
        """Level sets and separatrix, or the forbidden region, over the current ranges."""
        self._remove_static()
        self._static_stale = False
        if self.ranges.x is None or self.ranges.y is None:
            return
        q_range, p_range = tuple(self.ranges.x), tuple(self.ranges.y)
        if self.mode == "poincare" and self.section is None:
            return  # stroboscopic: every point of the plane is a start
        if self.mode == "poincare":
            size = 241
            qs, ps = np.linspace(*q_range, size), np.linspace(*p_range, size)
            rgba = np.zeros((size, size, 4), dtype=np.ubyte)
            rgba[self._forbidden_mask(qs, ps)] = FORBIDDEN_RGBA
            image = pg.ImageItem(rgba, levels=(0, 255))
            image.setRect(q_range[0], p_range[0], q_range[1] - q_range[0], p_range[1] - p_range[0])
            image.setZValue(-20)
            self._add_static(image)
            swatch = pg.BarGraphItem(x=[0], height=[0], width=0, brush=QColor(*FORBIDDEN_RGBA))
            self._legend_static.append((swatch, "energetically forbidden"))
            return
        if not self.level_sets_available:
            return
        self.grid = level_sets.energy_grid(self.compiled, q_range, p_range)
        self.saddles, self.centres = level_sets.find_stationary(self.compiled, self.grid)
        first = True
        for level in level_sets.spread_levels(self.grid):
            x, y = level_sets.contour(self.grid, level)
            item = pg.PlotDataItem(x, y, pen=LEVEL_PEN, connect="finite")
            item.setZValue(-10)
            self._add_static(item, "level sets of H" if first else None)
            first = False
        # + 0.0: a level a round-off below 0 (-2.8e-44) rounds to -0.0, shown "H = -0"
        energies = sorted({round(s.energy, 12) + 0.0 for s in self.saddles})
        for k, energy in enumerate(energies):
            x, y = level_sets.contour(self.grid, energy)
            item = pg.PlotDataItem(x, y, pen=SEPARATRIX_PEN, connect="finite")
            item.setZValue(-5)
            # a wide antialiased pen costs ms to stroke: kept as pixels until the view moves
            item.curve.setCacheMode(QGraphicsItem.CacheMode.DeviceCoordinateCache)
            self._add_static(item, f"separatrix (H = {energy:.4g})" if k == 0 else None)
        if self.saddles:
            marks = pg.ScatterPlotItem(
                [s.q for s in self.saddles],
                [s.p for s in self.saddles],
                symbol="x",
                size=12,
                pen=pg.mkPen("#e6550d", width=2),
            )
            marks.setCacheMode(QGraphicsItem.CacheMode.DeviceCoordinateCache)
            self._add_static(marks)
        for key, item in self._energy_items.items():  # the orbits' own level sets
            item.setData(*self._energy_contour(self._orbit_energy(key)))

    def _on_ranges_grown(self) -> None:
        self._static_stale = True

    # -- dynamic items ---------------------------------------------------------------------

    def _clear_dynamic(self) -> None:
        for key in list({*self._curves, *self._section_scatter, *self._heads}):
            self._forget(key, update_legend=False)
        self._show_heads()
        self._series.clear()
        self._shown.clear()
        self._colours.clear()
        self._orbit_energies.clear()
        self._update_legend()

    def _forget(self, key: int, update_legend: bool = True) -> None:
        curve = self._curves.pop(key, None)
        if curve is not None:
            curve.remove()
        if self._heads.pop(key, None) is not None:
            self._show_heads()
        for table in (self._energy_items, self._section_scatter):
            item = table.pop(key, None)
            if item is not None:
                self.plot.removeItem(item)
        for table in (
            self._section_points,
            self._series,
            self._shown,
            self._colours,
            self._orbit_energies,
        ):
            table.pop(key, None)
        if update_legend:
            self._update_legend()

    def _update_legend(self) -> None:
        """Orbits first (the main one, then the first few launched), then the statics."""
        entries = []
        for key, name in legend_orbit_names({*self._curves, *self._section_scatter}):
            item = self._curves[key].tail if key in self._curves else self._section_scatter[key]
            entries.append((item, name))
        layers = [entry for entries in self._legend_layers.values() for entry in entries]
        self.legend.set_entries(entries + self._legend_static + layers)
        # placed now: an export right after (a session's next line) renders before the
        # posted layout request, and a new entry's label sat at the legend's corner
        self.legend.layout.activate()

    def set_layer_legend(self, entries: list[tuple[object, str]], key: str = "chaos-map") -> None:
        """The legend entries of layer ``key`` drawn under the points, (item, name) each:
        the chaos map's colour key, the section fill's orbits; shown in the window and in
        its exports; [] removes them."""
        self._legend_layers[key] = list(entries)
        self._update_legend()

    def refresh(self, store) -> None:
        """Bring the plot up to date with ``store`` (called by the redraw timer)."""
        if self.compiled is None:
            return
        if store is not self._store or store.generation != self._generation:
            self._store = store
            self._generation = store.generation
            self._clear_dynamic()
        gone = [k for k in {*self._curves, *self._section_scatter} if k not in store.trajectories]
        for key in gone:
            self._forget(key)
        added = False
        width = 2 * self.compiled.n
        for trajectory in store:
            if trajectory.y.data.shape[1] != width:
                continue  # a trajectory of another system: the store is about to be replaced
            if self.mode == "poincare":
                added |= self._refresh_section(trajectory)
            else:
                added |= self._refresh_phase(trajectory)
        if self.mode == "phase":
            self._show_heads()
        if self._static_stale:
            self._draw_static()
            added = True
        if added:
            self._update_legend()

    def _show_heads(self) -> None:
        keys = list(self._heads)
        self._head_item.setData(
            [self._heads[k][0] for k in keys],
            [self._heads[k][1] for k in keys],
            brush=[_brush(self._colours[k]) for k in keys],
        )

    def _orbit_energy(self, key: int) -> float:
        return self._orbit_energies.get(key, math.nan)

    def _energy_contour(self, energy: float) -> tuple[np.ndarray, np.ndarray]:
        if self.grid is None or not math.isfinite(energy):
            return np.array([]), np.array([])
        return level_sets.contour(self.grid, energy)

    def _refresh_phase(self, trajectory) -> bool:
        n, i, key = self.compiled.n, self.index, trajectory.key
        added = key not in self._curves
        if added:
            self._colours[key] = trajectory.colour
            self._curves[key] = TrailCurve(self.plot, _pen(trajectory.colour), ranges=self.ranges)
            if self.angles[i]:
                self._series[key] = WrappedSeries((True, False))
            if self.level_sets_available:
                with np.errstate(all="ignore"):
                    energy = self.compiled.hamiltonian(trajectory.t0, trajectory.y0[None])[0]
                self._orbit_energies[key] = float(energy)
                x, y = self._energy_contour(float(energy))
                style = Qt.PenStyle.DashLine
                item = pg.PlotDataItem(x, y, pen=_pen(trajectory.colour, 1.0, style))
                item.setZValue(-4)
                self.plot.addItem(item)
                self._energy_items[key] = item
        data = trajectory.y.data
        q, p = data[:, i], data[:, n + i]
        if key in self._series:
            q, p = self._series[key].feed(q, p)
        self._shown[key] = (q, p)
        self._curves[key].update(q, p)
        last_q = data[-1, i]
        self._heads[key] = (wrap(last_q) if self.angles[i] else last_q, data[-1, n + i])
        return added

    def _refresh_section(self, trajectory) -> bool:
        key = trajectory.key
        added = key not in self._section_scatter
        if added:
            self._colours[key] = trajectory.colour
            scatter = pg.ScatterPlotItem(size=3, pen=None, brush=pg.mkBrush(trajectory.colour))
            self.plot.addItem(scatter)
            self._section_scatter[key] = scatter
        points = trajectory.events.data
        self._section_points[key] = points
        n = self.compiled.n
        s = self.index if self.section is None else self.section.shown
        q = wrap(points[:, s]) if self.angles[s] and len(points) else points[:, s]
        p = points[:, n + s]
        old = self._shown.get(key)
        if old is None or len(old[0]) != len(q):
            if len(q):
                start = 0 if old is None else min(len(old[0]), len(q))
                self.ranges.include(q[start:], p[start:])
            self._shown[key] = (q, p)
            self._section_scatter[key].setData(q, p)
        return added

    def section_points(self, key: int) -> np.ndarray:
        """The section crossings found so far for trajectory ``key``, shape (m, 2n)."""
        points = self._section_points.get(key)
        if points is None:
            return np.empty((0, 2 * (self.compiled.n if self.compiled else 1)))
        return points

    def shown_data(self, key: int) -> tuple[np.ndarray, np.ndarray]:
        """What is drawn for orbit ``key``: (x, y), each shape (k,), NaN at breaks.

        In the phase plane the curve (angles wrapped, with the break points), in the
        Poincaré mode the section points.
        """
        empty = np.empty(0)
        return self._shown.get(key, (empty, empty))

    # -- interaction -----------------------------------------------------------------------

    def launch_at(self, x: float, y: float) -> None:
        """Start a trajectory at the plot point (x, y): (q_i, p_i) or a section point."""
        if self.compiled is None:
            return
        n = self.compiled.n
        if self.mode == "poincare" and self.section is not None:
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

    def orbit_at(self, x: float, y: float, pixels: float = PICK_PIXELS) -> int | None:
        """The orbit drawn nearest the plot point (x, y), if within ``pixels``; else None."""
        width, height = self.view_box.viewPixelSize()
        if not (width > 0 and height > 0):
            return None
        best, found = pixels, None
        for key, (xs, ys) in self._shown.items():
            distance = nearest_distance(xs, ys, x, y, (width, height))
            if distance <= best:
                best, found = distance, key
        return found

    def request_delete(self, key: int) -> bool:
        """Ask to delete orbit ``key`` (emits ``orbit_delete_requested``); False for the
        main orbit, which stays."""
        if key == 0 or key not in self._shown:
            return False
        self.orbit_delete_requested.emit(int(key))
        return True

    def _on_delete_triggered(self) -> None:
        if self._delete_key is not None:
            self.request_delete(self._delete_key)

    def _extend_context_menu(self, event) -> None:
        """After pyqtgraph opened the view box's menu for a right-click near an orbit, put
        "Delete this orbit" at its top (taken out again when the menu closes)."""
        menu = self.view_box.menu
        self.last_menu = menu
        if menu is None or not menu.isVisible() or self._menu_actions:
            return
        point = self.view_box.mapSceneToView(event.scenePos())
        key = self.orbit_at(point.x(), point.y())
        if key is None:
            return
        self._delete_key = key
        action = self._delete_action
        if key == 0:
            action.setText("The main orbit cannot be deleted (Reset restarts it)")
            action.setEnabled(False)
        else:
            action.setText(f"Delete this orbit (orbit {key})")
            action.setEnabled(True)
        separator = QAction(menu)
        separator.setSeparator(True)
        self._menu_actions = [action, separator]
        before = menu.actions()[0] if menu.actions() else None
        menu.insertActions(before, self._menu_actions)
        menu.aboutToHide.connect(self._on_menu_hidden)

    def _on_menu_hidden(self) -> None:
        menu = self.view_box.menu
        menu.aboutToHide.disconnect(self._on_menu_hidden)
        for action in self._menu_actions:
            menu.removeAction(action)
        self._menu_actions = []

    def _on_scene_clicked(self, event) -> None:
        if event.button() == Qt.MouseButton.RightButton:
            self._extend_context_menu(event)
            return
        if event.button() != Qt.MouseButton.LeftButton or event.double():
            return
        view = self.plot.getViewBox()
        if not view.sceneBoundingRect().contains(event.scenePos()):
            return
        point = view.mapSceneToView(event.scenePos())
        self.launch_at(point.x(), point.y())

    def set_pair(self, index: int) -> None:
        """Show coordinate ``index``'s phase plane (as choosing it in the pair list)."""
        if self.compiled is not None and 0 <= index < self.compiled.n:
            self.pair_combo.setCurrentIndex(index)

    def _on_pair_changed(self, index: int) -> None:
        if index >= 0 and index != self.index:
            self.index = index
            self._rebuild()

    def _on_pair_text_finished(self) -> None:
        """A typed text that names no pair goes back to the pair shown."""
        combo = self.pair_combo
        if combo.findText(combo.currentText()) < 0:
            combo.setEditText(combo.itemText(combo.currentIndex()))

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
        """The widget that figure exports render (the plot with its legend)."""
        return self.plot_widget


class _ElidedLabel(QLabel):
    """The header's hint: as much of its text as the header leaves room for, cut with an
    ellipsis. A plain label's text is its minimum width, so a long hint (a layer's report)
    widened the phase view and put the window past a 1366-pixel screen."""

    def minimumSizeHint(self) -> QSize:  # noqa: N802 - Qt override
        return QSize(0, super().minimumSizeHint().height())

    def paintEvent(self, _event) -> None:  # noqa: N802 - Qt override
        rect = self.contentsRect()
        text = self.fontMetrics().elidedText(self.text(), Qt.TextElideMode.ElideRight, rect.width())
        painter = QPainter(self)
        self.style().drawItemText(
            painter, rect, int(self.alignment()), self.palette(), self.isEnabled(), text,
            self.foregroundRole(),
        )  # fmt: skip


def _with_margin(lo: float, hi: float) -> tuple[float, float]:
    span = hi - lo if hi > lo else max(abs(hi), 1.0) * 0.2
    return lo - FIT_MARGIN * span, hi + FIT_MARGIN * span
