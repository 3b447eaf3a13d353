"""Floquet theory: constant solutions of a periodically driven system with their
multipliers, a stability chart over two parameters (the Ince–Strutt diagram for the
Mathieu equation), and periodic orbits of autonomous systems by shooting."""

from __future__ import annotations

import html

import numpy as np
import pyqtgraph as pg
from PySide6.QtCore import QRectF
from PySide6.QtWidgets import (
    QComboBox,
    QHBoxLayout,
    QLabel,
    QProgressBar,
    QPushButton,
    QVBoxLayout,
    QWidget,
)

from explorer.textbook.base import TextbookTabView
from explorer.textbook.plots import (
    BLUE,
    RED,
    beside_notes,
    clear_plot,
    make_plot,
    note_label,
    pen,
    spin_box,
)
from systems.display import pretty_name
from systems.textbook import jobs
from systems.textbook.floquet import MARGINAL, STABLE, UNKNOWN, UNSTABLE

CHART_SIZE = (120, 90)
"""Points of a chart along the horizontal and the vertical parameter."""
BLOCK_POINTS = 1200
"""About this many points per job of a chart (a job is a few rows)."""
COLOURS = {
    STABLE: (236, 243, 251),
    MARGINAL: (30, 30, 30),
    UNKNOWN: (200, 200, 200),
}
UNSTABLE_LIGHT = np.array([253, 208, 162])
UNSTABLE_DARK = np.array([166, 54, 3])


def chart_image(codes: np.ndarray, growth: np.ndarray) -> np.ndarray:
    """RGB (ny, nx, 3) of a chart: stable pale blue, unstable orange to dark red by
    log |mu| (darker: faster growth), marginal black, unknown grey."""
    image = np.zeros((*codes.shape, 3), dtype=np.ubyte)
    for code, colour in COLOURS.items():
        image[codes == code] = colour
    unstable = codes == UNSTABLE
    if np.any(unstable):
        level = np.clip(np.log10(np.maximum(growth[unstable], 1.0)) / 3.0, 0.0, 1.0)
        shade = UNSTABLE_LIGHT + level[:, None] * (UNSTABLE_DARK - UNSTABLE_LIGHT)
        image[unstable] = shade.astype(np.ubyte)
    return image


def default_range(value: float) -> tuple[float, float]:
    """[0, 2 v] around a positive parameter value (a negative one mirrored), [-1, 1] at 0."""
    if value > 0:
        return 0.0, 2.0 * value
    if value < 0:
        return 2.0 * value, 0.0
    return -1.0, 1.0


def summary_html(result: jobs.FloquetResult) -> str:
    """The tab's notes: periodicity, the constant solutions and their verdicts."""
    if not result.driven:
        text = (
            "<b>Autonomous system</b>: its equilibria are in the Equilibria tab. Floquet "
            "theory applies to its <i>periodic orbits</i>: find one from the initial state "
            "below (shooting and Newton on the period and the start; two multipliers are "
            "always 1)."
        )
        if result.system is None:
            text += f"<br>Not available here: {html.escape(result.reason)}."
        return text
    analysis = result.analysis
    lines = [f"<b>Driven system</b>: {html.escape(analysis.periodicity.reason)}."]
    if analysis.periodicity.periodic:
        shown = {n: pretty_name(n) for n in result.names}
        sentences = analysis.sentences(shown, digits=5)
        if sentences:
            lines.append("Constant solutions (q̇ = 0 for all t) and their Floquet multipliers:")
            lines += [f"• {html.escape(s)}" for s in sentences]
        if analysis.note and analysis.note != analysis.periodicity.reason:
            extra = analysis.note.replace(analysis.periodicity.reason + "; ", "")
            lines.append(f"<i>{html.escape(extra)}</i>")
        lines.append(
            "Stable: every multiplier on the unit circle (one degree of freedom: |tr M| &lt; "
            "2). In the chart: pale blue stable, orange to dark red unstable (darker: larger "
            "|μ|), black marginal (|tr M| = 2), grey not periodic or not a solution there."
        )
    return "<br>".join(lines)


