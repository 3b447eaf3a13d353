"""What the API returns: frozen dataclasses of numpy arrays and sympy expressions, each
with a picture (``plot()`` -> ``Figure``) where one helps."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import sympy

from phase_explorer import figures


@dataclass(frozen=True)
class Derivation:
    """The derived equations of a system, as sympy objects.

    Attributes
    ----------
    title : str
    coordinates : tuple of str
    lagrangian, hamiltonian : sympy.Expr or None
        L(q, qdot, t) and H(q, p, t) (None where the scene gives only the other).
    momenta : dict of str to sympy.Expr
        ``p_<q>`` = dL/dqdot, in (q, qdot, t).
    lagrange_equations : tuple of sympy.Eq, shape (n,)
        Lagrange's equations as M(q) qddot = F(q, qdot, t), row by row (``<q>_ddot``
        symbols), effects included.
    hamilton_equations : tuple of sympy.Eq, shape (2n,)
        ``<q>_dot`` = dH/dp and ``p_<q>_dot`` = -dH/dq + Q, in (q, p, t).
    cyclic : tuple of str
        The cyclic coordinates.
    conserved : dict of str to sympy.Expr
        ``"H"``, conserved momenta and Noether charges.
    classification : dict
        The textbook's classification (``derive --json``'s ``classification``).
    latex_names : dict of str to str
        Each symbol's LaTeX (``theta_dot`` -> ``\\dot{\\theta}``).
    mechanics : systems.mechanics.Mechanics
        Everything the derivation found (see ``docs/internals.md``).
    """

    title: str
    coordinates: tuple[str, ...]
    lagrangian: sympy.Expr | None
    hamiltonian: sympy.Expr | None
    momenta: dict[str, sympy.Expr]
    lagrange_equations: tuple[sympy.Eq, ...]
    hamilton_equations: tuple[sympy.Eq, ...]
    cyclic: tuple[str, ...]
    conserved: dict[str, sympy.Expr]
    classification: dict
    latex_names: dict[str, str] = field(repr=False)
    mechanics: object = field(repr=False)

    def latex(self, expr: sympy.Basic) -> str:
        """The LaTeX of one expression or equation, with the scene's names."""
        known = self.latex_names
        names = {s: known[s.name] for s in expr.free_symbols if s.name in known}
        return sympy.latex(expr, symbol_names=names)

    def latex_lines(self) -> list[str]:
        """The derivation as LaTeX lines, ``lhs &= rhs`` (for an ``aligned`` block)."""
        rows = []
        if self.lagrangian is not None:
            rows.append(f"L &= {self.latex(self.lagrangian)}")
        if self.hamiltonian is not None:
            rows.append(f"H &= {self.latex(self.hamiltonian)}")
        for eq in (*self.lagrange_equations, *self.hamilton_equations):
            rows.append(f"{self.latex(eq.lhs)} &= {self.latex(eq.rhs)}")
        return rows

    def _repr_latex_(self) -> str:
        return "$$\\begin{aligned}" + " \\\\ ".join(self.latex_lines()) + "\\end{aligned}$$"


@dataclass(frozen=True)
class Trajectory:
    """States at evenly spaced times, as ``run`` writes them.

    Attributes
    ----------
    t : ndarray, shape (k,)
    y : ndarray, shape (k, 2n)
        Canonical states (q_1..q_n, p_1..p_n).
    qdot : ndarray, shape (k, n)
    H : ndarray, shape (k,)
    columns : tuple of str
        ``t``, the coordinates, their ``_dot`` velocities, the ``p_`` momenta, ``H``:
        the names ``self[name]`` takes (the columns of ``run --out``).
    method, why : str
        The method and why it was chosen.
    status, message : str
        ``"ok"``, or how the run ended (``"energy_error"``, ``"inaccurate"``, ...).
    steps : int
    max_rel_energy_error : float or None
        Where H is conserved.
    """

    t: np.ndarray
    y: np.ndarray
    qdot: np.ndarray
    H: np.ndarray
    columns: tuple[str, ...]
    method: str
    why: str
    status: str
    message: str
    steps: int
    max_rel_energy_error: float | None
    title: str = ""

    @property
    def n(self) -> int:
        """The number of coordinates."""
        return self.qdot.shape[1]

    @property
    def q(self) -> np.ndarray:
        """(k, n) coordinates."""
        return self.y[:, : self.n]

    @property
    def p(self) -> np.ndarray:
        """(k, n) momenta."""
        return self.y[:, self.n :]

    def table(self) -> np.ndarray:
        """(k, len(columns)): t, q, qdot, p, H side by side."""
        return np.column_stack([self.t, self.q, self.qdot, self.p, self.H])

    def __getitem__(self, name: str) -> np.ndarray:
        """The column ``name`` (k,), e.g. ``trajectory["theta"]``."""
        if name not in self.columns:
            raise KeyError(f"no column {name!r}; the columns are {', '.join(self.columns)}")
        return self.table()[:, self.columns.index(name)]

    def plot(self, *names: str) -> figures.Figure:
        """The columns ``names`` (default: the coordinates) against t."""
        names = names or self.columns[1 : 1 + self.n]
        return figures.lines(
            self.t, {name: self[name] for name in names}, xlabel="t", title=self.title
        )


