"""Hamilton's principle: S(eps) along varied paths, and the two-point problem."""

from __future__ import annotations

import numpy as np
import pyqtgraph as pg
from PySide6.QtWidgets import (
    QComboBox,
    QHBoxLayout,
    QLabel,
    QLineEdit,
    QPushButton,
    QSpinBox,
    QSplitter,
    QVBoxLayout,
    QWidget,
)

from explorer.textbook.base import TextbookTabView
from explorer.textbook.plots import (
    BLUE,
    GREEN,
    ORANGE,
    PURPLE,
    RED,
    beside_notes,
    clear_plot,
    headroom,
    make_plot,
    note_label,
    pen,
    spin_box,
)
from systems.display import pretty_name
from systems.textbook import jobs

NATURE_TEXT = {
    "minimum": "<b style='color:#2ca02c'>minimum</b>: every varied path has a larger action "
    "(no conjugate point inside the stretch)",
    "saddle": "<b style='color:#d62728'>stationary only (past a conjugate point)</b>: some "
    "variation lowers S, so the true path is not a minimum",
    "maximum": "<b style='color:#d62728'>maximum</b> of the action",
    "degenerate": "<b>at a conjugate point</b>: a variation leaves S unchanged to second order",
}


def _parse(text: str, n: int) -> np.ndarray:
    values = [float(v) for v in text.replace(";", ",").split(",") if v.strip()]
    if len(values) != n:
        raise ValueError(f"give {n} comma-separated value{'s' if n > 1 else ''}")
    return np.array(values)