class FloquetView(TextbookTabView):
    """Constant solutions and multipliers; a stability chart; periodic orbits."""

    title = "Floquet"

    def __init__(self, runner, parent: QWidget | None = None):
        super().__init__(runner, parent)
        self.result: jobs.FloquetResult | None = None
        self.orbit = None
        self.codes: np.ndarray | None = None
        self.growth: np.ndarray | None = None
        self._chart_axes: tuple | None = None
        self.summary = note_label("")
        self.orbit_note = note_label("")
        # chart controls
        self.solution = QComboBox()
        self.x_name, self.y_name = QComboBox(), QComboBox()
        self.x_low, self.x_high = spin_box(-1e6, 1e6, 0, 0.1, 4), spin_box(-1e6, 1e6, 1, 0.1, 4)
        self.y_low, self.y_high = spin_box(-1e6, 1e6, 0, 0.1, 4), spin_box(-1e6, 1e6, 1, 0.1, 4)
        self.x_name.currentTextChanged.connect(lambda _: self._default_ranges("x"))
        self.y_name.currentTextChanged.connect(lambda _: self._default_ranges("y"))
        self.chart_button = QPushButton("Compute chart")
        self.chart_button.clicked.connect(self.start_chart)
        self.stop_button = QPushButton("Stop")
        self.stop_button.clicked.connect(self.stop_chart)
        self.stop_button.setEnabled(False)
        self.progress = QProgressBar()
        self.progress.setRange(0, 100)
        self.progress.setValue(0)
        self.progress.setMaximumWidth(140)
        chart_row = QHBoxLayout()
        chart_row.addWidget(QLabel("chart of"))
        chart_row.addWidget(self.solution)
        for label, combo, low, high in (
            ("x:", self.x_name, self.x_low, self.x_high),
            ("y:", self.y_name, self.y_low, self.y_high),
        ):
            chart_row.addWidget(QLabel(label))
            chart_row.addWidget(combo)
            chart_row.addWidget(low)
            chart_row.addWidget(QLabel("…"))
            chart_row.addWidget(high)
        chart_row.addWidget(self.chart_button)
        chart_row.addWidget(self.stop_button)
        chart_row.addWidget(self.progress)
        chart_row.addStretch(1)
        self.chart_controls = QWidget()
        self.chart_controls.setLayout(chart_row)
        # periodic orbit controls
        self.period_guess = spin_box(0.0, 1e6, 0.0, 0.5, 5)
        self.period_guess.setSpecialValueText("first return")
        self.orbit_button = QPushButton("Find periodic orbit from the initial state")
        self.orbit_button.clicked.connect(self.start_orbit)
        orbit_row = QHBoxLayout()
        orbit_row.addWidget(QLabel("period guess"))
        orbit_row.addWidget(self.period_guess)
        orbit_row.addWidget(self.orbit_button)
        orbit_row.addStretch(1)
        self.orbit_controls = QWidget()
        self.orbit_controls.setLayout(orbit_row)
        self.plot = make_plot("Stability chart", "", "")
        self.image = pg.ImageItem()
        self.marker = pg.ScatterPlotItem(size=11, symbol="+", pen=pg.mkPen("#0a3d91", width=2.5))
        layout = QVBoxLayout(self)
        layout.setContentsMargins(4, 4, 4, 4)
        layout.addWidget(self.chart_controls)
        layout.addWidget(self.orbit_controls)
        layout.addLayout(beside_notes(self.plot, self.summary, self.orbit_note), 1)

    # -- lifecycle ----------------------------------------------------------------------

    @property
    def chart_key(self) -> str:
        return f"{self.key}.chart"

    @property
    def orbit_key(self) -> str:
        return f"{self.key}.orbit"

    def set_system(self, compiled) -> None:
        self.runner.cancel(self.chart_key)
        self.runner.cancel(self.orbit_key)
        super().set_system(compiled)

    def _clear(self) -> None:
        self.result = None
        self.orbit = None
        self.codes = self.growth = None
        self._chart_running(False)
        self.progress.setValue(0)
        clear_plot(self.plot)
        self.summary.setText("Looking at the time dependence…")
        self.orbit_note.setText("")
        self.chart_controls.setVisible(False)
        self.orbit_controls.setVisible(False)

    def _start(self) -> None:
        generation = self.generation
        self.runner.submit(
            self.key,
            jobs.floquet,
            self.compiled,
            on_done=lambda result: self._on_done(result, generation),
            on_failed=lambda message: self.summary.setText(f"Not available: {message}"),
            what="the Floquet analysis",
        )

    def _on_done(self, result: jobs.FloquetResult, generation: int) -> None:
        if generation != self.generation:
            return
        self.result = result
        self.summary.setText(summary_html(result))
        analysis = result.analysis
        chartable = bool(result.driven and analysis is not None and analysis.solutions)
        self.chart_controls.setVisible(chartable)
        self.orbit_controls.setVisible(not result.driven and result.system is not None)
        if not result.driven:
            self.plot.getPlotItem().setTitle(
                "Periodic orbit: press Find periodic orbit", color="#222", size="10pt"
            )
        if chartable:
            self._fill_chart_controls(result)
            self.plot.getPlotItem().setTitle(
                "Stability chart: press Compute chart", color="#222", size="10pt"
            )

    def _fill_chart_controls(self, result: jobs.FloquetResult) -> None:
        self.solution.blockSignals(True)
        self.solution.clear()
        for s in result.analysis.solutions:
            where = ", ".join(f"{pretty_name(k)} = {v:.4g}" for k, v in s.q.items())
            self.solution.addItem(where)
        # the inverted position of a pendulum is the interesting one: the last found
        self.solution.setCurrentIndex(self.solution.count() - 1)
        self.solution.blockSignals(False)
        names = list(result.parameters)
        for combo, index in ((self.x_name, 0), (self.y_name, 1)):
            combo.blockSignals(True)
            combo.clear()
            combo.addItems(names)
            combo.setCurrentIndex(min(index, len(names) - 1))
            combo.blockSignals(False)
        self._default_ranges("x")
        self._default_ranges("y")

    def _default_ranges(self, axis: str) -> None:
        if self.result is None:
            return
        combo, low, high = (
            (self.x_name, self.x_low, self.x_high)
            if axis == "x"
            else (self.y_name, self.y_low, self.y_high)
        )
        value = self.result.parameters.get(combo.currentText())
        if value is None:
            return
        lo, hi = default_range(value)
        low.setValue(lo)
        high.setValue(hi)

    # -- the chart ----------------------------------------------------------------------

    def start_chart(self) -> None:
        """Compute the chart of the chosen solution over the chosen parameters, in blocks
        of rows (one worker job each), drawing each block as it arrives."""
        result = self.result
        if result is None or not result.driven or not result.analysis.solutions:
            return
        x_name, y_name = self.x_name.currentText(), self.y_name.currentText()
        if not x_name or not y_name or x_name == y_name:
            self.orbit_note.setText("Choose two different parameters for the chart.")
            return
        nx, ny = CHART_SIZE
        x_values = np.linspace(self.x_low.value(), self.x_high.value(), nx)
        y_values = np.linspace(self.y_low.value(), self.y_high.value(), ny)
        solution = result.analysis.solutions[max(self.solution.currentIndex(), 0)]
        q_star = np.array([solution.q[n] for n in result.names])
        self.codes = np.full((ny, nx), UNKNOWN, dtype=int)
        self.growth = np.full((ny, nx), np.nan)
        self._chart_axes = (x_name, x_values, y_name, y_values, q_star)
        clear_plot(self.plot)
        plot = self.plot.getPlotItem()
        plot.setTitle(
            f"Stability chart of {self.solution.currentText()} (shaded: unstable)",
            color="#222",
            size="10pt",
        )
        plot.setLabel("bottom", pretty_name(x_name))
        plot.setLabel("left", pretty_name(y_name))
        self.image = pg.ImageItem()
        plot.addItem(self.image)
        dx = (x_values[-1] - x_values[0]) / max(nx - 1, 1)
        dy = (y_values[-1] - y_values[0]) / max(ny - 1, 1)
        self._rect = QRectF(
            x_values[0] - dx / 2, y_values[0] - dy / 2, dx * nx or 1.0, dy * ny or 1.0
        )
        self.marker = pg.ScatterPlotItem(size=13, symbol="+", pen=pg.mkPen("#0a3d91", width=2.5))
        self.marker.setData(
            [result.parameters[x_name]], [result.parameters[y_name]], name="current parameters"
        )
        plot.addItem(self.marker)
        self._draw_chart()
        plot.setXRange(self._rect.left(), self._rect.right(), padding=0)
        plot.setYRange(self._rect.top(), self._rect.bottom(), padding=0)
        self._chart_running(True)
        self.progress.setValue(0)
        self._submit_block(0, self.generation)

    def _submit_block(self, first: int, generation: int) -> None:
        x_name, x_values, y_name, y_values, q_star = self._chart_axes
        count = max(1, BLOCK_POINTS // len(x_values))
        self.runner.submit(
            self.chart_key,
            jobs.chart_block,
            self.result.system,
            q_star,
            dict(self.result.parameters),
            x_name,
            x_values,
            y_name,
            y_values,
            first,
            count,
            on_done=lambda block: self._on_block(block, generation),
            on_failed=self._on_chart_failed,
            what="a block of the stability chart",
        )

    def _on_block(self, block: jobs.ChartBlock, generation: int) -> None:
        if generation != self.generation or self.codes is None:
            return
        rows = slice(block.first, block.first + len(block.codes))
        self.codes[rows] = block.codes
        self.growth[rows] = block.growth
        self._draw_chart()
        done = block.first + len(block.codes)
        total = len(self.codes)
        self.progress.setValue(round(100 * done / total))
        if done < total:
            self._submit_block(done, generation)
        else:
            self._chart_running(False)

    def _on_chart_failed(self, message: str) -> None:
        self._chart_running(False)
        self.orbit_note.setText(f"The chart stopped: {html.escape(message)}")

    def stop_chart(self) -> None:
        """Stop the chart where it is (what is computed stays drawn)."""
        self.runner.cancel(self.chart_key)
        self._chart_running(False)

    def _chart_running(self, running: bool) -> None:
        self.chart_button.setEnabled(not running)
        self.stop_button.setEnabled(running)

    def _draw_chart(self) -> None:
        image = chart_image(self.codes, self.growth)
        self.image.setImage(np.transpose(image, (1, 0, 2)), levels=(0, 255))
        self.image.setRect(self._rect)

    # -- periodic orbits ----------------------------------------------------------------

    def start_orbit(self) -> None:
        """Shoot for a periodic orbit from the initial state (autonomous systems)."""
        result = self.result
        if result is None or result.driven or result.system is None:
            return
        guess = self.period_guess.value() or None
        t_max = float(self.compiled.mechanics.scene.view.get("t_end", 100.0) or 100.0)
        generation = self.generation
        self.orbit_note.setText("Shooting for a periodic orbit…")
        self.runner.submit(
            self.orbit_key,
            jobs.periodic_orbit_from,
            result.system,
            self.compiled.initial_state(),
            dict(result.parameters),
            guess,
            min(t_max, 1000.0),
            on_done=lambda orbit: self._on_orbit(orbit, generation),
            on_failed=lambda message: self.orbit_note.setText(
                f"No periodic orbit: {html.escape(message)}"
            ),
            what="the periodic orbit",
        )

    def _on_orbit(self, orbit, generation: int) -> None:
        if generation != self.generation:
            return
        self.orbit = orbit
        lines = [html.escape(line) for line in orbit.lines(digits=8)]
        self.orbit_note.setText("<br>".join(lines))
        if orbit.path is None:
            return
        n = len(orbit.names) // 2
        i, j = (0, 1) if n >= 2 else (0, n)  # two coordinates, or q and p
        clear_plot(self.plot)
        plot = self.plot.getPlotItem()
        plot.setTitle(
            f"Periodic orbit, T = {orbit.period:.6g} ({orbit.verdict.word})",
            color="#222",
            size="10pt",
        )
        plot.setLabel("bottom", pretty_name(orbit.names[i]))
        plot.setLabel("left", pretty_name(orbit.names[j]))
        plot.plot(orbit.path[:, i], orbit.path[:, j], pen=pen(BLUE, 2.2), name="the orbit")
        plot.plot(
            [orbit.start[i]],
            [orbit.start[j]],
            pen=None,
            symbol="o",
            symbolBrush=RED,
            name="start y₀",
        )
