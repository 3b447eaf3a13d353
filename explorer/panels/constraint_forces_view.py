"""Constraint-forces view: the multipliers or reaction forces over time, their virtual
work (zero: D'Alembert) and their power and work, with a one-line caption.

What is drawn comes from ``systems.constraint_forces`` on the main orbit's new rows:

- *forces*: each multiplier lambda_k of ``[constraints]``, named by what it belongs to
  (``λ₁ (holonomic)``, ``λ₁ (nonholonomic)``, ``λ₁ (y ≥ 0)`` for a unilateral
  constraint: non-zero only in contact), and the size |R_i| of the reaction force on each
  particle of ``[particles]`` (where it can be computed);
- *virtual work* (log scale): the largest relative virtual work of the constraint forces
  over the displacements tangent to the acting constraints, at round-off where
  D'Alembert's principle holds;
- *power and work*: the actual power P of the constraint forces and their work W so far
  (``WorkIntegral``), zero for fixed constraints and not for moving ones.

Impacts on unilateral constraints are velocity jumps, not forces lambda: nothing is drawn
for them, the caption says which contacts act at the last row and what the impacts
changed of the energy (E - E0 - W, never presented as a balance that holds).

``set_system`` rebuilds the view for a new system; the sympy part (the derivatives of
the positions, lambdified) is made in a worker process (``systems.processes``) the first
time a system is seen, and the view shows it when it arrives, or the reason nothing is
computed; the worker is ended when another system comes or the window closes. The
analysis is remembered per derivation (``constraint_forces.remember``), so a reset or a
parameter change needs no new one. ``refresh(store)`` (the window's redraw timer) takes
the main orbit's rows after the last one seen (O(new rows) a frame); curves against time
are ``EnvelopeCurve``s in a ``PacedLayoutWidget``, as in the conserved-quantities view.

``attach(window)`` puts the view in a dock tabbed with the conserved quantities, offered
(its tab shown) only for a scene with constraint forces: explicit constraints, or
particles with fewer coordinates than Cartesian components.
"""

from __future__ import annotations

import html
import math
import time

import numpy as np
import pyqtgraph as pg
from PySide6.QtCore import QObject, Qt, QTimer, Signal
from PySide6.QtWidgets import QLabel, QSizePolicy, QStackedWidget, QVBoxLayout, QWidget

from explorer.buffers import GrowingArray
from explorer.panels.curves import (
    EnvelopeCurve,
    PacedLayoutWidget,
    RangeKeeper,
    add_outside_legend,
    set_title,
    style_plot,
)
from explorer.panels.lazy_menu import add_plot
from explorer.panels.log_axis import SparseLogAxis
from explorer.panels.offered_dock import OfferedDockLink, attach_hidden
from explorer.trajectories import is_gap
from systems import constraint_forces as cf
from systems import processes

DOCK_KEY = "constraints"
FLOOR = 1e-17
"""Virtual work below this (exact zeros) is drawn at it on the log scale."""
ROUND_OFF = 1e-10
"""A relative power or virtual work below this is round-off: zero."""
REPAINT_GAP_SECONDS = 0.1
TIME_MARGIN = 0.2
DRAW_GAP_SECONDS = 0.2
"""Curves are handed their new rows at most this often (what is left waits on a timer):
at full speed a frame's rows cost more to hand to pyqtgraph than to compute."""
"""Room ahead on the time axes, a fraction of the span: each growth redraws every curve."""
COLOURS = ("#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#17becf", "#e377c2")
MAX_FORCE_CURVES = 7
"""Curves of the force plot, at most (one per colour): the Atwood rope's rope, four stops and
two reactions."""
CPU_SECONDS = 60.0
"""CPU seconds the analysis may take in its worker before it is stopped and said so."""


class _Series:
    """(t, value) rows with the non-finite ones left out, appended in blocks."""

    def __init__(self):
        self.rows = GrowingArray((2,))

    def extend(self, t: np.ndarray, values: np.ndarray) -> None:
        keep = np.isfinite(t) & np.isfinite(values)
        if keep.any():
            self.rows.extend(np.stack([t[keep], values[keep]], axis=1))

    def columns(self) -> tuple[np.ndarray, np.ndarray]:
        data = self.rows.data
        return data[:, 0], data[:, 1]


class _Relay(QObject):
    """Carries an analysis from the thread that waits for its worker to the GUI thread
    (queued). It has no parent and that thread holds it, so it is alive whenever the
    thread emits."""

    delivered = Signal(int, object, bool)  # generation, analysis, made by the worker


