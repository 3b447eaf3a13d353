"""Equilibria by virtual work: a table, and markers in the phase view."""

from __future__ import annotations

import math

import numpy as np
import pyqtgraph as pg
from PySide6.QtCore import Signal
from PySide6.QtWidgets import (
    QAbstractItemView,
    QHeaderView,
    QTableWidget,
    QTableWidgetItem,
    QVBoxLayout,
    QWidget,
)

from explorer.inline_math import LATEX_ROLE, MathDelegate
from explorer.textbook.base import TextbookTabView
from explorer.textbook.plots import GREEN, RED, note_label
from systems.display import pretty_name
from systems.textbook import jobs

KIND_TEXT = {
    "minimum": "stable (minimum of U)",
    "saddle": "unstable (saddle of U)",
    "maximum": "unstable (maximum of U)",
    "degenerate": "undecided (degenerate)",
    "continuum": "a set of equilibria",
}


def kind_text(equilibrium) -> str:
    """Stable or not, and what U does there: ``"stable (minimum of U)"``,
    ``"stable (gyroscopic; maximum of U)"``, ``"stable (degenerate minimum, order 4)"``,
    ``"stable set: the circle x² + y² = 1, neutral along it"``."""
    e = equilibrium
    verdict = "stable" if e.stable else "unstable"
    if e.kind == "continuum" and e.continuum is not None:
        return f"{verdict} set: {e.continuum.description}, neutral along it"
    if e.kind == "degenerate":
        order = f", order {e.order}" if e.order else ""
        if e.stable:
            return f"stable (degenerate minimum{order})"
        if e.verdict == "undecided":
            return "undecided (degenerate)"
        return f"unstable (degenerate{order})"
    where = " on the constraints" if e.multipliers else ""
    if e.kind in ("saddle", "maximum") and e.stable:
        return f"stable (gyroscopic; {e.kind} of U{where})"
    text = KIND_TEXT.get(e.kind, e.kind)
    return text.replace(" of U)", f" of U{where})")


def _number(value: float) -> str:
    if abs(value - math.pi) < 1e-9:
        return "π"
    if abs(value + math.pi) < 1e-9:
        return "−π"
    text = f"{value:.6g}"
    return "0" if text in ("0", "-0") else text.replace("-", "−")


def _gyroscopic(equilibrium) -> bool:
    G = np.asarray(equilibrium.gyroscopic)
    return G.size > 0 and bool(np.any(G != 0))


def frequency_text(equilibrium) -> str:
    """ω of every normal mode (stable), or the growth rates of the unstable directions."""
    if equilibrium.stable:
        parts = []
        for i, w in enumerate(equilibrium.frequencies):
            label = f"ω{_subscript(i)}" if len(equilibrium.frequencies) > 1 else "ω"
            extra = f"  (ω² = {w * w:.6g}, period {2 * math.pi / w:.5g})" if w > 0 else ""
            parts.append(f"{label} = {w:.6g}{extra}")
        if not parts:
            return "— (no linear oscillation)" if equilibrium.kind == "degenerate" else "—"
        text = ";  ".join(parts)
        if equilibrium.kind == "continuum":
            text += "  across the set"
        if _gyroscopic(equilibrium):
            text += "  (with the gyroscopic terms)"
        return text
    rates = equilibrium.growth_rates
    if not rates:
        return "—"
    text = "unstable: grows at rate " + ", ".join(f"λ = {r:.4g}" for r in rates)
    if not _gyroscopic(equilibrium):
        others = [math.sqrt(w2) for w2 in equilibrium.omega_squared if w2 > 0]
        if others:
            text += ";  oscillates along the other mode at " + ", ".join(
                f"ω = {w:.4g}" for w in others
            )
    return text


def force_text(equilibrium) -> str:
    """The multipliers that hold the equilibrium, ``"λ₁ = 4.905"``, a contact marked
    ``"λ₂ = −9.81 (contact)"``; "" without constraints."""
    parts = []
    for name, value in equilibrium.multipliers.items():
        label = "λ" + name.rsplit("_", 1)[-1].translate(str.maketrans("0123456789", "₀₁₂₃₄₅₆₇₈₉"))
        contact = " (contact)" if name in equilibrium.contacts else ""
        parts.append(f"{label} = {_number(value)}{contact}")
    return ",  ".join(parts)


