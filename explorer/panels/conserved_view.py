"""Conserved-quantities view: relative energy error (log scale) and conserved momenta over time.

The conserved momenta are the cyclic coordinates' p_q, state components, and the Noether
charges of ``systems.symmetries`` (``L_z``, ``P_x``, a ``[symmetries]`` name), functions
of the state (q, p) evaluated on the main trajectory's new rows by numpy functions made
once per system (``symmetries.charge_functions``); both are drawn in the same plot.

When H is not conserved (driven, dissipative or rheonomic scenes) the upper plot shows H(t)
itself instead of an error. ``set_system`` rebuilds both plots from the new system alone:
titles, legends, the momentum plot (there is none without a conserved momentum) and the
curves. The time axes fit the data (a few percent of room ahead, so they are not redrawn
every frame); legends sit beside the plots, never on the curves.

The energy curves draw H's range over every step (``Trajectory.envelope``, summed up by
the worker before it thins the states it hands over): each bin of time a vertical from
its lowest to its highest value, at most a few bins per pixel column over the whole run,
so at full speed the plot shows what every step did, not a line through the few states
kept. Before the envelope begins (H was not wanted while the plot was hidden), and for a
trajectory without one, the rows' H is drawn. The conserved momenta of the main orbit
are drawn the same way, from ``Trajectory.momenta`` (the worker sums them up per step
alongside H when ``explorer.envelope.MOMENTA`` is among the diagnostics). Curves
against time are drawn as ``EnvelopeCurve``: at most four rows per pixel column, so a
long record costs no more to draw than a short one. Rows that hold no state (gap rows)
are breaks in the curve (``FiniteSeries``): no line is drawn across what was left out.
"""

from __future__ import annotations

import html

import numpy as np
import pyqtgraph as pg
from PySide6.QtWidgets import QVBoxLayout, QWidget

from explorer.buffers import GrowingArray
from explorer.envelope import conserved_quantities
from explorer.labels import momentum_label
from explorer.panels.curves import (
    EnvelopeCurve,
    OutsideLegend,
    PacedLayoutWidget,
    RangeKeeper,
    add_outside_legend,
    legend_orbit_names,
    set_title,
    style_plot,
)
from explorer.panels.lazy_menu import add_plot
from explorer.panels.log_axis import SparseLogAxis
from explorer.trajectories import backfill_energy, is_gap
from systems.symmetries import ROTATIONS, TRANSLATIONS, charge_functions

FLOOR = 1e-17
REPAINT_GAP_SECONDS = 0.1
"""Time left free after each paint: a record over time shows as well at ten frames a
second as at forty."""