def _failed(exc: BaseException) -> cf.ConstraintForces:
    """What the view shows when the analysis raised (or its worker failed)."""
    return cf.ConstraintForces(
        applies=True, note=f"the constraint forces could not be formed: {exc}"
    )


def _number(value: float) -> str:
    if not math.isfinite(value):
        return "—"
    return f"{value:.2g}" if abs(value) < 1e-3 and value != 0 else f"{value:.4g}"


class ConstraintForcesView(QWidget):
    """The constraint forces of the main orbit (see the module)."""

    analysed = Signal(object)

    def __init__(self, parent: QWidget | None = None):
        super().__init__(parent)
        self.compiled = None
        self.analysis: cf.ConstraintForces | None = None
        self._generation = 0
        self._closed = False
        self._job: processes.Job | None = None
        self._relay = _Relay()
        self._relay.delivered.connect(self._on_relay_delivered, Qt.ConnectionType.QueuedConnection)
        self._store = None
        self._key = None
        self._seen_t = -math.inf
        self._force_series: list[_Series] = []
        self._force_curves: list[EnvelopeCurve] = []
        self._virtual = _Series()
        self._power = _Series()
        self._work_series = _Series()
        self._integral: cf.WorkIntegral | None = None
        self.largest_virtual_work = math.nan
        self.largest_relative_power = math.nan
        self.work = math.nan
        self.energy_change = math.nan
        self._energy0 = math.nan
        self.contacts: list[tuple[int, float]] | None = None
        self.link: ConstraintDockLink | None = None
        self._drawn_at = -math.inf
        self._draw_later = QTimer(self)
        self._draw_later.setSingleShot(True)
        self._draw_later.timeout.connect(self._on_draw_later_timeout)

        self.caption = QLabel("")
        self.caption.setTextFormat(Qt.TextFormat.RichText)
        self.caption.setSizePolicy(QSizePolicy.Policy.Ignored, QSizePolicy.Policy.Preferred)
        self.caption.setContentsMargins(4, 0, 4, 0)

        self.layout_widget = PacedLayoutWidget(gap=REPAINT_GAP_SECONDS)
        self.layout_widget.setBackground("w")
        ci = self.layout_widget.ci
        self.force_plot = add_plot(self.layout_widget, row=0, col=0)
        style_plot(self.force_plot)
        self.force_plot.setLabel("bottom", "t")
        self.force_legend = add_outside_legend(ci, row=0, col=1, columns=1, side="right")
        self.virtual_plot = add_plot(
            self.layout_widget, row=0, col=2, axisItems={"left": SparseLogAxis("left")}
        )
        style_plot(self.virtual_plot)
        self.virtual_plot.setLabel("bottom", "t")
        self.virtual_plot.setLogMode(y=True)
        set_title(self.virtual_plot, "Virtual work (relative)")
        self.power_plot = add_plot(self.layout_widget, row=0, col=3)
        style_plot(self.power_plot)
        self.power_plot.setLabel("bottom", "t")
        set_title(self.power_plot, "Power P and work W")
        self.power_legend = add_outside_legend(ci, row=0, col=4, columns=1, side="right")
        # not linked in x: a range grown in one plot redoes only its own curves; the
        # keepers fit all three to the same times anyway, with room ahead so that they
        # grow seldom at full speed
        self.force_range = RangeKeeper(self.force_plot, time_axis=True, time_margin=TIME_MARGIN)
        self.virtual_range = RangeKeeper(
            self.virtual_plot, log_y=True, time_axis=True, time_margin=TIME_MARGIN
        )
        self.power_range = RangeKeeper(self.power_plot, time_axis=True, time_margin=TIME_MARGIN)
        self.virtual_curve = EnvelopeCurve(
            self.virtual_plot, pg.mkPen("#444444", width=1.2), ranges=self.virtual_range
        )
        self.power_curve = EnvelopeCurve(
            self.power_plot, pg.mkPen("#d62728", width=1.2), ranges=self.power_range
        )
        self.work_curve = EnvelopeCurve(
            self.power_plot, pg.mkPen("#1f77b4", width=1.5), ranges=self.power_range
        )
        self.power_legend.addItem(self.power_curve.tail, "P")
        self.power_legend.addItem(self.work_curve.tail, "W")
        self.power_legend.updateSize()

        self.message = QLabel("")
        self.message.setWordWrap(True)
        self.message.setAlignment(Qt.AlignmentFlag.AlignCenter)
        self.message.setMargin(12)
        self.stack = QStackedWidget()
        self.stack.addWidget(self.layout_widget)
        self.stack.addWidget(self.message)
        layout = QVBoxLayout(self)
        layout.setContentsMargins(2, 2, 2, 2)
        layout.setSpacing(2)
        layout.addWidget(self.caption)
        layout.addWidget(self.stack, 1)
        self._show_message("No system yet.")

    # -- the system -----------------------------------------------------------------------

    def set_system(self, compiled) -> None:
        """Show a newly compiled system (a reset or new parameters count as new): the data
        start again; the analysis is made in a worker process unless this derivation has
        one."""
        self._end_job()
        self.compiled = compiled
        self.analysis = None
        self._generation += 1
        self._store = None
        self._clear()
        mechanics = compiled.mechanics
        reason = cf.presence(mechanics.scene)
        if reason is not None:
            self._offered(compiled)
            self._deliver(cf.ConstraintForces(applies=False, reason=reason))
            return
        self._offered(compiled)
        known = cf.known(mechanics)
        if known is not None:
            self._deliver(known)
            return
        self._show_message("Working out the constraint forces…")
        generation, relay = self._generation, self._relay

        def report(job: processes.Job) -> None:  # in the thread that waited for the worker
            made = False
            try:
                result, made = job.result(0), True
            except processes.Cancelled:  # another system came, or the window closed
                return
            except Exception as exc:  # noqa: BLE001 - shown in the view, never lost
                result = _failed(exc)
            try:
                relay.delivered.emit(generation, result, made)
            except RuntimeError:  # the relay's C++ side is gone: nobody is left to tell
                pass

        try:
            self._job = processes.submit(
                cf.analyse,
                mechanics,
                cpu_seconds=CPU_SECONDS,
                what="working out the constraint forces",
                on_done=report,
            )
        except Exception as exc:  # noqa: BLE001 - no worker: said in the view
            relay.delivered.emit(generation, _failed(exc), False)

    def _offered(self, compiled) -> None:
        if self.link is not None:
            self.link.system_set(compiled)

    def shutdown(self) -> None:
        """End any analysis still under way (the window is closing)."""
        self._closed = True
        self._generation += 1
        self._draw_later.stop()
        self._end_job()

    def _end_job(self) -> None:
        """End the worker of an analysis nobody waits for any more."""
        job, self._job = self._job, None
        if job is not None:
            job.cancel()

    def _on_relay_delivered(self, generation: int, analysis, made: bool) -> None:
        if self._closed or generation != self._generation:
            return  # a system replaced meanwhile
        if made:  # from a copy of this derivation: filed under the window's own
            cf.remember(self.compiled.mechanics, analysis)
        self._deliver(analysis)

    def _deliver(self, analysis: cf.ConstraintForces) -> None:
        self.analysis = analysis
        if not analysis.applies:
            self._show_message(f"No constraint forces in this system: {analysis.reason}.")
        elif not analysis.computes:
            self._show_message(f"Constraint forces not computed: {analysis.note}.")
        else:
            self._build(analysis)
        self.analysed.emit(analysis)
        if analysis.computes and self._store is not None:
            self.refresh(self._store)

    def _show_message(self, text: str) -> None:
        self.message.setText(text)
        self.caption.setText("")
        self.caption.setToolTip("")
        self.stack.setCurrentWidget(self.message)

    def _clear(self) -> None:
        """Forget every row seen (a new system, a reset, another main orbit)."""
        for curve in self._force_curves:
            curve.remove()
        self._force_curves = []
        self._force_series = []
        self.force_legend.clear()
        for curve in (self.virtual_curve, self.power_curve, self.work_curve):
            curve.reset()
        self._reset_data()

    def _reset_data(self) -> None:
        self._draw_later.stop()
        self._drawn_at = -math.inf
        for curve in [*self._force_curves, self.virtual_curve, self.power_curve, self.work_curve]:
            curve.reset()
        self._force_series = [_Series() for _ in self._force_curves]
        self._virtual, self._power, self._work_series = _Series(), _Series(), _Series()
        analysis = self.analysis
        self._integral = None
        if analysis is not None and analysis.computes and self.compiled is not None:
            self._integral = cf.WorkIntegral(analysis, self.compiled)
        self._seen_t = -math.inf
        self._key = None
        self.largest_virtual_work = math.nan
        self.largest_relative_power = math.nan
        self.work = math.nan
        self.energy_change = math.nan
        self._energy0 = math.nan
        self.contacts = None
        for keeper in (self.force_range, self.virtual_range, self.power_range):
            keeper.reset()

    def _build(self, analysis: cf.ConstraintForces) -> None:
        for curve in self._force_curves:
            curve.remove()
        self._force_curves = []
        self.force_legend.clear()
        names = [
            f"λ{_subscript(i + 1)} ({html.escape(what)})"
            for i, what in enumerate(analysis.descriptions)
        ]
        names += [f"|R<sub>{html.escape(p)}</sub>|" for p in analysis.particles]
        # a drawn point [x, y] of two coordinates: Q_c's components are its force
        names += [f"|R<sub>{html.escape(p)}</sub>|" for p, _, _ in analysis.points]
        for k, name in enumerate(names[:MAX_FORCE_CURVES]):
            pen = pg.mkPen(COLOURS[k % len(COLOURS)], width=1.3)
            curve = EnvelopeCurve(self.force_plot, pen, ranges=self.force_range)
            self._force_curves.append(curve)
            self.force_legend.addItem(curve.tail, name)
        self.force_legend.updateSize()
        what = []
        if analysis.k:
            what.append("multipliers λ")
        if analysis.particles or analysis.points:
            what.append(
                "reaction forces |R| on the " + ("particles" if analysis.particles else "points")
            )
        set_title(self.force_plot, "Constraint forces: " + " and ".join(what))
        self._reset_data()
        self.stack.setCurrentWidget(self.layout_widget)
        self._caption()

    # -- data -----------------------------------------------------------------------------

    def refresh(self, store) -> None:
        """Take the main orbit's rows after the last one seen from ``store`` and redraw."""
        self._store = store
        analysis, compiled = self.analysis, self.compiled
        main = store.main
        if analysis is None or not analysis.computes or main is None:
            return
        if main.y.data.shape[1] != 2 * compiled.n:
            return  # a trajectory of another system: the store is about to be replaced
        if main.key != self._key:  # another main orbit: start again
            self._reset_data()
            self._key = main.key
        t = main.t.data
        start = int(np.searchsorted(t, self._seen_t, side="right"))
        if start < len(t):
            self.update(t[start:], main.y.data[start:])

    def update(self, t: np.ndarray, Y: np.ndarray) -> None:
        """Add the main orbit's rows ``Y`` (k, 2n) at times ``t`` (k,), gap rows included."""
        analysis = self.analysis
        if analysis is None or not analysis.computes or self._integral is None or not len(t):
            return
        self._seen_t = float(t[-1])
        gap = is_gap(Y)
        energy = np.full(len(t), np.nan)
        good = np.flatnonzero(~gap)
        forces = None
        if len(good):
            forces = analysis.evaluate(self.compiled, t[good], Y[good])
            self._add_forces(t[good], forces)
            if forces.energy is not None:
                energy[good] = forces.energy
        work = self._integral.add(t, Y, energy if analysis.balance else None, forces)
        self._work_series.extend(t, work)
        self.work = self._integral.work  # NaN once a gap made it unknown
        if analysis.energy_name and len(good):
            if math.isnan(self._energy0):
                self._energy0 = float(energy[good[0]])
            self.energy_change = float(energy[good[-1]] - self._energy0)
        if analysis.impacts and forces is not None and forces.acting is not None:
            # the unilateral rows in contact at the last row, with their multipliers
            last = forces.acting[-1] & analysis.unilateral
            self.contacts = [
                (int(i), float(forces.multipliers[-1, i])) for i in np.flatnonzero(last)
            ]
        self._paced_draw()
        self._caption()

    def _paced_draw(self) -> None:
        wait = self._drawn_at + DRAW_GAP_SECONDS - time.perf_counter()
        if wait <= 0:
            self._draw()
        elif not self._draw_later.isActive():
            self._draw_later.start(max(1, math.ceil(1000 * wait)))

    def _on_draw_later_timeout(self) -> None:
        if self.analysis is not None and self.analysis.computes:
            self._draw()

    def _add_forces(self, t: np.ndarray, forces: cf.Forces) -> None:
        columns = []
        if forces.multipliers is not None:
            columns += list(forces.multipliers.T)
        if forces.reactions is not None:
            columns += list(np.linalg.norm(forces.reactions, axis=2).T)
        Q = forces.generalized
        columns += [np.hypot(Q[:, a], Q[:, b]) for _, a, b in self.analysis.points]
        for series, values in zip(self._force_series, columns, strict=False):
            series.extend(t, values)
        self._virtual.extend(t, np.maximum(forces.virtual_work, FLOOR))
        self._power.extend(t, forces.power)
        with np.errstate(all="ignore"):
            relative = np.abs(forces.power) / forces.power_scale
        relative = np.where(forces.power == 0, 0.0, relative)
        self.largest_virtual_work = np.fmax(
            self.largest_virtual_work, cf.largest(forces.virtual_work)
        )
        self.largest_relative_power = np.fmax(self.largest_relative_power, cf.largest(relative))

    def _draw(self) -> None:
        self._draw_later.stop()
        self._drawn_at = time.perf_counter()
        for curve, series in zip(self._force_curves, self._force_series, strict=True):
            curve.update(*series.columns())
        self.virtual_curve.update(*self._virtual.columns())
        self.power_curve.update(*self._power.columns())
        self.work_curve.update(*self._work_series.columns())

    def _caption(self) -> None:
        """The one line that says what the plots show, with the numbers so far."""
        analysis = self.analysis
        if analysis is None or not analysis.computes:
            return
        text, tip = caption(
            analysis,
            self.largest_virtual_work,
            self.largest_relative_power,
            self.work,
            self.energy_change,
            self._integral.gaps if self._integral is not None else 0,
            contacts=self.contacts,
            restitution=cf.restitution(self.compiled) if analysis.impacts else 1.0,
        )
        if self.caption.text() != text:
            self.caption.setText(text)
            self.caption.setToolTip(tip)

    def export_target(self) -> QWidget:
        """The widget that figure exports render (the plots with their legends)."""
        return self.layout_widget