def _subscript(i: int) -> str:
    return str(i + 1).translate(str.maketrans("0123456789", "₀₁₂₃₄₅₆₇₈₉"))


def _amplitude(x: complex) -> str:
    """A mode-shape entry: ``+0.5``, ``−0.3i`` or ``+0.2+0.1i``."""
    x = complex(x)
    re = 0.0 if abs(x.real) < 5e-4 else x.real
    im = 0.0 if abs(x.imag) < 5e-4 else x.imag
    if im == 0.0:
        text = f"{re:+.3g}"
    elif re == 0.0:
        text = f"{im:+.3g}i"
    else:
        text = f"{re:+.3g}{im:+.3g}i"
    return text.replace("-", "−")


def mode_text(equilibrium, names: tuple[str, ...]) -> str:
    """Each normal mode as the relative amplitudes of the coordinates (complex with
    gyroscopic terms: a factor i is a quarter period behind)."""
    modes = np.asarray(equilibrium.modes)
    if modes.ndim != 2 or modes.shape[0] < 2:
        return "—"
    parts = []
    for j in range(modes.shape[1]):
        v = modes[:, j]
        big = v[np.argmax(np.abs(v))]
        if abs(big) == 0:
            continue
        v = v / (abs(big) if np.isrealobj(v) else big)
        if np.isrealobj(v) and v[np.argmax(np.abs(v))] < 0:
            v = -v
        parts.append("(" + ", ".join(_amplitude(x) for x in v) + ")")
    return "  ".join(parts) or "—"


