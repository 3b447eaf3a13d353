"""The energy theorem: dH/dt = −∂L/∂t + Σ q̇ᵢ Qᵢ along the current motion."""

from __future__ import annotations

import numpy as np
from PySide6.QtWidgets import QHBoxLayout, QLabel, QSplitter, QVBoxLayout, QWidget

from explorer.textbook.base import TextbookTabView
from explorer.textbook.plots import (
    BLUE,
    GREEN,
    ORANGE,
    RED,
    beside_notes,
    clear_plot,
    headroom,
    make_plot,
    note_label,
    pen,
    spin_box,
)
from explorer.textbook.tasks import CPU_SECONDS
from systems.textbook import jobs

CPU_SECONDS_PER_TIME = 0.05
"""CPU seconds the run may take per unit of its duration, beyond ``CPU_SECONDS``: a long
run is numeric work, not runaway algebra (the double pendulum takes about 0.007)."""


def explanation(result: jobs.EnergyResult) -> str:
    """The energy theorem in words for this kind of system."""
    words = []
    if result.explicit_time:
        cause = "the constraint moves" if result.rheonomic else "a time-dependent potential"
        words.append(
            f"<b>L depends explicitly on t</b> ({cause}): H is not conserved. It changes "
            "<i>only</i> through the explicit time dependence, dH/dt = −∂L/∂t, which the "
            "two curves above show agree at every instant."
        )
    elif result.effects:
        words.append(
            "<b>Effects act</b> (dissipation or forces): H changes exactly by their power, "
            "dH/dt = Σ q̇ᵢ Qᵢ."
        )
    else:
        words.append("<b>L has no explicit t</b> and no effects act: H is conserved, dH/dt = 0.")
        if result.rheonomic:
            words.append(
                "The constraint moves (the scene is rheonomic), yet H is conserved because L "
                "does not contain t in these coordinates."
            )
    if result.explicit_time and result.effects:
        words.append("Effects act as well: their power Σ q̇ᵢ Qᵢ adds to −∂L/∂t.")
    balance = result.balance
    if balance.energy is not None and result.hamiltonian_is_energy is False:
        swing = float(np.ptp(balance.energy))
        if result.rheonomic:
            why = "the agent that drives the constraint does work on the system"
        else:  # scleronomic, yet h = Σ q̇ᵢ ∂L/∂q̇ᵢ − L is not T + V: T is not quadratic
            why = "T is not a quadratic form in the velocities, so Σ q̇ᵢ ∂T/∂q̇ᵢ ≠ 2T"
        words.append(
            f"H is <b>not</b> T + V here: T + V varies by {swing:.3g} along the motion "
            f"({why}), while H "
            + (
                "stays constant."
                if not (result.explicit_time or result.effects)
                else "follows the theorem."
            )
        )
    elif result.hamiltonian_is_energy is None:
        words.append(
            "No energy T + V can be named here: the scene gives L (or H) alone, with an "
            "explicit t or without a positive kinetic energy, so H is not compared with one."
        )
    mismatch = float(np.max(np.abs(balance.rate - balance.predicted)))
    size = float(np.max(np.abs(balance.rate))) if len(balance.rate) else 0.0
    words.append(f"Largest |dH/dt − prediction| = {mismatch:.2g} (|dH/dt| up to {size:.2g}).")
    return " ".join(words)