def caption(
    analysis: cf.ConstraintForces,
    virtual_work: float,
    relative_power: float,
    work: float,
    energy_change: float,
    gaps: int = 0,
    contacts: list[tuple[int, float]] | None = None,
    restitution: float = 1.0,
) -> tuple[str, str]:
    """The caption's text (rich text, one line) and its tooltip.

    Parameters
    ----------
    virtual_work, relative_power : float
        The largest relative virtual work and |P| / scale seen (NaN: nothing yet).
    work, energy_change : float
        W so far (NaN: unknown) and E - E0 (NaN where no energy is formed).
    gaps : int
        Gaps in the rows that the work was carried across.
    contacts : list of (int, float), optional
        With unilateral constraints (``analysis.impacts``): the index and multiplier of
        each one in contact at the last row (empty: free); None before the first row.
    restitution : float
        Newton's coefficient e of the impacts (``constraint_forces.restitution``).
    """
    if math.isnan(virtual_work):
        return "Waiting for the first states…", ""
    parts = []
    if virtual_work <= ROUND_OFF:
        parts.append(
            f"virtual work of the constraint forces: {virtual_work:.1g} (zero: D'Alembert)"
        )
    else:
        parts.append(f"virtual work of the constraint forces: {virtual_work:.3g} (NOT zero)")
    if not analysis.rheonomic:
        if relative_power <= ROUND_OFF:
            parts.append(f"power: zero, scleronomic ({relative_power:.1g} of |F||v|)")
        else:
            parts.append(f"power: {relative_power:.3g} of |F||v| although scleronomic")
    else:
        line = "power ≠ 0: the constraint moves (rheonomic); work so far W = "
        if math.isfinite(work):
            line += _number(work)
        elif analysis.impacts:  # the quintic between two rows cannot follow a jump
            line += "unknown (from an impact on, or rows left out at full speed)"
        else:
            line += "unknown (rows left out at full speed)"
        if analysis.balance and math.isfinite(energy_change):
            name = "E" if analysis.energy_name == "T + V" else "h"
            line += f", {name} − {name}₀ = {_number(energy_change)}"
        parts.append(line)
    if analysis.impacts:
        parts += _impact_parts(analysis, work, energy_change, contacts)
    text = " · ".join(html.escape(p, quote=False) for p in parts)
    tips = [
        "Virtual work: the largest |Σ F·δr| over the displacements δq tangent to the "
        "acting constraints (A δq = 0: a·δq = 0 for a nonholonomic one, a unilateral one "
        "only in contact), relative to the size of the forces; round-off where "
        "D'Alembert's principle holds.",
        "Power: the actual power of the constraint forces, P = Σ F·v (= λᵀ c, c the "
        "velocity-free part of each row: Φ_t, b or g_t); it vanishes for constraints fixed "
        "in time and not for moving ones. W is P integrated along the motion (between the "
        "rows the window keeps, over the quintic through their q, q̇ and q̈).",
    ]
    if analysis.impacts:
        tips.append(_impact_tip(analysis, restitution))
    if analysis.balance:
        if analysis.energy_name == "T + V":
            energy, balance = "the energy E = T + V", "E(t) − E(0)"
        else:
            energy, balance = "Jacobi's energy function h", "h(t) − h(0)"
        tips.append(f"Nothing but the constraint forces changes {energy} here: W = {balance}.")
        if gaps:
            tips.append(
                f"Across the {gaps} gap(s) where rows were left out or lie too far apart "
                "to follow the motion (full speed), W takes that change."
            )
    elif gaps:
        tips.append(
            "Rows were left out or lie too far apart to follow the motion (full speed): "
            "the work from there on is not known."
        )
    if analysis.note:
        text += " · <i>some forces not computed (see tooltip)</i>"
        tips.append(f"Not computed: {analysis.note}.")
    return text, "\n".join(tips)


