"""Action–angle quantities of one-degree systems: J(E) and T(E) = dJ/dE against E."""

from __future__ import annotations

import numpy as np
import pyqtgraph as pg
from PySide6.QtWidgets import QSplitter, QVBoxLayout, QWidget

from explorer.textbook.base import TextbookTabView
from explorer.textbook.plots import (
    BLUE,
    GREY,
    ORANGE,
    PURPLE,
    RED,
    beside_notes,
    clear_plot,
    headroom,
    make_plot,
    note_label,
    pen,
)
from systems.display import pretty_name
from systems.textbook import jobs


class ActionAngleView(TextbookTabView):
    """J(E) = ∮ p dq and T(E) = dJ/dE from the bottom of the well to past the separatrix."""

    title = "Action–angle"

    def __init__(self, runner, parent: QWidget | None = None):
        super().__init__(runner, parent)
        self.result: jobs.ActionAngleResult | None = None
        self.summary = note_label("")
        self.action_plot = make_plot("Action J(E)", "E", "J = ∮ p dq", corner="top-left")
        self.period_plot = make_plot("Period T(E) = dJ/dE", "E", "T")
        self.splitter = QSplitter()
        self.splitter.addWidget(self.action_plot)
        self.splitter.addWidget(self.period_plot)
        layout = QVBoxLayout(self)
        layout.setContentsMargins(4, 4, 4, 4)
        layout.addLayout(beside_notes(self.splitter, self.summary), 1)

    def _clear(self) -> None:
        self.result = None
        clear_plot(self.action_plot)
        clear_plot(self.period_plot)
        self.splitter.setVisible(True)
        self.summary.setText("Integrating J(E) and T(E)…")

    def _start(self) -> None:
        reason = jobs.action_angle_reason(self.compiled)
        if reason:
            self._show_reason(reason)
            return
        generation = self.generation
        self.runner.submit(
            self.key,
            jobs.action_angle_table,
            self.compiled,
            on_done=lambda result: self._on_table_done(result, generation),
            on_failed=lambda message: self._show_reason(message.split(": ", 1)[-1]),
            what="the action–angle table",
        )

    def _show_reason(self, reason: str) -> None:
        self.splitter.setVisible(False)
        self.summary.setText(
            f"<b>Not available:</b> {reason}. Action–angle variables apply to autonomous "
            "one-degree systems with periodic motion, such as the simple pendulum."
        )

    def _on_table_done(self, result: jobs.ActionAngleResult, generation: int) -> None:
        if generation != self.generation:
            return
        self.result = result
        name = pretty_name(self.compiled.mechanics.scene.coordinates[0])
        E = result.energies
        librating = np.array([m == "libration" for m in result.motion])
        rotating = np.array([m == "rotation" for m in result.motion])
        for widget, values, label in (
            (self.action_plot, result.action, f"J = ∮ p<sub>{name}</sub> d{name}"),
            (self.period_plot, result.period, "T"),
        ):
            clear_plot(widget)
            plot = widget.getPlotItem()
            plot.setLabel("bottom", "E  (energy of the orbit)")
            plot.setLabel("left", label)
            plot.plot(
                E,
                np.where(librating, values, np.nan),
                pen=pen(BLUE),
                connect="finite",
                name="libration",
            )
            if rotating.any():
                plot.plot(
                    E,
                    np.where(rotating, values, np.nan),
                    pen=pen(PURPLE),
                    connect="finite",
                    name="rotation (full turns)",
                )
            if result.separatrix is not None:
                plot.addItem(
                    pg.InfiniteLine(
                        result.separatrix,
                        angle=90,
                        pen=pen(RED, 1.5, dash=True),
                        label=f"separatrix E = {result.separatrix:.4g}",
                        labelOpts={
                            "position": 0.1 if widget is self.period_plot else 0.55,
                            "color": RED,
                            "fill": (255, 255, 255, 210),
                        },
                    )
                )
            plot.addItem(
                pg.InfiniteLine(
                    result.current,
                    angle=90,
                    pen=pen(ORANGE, 1.2, dot=True),
                    label="this orbit",
                    labelOpts={"position": 0.1, "color": ORANGE, "fill": (255, 255, 255, 210)},
                )
            )
        own = ""
        if result.current_action is not None:
            for widget, value in (
                (self.action_plot, result.current_action),
                (self.period_plot, result.current_period),
            ):
                widget.getPlotItem().plot(
                    [result.current],
                    [value],
                    pen=None,
                    symbol="o",
                    symbolSize=9,
                    symbolBrush=ORANGE,
                    symbolPen="w",
                )
            own = (
                f" This orbit: E = {result.current:.5g}, J = {result.current_action:.5g}, "
                f"T = {result.current_period:.5g}."
            )
        plot = self.period_plot.getPlotItem()
        plot.setTitle("Period T(E) = dJ/dE", color="#222", size="10pt")
        self.action_plot.getPlotItem().setTitle("Action J(E)", color="#222", size="10pt")
        if result.small_period is not None:
            plot.plot(
                [E[0], E[-1]],
                [result.small_period] * 2,
                pen=pen(GREY, 1.2, dash=True),
                name=f"2π/ω = {result.small_period:.4g} (small oscillations)",
            )
        finite = np.isfinite(result.period)
        check = ""
        if result.exact is not None:
            show = np.isfinite(result.exact) & librating
            plot.plot(
                E[show][::3],
                result.exact[show][::3],
                pen=None,
                symbol="o",
                symbolSize=5,
                symbolBrush=None,
                symbolPen=pen(RED, 1.2),
                name="exact 4√(M/c) K(k²)",
            )
            if show.any():
                deviation = np.abs(result.period[show] / result.exact[show] - 1)
                check = (
                    f" Exact elliptic-integral period {result.exact_formula}: largest relative "
                    f"difference below the separatrix <b>{np.nanmax(deviation):.1e}</b>."
                )
        if finite.any():
            top = float(np.nanmax(result.period[finite]))
            low = float(np.nanmin(result.period[finite]))
            high = min(top, 6 * low) if low > 0 else top
            headroom(plot, min(0.0, low), high, 0.8)
        sep = (
            f" T diverges at the separatrix E = {result.separatrix:.5g}, where the motion "
            "takes forever to reach the unstable equilibrium."
            if result.separatrix is not None
            else ""
        )
        small = (
            f" At the bottom of the well T → 2π/ω = {result.small_period:.5g}."
            if result.small_period is not None
            else ""
        )
        self.summary.setText(
            f"Orbits through {name} = {result.q0:.4g} (U<sub>min</sub> = {result.minimum:.5g}); "
            "J = area inside the level set H = E (a rotation: the area under one turn); "
            "T = dJ/dE is integrated on its own." + own + small + sep + check
        )
