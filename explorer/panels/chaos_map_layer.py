"""A chaos map under the Poincaré section (issue 27 item 2).

"Chaos map" in the phase view's header (enabled in the Poincaré mode) computes MEGNO
over a ``GRID`` x ``GRID`` grid of the section's visible box at the section's energy
(``systems.chaos.maps``): the variational equations are written in a worker process
(``systems.processes``, as the Chaos dock's), the map runs in a thread of its own
(``chaos-map``: its compiled loop releases the GIL; progress and cancel between chunks of
``CHUNK`` orbits), and the result is an image under the section's points, dark where the
orbits are regular (<Y> near 2), yellow where they are chaotic (<Y> >= 8). A click on a
pixel starts that orbit, as any click on the section does. A new system, another mode or
energy (the view rebuilt) cancels the map and removes it.
"""

from __future__ import annotations

import numpy as np
import pyqtgraph as pg
from PySide6.QtCore import QObject, Signal
from PySide6.QtWidgets import QPushButton

from explorer.panels.background import ProgressControls, RelayThread
from explorer.panels.chaos_view import submit_tangent_code
from systems import processes

GRID = 120
CHUNK = 64
T_END = None
"""Each orbit's end time: None for the method's default (``maps.default_t_end``: 500, or
100 for an implicit method)."""
LEVELS = (0.0, 8.0)
"""MEGNO's colour scale: 2 regular, above 4 chaotic (the threshold), 8 and more yellow."""
Z_VALUE = -25
"""Under the forbidden region (-20, transparent where motion is allowed) and the points."""
CPU_SECONDS = 60.0


class _Relay(QObject):
    """Carries results from the map's worker and thread to the GUI thread (queued)."""

    coded = Signal(int, object)  # generation, TangentCode or an error message
    progressed = Signal(int, int, int)  # generation, done, total
    finished = Signal(int, object)  # generation, ChaosMap
    failed = Signal(int, str)


class MapRun(RelayThread):
    """One map of one section, in its own thread; ``cancel`` ends it between chunks."""

    def __init__(self, compiled, code, section, energy, box, relay: _Relay, generation: int):
        super().__init__("chaos-map", relay, generation)
        self.compiled, self.code, self.section = compiled, code, section
        self.energy, self.box = float(energy), box

    def run(self) -> None:
        from systems.chaos import maps
        from systems.chaos.variational import Tangent

        try:
            kernel = maps.map_kernel(Tangent(self.compiled, self.code), t_end=T_END)
            grid = maps.section_grid(self.compiled, self.section, self.energy, GRID, GRID, self.box)
            result = maps.chaos_map(
                kernel, grid, chunk=CHUNK, cancelled=self.stopping.is_set,
                progress=lambda done, total: self._emit("progressed", done, total),
            )  # fmt: skip
        except Exception as exc:  # noqa: BLE001 - said in the view, never lost
            self._emit("failed", f"the chaos map failed: {exc}")
            return
        if result.complete:
            self._emit("finished", result)


def _t_end_text() -> str:
    from systems.chaos import maps

    if T_END is not None:
        return f"{T_END:g}"
    return f"{maps.DEFAULT_T_END:g} ({maps.IMPLICIT_T_END:g} with an implicit method)"


def map_image(result) -> np.ndarray:
    """RGBA (nx, ny, 4) bytes of a map's MEGNO (viridis over ``LEVELS``, transparent
    where there is no value), in pyqtgraph's (x, y) order."""
    values = result.megno
    lo, hi = LEVELS
    cmap = pg.colormap.get("viridis")
    scaled = np.clip((np.nan_to_num(values) - lo) / (hi - lo), 0.0, 1.0)
    rgba = cmap.map(scaled.ravel(), mode="byte").reshape(*values.shape, 4)
    rgba[~np.isfinite(values)] = 0
    return np.ascontiguousarray(rgba.transpose(1, 0, 2))


def key_entries() -> list[tuple[object, str]]:
    """The map's colour key as legend swatches, in ``map_image``'s colours: MEGNO 2
    (regular), 4 (the threshold) and the top of the scale (chaotic)."""
    lo, hi = LEVELS
    cmap = pg.colormap.get("viridis")
    entries = []
    for value, text in ((2.0, "MEGNO 2: regular"), (4.0, "MEGNO 4: the threshold"),
                        (hi, f"MEGNO {hi:g} and more: chaotic")):  # fmt: skip
        colour = cmap.map((value - lo) / (hi - lo), mode="qcolor")
        entries.append((pg.BarGraphItem(x=[0], height=[0], width=0, brush=colour), text))
    return entries