def _impact_parts(
    analysis: cf.ConstraintForces,
    work: float,
    energy_change: float,
    contacts: list[tuple[int, float]] | None,
) -> list[str]:
    """The caption's parts on unilateral constraints: the contacts at the last row and
    what the impacts changed of the energy."""
    parts = []
    if contacts is not None:
        if contacts:
            parts.append(
                "in contact: "
                + ", ".join(
                    f"{analysis.descriptions[i]} (λ{_digits(i + 1)} = {_number(lam)})"
                    for i, lam in contacts
                )
            )
        else:
            parts.append("no contact (free)")
    line = "impacts: velocity jumps, not forces λ"
    if analysis.energy_name and math.isfinite(energy_change) and math.isfinite(work):
        name = "E" if analysis.energy_name == "T + V" else "h"
        line += f"; {name} − {name}₀ − W = {_number(energy_change - work)}"
    parts.append(line)
    return parts


def _impact_tip(analysis: cf.ConstraintForces, e: float) -> str:
    """The tooltip's paragraph on impacts (e: the coefficient of restitution)."""
    name = "E − E₀" if analysis.energy_name == "T + V" else "h − h₀"
    tip = (
        f"Impacts on the unilateral constraints are velocity jumps (Newton's law, e = {e:g}),"
        " not forces: an impulse has no finite value at any time, so none is drawn. λ of a "
        "unilateral constraint is the force of a resting contact (λ ≤ 0 pushes: the force "
        "on the coordinates is −Gᵀλ), 0 while free. W is the work of the forces λ only, and "
        f"the balance {name} = W does not hold across impacts: off a fixed wall each one "
        "takes a fraction 1 − e² of the kinetic energy of the normal motion (all of it when "
        "a rebound too slow to leave becomes a resting contact)."
    )
    if analysis.energy_name:
        tip += (
            f" {name} − W is what the impacts changed (with the run's own error): reported, "
            "not a check."
        )
        if e == 1 and not analysis.rheonomic:
            tip += " With e = 1 and walls fixed in time they keep the energy: it stays near 0."
    return tip


