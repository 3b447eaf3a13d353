"""Routhian reduction: V_eff(q; p_c) with the conserved momenta on sliders, and the
reduced phase portrait."""

from __future__ import annotations

import html

import numpy as np
import pyqtgraph as pg
import scipy.optimize
from PySide6.QtCore import Qt
from PySide6.QtWidgets import (
    QGridLayout,
    QLabel,
    QPushButton,
    QSlider,
    QSplitter,
    QVBoxLayout,
    QWidget,
)

from explorer.inline_math import marked
from explorer.textbook.base import TextbookTabView
from explorer.textbook.plots import (
    BLUE,
    GREEN,
    GREY,
    ORANGE,
    RED,
    beside_notes,
    clear_plot,
    make_plot,
    note_label,
    pen,
)
from systems.display import pretty_name
from systems.textbook import jobs

SLIDER_STEPS = 1000


class ReductionView(TextbookTabView):
    """V_eff of the remaining coordinate and the reduced portrait (q_rest, p_rest)."""

    title = "Reduction"

    def __init__(self, runner, parent: QWidget | None = None):
        super().__init__(runner, parent)
        self.setup: jobs.ReductionSetup | None = None
        self.items: dict = {}
        self.curves: jobs.ReductionCurves | None = None
        self.sliders: list[QSlider] = []
        self.slider_labels: list[QLabel] = []
        self.slider_ranges: list[tuple[float, float]] = []
        self.summary = note_label("")
        self.slider_box = QGridLayout()
        self.reset_button = QPushButton("Back to the current orbit")
        self.reset_button.clicked.connect(self._on_reset_clicked)
        self.potential_plot = make_plot("Effective potential", "q", "V<sub>eff</sub>")
        self.portrait_plot = make_plot("Reduced phase portrait", "q", "p")
        self.splitter = QSplitter()
        self.splitter.addWidget(self.potential_plot)
        self.splitter.addWidget(self.portrait_plot)
        layout = QVBoxLayout(self)
        layout.setContentsMargins(4, 4, 4, 4)
        layout.addLayout(beside_notes(self.splitter, self.summary, self.slider_box), 1)

    def _clear(self) -> None:
        self.setup = None
        self.curves = None
        self.items = {}
        for widget in [*self.sliders, *self.slider_labels]:
            self.slider_box.removeWidget(widget)
            widget.deleteLater()
        self.slider_box.removeWidget(self.reset_button)
        self.reset_button.hide()
        self.sliders, self.slider_labels, self.slider_ranges = [], [], []
        clear_plot(self.potential_plot)
        clear_plot(self.portrait_plot)
        self.splitter.setVisible(True)
        self.summary.setText("Looking for cyclic coordinates…")

    def _start(self) -> None:
        generation = self.generation
        self.runner.submit(
            self.key,
            jobs.reduction_with_curves,
            self.compiled,
            on_done=lambda result: self._on_setup_done(result, generation),
            on_failed=lambda message: self.summary.setText(f"Reduction failed: {message}"),
            what="the Routhian reduction",
        )

    def _on_setup_done(self, result, generation: int) -> None:
        if generation != self.generation:
            return
        setup, curves = result
        self.setup = setup
        if setup.reduction is None and setup.needs_closed_form:
            self.splitter.setVisible(False)
            self.summary.setText(f"<b>Not available:</b> {setup.reason}.")
            return
        if setup.reduction is None:
            self.splitter.setVisible(False)
            self.summary.setText(
                "<b>No reduction:</b> "
                + setup.reason
                + ". Routhian reduction needs a cyclic coordinate (one absent from L, with "
                "no force on it), whose conserved momentum p<sub>c</sub> can be held as a "
                "constant. Try planetary motion or the spherical pendulum."
            )
            return
        reduction = setup.reduction
        names = [pretty_name(n) for n in reduction.cyclic]
        rest = [pretty_name(n) for n in reduction.rest]
        held = ""
        if len(rest) > 1:
            held = (
                f" The plots vary {rest[0]} with {', '.join(rest[1:])} held at the current values."
            )
        self.summary.setText(
            f"<b>Cyclic:</b> {', '.join(names)} — its momentum is conserved, so the motion of "
            f"{', '.join(rest)} alone follows the Routhian R = L − Σ p<sub>c</sub> q̇<sub>c</sub>."
            f" {marked('V<sub>eff</sub> = ' + html.escape(str(setup.expression)))}.{held}"
        )
        for j, name in enumerate(reduction.cyclic):
            value = float(setup.p_cyclic[j])
            lo, hi = _slider_range(self.compiled.mechanics.scene, name, value)
            slider = QSlider(Qt.Orientation.Horizontal)
            slider.setRange(0, SLIDER_STEPS)
            slider.setValue(_to_step(value, lo, hi))
            slider.valueChanged.connect(self._on_slider_changed)
            label = QLabel()
            self.slider_box.addWidget(label, j, 0)
            self.slider_box.addWidget(slider, j, 1)
            self.sliders.append(slider)
            self.slider_labels.append(label)
            self.slider_ranges.append((lo, hi))
        self.slider_box.addWidget(self.reset_button, 0, 2)
        self.reset_button.show()
        self._show(curves)

    def momenta(self) -> np.ndarray:
        """The conserved momenta the sliders hold."""
        values = []
        for slider, (lo, hi) in zip(self.sliders, self.slider_ranges, strict=True):
            values.append(lo + (hi - lo) * slider.value() / SLIDER_STEPS)
        return np.array(values)

    def set_momenta(self, values) -> None:
        """Move the sliders to ``values`` (and redraw)."""
        for slider, value, (lo, hi) in zip(self.sliders, values, self.slider_ranges, strict=True):
            slider.blockSignals(True)
            slider.setValue(_to_step(float(value), lo, hi))
            slider.blockSignals(False)
        self._on_slider_changed()

    def _on_reset_clicked(self) -> None:
        if self.setup is not None and self.setup.reduction is not None:
            self.set_momenta(self.setup.p_cyclic)

    def _on_slider_changed(self, *_args) -> None:
        if self.setup is None or self.setup.reduction is None:
            return
        p_c = self.momenta()
        exact = all(
            _to_step(v, lo, hi) == s.value()
            for v, s, (lo, hi) in zip(
                self.setup.p_cyclic, self.sliders, self.slider_ranges, strict=True
            )
        )
        if exact:
            p_c = np.asarray(self.setup.p_cyclic, dtype=float)
        curves = jobs.reduction_curves(self.setup, jobs.parameters_of(self.compiled), p_c)
        self._show(curves)

    def _build_items(self, q_name: str) -> None:
        """Create the plot items once per system; slider moves only call ``setData``."""
        clear_plot(self.potential_plot)
        clear_plot(self.portrait_plot)
        plot = self.potential_plot.getPlotItem()
        plot.setLabel("bottom", q_name)
        plot.setLabel("left", f"V<sub>eff</sub>({q_name})")
        self.items = {
            "v_eff": plot.plot(pen=pen(BLUE), name=f"V<sub>eff</sub>({q_name})", connect="finite"),
            "energy": plot.plot(pen=pen(ORANGE, 1.6, dash=True), name="E"),
            "turning": plot.plot(
                pen=None, symbol="o", symbolBrush=RED, symbolSize=9, name="turning points"
            ),
            "minimum": pg.InfiniteLine(
                0.0,
                angle=90,
                pen=pen(GREEN, 1.2, dot=True),
                label="",
                labelOpts={"position": 0.92, "color": GREEN, "fill": (255, 255, 255, 200)},
            ),
        }
        plot.addItem(self.items["minimum"])
        portrait = self.portrait_plot.getPlotItem()
        portrait.setLabel("bottom", q_name)
        portrait.setLabel("left", f"p<sub>{q_name}</sub>")
        self.items["levels"] = portrait.plot(
            pen=pen(GREY, 1.0), connect="finite", name="level sets of H<sub>red</sub>"
        )
        self.items["orbit"] = portrait.plot(pen=pen(ORANGE, 2.2), connect="finite", name="H = E")
        self.items["state"] = portrait.plot(
            pen=None, symbol="o", symbolBrush=BLUE, symbolSize=9, name="the state"
        )
        self._legend_labels = {
            key: _legend_label(plot, self.items[key]) for key in ("energy", "turning")
        }
        self._legend_labels["orbit"] = _legend_label(portrait, self.items["orbit"])

    def _show(self, curves: jobs.ReductionCurves) -> None:
        self.curves = curves
        setup = self.setup
        reduction = setup.reduction
        for label, name, value, current in zip(
            self.slider_labels, reduction.cyclic, curves.p_cyclic, setup.p_cyclic, strict=True
        ):
            label.setText(
                f"p<sub>{pretty_name(name)}</sub> = {value:.4g}  (current orbit {current:.4g})"
            )
        q_name = pretty_name(reduction.rest[0])
        if not getattr(self, "items", None):
            self._build_items(q_name)
        pc = ", ".join(
            f"p<sub>{pretty_name(n)}</sub> = {v:.4g}"
            for n, v in zip(reduction.cyclic, curves.p_cyclic, strict=True)
        )
        items = self.items
        plot = self.potential_plot.getPlotItem()
        plot.setTitle(f"Effective potential at {pc}", color="#222", size="10pt")
        finite = np.isfinite(curves.v_eff)
        items["v_eff"].setData(curves.q, np.where(finite, curves.v_eff, np.nan))
        items["energy"].setData([curves.q[0], curves.q[-1]], [curves.energy, curves.energy])
        items["turning"].setData(curves.turning, np.full(len(curves.turning), curves.energy))
        self._legend_labels["energy"].setText(f"E = {curves.energy:.4g} (the state's energy)")
        self._legend_labels["turning"].setText(
            "turning points " + (", ".join(f"{x:.4g}" for x in curves.turning) or "none")
        )
        minimum = self.minimum_position()
        items["minimum"].setVisible(minimum is not None)
        if minimum is not None:
            items["minimum"].setValue(minimum)
            items["minimum"].label.setFormat(f"min at {q_name} = {minimum:.4g}")
        if finite.any():
            vmin = float(np.min(curves.v_eff[finite]))
            top = max(curves.energy, vmin)
            span = max(top - vmin, 0.5 * abs(vmin), 1e-6)
            plot.setYRange(vmin - 0.3 * span, top + 1.6 * span, padding=0)
        plot.setXRange(float(curves.q[0]), float(curves.q[-1]), padding=0.02)
        portrait = self.portrait_plot.getPlotItem()
        portrait.setTitle(
            f"Reduced phase portrait: level sets of H at {pc}", color="#222", size="10pt"
        )
        xs = [x for x, _ in curves.lines]
        ys = [y for _, y in curves.lines]
        if xs:
            items["levels"].setData(np.concatenate(xs), np.concatenate(ys))
        else:
            items["levels"].setData([], [])
        items["orbit"].setData(*curves.orbit)
        items["state"].setData([curves.q0], [curves.p0])
        self._legend_labels["orbit"].setText(f"H = {curves.energy:.4g} (the state)")
        portrait.setXRange(float(curves.q[0]), float(curves.q[-1]), padding=0.02)
        portrait.setYRange(*setup.p_range, padding=0.02)
        if setup.quadratic is None:
            self.summary.setText(
                self.summary.text() + " (H is not quadratic in the momentum: no portrait.)"
            )

    def minimum_position(self) -> float | None:
        """The minimum of V_eff in the plotted range, refined (None at an end)."""
        curves = self.curves
        if curves is None or curves.minimum is None or len(self.setup.rest_index) != 1:
            return curves.minimum if curves is not None else None
        V = self.setup.reduction.effective_potential_function(jobs.parameters_of(self.compiled))
        step = float(curves.q[1] - curves.q[0])
        with np.errstate(all="ignore"):
            found = scipy.optimize.minimize_scalar(
                lambda x: float(V(np.array([x]), curves.p_cyclic)[0]),
                bounds=(curves.minimum - step, curves.minimum + step),
                method="bounded",
                options={"xatol": 1e-10},
            )
        return float(found.x) if found.success else curves.minimum


def _slider_range(scene, name: str, value: float) -> tuple[float, float]:
    ranges = scene.view.get("ranges", {}) if isinstance(scene.view, dict) else {}
    key = f"p_{name}"
    if key in ranges:
        lo, hi = (float(v) for v in ranges[key])
        if lo < hi and lo <= value <= hi:
            return lo, hi
    half = max(1.0, 2.0 * abs(value))
    return (0.0, value + half) if value > 0 else (value - half, value + half)


def _to_step(value: float, lo: float, hi: float) -> int:
    return int(round((value - lo) / (hi - lo) * SLIDER_STEPS))


def _legend_label(plot: pg.PlotItem, item) -> pg.LabelItem:
    """The legend's text label of ``item`` (to rename it as the values change)."""
    for sample, label in plot.legend.items:
        if sample.item is item:
            return label
    raise KeyError("item not in the legend")