class ChaosMapLayer(QObject):
    """The map's button, progress bar and image for one ``PhaseView``.

    Signals
    -------
    started()
        A map was started (a session's ``chaos-map`` line).
    """

    started = Signal()

    def __init__(self, view):
        super().__init__(view)
        self.view = view
        self.result = None
        self.image: pg.ImageItem | None = None
        self._generation = 0
        self._job: processes.Job | None = None
        self._thread: MapRun | None = None
        self._codes: dict[int, object] = {}  # id(mechanics) -> TangentCode
        self._closed = False
        self._relay = _Relay()
        self._relay.coded.connect(self._on_relay_coded)
        self._relay.progressed.connect(self._on_relay_progressed)
        self._relay.finished.connect(self._on_relay_finished)
        self._relay.failed.connect(self._on_relay_failed)
        self.button = QPushButton("Chaos map")
        self.button.setToolTip(
            f"Colour the section by MEGNO: {GRID} x {GRID} orbits at this energy, each to "
            f"t = {_t_end_text()} (dark: regular, <Y> near 2; yellow: chaotic). Click a "
            "pixel to start that orbit."
        )
        self.button.clicked.connect(self._on_button_clicked)
        self.controls = ProgressControls(self.cancel)
        self.progress, self.cancel_button = self.controls.progress, self.controls.cancel_button
        self.update_enabled()

    @property
    def available(self) -> bool:
        view = self.view
        return view.compiled is not None and view.mode == "poincare" and view.section is not None

    @property
    def running(self) -> bool:
        return self._job is not None or self._thread is not None

    def widgets(self) -> tuple:
        """What goes in the view's header."""
        return (self.button, self.progress, self.cancel_button)

    def update_enabled(self) -> None:
        self.button.setEnabled(self.available and not self.running and not self._closed)

    def start(self) -> None:
        """Map the section's visible box at the section's energy."""
        if not self.available or self.running or self._closed:
            return
        from systems.chaos.variational import refusal

        self.clear()
        reason = refusal(self.view.compiled.mechanics)
        if reason:
            self.view.hint.setText(f"No chaos map: {reason}")
            return
        self._generation += 1
        generation, relay = self._generation, self._relay
        self._show_running(True)
        self.started.emit()
        mechanics = self.view.compiled.mechanics
        code = self._codes.get(id(mechanics))
        if code is not None:
            self._on_relay_coded(generation, code)
            return

        self._job = submit_tangent_code(mechanics, relay.coded, generation, CPU_SECONDS)

    def cancel(self) -> None:
        """Stop the map being computed (the last finished one stays)."""
        self._generation += 1
        job, self._job = self._job, None
        if job is not None:
            job.cancel()
        thread, self._thread = self._thread, None
        if thread is not None:
            thread.cancel()
        self._show_running(False)

    def clear(self) -> None:
        """Cancel and remove the map (the view was rebuilt: another system, mode or energy)."""
        self.cancel()
        if self.image is not None:
            self.view.plot.removeItem(self.image)
            self.image = None
            self.view.set_layer_legend([])
        self.result = None
        self.update_enabled()

    def shutdown(self) -> None:
        """The window is closing: end the worker and the thread."""
        self._closed = True
        self.cancel()

    def _show_running(self, running: bool) -> None:
        self.controls.show_running(running)
        self.update_enabled()

    def _on_button_clicked(self) -> None:
        self.start()

    def _on_relay_coded(self, generation: int, code) -> None:
        if self._closed or generation != self._generation:
            return
        self._job = None
        if isinstance(code, str):
            self._show_running(False)
            self.view.hint.setText(f"No chaos map: {code}")
            return
        view = self.view
        self._codes = {id(view.compiled.mechanics): code}
        box = (tuple(view.ranges.x), tuple(view.ranges.y))
        self._thread = MapRun(
            view.compiled, code, view.section, view.section_energy, box, self._relay, generation
        )
        self._thread.start()

    def _on_relay_progressed(self, generation: int, done: int, total: int) -> None:
        if self._closed or generation != self._generation:
            return
        self.controls.set_progress(done, total)

    def _on_relay_finished(self, generation: int, result) -> None:
        if self._closed or generation != self._generation:
            return
        thread, self._thread = self._thread, None
        if thread is not None:
            thread.join(1.0)
        self._show_running(False)
        self.result = result
        grid = result.grid
        image = pg.ImageItem(map_image(result), levels=(0, 255))
        dx = (grid.xs[-1] - grid.xs[0]) / (len(grid.xs) - 1)
        dy = (grid.ys[-1] - grid.ys[0]) / (len(grid.ys) - 1)
        image.setRect(
            grid.xs[0] - dx / 2, grid.ys[0] - dy / 2, dx * len(grid.xs), dy * len(grid.ys)
        )
        image.setZValue(Z_VALUE)
        self.view.plot.addItem(image)
        self.image = image
        self.view.set_layer_legend(key_entries())
        self.view.hint.setText(
            f"MEGNO to t = {result.t_end:g}: chaotic (<Y> > 4) in "
            f"{result.chaotic_fraction():.0%} of the section. Click a pixel to start that orbit."
        )

    def _on_relay_failed(self, generation: int, message: str) -> None:
        if self._closed or generation != self._generation:
            return
        self._thread = None
        self._show_running(False)
        self.view.hint.setText(message)