def _digits(k: int) -> str:
    return str(k).translate(str.maketrans("0123456789", "₀₁₂₃₄₅₆₇₈₉"))


def _subscript(k: int) -> str:
    return f"<sub>{k}</sub>"


class ConstraintDockLink(OfferedDockLink):
    """Offers the view's dock for scenes with constraint forces: the dock's tab is shown
    for a new such scene and hidden for one without (View > Constraint forces)."""

    def __init__(self, window, view: ConstraintForcesView, dock):
        self._scene_key = None
        super().__init__(
            window,
            view,
            dock,
            "The constraint forces, their virtual work and their power",
            "No constraint forces in this system: {why}",
        )

    def system_set(self, compiled) -> None:
        scene = compiled.mechanics.scene
        reason = cf.presence(scene)
        key = (scene.name, scene.source, tuple(scene.coordinates), reason is None)
        fresh = key != self._scene_key
        self._scene_key = key
        self._offer(reason is None, reason or "")
        self.wanted = reason is None
        if fresh:
            if reason is None:
                self.dock.show()
            else:
                self.dock.hide()


def attach(window, key: str = DOCK_KEY) -> ConstraintForcesView:
    """Add the view to ``window`` (a ``MainWindow``) in a dock tabbed with the conserved
    quantities, hidden until a scene with constraint forces opens; returns the view.

    The window calls ``view.set_system(compiled)`` whenever it starts a system.
    """
    return attach_hidden(
        window, key, "Constraint forces", ConstraintForcesView(), ConstraintDockLink
    )