class EnergyTheoremView(TextbookTabView):
    """Both sides of the energy theorem over [0, T], and H against T + V."""

    title = "Energy theorem"

    def __init__(self, runner, parent: QWidget | None = None):
        super().__init__(runner, parent)
        self.result: jobs.EnergyResult | None = None
        self.duration = spin_box(0.1, 10000.0, 20.0, 5.0, decimals=2)
        self.duration.valueChanged.connect(self._on_duration_changed)
        controls = QHBoxLayout()
        controls.addWidget(QLabel("run over [0, T], T ="))
        controls.addWidget(self.duration)
        controls.addStretch(1)
        self.summary = note_label("")
        self.rate_plot = make_plot("Energy theorem", "t", "rate of change of H")
        self.energy_plot = make_plot("H and T + V", "t", "energy")
        splitter = QSplitter()
        splitter.addWidget(self.rate_plot)
        splitter.addWidget(self.energy_plot)
        layout = QVBoxLayout(self)
        layout.setContentsMargins(4, 4, 4, 4)
        layout.addLayout(controls)
        layout.addLayout(beside_notes(splitter, self.summary), 1)
        self._scene_name = None

    def set_system(self, compiled) -> None:
        scene = compiled.mechanics.scene
        if scene.name != self._scene_name:
            self._scene_name = scene.name
            t_end = float(scene.view.get("t_end", 20.0) or 20.0)
            self.duration.blockSignals(True)
            self.duration.setValue(min(max(t_end, 0.1), 200.0))
            self.duration.blockSignals(False)
        super().set_system(compiled)

    def _on_duration_changed(self, _value: float) -> None:
        if self.compiled is not None:
            self.stale = True
            self._clear()
            if self.isVisible():
                self.refresh()

    def _clear(self) -> None:
        self.result = None
        clear_plot(self.rate_plot)
        clear_plot(self.energy_plot)
        self.summary.setText("Integrating the motion…")

    def _start(self) -> None:
        generation = self.generation
        self.runner.submit(
            self.key,
            jobs.energy,
            self.compiled,
            self.duration.value(),
            on_done=lambda result: self._on_balance_done(result, generation),
            on_failed=lambda message: self.summary.setText(f"Not available: {message}"),
            what="the energy balance along the run",
            cpu_seconds=CPU_SECONDS + CPU_SECONDS_PER_TIME * self.duration.value(),
        )

    def _on_balance_done(self, result: jobs.EnergyResult, generation: int) -> None:
        if generation != self.generation:
            return
        self.result = result
        b = result.balance
        clear_plot(self.rate_plot)
        plot = self.rate_plot.getPlotItem()
        plot.setTitle("dH/dt = −∂L/∂t + Σ q̇ᵢ Qᵢ along the motion", color="#222", size="10pt")
        plot.setLabel("bottom", "t")
        plot.setLabel("left", "rate of change of H")
        plot.plot(b.t, b.rate, pen=pen(BLUE, 2.5), name="dH/dt (from H(t) along the run)")
        plot.plot(
            b.t, b.predicted, pen=pen(ORANGE, 1.6, dash=True), name="−∂L/∂t + Σ q̇ᵢ Qᵢ (the formula)"
        )
        self._pad(plot, np.concatenate([b.rate, b.predicted]), 0.8)
        clear_plot(self.energy_plot)
        plot = self.energy_plot.getPlotItem()
        plot.setTitle("H and T + V", color="#222", size="10pt")
        plot.setLabel("bottom", "t")
        plot.setLabel("left", "energy")
        plot.plot(b.t, b.hamiltonian, pen=pen(GREEN, 2.5), name="H (the Hamiltonian)")
        values = [b.hamiltonian]
        if b.energy is not None and result.hamiltonian_is_energy is False:
            plot.plot(b.t, b.energy, pen=pen(RED, 1.8), name="T + V")
            values.append(b.energy)
        self._pad(plot, np.concatenate(values), 0.45 if len(values) == 1 else 0.9)
        complete = "" if result.run.complete else f" (the run stopped early: {result.run.message})"
        self.summary.setText(explanation(result) + complete)

    @staticmethod
    def _pad(plot, values: np.ndarray, top: float = 0.45) -> None:
        """A y range that does not magnify rounding noise on a conserved quantity."""
        values = values[np.isfinite(values)]
        if not values.size:
            return
        lo, hi = float(values.min()), float(values.max())
        floor = 1e-6 * max(abs(lo), abs(hi), 1.0)
        if hi - lo < floor:
            middle = (hi + lo) / 2
            half = max(abs(middle) * 0.05, 1e-3)
            lo, hi = middle - half, middle + half
        headroom(plot, lo, hi, top)