class EquilibriaView(TextbookTabView):
    """The equilibria of the current system (computed even while hidden, for the markers).

    Signals
    -------
    equilibria_found(object)
        A ``jobs.EquilibriaResult``; None when a new system is being searched.
    """

    title = "Equilibria"
    equilibria_found = Signal(object)

    def __init__(self, runner, parent: QWidget | None = None):
        super().__init__(runner, parent)
        self.result: jobs.EquilibriaResult | None = None
        self.status = note_label("Open a system to find where it can rest.")
        self.table = QTableWidget(0, 0)
        self.table.setEditTriggers(QAbstractItemView.EditTrigger.NoEditTriggers)
        self.table.setSelectionBehavior(QAbstractItemView.SelectionBehavior.SelectRows)
        self.table.verticalHeader().setVisible(False)
        self.table.setAlternatingRowColors(True)
        self.table.setItemDelegate(MathDelegate(self.table))  # formulas set in type
        layout = QVBoxLayout(self)
        layout.setContentsMargins(4, 4, 4, 4)
        layout.addWidget(self.status)
        layout.addWidget(self.table, 1)

    def set_system(self, compiled) -> None:
        super().set_system(compiled)
        self.refresh()  # the phase view's markers need the equilibria even if hidden

    def _clear(self) -> None:
        self.result = None
        self.table.setRowCount(0)
        self.status.setText("Searching for equilibria: dU/dq = 0 (virtual work)…")
        self.equilibria_found.emit(None)

    def _start(self) -> None:
        generation = self.generation
        self.runner.submit(
            self.key,
            jobs.equilibria,
            self.compiled,
            on_done=lambda result: self._on_search_done(result, generation),
            on_failed=self._on_search_failed,
            what="the equilibrium search",
        )

    def _on_search_failed(self, message: str) -> None:
        self.status.setText(f"The search failed: {message}")

    def _on_search_done(self, result: jobs.EquilibriaResult, generation: int) -> None:
        if generation != self.generation:
            return
        self.result = result
        search = result.search
        self._fill(result)
        found = len(search.equilibria)
        how = {
            "symbolic": "solved exactly by sympy",
            "symbolic+numeric": "solved by sympy, completed by a numeric scan",
            "numeric": "found by a numeric scan of the view",
        }.get(search.method, "")
        lines = []
        sets = sum(1 for e in search.equilibria if e.continuum is not None)
        if found:
            points = found - sets
            count = f"{points} equilibri{'um' if points == 1 else 'a'}"
            if sets and points:
                count += f" and {sets} set{'s' if sets > 1 else ''} of them"
            elif sets:
                count = f"{sets} set{'s' if sets > 1 else ''} of equilibria"
            if any(_gyroscopic(e) for e in search.equilibria):
                small = "det(−ω² M + iω G + K) = 0, with the gyroscopic terms G of L"
            else:
                small = "K v = ω² M v"
            if search.multipliers:
                push = (
                    "; a contact must push, λ ≤ 0"
                    if any(e.contacts for e in search.equilibria)
                    else ""
                )
                lines.append(
                    f"<b>{count}</b> where the constraint force −Aᵀλ balances −∂U/∂q "
                    f"(∂U/∂q + Aᵀλ = 0 on the constraints; {how}){push}. Small "
                    f"oscillations solve {small} on the constraints' tangent space; where K "
                    "is singular, the terms of U beyond the quadratic ones decide."
                )
            else:
                lines.append(
                    f"<b>{count}</b> where the generalized forces −∂U/∂q vanish ({how}). "
                    f"Small oscillations solve {small}; where K is singular, the terms of U "
                    "beyond the quadratic ones decide."
                )
        else:
            lines.append("<b>No equilibria.</b>")
        if search.reason:
            text = search.reason
            for name in search.free:
                text = text.replace(f"depend on {name}", f"depend on {pretty_name(name)}")
            lines.append(f"<i>Note:</i> {text}.")
        self.status.setText(" ".join(lines))
        self.equilibria_found.emit(result)

    def _fill(self, result: jobs.EquilibriaResult) -> None:
        search, names = result.search, result.names
        shown = [name for name in names if name not in search.free] or list(names)
        exact = any(self._symbolic(e) for e in search.equilibria)
        headers = [pretty_name(name) for name in shown]
        if exact:
            headers.append("closed form (sympy)")
        headers += ["kind", "U (= H at rest)"]
        forces = bool(search.multipliers)
        if forces:
            headers.append("constraint force (multipliers)")
        headers.append("small oscillations")
        if len(names) > 1:
            headers.append("normal modes (" + ", ".join(pretty_name(n) for n in names) + ")")
        headers.append("decided by")
        self.table.clear()
        self.table.setColumnCount(len(headers))
        self.table.setHorizontalHeaderLabels(headers)
        self.table.setRowCount(len(search.equilibria))
        for row, e in enumerate(search.equilibria):
            cells = [_number(e.q[name]) for name in shown]
            latex: dict[int, str | None] = {}  # cells that are one formula: their LaTeX
            if exact:
                forms = [
                    f"{pretty_name(name)} = {self._closed_form(e.exact[name])}"
                    + (" (mod 2π)" if name in search.periodic else "")
                    for name in shown
                    if name in e.exact
                ]
                cells.append(",  ".join(forms) if self._symbolic(e) else "")
                latex[len(cells) - 1] = self._closed_form_latex(e, shown, search.periodic)
            kind_column = len(cells)
            cells += [kind_text(e), f"{e.potential:.6g}"]
            if forces:
                cells.append(force_text(e))
            cells.append(frequency_text(e))
            if len(names) > 1:
                cells.append(mode_text(e, names) if e.continuum is None else "—")
            cells.append(e.decided_by)
            for column, text in enumerate(cells):
                item = QTableWidgetItem(text)
                item.setToolTip(e.decided_by)
                if latex.get(column) and text:
                    item.setData(LATEX_ROLE, latex[column])
                if column == kind_column:
                    item.setForeground(pg.mkColor(GREEN if e.stable else RED))
                self.table.setItem(row, column, item)
        header = self.table.horizontalHeader()
        header.setSectionResizeMode(QHeaderView.ResizeMode.ResizeToContents)
        header.setStretchLastSection(True)

    def _parse(self, text: str):
        """A closed form read back through the whitelist parser (scene names only)."""
        from systems.expressions import parse_expression

        scene = self.compiled.mechanics.scene
        return parse_expression(text, scene.allowed("q", "params"))

    def _symbolic(self, equilibrium) -> bool:
        """Whether sympy's closed form involves the parameters (worth a column)."""
        from systems.expressions import ExpressionError

        for text in equilibrium.exact.values():
            try:
                if self._parse(text).free_symbols:
                    return True
            except ExpressionError:
                continue
        return False

    def _closed_form_latex(self, equilibrium, shown, periodic) -> str | None:
        """The closed forms of ``equilibrium`` as one LaTeX formula (None if one does
        not read back)."""
        from systems.display import latex_names
        from systems.expressions import ExpressionError
        from systems.typeset import expression_latex

        scene = self.compiled.mechanics.scene
        names = latex_names(scene)
        forms = []
        for name in shown:
            if name not in equilibrium.exact:
                continue
            try:
                body = expression_latex(self._parse(equilibrium.exact[name]), scene)
            except (ExpressionError, TypeError, ValueError, AttributeError):
                return None
            if body is None:
                return None
            mod = r"\ \ (\mathrm{mod}\ 2\pi)" if name in periodic else ""
            forms.append(f"{names.get(name, name)} = {body}{mod}")
        return r",\quad ".join(forms) or None

    def _closed_form(self, text: str) -> str:
        from systems.display import for_display
        from systems.expressions import ExpressionError
        from systems.report import one_line

        try:
            return one_line(for_display(self._parse(text), self.compiled.mechanics.scene))
        except (ExpressionError, TypeError, ValueError, AttributeError):
            return text

    def row_texts(self) -> list[list[str]]:
        """The table's cells (for tests and exports)."""
        return [
            [self.table.item(r, c).text() for c in range(self.table.columnCount())]
            for r in range(self.table.rowCount())
        ]