@dataclass(frozen=True)
class Section:
    """Crossings of a Poincaré section (or a stroboscopic one, once per period of a
    periodic drive).

    Attributes
    ----------
    t : ndarray, shape (k,)
    y : ndarray, shape (k, 2n)
        The states at the crossings.
    orbit : ndarray of int, shape (k,)
        Which start each crossing belongs to (0, 1, ...).
    axes : tuple of str
        The two state variables the section is drawn in.
    kind : str
        ``"poincare"`` (q_j = value crossed with p_j > 0) or ``"stroboscopic"``.
    cut : str
        What was cut: ``"x = 0"``, or ``"t = 2.0944 k"``.
    energy : float or None
    status : tuple of str
        How each orbit's run ended: ``"ok"`` at ``t_end``, else the problem that stopped
        it early (``"energy_error"``, ``"unbounded"``, ...), as ``Trajectory.status``.
    """

    t: np.ndarray
    y: np.ndarray
    orbit: np.ndarray
    axes: tuple[str, str]
    names: tuple[str, ...]
    kind: str
    cut: str
    energy: float | None
    status: tuple[str, ...] = ()
    title: str = ""

    def points(self) -> np.ndarray:
        """(k, 2): the crossings in the section's ``axes``."""
        i, j = (self.names.index(name) for name in self.axes)
        return self.y[:, [i, j]]

    def plot(self) -> figures.Figure:
        """The crossings as dots in the section's axes."""
        xy = self.points()
        return figures.points(
            xy[:, 0], xy[:, 1], labels=self.axes, size=2.0,
            title=f"{self.title}: {self.kind} section {self.cut}",
        )  # fmt: skip


@dataclass(frozen=True)
class Lyapunov:
    """The Lyapunov spectrum and the fast indicators of one orbit (``lyapunov``).

    Attributes
    ----------
    exponents : ndarray, shape (k,)
        Largest first.
    max : float
    megno : float
        MEGNO's mean <Y>: 2 quasi-periodic, 0 periodic (isochronous), ~ max t / 2 chaotic.
    verdict : str
        ``"periodic"``, ``"regular"``, ``"chaotic"`` or ``"undecided"``.
    sali, gali : float
    t_end : float
        The time reached.
    status, message : str
    energy_error : float or None
    history : dict of str to ndarray
        The running estimates (``"t"`` (h,), ``"exponents"`` (h, k), ``"megno"`` (h,) ...).
    report : dict
        ``lyapunov --json``'s object.
    """

    exponents: np.ndarray
    max: float
    megno: float
    verdict: str
    sali: float
    gali: float
    t_end: float
    status: str
    message: str
    energy_error: float | None
    history: dict = field(repr=False)
    report: dict = field(repr=False)

    def plot(self) -> figures.Figure:
        """The running estimates against t: the maximal exponent, MEGNO's <Y> (a dashed
        line at 2, the regular value) and SALI."""
        h = self.history
        figure = figures.new_figure((7.0, 6.0))
        rows = figure.subplots(3, 1, sharex=True)
        rows[0].plot(h["t"], h["maximal"], linewidth=1.0)
        rows[0].set_ylabel("max exponent")
        rows[0].set_title(
            f"max {self.max:.4g}, <Y> {self.megno:.4g} ({self.verdict}) by t = {self.t_end:g}",
            fontsize=10,
        )
        rows[1].plot(h["t"], h["megno"], linewidth=1.0)
        rows[1].axhline(2.0, linestyle="--", linewidth=0.8, color="grey")
        rows[1].set_ylabel("MEGNO <Y>")
        sali = np.where(np.asarray(h["sali"]) > 0, h["sali"], np.nan)
        rows[2].plot(h["t"], sali, linewidth=1.0)
        rows[2].set_yscale("log")
        rows[2].set_ylabel("SALI")
        rows[2].set_xlabel("t")
        for axes in rows:
            axes.set_xscale("log")
            axes.grid(alpha=0.2)
        return figures.Figure(figure)


