"""Figures and data out of the application: PNG, SVG (through ``QSvgGenerator``) and CSV.

pyqtgraph's own SVGExporter is broken on Qt 6.12 (pyqtgraph issue 3485), so an SVG is
made by rendering the panel's widget into a ``QSvgGenerator`` (see ``explorer.svg``):
every curve becomes a vector path in pixel coordinates, clipped to its plot. PNGs are
the widget's own rendering (``QWidget.grab``).
``render_headless`` builds a panel without a main window (for the ``export`` command),
integrates the scene to ``t_end`` and draws it.
"""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

FIGURE_SUFFIXES = (".png", ".svg")
PANELS = ("configuration", "phase", "conserved", "workprecision")


def export_widget(widget, path: str | Path) -> Path:
    """Render ``widget`` to ``path``: PNG or SVG by its suffix. Returns the path."""

    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in FIGURE_SUFFIXES:
        raise ValueError(
            f"cannot export a figure as {suffix or 'a file without suffix'}; use .png or .svg"
        )
    from systems.files import atomic_path

    with atomic_path(path) as temporary:
        if suffix == ".svg":
            from explorer.svg import write_svg

            write_svg(widget, temporary, title=widget.window().windowTitle() or "Phase Explorer")
            check_svg(temporary)
        elif not widget.grab().save(str(temporary)):
            raise OSError(f"could not write {path}")
    return path


def check_svg(path: Path) -> None:
    """``OSError`` unless ``path`` holds a whole SVG document (a full disk cuts it short
    without Qt saying so)."""
    data = path.read_bytes()
    if not data.rstrip().endswith(b"</svg>"):
        raise OSError(f"the SVG written to {path} is incomplete (is the disk full?)")


def csv_header(scene) -> list[str]:
    """Columns as the ``run`` command writes them: t, q, q_dot, p_q, H."""
    return ["t", *scene.coordinates, *scene.velocity_names, *scene.momentum_names, "H"]


def trajectory_table(compiled, trajectory) -> np.ndarray:
    """Rows (t, q, q_dot, p, H) of one trajectory; shape (k, 2 + 3n)."""
    from explorer.trajectories import backfill_energy

    n = compiled.n
    t = trajectory.t.data
    y = trajectory.y.data
    with np.errstate(all="ignore"):
        qdot = compiled.velocities(t, y)
    energy = backfill_energy(trajectory, compiled)
    return np.column_stack([t, y[:, :n], qdot, y[:, n:], energy])


def write_trajectories_csv(compiled, trajectories, path: str | Path) -> Path:
    """Write trajectories as CSV; with more than one, an ``orbit`` column comes first."""
    path = Path(path)
    scene = compiled.mechanics.scene
    header = csv_header(scene)
    many = len(trajectories) > 1
    from systems.files import atomic_path

    with atomic_path(path) as temporary, temporary.open("w", newline="", encoding="utf-8") as out:
        writer = csv.writer(out)
        writer.writerow((["orbit"] if many else []) + header)
        for number, trajectory in enumerate(trajectories, start=1):
            table = trajectory_table(compiled, trajectory)
            for row in table:
                values = [repr(float(v)) for v in row]
                writer.writerow(([str(number)] if many else []) + values)
    return path


def render_workprecision(result, path: str | Path, size=(1100, 560)) -> Path:
    """Draw a work-precision result (``systems.workprecision.WorkPrecision``) to PNG or
    SVG, headless (offscreen Qt unless a platform was chosen)."""
    from explorer.app import application
    from explorer.headless import ensure_qt_platform

    ensure_qt_platform()
    from explorer.panels.workprecision_view import WorkPrecisionView

    app = application()
    view = WorkPrecisionView()
    view.resize(*size)
    view.show_result(result)
    view.show()
    app.processEvents()
    written = export_widget(view.export_target(), path)
    view.shutdown()
    view.close()
    view.deleteLater()
    app.processEvents()
    return written
