"""What the panels draw: the trajectories of a run, filled block by block from the worker.

A ``Trajectory`` keeps buffers of time, canonical state and the optional diagnostics
(``H``, drawing ``points``); rows whose diagnostic was not computed (the panel that needs
it was hidden) hold NaN and are filled on demand by ``backfill_energy``.
``TrajectoryStore`` is the list of trajectories of the current system plus a dirty flag
per consumer, so the redraw timer only touches panels that have something new.

Bounded memory
--------------
A trajectory holds at most ``capacity`` rows (``DEFAULT_CAPACITY``), however long it
runs, in levels of resolution like an exponential histogram: level 0 holds the most recent
``capacity / 4`` samples whole; when a block would overflow the capacity, the oldest
samples of each level beyond its quota are thinned by two and moved up a level (level
``l`` keeps one run in ``2**l``; ``MAX_LEVEL`` levels cover thousands of capacities of
history, and beyond that the oldest runs are dropped). Thinning drops every other *run*
of ``THIN_RUN`` consecutive samples (a stretch between two gaps is never longer), never
every other sample: what stays is at full resolution, so closed orbits stay curves, never
chords across the orbit. The first row (the start) is always kept. So the recent past is
complete and older samples thin out with age, and thinning happens seldom (each frees
at least a quarter of the capacity), since it makes the panels redraw everything.

A *gap row* marks where samples were left out: its state (and diagnostics) are NaN and
its time lies between those of its neighbours, so times never decrease. Panels draw with
``connect="finite"``, so no line is drawn across a gap. The worker inserts gap rows too,
when at full speed it hands over only the most recent part of what it computed.
``is_gap`` tells them apart; ``finite_rows`` gives the rows that are states.

Besides the rows, a trajectory keeps ``envelope`` (``explorer.envelope.Envelope``): H's
lowest and highest value over every step, in bins of time from the start, merged in
pairs to stay bounded and never thinned otherwise; the energy plots draw it. Likewise
``momenta`` (None until the worker sums them up): the conserved momenta's ranges, in the
order of ``explorer.envelope.conserved_quantities``, which their plot draws.

Thinning removes rows, which panels that draw incrementally (O(new rows) per frame) must
notice: each thinning raises ``Trajectory.revision``, and the store then raises its
``generation``, which every panel already treats as "redraw everything".
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from explorer.buffers import GrowingArray
from explorer.envelope import Envelope

COLOURS = (
    "#1f77b4",
    "#d62728",
    "#2ca02c",
    "#9467bd",
    "#ff7f0e",
    "#17becf",
    "#e377c2",
    "#8c564b",
    "#bcbd22",
    "#7f7f7f",
)
DEFAULT_CAPACITY = 1 << 17
"""Rows one trajectory keeps at most (about 12 MB for a double pendulum with its drawing)."""
THIN_RUN = 256
"""Samples per run when a level is thinned: every other run is dropped whole."""
MAX_LEVEL = 16
"""Levels of thinning: level ``l`` keeps one run in ``2**l``."""
THIN_TOGETHER = 0.6
"""When one trajectory is thinned, the others fuller than this fraction are thinned with
it, so that the panels redraw everything once rather than once per trajectory."""


def is_gap(y: np.ndarray) -> np.ndarray:
    """Which rows of states ``y``, shape (k, 2n), are gap rows (no state: NaN); shape (k,)."""
    y = np.asarray(y, dtype=float)
    if not len(y):
        return np.zeros(0, dtype=bool)
    return ~np.isfinite(y.reshape(len(y), -1)[:, 0])


def thin_runs(rows: np.ndarray, parity: int = 0, run: int = THIN_RUN) -> tuple[np.ndarray, int]:
    """Every other run of the samples ``rows``.

    Parameters
    ----------
    rows : ndarray of int, shape (k,)
        Increasing indices of samples (not gap rows). Consecutive indices form a stretch;
        a jump (samples or a gap row in between) starts a new one. Each stretch is cut
        into runs of ``run`` samples.
    parity : int
        0: the first run is kept, then every other one; 1: the first is dropped. Handing
        on the returned parity to the next call alternates across calls, so that thinning
        a few runs at a time still halves them.
    run : int

    Returns
    -------
    kept : ndarray of int, shape (j,)
        The indices kept, in order.
    parity : int
        The parity for the run after these.
    """
    rows = np.asarray(rows, dtype=np.int64)
    if not len(rows):
        return rows, parity
    index = np.arange(len(rows))
    jump = np.ones(len(rows), dtype=bool)
    jump[1:] = np.diff(rows) != 1
    stretch_start = np.maximum.accumulate(np.where(jump, index, 0))
    starts = (index - stretch_start) % run == 0
    number = np.cumsum(starts) - 1 + parity  # runs counted from the first, shifted
    return rows[number % 2 == 0], int(number[-1] + 1) % 2


def with_gaps(kept: np.ndarray) -> np.ndarray:
    """The rows ``kept`` (increasing indices) with a gap row wherever rows in between were
    left out: shape (j + gaps,); a gap is ``-1 - i`` where ``i`` is the last row left out
    (the gap takes its time)."""
    kept = np.asarray(kept, dtype=np.int64)
    if len(kept) < 2:
        return kept
    missing = np.diff(kept) > 1
    out = np.empty(len(kept) + int(missing.sum()), dtype=np.int64)
    where = np.arange(len(kept)) + np.concatenate([[0], np.cumsum(missing)])
    out[where] = kept
    out[where[1:][missing] - 1] = -1 - (kept[1:][missing] - 1)
    return out


def _take(data: np.ndarray, order: np.ndarray, times: bool = False) -> np.ndarray:
    """Rows ``order`` of ``data`` (see ``with_gaps``): gap rows are NaN, except in a
    column of ``times``, where they take the time of the row they stand for."""
    rows = data[np.where(order < 0, -1 - order, order)]
    if not times:
        rows[order < 0] = np.nan
    return rows


def level_quotas(capacity: int) -> tuple[int, int]:
    """Samples kept whole at level 0, and at most at each higher level."""
    return capacity // 4, max(capacity // (2 * MAX_LEVEL), THIN_RUN)


def compact(
    gap: np.ndarray, levels: list[int], capacity: int, parities: list[int] | None = None
) -> tuple[np.ndarray, list[int], list[int]]:
    """Which rows a full trajectory keeps, by levels (see the module's docstring).

    Parameters
    ----------
    gap : ndarray of bool, shape (k,)
        Which rows are gap rows. Row 0 is the start; then come the rows of the highest
        level down to level 1 (``levels``), then level 0 (the rest).
    levels : list of int
        Rows at levels 1, 2, ... (``levels[l - 1]``), gap rows included.
    capacity : int
    parities : list of int, optional
        Per level, the parity of the next run thinned on the way up (``thin_runs``).

    Returns
    -------
    order : ndarray of int, shape (j,)
        The rows kept, with gap rows (``with_gaps``).
    levels : list of int
        The new rows at levels 1, 2, ...
    parities : list of int
        The new parities per level (0, 1, ...).
    """
    k = len(gap)
    bounds = np.cumsum([1, *levels[::-1]])  # ends of the levels, highest level first
    ranges = {len(levels) - i: (int(bounds[i]), int(bounds[i + 1])) for i in range(len(levels))}
    ranges[0] = (int(bounds[-1]), k)
    first, quota = level_quotas(capacity)
    samples = np.flatnonzero(~gap)
    parities = list(parities or [])
    parities += [0] * (MAX_LEVEL + 1 - len(parities))
    members: dict[int, np.ndarray] = {}
    carry = np.empty(0, dtype=np.int64)
    level = 0
    while level <= MAX_LEVEL and (level in ranges or len(carry)):
        lo, hi = ranges.get(level, (0, 0))
        own = samples[(samples >= max(lo, 1)) & (samples < hi)]
        rows = np.concatenate([own, carry])  # those from below are newer
        limit = first if level == 0 else quota
        excess = max(len(rows) - limit, 0)
        members[level] = rows[excess:]
        carry = np.empty(0, dtype=np.int64)
        if level < MAX_LEVEL and excess:
            carry, parities[level] = thin_runs(rows[:excess], parities[level])
        level += 1
    label = np.concatenate(
        [[MAX_LEVEL + 1], *[np.full(len(members[lv]), lv) for lv in sorted(members, reverse=True)]]
    )
    kept = np.concatenate([[0], *[members[lv] for lv in sorted(members, reverse=True)]])
    order = with_gaps(kept)
    labels = np.empty(len(order), dtype=np.int64)
    real = order >= 0
    labels[real] = label
    # a gap belongs to the level of the row after it
    following = np.flatnonzero(real)[np.cumsum(real)[~real]]
    labels[~real] = labels[following]
    counts = np.bincount(labels, minlength=MAX_LEVEL + 2)
    top = max(members)
    return order, [int(c) for c in counts[1 : top + 1]], parities


@dataclass
class Trajectory:
    """One integrated orbit: its id, colour, starting state and the data so far.

    Attributes
    ----------
    t : GrowingArray, rows ()
        Times, never decreasing (a gap row repeats the time before it).
    y : GrowingArray, rows (2n,)
        States ``(q, p)``; NaN in gap rows.
    energy : GrowingArray, rows ()
        H where computed, NaN elsewhere (``backfill_energy`` fills it).
    points : GrowingArray, rows (npoints, 2)
        Drawing points where computed (``backfill_points``).
    events : GrowingArray, rows (2n,)
        Section crossings, all of them (never thinned).
    envelope : Envelope
        H's range over every step, per bin of time (where the worker summed it up).
    momenta : Envelope or None
        The conserved momenta's ranges over every step, likewise.
    steps, rhs_evaluations : int
        Integrator steps and right-hand-side evaluations of this orbit so far, over all
        its runs (a method change starts a new run).
    revision : int
        Raised whenever rows were removed (thinning); rows are otherwise only appended.
    capacity : int
        Rows kept at most.
    """

    key: int
    colour: str
    y0: np.ndarray
    t0: float = 0.0
    n_points: int = 0
    status: str = "running"
    message: str = ""
    method: str = ""
    setting: str = ""
    setting_value: float = float("nan")
    steps: int = 0
    rhs_evaluations: int = 0
    energy_done: int = 0  # rows before this one have H where they hold a state
    capacity: int = DEFAULT_CAPACITY
    revision: int = 0
    levels: list[int] = field(default_factory=list)  # rows at levels 1, 2, ... (compact)
    parities: list[int] = field(default_factory=list)  # per level (compact)
    t: GrowingArray = field(init=False)
    y: GrowingArray = field(init=False)
    energy: GrowingArray = field(init=False)
    points: GrowingArray = field(init=False)
    events: GrowingArray = field(init=False)
    envelope: Envelope = field(init=False)
    momenta: Envelope | None = field(init=False, default=None)

    def __post_init__(self) -> None:
        self.y0 = np.asarray(self.y0, dtype=float).copy()
        self.capacity = max(int(self.capacity), 4 * THIN_RUN)
        start = min(1024, self.capacity)
        self.t = GrowingArray((), capacity=start)
        self.y = GrowingArray((len(self.y0),), capacity=start)
        self.energy = GrowingArray((), capacity=start)
        self.points = GrowingArray((max(self.n_points, 1), 2), capacity=start)
        self.events = GrowingArray((len(self.y0),), capacity=256)
        self.envelope = Envelope()
        self.t.extend(np.array([self.t0]))
        self.y.extend(self.y0[None, :])
        self.energy.extend_missing(1)
        self.points.extend_missing(1)

    def __len__(self) -> int:
        return len(self.t)

    @property
    def finished(self) -> bool:
        return self.status != "running"

    @property
    def last_t(self) -> float:
        return float(self.t.data[-1])

    @property
    def last_y(self) -> np.ndarray:
        """The latest state, shape (2n,) (the last row is never a gap row)."""
        return self.y.data[-1].copy()

    @property
    def nbytes(self) -> int:
        """Bytes allocated for the rows (all buffers, including unused capacity)."""
        buffers = (self.t, self.y, self.energy, self.points)
        return sum(8 * b.capacity * int(np.prod(b.row_shape, dtype=int)) for b in buffers)

    def append(self, block) -> None:
        """Append a ``systems.simulation.Block`` (its first row may repeat our last one,
        or be older: either is left out).

        ``block.steps`` and ``block.rhs_evaluations`` are those of this block (the
        worker's frames carry them so). Thins the old rows first when the block would
        overflow ``capacity``.
        """
        t = np.asarray(block.t, dtype=float)
        y = np.asarray(block.y, dtype=float).reshape(len(t), -1)
        start = 0
        if len(t) and len(self.t):
            # an impact keeps two rows at one time (arriving, leaving): only a row equal
            # to our last one is a repeat
            last = self.y.data[-1]
            repeat = t[0] == self.last_t and np.array_equal(y[0], last, equal_nan=True)
            start = 1 if t[0] < self.last_t or repeat else 0
        t, y = t[start:], y[start:]
        self.status = block.status
        self.message = block.message
        self.method = block.method
        self.setting = getattr(block, "setting", "")
        self.setting_value = getattr(block, "setting_value", float("nan"))
        self.steps += int(block.steps)
        self.rhs_evaluations += int(block.rhs_evaluations)
        events = getattr(block, "events_y", None)
        if events is not None and len(events):
            self.events.extend(events)
        diagnostics = block.diagnostics or {}
        envelope = diagnostics.get("envelope")
        if envelope is not None:
            self.envelope.extend(envelope)
        momenta = diagnostics.get("momenta_envelope")
        if momenta is not None:
            if self.momenta is None or self.momenta.quantities != momenta.quantities:
                self.momenta = Envelope(quantities=momenta.quantities)
            self.momenta.extend(momenta)
        if not len(t):
            return
        energy = np.full(len(t), np.nan)
        if "H" in diagnostics:
            energy = np.asarray(diagnostics["H"], dtype=float)[start:]
        points = None
        if "points" in diagnostics and self.n_points:
            points = np.asarray(diagnostics["points"], dtype=float)[start:]
        if len(self.t) + len(t) > self.capacity:
            self._thin_with(t, y, energy, points)
            return
        self.t.extend(t)
        self.y.extend(y)
        self.energy.extend(energy)
        if points is not None:
            self.points.extend(points)
        else:
            self.points.extend_missing(len(t))

    def thin(self) -> None:
        """Thin the rows now, as an overflow would (see the module's docstring)."""
        self._thin_with(np.empty(0), np.empty((0, len(self.y0))), np.empty(0), None)

    def _thin_with(self, t, y, energy, points) -> None:
        """Store the rows and the new ones (t, y, energy, points), thinned by levels."""
        if points is None:
            points = np.full((len(t), *self.points.row_shape), np.nan)
        columns = [
            np.concatenate([self.t.data, t]),
            np.concatenate([self.y.data, y]),
            np.concatenate([self.energy.data, energy]),
            np.concatenate([self.points.data, points]),
        ]
        order, self.levels, self.parities = compact(
            is_gap(columns[1]), self.levels, self.capacity, self.parities
        )
        if len(order) > self.capacity:  # only when nearly every sample is its own stretch
            real = order[order >= 0]
            order = with_gaps(np.concatenate([[0], real[len(real) - self.capacity // 4 :]]))
            self.levels = []
        buffers = (self.t, self.y, self.energy, self.points)
        for k, (buffer, column) in enumerate(zip(buffers, columns, strict=True)):
            buffer.clear()
            buffer.extend(_take(column, order, times=k == 0))
        self.energy_done = 0
        self.revision += 1

    def finite_rows(self) -> np.ndarray:
        """Indices of the rows that hold states (not gap rows), shape (j,)."""
        return np.flatnonzero(~is_gap(self.y.data))


class TrajectoryStore:
    """The trajectories of the current system; panels read, the main window appends.

    Parameters
    ----------
    n_points : int
        Drawing points per state (0: the scene has no drawing).
    capacity : int
        Rows each trajectory keeps at most (``DEFAULT_CAPACITY``).
    """

    def __init__(self, n_points: int = 0, capacity: int = DEFAULT_CAPACITY):
        self.n_points = n_points
        self.capacity = capacity
        self.trajectories: dict[int, Trajectory] = {}
        self._next_key = 0
        self._dirty: dict[str, bool] = {}
        self.generation = 0

    def __iter__(self):
        return iter(self.trajectories.values())

    def __len__(self) -> int:
        return len(self.trajectories)

    @property
    def main(self) -> Trajectory | None:
        """The first trajectory: the one the mechanism animates."""
        return next(iter(self.trajectories.values()), None)

    @property
    def rows(self) -> int:
        """Rows held by all trajectories together."""
        return sum(len(trajectory.t) for trajectory in self)

    @property
    def nbytes(self) -> int:
        """Bytes allocated for the rows of all trajectories."""
        return sum(trajectory.nbytes for trajectory in self)

    def add(self, y0: np.ndarray, t0: float = 0.0) -> Trajectory:
        key = self._next_key
        self._next_key += 1
        colour = COLOURS[key % len(COLOURS)]
        trajectory = Trajectory(key, colour, y0, t0, n_points=self.n_points, capacity=self.capacity)
        self.trajectories[key] = trajectory
        self.mark_dirty()
        return trajectory

    def remove(self, key: int) -> None:
        self.trajectories.pop(key, None)
        self.mark_dirty()

    def clear(self) -> None:
        self.trajectories.clear()
        self._next_key = 0
        self.generation += 1
        self.mark_dirty()

    def append(self, key: int, block) -> None:
        """Append ``block`` to trajectory ``key`` (ignored if it was removed).

        When that thinned the trajectory, the others that are nearly full are thinned
        too and ``generation`` goes up, so that panels redraw from the new rows.
        """
        trajectory = self.trajectories.get(key)
        if trajectory is None:
            return
        revision = trajectory.revision
        trajectory.append(block)
        if trajectory.revision != revision:
            for other in self:
                if other is not trajectory and len(other.t) > THIN_TOGETHER * other.capacity:
                    other.thin()
            self.generation += 1
        self.mark_dirty()

    # -- dirty flags: one per consumer ---------------------------------------------------

    def mark_dirty(self) -> None:
        for name in self._dirty:
            self._dirty[name] = True

    def take_dirty(self, consumer: str) -> bool:
        """True (once) when something changed since ``consumer`` last asked."""
        dirty = self._dirty.get(consumer, True)
        self._dirty[consumer] = False
        return dirty


def backfill_energy(trajectory: Trajectory, compiled) -> np.ndarray:
    """H along the trajectory, shape (k,), computing the rows that were not streamed.

    Gap rows stay NaN. Only rows from ``trajectory.energy_done`` on are looked at, so a
    redraw costs O(new rows).
    """
    energy = trajectory.energy.data
    done = min(trajectory.energy_done, len(energy))
    window = energy[done:]
    y = trajectory.y.data[done:]
    missing = np.isnan(window) & ~is_gap(y)
    if missing.any():
        with np.errstate(all="ignore"):
            window[missing] = compiled.hamiltonian(trajectory.t.data[done:][missing], y[missing])
    trajectory.energy_done = len(energy)
    return energy


def backfill_points(trajectory: Trajectory, compiled, start: int = 0) -> np.ndarray:
    """Drawing points of rows ``start:``, shape (k - start, npoints, 2), computing those
    that were not streamed (gap rows stay NaN)."""
    points = trajectory.points.data
    if not trajectory.n_points:
        return points[start:]
    window = points[start:]
    y = trajectory.y.data[start:]
    missing = np.isnan(window[:, 0, 0]) & ~is_gap(y)
    if missing.any():
        t = trajectory.t.data[start:][missing]
        with np.errstate(all="ignore"):
            window[missing] = compiled.drawing(t, y[missing])
    return window
