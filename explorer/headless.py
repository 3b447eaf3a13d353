"""Panels drawn without a main window: integrate a scene to ``t_end`` and render a figure.

Used by the ``export`` command. The scene is built and integrated synchronously (there is
no event loop to keep responsive), then the panel is laid out offscreen and exported at
the size asked for (``explorer.export.figure_layout``), or its trajectory is written as
CSV at the times asked for (``write_csv``; the ``export`` command chooses them as ``run``
does).
"""

from __future__ import annotations

import math
import os
import sys
from pathlib import Path

import numpy as np

FIGURE_SIZE = (1000, 720)


def ensure_qt_platform() -> None:
    """Render offscreen unless a Qt platform was chosen (must run before Qt starts), and
    load Qt's bindings with Ctrl+C, SIGTERM and SIGHUP held until they are loaded: a
    signal landing in shiboken's start-up aborted the process ("Fatal Python error:
    libshiboken/signature: could not initialize part 2") instead of stopping it."""
    os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")
    if "PySide6.QtCore" in sys.modules:
        return
    from explorer.export import signals_held

    with signals_held():
        import PySide6.QtCore  # noqa: F401


EXPORT_SAMPLES = 20_000
"""States an exported figure is drawn from, evenly spaced in simulation time: enough for
a smooth curve at print resolution, and the same figure on any machine."""


def integrate(built, t_end: float, *, diagnostics=("H",), section=None, times=None, strobe=None):
    """A ``TrajectoryStore`` holding the scene's main trajectory from 0 to ``t_end``.

    The trajectory is sampled at ``times`` (default: ``EXPORT_SAMPLES`` evenly spaced
    times; each sample is the state at exactly its time, ``systems.simulation.Sampler``)
    and keeps
    every section crossing, so memory does not grow with ``t_end``; the run has the
    command line's step budget. With ``strobe`` (a driven system's period T) the events
    are the states at t = T, 2T, ... up to ``t_end`` (the stroboscopic section), sampled
    by the same run as the curve.

    Raises
    ------
    KeyboardInterrupt
        When Ctrl+C (or a signal handled as it) stopped the integration: the sampler
        ends quietly, but a figure of part of the run is not the one asked for.
    """
    import dataclasses

    import numpy as np

    from explorer.trajectories import TrajectoryStore
    from systems.limits import DEFAULT_MAX_STEPS
    from systems.simulation import Run, Sampler

    compiled = built.compiled
    if times is None:
        times = np.linspace(0.0, t_end, EXPORT_SAMPLES + 1)
    times = np.asarray(times, dtype=float)
    strobe_times = np.empty(0)
    if strobe is not None:
        strobe_times = strobe * np.arange(1, math.floor(t_end / strobe + 1e-9) + 1)
        times = np.union1d(times, strobe_times)
    store = TrajectoryStore(n_points=len(compiled.point_names), capacity=len(times) + 16)
    y0 = compiled.initial_state()
    trajectory = store.add(y0)
    run = Run(
        compiled,
        method=built.method or None,
        y0=y0,
        t_end=t_end,
        diagnostics=("H",),
        section=section,
        max_points=64,
        max_steps=DEFAULT_MAX_STEPS,
    )
    sampler = Sampler(run, times)
    samples = list(sampler)
    if sampler.interrupted:
        raise KeyboardInterrupt
    t = np.array([row[0] for row in samples])
    y = np.array([row[1] for row in samples])
    last = sampler.last if sampler.last is not None else run.stop("ok", "")
    found = {}
    with np.errstate(all="ignore"):
        if "H" in diagnostics and "hamiltonian" in compiled.wanted:
            found["H"] = compiled.hamiltonian(t, y)
        if "drawing" in compiled.wanted:
            found["points"] = compiled.drawing(t, y)
    events_t = np.array(sampler.events_t)
    events_y = np.array(sampler.events_y).reshape(-1, len(y0))
    if strobe is not None:
        on_strobe = np.isin(t, strobe_times)
        events_t, events_y = t[on_strobe], y[on_strobe]
    block = dataclasses.replace(
        last,
        t=t,
        y=y,
        diagnostics=found,
        events_t=events_t,
        events_y=events_y,
    )
    store.append(trajectory.key, block)
    return store


def make_panel(key: str):
    from explorer.panels.configuration_view import ConfigurationView
    from explorer.panels.conserved_view import ConservedView
    from explorer.panels.phase_view import PhaseView

    return {"phase": PhaseView, "configuration": ConfigurationView, "conserved": ConservedView}[
        key
    ]()


def render_panel(
    scene,
    panel: str,
    out: str | Path,
    *,
    t_end: float | None = None,
    poincare: bool = False,
    size=FIGURE_SIZE,
    image_size: tuple[int, int] | None = None,
) -> tuple[Path, object]:
    """Build ``scene``, integrate it to ``t_end`` and export ``panel`` to ``out``.

    The panel is laid out at ``size`` and drawn at ``image_size`` pixels (default: as
    laid out; ``explorer.export.figure_layout``). Returns the written path and the main
    trajectory (its ``status`` is ``"ok"`` or a problem).
    """
    ensure_qt_platform()
    from explorer.app import application
    from explorer.builder import build
    from explorer.export import export_widget, signals_held

    app = application()
    built = build(scene)
    compiled = built.compiled
    t_end = float(t_end if t_end is not None else scene.view.get("t_end", 20.0))
    view = make_panel(panel)
    try:
        view.resize(*size)
        y0 = compiled.initial_state()
        section = strobe = None
        if panel == "phase":
            view.set_system(compiled, y0)
            if poincare:
                view.set_mode("poincare")
                if view.mode != "poincare":
                    raise ValueError(
                        "a Poincaré section needs an autonomous conservative system "
                        "of two degrees of freedom, or a periodically driven one (its "
                        "stroboscopic section)"
                    )
                if view.section is not None:
                    section = (view.section.coordinate, view.section.value, 1)
                else:
                    strobe = view.strobe_period
        else:
            view.set_system(compiled)
        store = integrate(built, t_end, section=section, strobe=strobe)
        with signals_held():  # Qt draws: a signal waits for it (explorer.export)
            view.show()
            app.processEvents()
            view.refresh(store)
            app.processEvents()
        return export_widget(view.export_target(), out, image_size), store.main
    finally:  # on a failed write or Ctrl+C too: a view left to the interpreter's exit crashed it
        with signals_held():
            view.close()
            view.deleteLater()
            app.processEvents()


def write_csv(scene, out: str | Path, t_end: float, times: np.ndarray) -> tuple[Path, object]:
    """Build ``scene``, integrate it to ``t_end`` and write its main trajectory to the CSV
    ``out``: one row per time of ``times``, shape (k,), each the state at that time
    (``systems.simulation.Sampler``). Returns the path and the trajectory."""
    from explorer.builder import build
    from explorer.export import write_trajectories_csv

    built = build(scene, t_end=float(t_end))
    store = integrate(built, float(t_end), times=times)
    written = write_trajectories_csv(built.compiled, list(store), out)
    return written, store.main
