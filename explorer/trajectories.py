"""What the panels draw: the trajectories of a run, filled block by block from the worker.

A ``Trajectory`` keeps growing buffers of time, canonical state and the optional
diagnostics (``H``, drawing ``points``); rows whose diagnostic was not computed (the panel
that needs it was hidden) hold NaN and are filled on demand by ``backfill_energy``.
``TrajectoryStore`` is the list of trajectories of the current system plus a dirty flag
per consumer, so the redraw timer only touches panels that have something new.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from explorer.buffers import GrowingArray

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


@dataclass
class Trajectory:
    """One integrated orbit: its id, colour, starting state and the data so far."""

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
    energy_done: int = 0  # rows before this one have H (none is NaN)
    t: GrowingArray = field(init=False)
    y: GrowingArray = field(init=False)
    energy: GrowingArray = field(init=False)
    points: GrowingArray = field(init=False)
    events: GrowingArray = field(init=False)

    def __post_init__(self) -> None:
        self.y0 = np.asarray(self.y0, dtype=float).copy()
        self.t = GrowingArray(())
        self.y = GrowingArray((len(self.y0),))
        self.energy = GrowingArray(())
        self.points = GrowingArray((max(self.n_points, 1), 2))
        self.events = GrowingArray((len(self.y0),), capacity=256)
        self.t.extend(np.array([self.t0]))
        self.y.extend(self.y0[None, :])
        self.energy.extend_missing(1)
        self.points.extend_missing(1)

    @property
    def finished(self) -> bool:
        return self.status != "running"

    @property
    def last_t(self) -> float:
        return float(self.t.data[-1])

    @property
    def last_y(self) -> np.ndarray:
        return self.y.data[-1].copy()

    def append(self, block) -> None:
        """Append a ``systems.simulation.Block`` (its first row may repeat our last one)."""
        t = np.asarray(block.t, dtype=float)
        y = np.asarray(block.y, dtype=float)
        start = 1 if len(t) and len(self.t) and t[0] <= self.last_t else 0
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
        if not len(t):
            return
        self.t.extend(t)
        self.y.extend(y)
        diagnostics = block.diagnostics or {}
        if "H" in diagnostics:
            self.energy.extend(np.asarray(diagnostics["H"])[start:])
        else:
            self.energy.extend_missing(len(t))
        if "points" in diagnostics and self.n_points:
            self.points.extend(np.asarray(diagnostics["points"])[start:])
        else:
            self.points.extend_missing(len(t))


class TrajectoryStore:
    """The trajectories of the current system; panels read, the main window appends."""

    def __init__(self, n_points: int = 0):
        self.n_points = n_points
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

    def add(self, y0: np.ndarray, t0: float = 0.0) -> Trajectory:
        key = self._next_key
        self._next_key += 1
        colour = COLOURS[key % len(COLOURS)]
        trajectory = Trajectory(key, colour, y0, t0, n_points=self.n_points)
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
        trajectory = self.trajectories.get(key)
        if trajectory is not None:
            trajectory.append(block)
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
    """H along the trajectory, computing the rows that were not streamed (NaN)."""
    energy = trajectory.energy.data
    missing = np.isnan(energy)
    if missing.any():
        energy[missing] = compiled.hamiltonian(
            trajectory.t.data[missing], trajectory.y.data[missing]
        )
    return energy


def backfill_points(trajectory: Trajectory, compiled, start: int = 0) -> np.ndarray:
    """Drawing points of rows ``start:``, computing those that were not streamed."""
    points = trajectory.points.data
    if not trajectory.n_points:
        return points[start:]
    window = points[start:]
    missing = np.isnan(window[:, 0, 0])
    if missing.any():
        t = trajectory.t.data[start:][missing]
        window[missing] = compiled.drawing(t, trajectory.y.data[start:][missing])
    return window