@dataclass(frozen=True)
class ChaosMap:
    """A chaos map: an indicator over a grid of starts.

    Attributes
    ----------
    xs, ys : ndarray, shape (nx,), (ny,)
    axes : tuple of str
        The grid's state variables (x first).
    megno, lyapunov : ndarray, shape (ny, nx)
        MEGNO's <Y> and the maximal exponent's estimate ln|delta(t)|/t; NaN where no
        state is or the orbit stopped.
    status : ndarray of int, shape (ny, nx)
        -1 no state, 0 reached the end, else the code that stopped the orbit.
    indicator : str
        The indicator ``chaotic_fraction`` and ``plot`` use by default.
    chaotic_fraction, threshold : float
        Of the orbits that reached the end, the fraction above the threshold.
    energy : float or None
        The section's energy.
    method, dt, t_end
    """

    xs: np.ndarray
    ys: np.ndarray
    axes: tuple[str, str]
    megno: np.ndarray
    lyapunov: np.ndarray
    status: np.ndarray
    indicator: str
    chaotic_fraction: float
    threshold: float
    energy: float | None
    method: str
    dt: float
    t_end: float
    starts: np.ndarray = field(repr=False)
    title: str = ""

    def values(self) -> np.ndarray:
        """(ny, nx) of the map's indicator."""
        return self.megno if self.indicator == "megno" else self.lyapunov

    def plot(self) -> figures.Figure:
        """The map: viridis over [0, 2 x threshold] for MEGNO, up to the 99th percentile
        for the exponent; grey where there is no value."""
        values = self.values()
        if self.indicator == "megno":
            levels = (0.0, 2 * self.threshold)
        else:
            finite = values[np.isfinite(values)]
            levels = (0.0, float(np.quantile(finite, 0.99)) if finite.size else 1.0)
        label = "MEGNO <Y>" if self.indicator == "megno" else "maximal exponent"
        where = "" if self.energy is None else f", section at E = {self.energy:.4g}"
        return figures.image(
            values, self.xs, self.ys, labels=self.axes, colour_label=label, levels=levels,
            title=f"{self.title}: {label} to t = {self.t_end:g}{where}",
        )  # fmt: skip


@dataclass(frozen=True)
class OrbitDiagram:
    """An orbit (bifurcation) diagram: the state once per period of the drive.

    Attributes
    ----------
    parameter : str
    values : ndarray, shape (N,)
    samples : ndarray, shape (N, K, 2n)
        The state after each of K periods past the transient; NaN past a stop.
    variable : str
        The state variable ``points`` and ``plot`` show.
    periods : ndarray of int, shape (N,)
        Each value's period in periods of the drive (0: none within K/2).
    status : ndarray of int, shape (N,)
    drive_period : float or None
    names : tuple of str
        The state variables, in the order of ``samples``' last axis.
    """

    parameter: str
    values: np.ndarray
    samples: np.ndarray
    variable: str
    periods: np.ndarray
    status: np.ndarray
    drive_period: float | None
    names: tuple[str, ...]
    method: str
    transient_periods: int
    wrap: bool = False
    title: str = ""

    def points(self) -> tuple[np.ndarray, np.ndarray]:
        """(x (N K,), y (N K,)): each sample of ``variable`` beside its parameter value
        (an angle wrapped to (-pi, pi]); NaN samples left out."""
        column = self.samples[:, :, self.names.index(self.variable)]
        if self.wrap:
            column = np.pi - np.mod(np.pi - column, 2 * math.pi)
        x = np.repeat(self.values, column.shape[1])
        y = column.ravel()
        keep = np.isfinite(y)
        return x[keep], y[keep]

    def plot(self) -> figures.Figure:
        """The diagram: ``variable`` once per period against the parameter."""
        x, y = self.points()
        return figures.points(
            x, y, labels=(self.parameter, self.variable), size=0.5,
            title=f"{self.title}: {self.variable} once per period of the drive",
        )  # fmt: skip
