"""Conserved-quantities view: relative energy error (log scale) and conserved momenta over time.

When H is not conserved (driven, dissipative or rheonomic scenes) the upper plot shows H(t)
itself instead of an error.
"""

from __future__ import annotations

import numpy as np
import pyqtgraph as pg
from PySide6.QtWidgets import QVBoxLayout, QWidget

from explorer.buffers import GrowingArray
from explorer.labels import momentum_label
from explorer.panels.curves import LEGEND_BRUSH, RangeKeeper, TrailCurve, style_plot
from explorer.trajectories import backfill_energy

FLOOR = 1e-17


class ConservedView(QWidget):
    """Energy error or H(t) per trajectory, and each conserved momentum of the main one."""

    def __init__(self, parent: QWidget | None = None):
        super().__init__(parent)
        self.compiled = None
        self.layout_widget = pg.GraphicsLayoutWidget()
        self.layout_widget.setBackground("w")
        layout = QVBoxLayout(self)
        layout.setContentsMargins(2, 2, 2, 2)
        layout.addWidget(self.layout_widget)
        self.energy_plot = self.layout_widget.addPlot(row=0, col=0)
        style_plot(self.energy_plot)
        self.energy_plot.setLabel("bottom", "t")
        self.energy_legend = self.energy_plot.addLegend(
            offset=(-10, 10), brush=LEGEND_BRUSH, colCount=2
        )
        self.momentum_plot: pg.PlotItem | None = None
        self.momentum_legend = None
        self._energy_curves: dict[int, TrailCurve] = {}
        self._momentum_curves: dict[int, TrailCurve] = {}
        self._reference: dict[int, float] = {}
        self._values: dict[int, GrowingArray] = {}
        self.energy_range = RangeKeeper(self.energy_plot, time_axis=True)
        self.momentum_range: RangeKeeper | None = None
        self._generation = -1
        self.conserved_momenta: list[int] = []

    @property
    def shows_error(self) -> bool:
        return bool(self.compiled and self.compiled.mechanics.classification.hamiltonian_conserved)

    def set_system(self, compiled) -> None:
        self.compiled = compiled
        scene = compiled.mechanics.scene
        self._reset_curves()
        self.energy_range.log_y = self.shows_error
        if self.shows_error:
            self.energy_plot.setLogMode(y=True)
            self.energy_plot.setTitle("Relative energy error |H − H₀| / |H₀|")
            self.energy_plot.setLabel("left", "|ΔH / H₀|")
        else:
            self.energy_plot.setLogMode(y=False)
            self.energy_plot.setTitle("H(t) (not conserved in this system)")
            self.energy_plot.setLabel("left", "H")
        conserved = [name for name in compiled.mechanics.conserved if name.startswith("p_")]
        self.conserved_momenta = [scene.coordinates.index(name[2:]) for name in conserved]
        if self.momentum_plot is not None:
            self.layout_widget.removeItem(self.momentum_plot)
            self.momentum_plot = None
        if self.conserved_momenta:
            self.momentum_plot = self.layout_widget.addPlot(row=0, col=1)
            self.momentum_plot.setXLink(self.energy_plot)
            style_plot(self.momentum_plot)
            self.momentum_plot.setLabel("bottom", "t")
            labels = ", ".join(momentum_label(scene.coordinates[i]) for i in self.conserved_momenta)
            self.momentum_plot.setTitle(f"Conserved momenta: {labels}")
            self.momentum_legend = self.momentum_plot.addLegend(
                offset=(-10, 10), brush=LEGEND_BRUSH
            )
            self.momentum_range = RangeKeeper(self.momentum_plot, time_axis=True)
            colours = ("#2ca02c", "#9467bd", "#8c564b", "#17becf")
            for k, i in enumerate(self.conserved_momenta):
                pen = pg.mkPen(colours[k % len(colours)], width=1.5)
                name = momentum_label(scene.coordinates[i])
                self._momentum_curves[i] = TrailCurve(
                    self.momentum_plot, pen, name=name, ranges=self.momentum_range, monotonic_x=True
                )

    def _reset_curves(self) -> None:
        for curve in self._energy_curves.values():
            curve.remove()
        self._energy_curves.clear()
        self._reference.clear()
        self._values.clear()
        self.energy_legend.clear()
        self.energy_range.reset()
        if self.momentum_range is not None:
            self.momentum_range.reset()
        for curve in self._momentum_curves.values():
            curve.reset()

    def refresh(self, store) -> None:
        if self.compiled is None:
            return
        if store.generation != self._generation:
            self._generation = store.generation
            self._reset_curves()
            self.set_system(self.compiled)
        for key in [k for k in self._energy_curves if k not in store.trajectories]:
            self._energy_curves.pop(key).remove()
            self._values.pop(key, None)
        for trajectory in store:
            key = trajectory.key
            energy = backfill_energy(trajectory, self.compiled)
            if key not in self._energy_curves:
                name = "main orbit" if key == 0 else f"orbit {key + 1}"
                pen = pg.mkPen(trajectory.colour, width=1.3)
                self._energy_curves[key] = TrailCurve(
                    self.energy_plot, pen, name=name, ranges=self.energy_range, monotonic_x=True
                )
                self._reference[key] = float(energy[0])
                self._values[key] = GrowingArray(())
            values = self._values[key]
            new = energy[len(values) :]  # only rows not seen before are computed
            if self.shows_error:
                h0 = self._reference[key]
                scale = abs(h0) if abs(h0) > 1e-300 else 1.0
                values.extend(np.maximum(np.abs(new - h0) / scale, FLOOR))
            else:
                values.extend(new)
            self._energy_curves[key].update(trajectory.t.data, values.data)
        main = store.main
        if main is not None:
            n = self.compiled.n
            for i, curve in self._momentum_curves.items():
                curve.update(main.t.data, main.y.data[:, n + i])

    def export_target(self) -> QWidget:
        return self.layout_widget