class EquilibriumMarkers:
    """Dots (stable) and crosses (unstable) at the equilibria in the phase view's plot."""

    def __init__(self, plot: pg.PlotItem):
        self.plot = plot
        self.item = pg.ScatterPlotItem(hoverable=True, tip=self._tip, pxMode=True)
        self.item.setZValue(20)
        plot.addItem(self.item, ignoreBounds=True)
        self.result: jobs.EquilibriaResult | None = None
        self.index = 0
        self.visible = True

    @staticmethod
    def _tip(x: float, y: float, data) -> str:
        return str(data)

    def show_result(self, result: jobs.EquilibriaResult | None) -> None:
        self.result = result
        self.update()

    def set_pair(self, index: int, visible: bool) -> None:
        """Show the coordinate pair ``index`` (q_i, p_i); hide in the Poincaré mode."""
        self.index = index
        self.visible = visible
        self.update()

    def spots(self) -> list[dict]:
        """The markers as pyqtgraph spot dictionaries (x, y, symbol, brush, pen, data)."""
        if self.result is None or not self.visible:
            return []
        search, names = self.result.search, self.result.names
        if self.index >= len(names):
            return []
        name = names[self.index]
        spots = []
        for e in search.equilibria:
            where = ", ".join(f"{pretty_name(k)} = {_number(v)}" for k, v in e.q.items())
            if e.continuum is not None:
                spots += self._set_spots(e, name, names.index(name), where)
                continue
            q = e.q.get(name, 0.0)
            p = e.p.get(f"p_{name}", 0.0)
            copies = [q]
            if name in search.periodic:
                copies += [q - 2 * math.pi, q + 2 * math.pi]
            tip = f"equilibrium {where}\n{kind_text(e)}\n{frequency_text(e)}"
            if e.stable and e.frequencies:
                tip += "\nperiods 2π/ω = " + ", ".join(
                    f"{2 * math.pi / w:.5g}" for w in e.frequencies if w > 0
                )
            tip += f"\nU = {e.potential:.6g}"
            for x in copies:
                if e.stable:
                    style = {"symbol": "o", "brush": pg.mkBrush(GREEN), "pen": pg.mkPen("w")}
                else:
                    style = {"symbol": "x", "brush": pg.mkBrush(RED), "pen": pg.mkPen(RED)}
                spots.append({"pos": (x, p), "size": 14, "data": tip, **style})
        return spots

    @staticmethod
    def _set_spots(e, name: str, index: int, where: str) -> list[dict]:
        """Small dots along a set of equilibria, projected on the pair (q_i, p_i)."""
        tip = f"{kind_text(e)}\nthrough {where}\n{frequency_text(e)}\nU = {e.potential:.6g}"
        color = GREEN if e.stable else RED
        spots = []
        for q, p in zip(e.continuum.points[:, index], e.continuum.momenta[:, index], strict=True):
            spots.append(
                {
                    "pos": (float(q), float(p)),
                    "size": 6,
                    "data": tip,
                    "symbol": "o",
                    "brush": pg.mkBrush(color),
                    "pen": pg.mkPen(color),
                }
            )
        return spots

    def update(self) -> None:
        self.item.setData(self.spots())

    def remove(self) -> None:
        self.plot.removeItem(self.item)
        self.item.deleteLater()