class PrincipleView(TextbookTabView):
    """S(eps) for ``q + eps·sin(kπt/T)`` on the chosen coordinate, over [0, T] of the run."""

    title = "Hamilton's principle"

    def __init__(self, runner, parent: QWidget | None = None):
        super().__init__(runner, parent)
        self.result: jobs.PrincipleResult | None = None
        self.boundary: jobs.TwoPointResult | None = None
        self.start_time = spin_box(0.0, 1000.0, 0.0, 0.5)
        self.duration = spin_box(0.05, 1000.0, 1.0, 0.25)
        self.coordinate = QComboBox()
        self.mode = QSpinBox()
        self.mode.setRange(1, 6)
        self.mode.setValue(1)
        self.mode.setKeyboardTracking(False)
        self.amplitude = spin_box(0.001, 100.0, 0.5, 0.1)
        for box in (self.start_time, self.duration, self.amplitude):
            box.valueChanged.connect(self._on_setting_changed)
        self.mode.valueChanged.connect(self._on_setting_changed)
        self.coordinate.currentIndexChanged.connect(self._on_setting_changed)
        controls = QHBoxLayout()
        for text, widget in (
            ("stretch from t₁ =", self.start_time),
            ("of length T =", self.duration),
            ("vary", self.coordinate),
            ("sine mode k =", self.mode),
            ("ε up to ±", self.amplitude),
        ):
            controls.addWidget(QLabel(text))
            controls.addWidget(widget)
        controls.addStretch(1)

        self.point_a = QLineEdit()
        self.point_b = QLineEdit()
        self.boundary_time = spin_box(0.05, 1000.0, 1.0, 0.25)
        self.solve_button = QPushButton("Solve A → B")
        self.solve_button.clicked.connect(self._on_solve_clicked)
        ends = QHBoxLayout()
        ends.addWidget(QLabel("A ="))
        ends.addWidget(self.point_a)
        ends.addWidget(QLabel("B ="))
        ends.addWidget(self.point_b)
        solve = QHBoxLayout()
        solve.addWidget(QLabel("in time"))
        solve.addWidget(self.boundary_time)
        solve.addWidget(self.solve_button)
        solve.addStretch(1)
        boundary = QVBoxLayout()
        boundary.addWidget(QLabel("<b>Two-point problem</b>"))
        boundary.addLayout(ends)
        boundary.addLayout(solve)

        self.action_plot = make_plot("Action of the varied paths", "ε", "S(ε)")
        self.path_plot = make_plot("True and varied path", "t", "q")
        for widget in (self.action_plot, self.path_plot):
            widget.getPlotItem().legend.setColumnCount(2)
        self._b_edited = False
        self.point_b.textEdited.connect(self._on_point_b_edited)
        self.point_a.textEdited.connect(self._on_point_b_edited)
        splitter = QSplitter()
        splitter.addWidget(self.action_plot)
        splitter.addWidget(self.path_plot)
        self.summary = note_label("")
        self.boundary_note = note_label("")
        layout = QVBoxLayout(self)
        layout.setContentsMargins(4, 4, 4, 4)
        layout.addLayout(controls)
        layout.addLayout(beside_notes(splitter, self.summary, boundary, self.boundary_note), 1)

    # -- system ------------------------------------------------------------------------------

    def set_system(self, compiled) -> None:
        names = compiled.mechanics.scene.coordinates
        current = [self.coordinate.itemText(i) for i in range(self.coordinate.count())]
        wanted = [pretty_name(name) for name in names]
        if current != wanted:
            self.coordinate.blockSignals(True)
            self.coordinate.clear()
            self.coordinate.addItems(wanted)
            self.coordinate.blockSignals(False)
            self._b_edited = False
        super().set_system(compiled)

    def _clear(self) -> None:
        self.result = None
        self.boundary = None
        clear_plot(self.action_plot)
        clear_plot(self.path_plot)
        self.summary.setText("Integrating the true path and varying it…")
        self.boundary_note.setText(
            "Find the path from configuration A to configuration B in the given time by "
            "making the discretized action stationary, and compare with shooting."
        )

    def _on_setting_changed(self, *_args) -> None:
        if self.compiled is None:
            return
        self.stale = True
        if self.isVisible():
            self._clear()
            self.refresh()

    def _start(self) -> None:
        generation = self.generation
        index = max(self.coordinate.currentIndex(), 0)
        self.runner.submit(
            self.key,
            jobs.principle,
            self.compiled,
            self.duration.value(),
            self.mode.value(),
            index,
            self.amplitude.value(),
            self.start_time.value(),
            on_done=lambda result: self._on_principle_done(result, generation),
            on_failed=self._on_failed,
            what="the action along the run (Hamilton's principle)",
        )

    def _on_failed(self, message: str) -> None:
        self.summary.setText(f"Not available: {message}")

    # -- the action curve -------------------------------------------------------------------

    def _on_principle_done(self, result: jobs.PrincipleResult, generation: int) -> None:
        if generation != self.generation:
            return
        self.result = result
        names = self.compiled.mechanics.scene.coordinates
        name = pretty_name(names[result.index])
        t1 = float(result.run.t[0])
        T = float(result.run.t[-1]) - t1
        shape = f"sin({result.k}π(t − t₁)/T), t₁ = {t1:g}" if t1 > 0 else f"sin({result.k}πt/T)"
        clear_plot(self.action_plot)
        plot = self.action_plot.getPlotItem()
        plot.setTitle(f"S(ε) along {name}(t) + ε·{shape},  T = {T:g}", color="#222", size="10pt")
        plot.setLabel("bottom", "ε  (amplitude of the variation)")
        plot.setLabel("left", "S(ε) = ∫ L dt")
        plot.plot(result.eps, result.action, pen=pen(BLUE), name="S(ε)")
        s0 = float(np.interp(0.0, result.eps, result.action))
        plot.plot(
            result.eps,
            s0 + result.slope * result.eps,
            pen=pen(RED, 1.6, dash=True),
            name=f"tangent at ε = 0, slope {result.slope:.2g}",
        )
        plot.plot([0.0], [s0], pen=None, symbol="o", symbolBrush=RED, symbolSize=8)
        low, high = float(np.min(result.action)), float(np.max(result.action))
        span = max(high - low, 1e-9 * max(abs(high), 1.0))
        legend = plot.legend
        if result.curvature >= 0:  # a cup: the legend goes top centre, above the curve
            plot.setYRange(low - 0.05 * span, high + 0.55 * span, padding=0)
            legend.anchor((0.5, 0), (0.5, 0), offset=(0, 8))
        else:  # a cap: bottom centre, below it
            plot.setYRange(low - 0.55 * span, high + 0.05 * span, padding=0)
            legend.anchor((0.5, 1), (0.5, 1), offset=(0, -8))
        scale = max(abs(result.curvature) * float(np.max(np.abs(result.eps))), 1e-300)
        verdict = NATURE_TEXT.get(result.nature, result.nature)
        relative = abs(result.slope) / scale
        lines = [
            f"dS/dε at ε = 0: <b>{result.slope:.3g}</b> "
            + ("≈ 0: the true path makes S stationary." if relative < 1e-4 else ""),
            f"d²S/dε² = {result.curvature:.4g} along this variation. Second variation over "
            f"sine modes: {verdict}.",
        ]
        if result.lagrangian_only:
            lines.append(
                "Effects (dissipation, forces) are not part of L: the computed path is not "
                "a stationary path of this action."
            )
        self.summary.setText("<br>".join(lines))
        self._draw_paths()

    def _draw_paths(self) -> None:
        result = self.result
        clear_plot(self.path_plot)
        if result is None:
            return
        names = self.compiled.mechanics.scene.coordinates
        i = result.index
        name = pretty_name(names[i])
        plot = self.path_plot.getPlotItem()
        plot.legend.setVisible(False)  # the title says which curve is which
        eps = float(np.max(np.abs(result.eps))) / 2
        keys = [(BLUE, f"true {name}(t)"), (ORANGE, f"varied, ε = {eps:.3g}")]
        if self.boundary is not None:
            keys.append((GREEN, "A → B, stationary action"))
            if self.boundary.shooting_path is not None:
                keys.append((PURPLE, "A → B, shooting"))
        plot.setTitle(
            "&nbsp;&nbsp;".join(
                f"<span style='color:{colour}'>━</span> {text}" for colour, text in keys
            ),
            color="#222",
            size="10pt",
        )
        plot.setLabel("bottom", "t")
        plot.setLabel("left", name)
        t = result.run.t
        q = result.run.y[:, i]
        plot.plot(t, q, pen=pen(BLUE), name=f"true path {name}(t)")
        plot.plot(
            t, q + eps * result.eta[:, i], pen=pen(ORANGE, dash=True), name=f"varied, ε = {eps:.3g}"
        )
        shown = [q, q + eps * result.eta[:, i]]
        if self.boundary is not None:
            self._draw_boundary(plot, i)
            shown.append(self.boundary.action_path.q[:, i])
        values = np.concatenate(shown)
        headroom(plot, float(np.nanmin(values)), float(np.nanmax(values)), 0.1)
        if not self._b_edited and len(t):  # A and B follow the true path until edited
            n = self.compiled.n
            self.point_a.setText(", ".join(f"{v:.6g}" for v in result.run.y[0, :n]))
            self.point_b.setText(", ".join(f"{v:.6g}" for v in result.run.y[-1, :n]))
            self.boundary_time.setValue(float(t[-1] - t[0]))

    # -- the two-point problem --------------------------------------------------------------

    def _on_point_b_edited(self, _text: str) -> None:
        self._b_edited = True

    def _on_solve_clicked(self) -> None:
        if self.compiled is None:
            return
        n = self.compiled.n
        try:
            qa = _parse(self.point_a.text(), n)
            qb = _parse(self.point_b.text(), n)
        except ValueError as exc:
            self.boundary_note.setText(f"A and B: {exc}")
            return
        generation = self.generation
        self.boundary_note.setText("Solving the two-point problem…")
        self.runner.submit(
            self.key + ".two_point",
            jobs.two_point,
            self.compiled,
            qa,
            qb,
            self.boundary_time.value(),
            self.result.run.t[0] if self.result is not None else 0.0,
            on_done=lambda result: self._on_two_point_done(result, generation),
            on_failed=lambda message: self.boundary_note.setText(f"Two-point problem: {message}"),
            what="the two-point problem",
        )

    def _on_two_point_done(self, result: jobs.TwoPointResult, generation: int) -> None:
        if generation != self.generation:
            return
        self.boundary = result
        path, shot = result.action_path, result.shooting_path
        text = (
            f"Stationary discrete action: S = {path.action:.8g} "
            f"({'converged' if path.converged else 'Newton did not converge'})."
        )
        if shot is not None:
            miss = float(np.max(np.abs(shot.q[-1] - path.q[-1])))
            on_nodes = np.column_stack(
                [np.interp(path.t, shot.t, shot.q[:, j]) for j in range(path.q.shape[1])]
            )
            difference = float(np.max(np.abs(on_nodes - path.q)))
            text += (
                f" Shooting: S = {shot.action:.8g} (ends {miss:.1e} from B). The paths "
                f"differ by {difference:.2g}: O(h²) with 201 nodes."
            )
        else:
            text += f" Shooting failed: {result.shooting_error}"
        if not self._b_edited:
            text += " A, B: the ends of the true path, so all three coincide."
        self.boundary_note.setText(text)
        self._draw_paths()

    def _draw_boundary(self, plot: pg.PlotItem, i: int) -> None:
        path, shot = self.boundary.action_path, self.boundary.shooting_path
        plot.plot(path.t, path.q[:, i], pen=pen(GREEN, 2.5), name="A → B: stationary action")
        if shot is not None:
            plot.plot(shot.t, shot.q[:, i], pen=pen(PURPLE, 1.5, dash=True), name="A → B: shooting")