class FiniteSeries:
    """(t, value) rows of a trajectory to draw, built from the rows not seen before
    (O(new rows) a frame): the finite rows, and one NaN row (a break) for each stretch of
    non-finite values (gap rows) between them, so no line joins the rows across a gap.

    ``feed(t, values)`` takes the whole columns, shape (k,), and returns views of the
    kept rows; columns that got shorter start it afresh.
    """

    def __init__(self):
        self._rows = GrowingArray((2,))
        self._seen = 0
        self._finite = False  # the last row kept is finite (a break may follow)

    def feed(self, t: np.ndarray, values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        if len(t) < self._seen:
            self._rows.clear()
            self._seen = 0
            self._finite = False
        new_t, new_v = t[self._seen :], values[self._seen :]
        timed = np.isfinite(new_t)
        new_t, new_v = new_t[timed], new_v[timed]
        if len(new_t):
            finite = np.isfinite(new_v)
            after = np.concatenate([[self._finite], finite[:-1]])
            keep = finite | after  # a finite row, or the first non-finite one after it
            rows = np.stack([new_t[keep], np.where(finite[keep], new_v[keep], np.nan)], axis=1)
            self._rows.extend(rows)
            self._finite = bool(finite[-1])
        self._seen = len(t)
        data = self._rows.data
        return data[:, 0], data[:, 1]


MOMENTUM_COLOURS = ("#2ca02c", "#9467bd", "#8c564b", "#17becf", "#bcbd22", "#e377c2")


def charge_label(name: str) -> str:
    """``L<sub>z</sub>``, ``P<sub>x</sub>``, or the ``[symmetries]`` name as written."""
    if name in ROTATIONS or name in TRANSLATIONS:
        return f"{name[0]}<sub>{name[2]}</sub>"
    return html.escape(name)


class ConservedView(QWidget):
    """Energy error or H(t) per trajectory, and each conserved momentum of the main one."""

    def __init__(self, parent: QWidget | None = None):
        super().__init__(parent)
        self.compiled = None
        self.layout_widget = PacedLayoutWidget(gap=REPAINT_GAP_SECONDS)
        self.layout_widget.setBackground("w")
        layout = QVBoxLayout(self)
        layout.setContentsMargins(2, 2, 2, 2)
        layout.addWidget(self.layout_widget)
        # the relative error spans a fraction of a decade over a short run: sparse labels
        self.energy_plot = add_plot(
            self.layout_widget, row=0, col=0, axisItems={"left": SparseLogAxis("left")}
        )
        style_plot(self.energy_plot)
        self.energy_plot.setLabel("bottom", "t")
        self.energy_legend = add_outside_legend(
            self.layout_widget.ci, row=0, col=1, columns=1, side="right"
        )
        self.momentum_plot: pg.PlotItem | None = None
        self.momentum_legend: OutsideLegend | None = None
        self._energy_curves: dict[int, EnvelopeCurve] = {}
        self._momentum_curves: dict[int, EnvelopeCurve] = {}
        self._reference: dict[int, float] = {}
        self._values: dict[int, GrowingArray] = {}
        self._energy_series: dict[int, FiniteSeries] = {}
        self._envelope_drawn: dict[int, tuple] = {}
        self._momenta_drawn: dict[int, tuple] = {}
        self._quantities: list = []  # explorer.envelope.conserved_quantities, in order
        self._momentum_series: dict[int, FiniteSeries] = {}
        self.conserved_charges: list[str] = []
        self._charge_functions: dict = {}
        self._charge_curves: dict[str, EnvelopeCurve] = {}
        self._charge_values: dict[str, GrowingArray] = {}
        self._charge_series: dict[str, FiniteSeries] = {}
        self._charge_key = None
        self.energy_range = RangeKeeper(self.energy_plot, time_axis=True)
        self.momentum_range: RangeKeeper | None = None
        self._kept_momentum: tuple[pg.PlotItem, OutsideLegend, RangeKeeper] | None = None
        self._store = None
        self._generation = -1
        self.conserved_momenta: list[int] = []

    @property
    def shows_error(self) -> bool:
        """H is conserved: the upper plot shows its relative error (log scale)."""
        return bool(self.compiled and self.compiled.mechanics.classification.hamiltonian_conserved)

    def set_system(self, compiled) -> None:
        """Show a newly compiled system: everything is rebuilt from ``compiled``."""
        self.compiled = compiled
        scene = compiled.mechanics.scene
        self._store = None
        self._generation = -1
        self._remove_momentum_plot()
        self._reset_curves()
        self.energy_range.log_y = self.shows_error
        if self.shows_error:
            self.energy_plot.setLogMode(y=True)
            set_title(self.energy_plot, "Relative energy error |H − H₀| / |H₀|")
            self.energy_plot.setLabel("left", "|ΔH / H₀|")
        else:
            self.energy_plot.setLogMode(y=False)
            set_title(self.energy_plot, "H(t) (not conserved in this system)")
            self.energy_plot.setLabel("left", "H")
        conserved = [name for name in compiled.mechanics.conserved if name.startswith("p_")]
        self.conserved_momenta = [
            scene.coordinates.index(name[2:]) for name in conserved if name[2:] in scene.coordinates
        ]
        self._charge_functions = charge_functions(compiled.mechanics)
        self.conserved_charges = list(self._charge_functions)
        self._quantities = conserved_quantities(compiled)
        if self.conserved_momenta or self.conserved_charges:
            self._add_momentum_plot(scene)

    def _remove_momentum_plot(self) -> None:
        for curve in [*self._momentum_curves.values(), *self._charge_curves.values()]:
            curve.remove()
        self._momentum_curves.clear()
        self._charge_curves.clear()
        # The plot and its legend stay in the layout, hidden (a hidden item takes no
        # room there), for the next scene that has conserved momenta. A PlotItem removed
        # and deleted crashed Qt's next paint; one removed from the layout and kept was
        # Python's to delete, and its destructor crashed (SIGSEGV in ~QGraphicsWidget)
        # when the garbage collector freed it after the window was gone.
        if self.momentum_plot is not None:
            self.momentum_plot.clear()
            self.momentum_plot.hide()
            self.momentum_plot = None
        if self.momentum_legend is not None:
            self.momentum_legend.clear()  # hides it: no entries
            self.momentum_legend = None
        self.momentum_range = None

    def _add_momentum_plot(self, scene) -> None:
        if self._kept_momentum is None:
            plot = add_plot(self.layout_widget, row=0, col=2)
            plot.setXLink(self.energy_plot)
            style_plot(plot)
            plot.setLabel("bottom", "t")
            legend = add_outside_legend(
                self.layout_widget.ci, row=0, col=3, columns=1, side="right"
            )
            self._kept_momentum = (plot, legend, RangeKeeper(plot, time_axis=True))
        else:
            self._kept_momentum[0].show()
        self.momentum_plot, self.momentum_legend, self.momentum_range = self._kept_momentum
        self.momentum_range.reset()
        labels = [momentum_label(scene.coordinates[i]) for i in self.conserved_momenta]
        labels += [charge_label(name) for name in self.conserved_charges]
        set_title(self.momentum_plot, f"Conserved momenta: {', '.join(labels)}")
        for k, i in enumerate(self.conserved_momenta):
            pen = pg.mkPen(MOMENTUM_COLOURS[k % len(MOMENTUM_COLOURS)], width=1.5)
            curve = EnvelopeCurve(self.momentum_plot, pen, ranges=self.momentum_range)
            self._momentum_curves[i] = curve
            self.momentum_legend.addItem(curve.tail, momentum_label(scene.coordinates[i]))
        for k, name in enumerate(self.conserved_charges, start=len(self.conserved_momenta)):
            pen = pg.mkPen(MOMENTUM_COLOURS[k % len(MOMENTUM_COLOURS)], width=1.5)
            curve = EnvelopeCurve(self.momentum_plot, pen, ranges=self.momentum_range)
            self._charge_curves[name] = curve
            self.momentum_legend.addItem(curve.tail, charge_label(name))
        self.momentum_legend.updateSize()

    def _reset_curves(self) -> None:
        """Forget every curve's data (a new store: new trajectories)."""
        for curve in self._energy_curves.values():
            curve.remove()
        self._energy_curves.clear()
        self._reference.clear()
        self._values.clear()
        self._energy_series.clear()
        self._envelope_drawn.clear()
        self._momenta_drawn.clear()
        self._momentum_series.clear()
        self.energy_legend.clear()
        self.energy_range.reset()
        if self.momentum_range is not None:
            self.momentum_range.reset()
        for curve in [*self._momentum_curves.values(), *self._charge_curves.values()]:
            curve.reset()
        self._forget_charges()

    def _forget_charges(self) -> None:
        self._charge_values.clear()
        self._charge_series.clear()
        self._charge_key = None

    def _update_energy_legend(self) -> None:
        self.energy_legend.set_entries(
            (self._energy_curves[key].tail, name)
            for key, name in legend_orbit_names(self._energy_curves, main="main orbit")
        )

    def refresh(self, store) -> None:
        """Bring the plots up to date with ``store`` (called by the redraw timer)."""
        if self.compiled is None:
            return
        if store is not self._store or store.generation != self._generation:
            self._store = store
            self._generation = store.generation
            self._reset_curves()
        changed = False
        for key in [k for k in self._energy_curves if k not in store.trajectories]:
            self._energy_curves.pop(key).remove()
            self._values.pop(key, None)
            self._reference.pop(key, None)
            self._energy_series.pop(key, None)
            self._envelope_drawn.pop(key, None)
            changed = True
        n = self.compiled.n
        for trajectory in store:
            key = trajectory.key
            if trajectory.y.data.shape[1] != 2 * n:
                continue  # a trajectory of another system: the store is about to be replaced
            energy = backfill_energy(trajectory, self.compiled)
            if key not in self._energy_curves:
                pen = pg.mkPen(trajectory.colour, width=1.3)
                self._energy_curves[key] = EnvelopeCurve(
                    self.energy_plot, pen, ranges=self.energy_range
                )
                self._reference[key] = float(energy[0])
                self._values[key] = GrowingArray(())
                self._energy_series[key] = FiniteSeries()
                changed = True
            if len(trajectory.envelope):
                self._draw_envelope(trajectory, energy)
                continue
            values = self._values[key]
            new = energy[len(values) :]  # only rows not seen before are computed
            values.extend(self._shown(key, new))
            t, shown = self._energy_series[key].feed(trajectory.t.data, values.data)
            self._energy_curves[key].update(t, shown)
        if changed:
            self._update_energy_legend()
        main = store.main
        if main is not None and main.y.data.shape[1] == 2 * n and self._momenta_binned(main):
            self._draw_momenta(main)
        elif main is not None and main.y.data.shape[1] == 2 * n:
            for i, curve in self._momentum_curves.items():
                series = self._momentum_series.setdefault(i, FiniteSeries())
                curve.update(*series.feed(main.t.data, main.y.data[:, n + i]))
            if self._charge_curves:
                self._update_charges(main)

    def _shown(self, key: int, energy: np.ndarray) -> np.ndarray:
        """What the upper plot draws of H values: the relative error, or H."""
        if not self.shows_error:
            return energy
        h0 = self._reference[key]
        return np.maximum(np.abs(energy - h0) / self._scale(key), FLOOR)

    def _scale(self, key: int) -> float:
        h0 = self._reference[key]
        return abs(h0) if abs(h0) > 1e-300 else 1.0

    def _draw_envelope(self, trajectory, energy: np.ndarray) -> None:
        """Draw the trajectory's envelope of H (``explorer.envelope``), after the rows'
        H before it began (with a break between)."""
        key = trajectory.key
        self._draw_bins(
            self._energy_curves[key],
            self._envelope_drawn,
            key,
            trajectory,
            trajectory.envelope,
            trajectory.envelope.polyline(self.shows_error, self._scale(key), FLOOR),
            lambda rows: self._shown(key, energy[:rows]),
        )

    def _momenta_binned(self, main) -> bool:
        """The main trajectory has the conserved momenta's envelope, of these momenta."""
        envelope = main.momenta
        return (
            envelope is not None
            and len(envelope) > 0
            and envelope.quantities == len(self._quantities)
            and len(self._quantities) == len(self._momentum_curves) + len(self._charge_curves)
        )

    def _draw_momenta(self, main) -> None:
        """Draw the conserved momenta's envelope (their range over every step, as H's),
        after the rows' values before it began."""
        curves = [*self._momentum_curves.values(), *self._charge_curves.values()]
        for j, (curve, (_, function)) in enumerate(zip(curves, self._quantities, strict=True)):

            def before(rows: int, function=function):
                with np.errstate(all="ignore"):
                    return np.asarray(function(main.t.data[:rows], main.y.data[:rows]), dtype=float)

            polyline = main.momenta.polyline(quantity=j)
            self._draw_bins(curve, self._momenta_drawn, j, main, main.momenta, polyline, before)

    @staticmethod
    def _draw_bins(curve, drawn: dict, key, trajectory, envelope, polyline, rows_before) -> None:
        """Draw ``envelope``'s ``polyline`` on ``curve`` after the rows before its first
        bin (``rows_before(rows)``: their values; gap rows are breaks), with a break
        between; ``drawn[key]`` remembers what was drawn, so a new bin adds to the curve
        and bins merged in pairs (or another trajectory) redraw it."""
        start = float(envelope.data[0, 1])
        before = int(np.searchsorted(trajectory.t.data, start, side="left"))
        state = (envelope.revision, before, trajectory.key, id(envelope))
        last = drawn.get(key)
        if last is None or last[:4] != state:
            curve.reset()  # from rows to bins, or the bins were merged in pairs
        revised = last is not None and last[4] != envelope.version
        drawn[key] = (*state, envelope.version)
        x, y = polyline
        if before:
            rows_t = trajectory.t.data[:before]
            rows_v = np.where(is_gap(trajectory.y.data[:before]), np.nan, rows_before(before))
            x = np.concatenate([rows_t, [start], x])
            y = np.concatenate([rows_v, [np.nan], y])
        curve.update(x, y, revised=revised)

    def _update_charges(self, main) -> None:
        """Evaluate each Noether charge on the main trajectory's rows not seen before."""
        t, y = main.t.data, main.y.data
        if main.key != self._charge_key or any(
            len(v) > len(t) for v in self._charge_values.values()
        ):
            self._forget_charges()  # another main trajectory, or one that started afresh
            self._charge_key = main.key
        for name, curve in self._charge_curves.items():
            values = self._charge_values.setdefault(name, GrowingArray(()))
            done = len(values)
            if done < len(t):
                with np.errstate(all="ignore"):
                    values.extend(
                        self._charge_functions[name](t[done:], y[done:], self.compiled.parameters)
                    )
            series = self._charge_series.setdefault(name, FiniteSeries())
            curve.update(*series.feed(t, values.data))

    def export_target(self) -> QWidget:
        """The widget that figure exports render (both plots with their legends)."""
        return self.layout_widget
