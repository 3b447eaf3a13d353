"""Exports sized for use (issue 10, item 6): figures at a chosen size, SVG paths simplified
to the drawing's resolution, CSV tables thinned by time, and the Export dialog."""

from __future__ import annotations

import csv
import math
import shutil
import subprocess
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from PySide6.QtCore import QTimer
from PySide6.QtGui import QImage

from explorer.cli import main
from explorer.export import (
    ExportOptions,
    csv_rows,
    export_widget,
    figure_layout,
    scaled_size,
    write_trajectories_csv,
)
from explorer.svg import simplify
from explorer.trajectories import TrajectoryStore, is_gap

HAVE_RSVG = shutil.which("rsvg-convert") is not None


def read_csv(path: Path) -> tuple[list[str], np.ndarray]:
    with Path(path).open() as handle:
        rows = list(csv.reader(handle))
    return rows[0], np.array(rows[1:], dtype=float)


def pixels(image: QImage) -> np.ndarray:
    image = image.convertToFormat(QImage.Format.Format_RGB32)
    data = np.frombuffer(image.constBits(), np.uint8)
    return data.reshape(image.height(), image.width(), 4)[..., 2::-1].astype(int)  # RGB


@pytest.fixture(scope="module")
def double_pendulum():
    from explorer.builder import build
    from systems.scene import load_scene

    built = build(load_scene("double_pendulum"))
    return built, built.compiled


def long_store(built, compiled, rows: int, capacity: int) -> TrajectoryStore:
    """A store given ``rows`` finely sampled states of the double pendulum (it keeps at
    most ``capacity`` of them)."""
    from systems.simulation import Run

    store = TrajectoryStore(n_points=len(compiled.point_names), capacity=capacity)
    trajectory = store.add(compiled.initial_state())
    run = Run(compiled, method=built.method, max_points=1 << 16, energy_tolerance=None)
    while trajectory.steps < rows:  # rows appended (steps counts them here)
        block = run.advance(0.05)
        store.append(
            0,
            SimpleNamespace(
                t=block.t,
                y=block.y,
                diagnostics={},
                status=block.status,
                message="",
                method=block.method,
                steps=len(block.t),
                rhs_evaluations=0,
            ),
        )
    return store


# -- figures at a chosen size -----------------------------------------------------------------


def test_export_command_draws_a_png_at_the_size_asked(tmp_path, capsys):
    wide = tmp_path / "wide.png"
    args = ["export", "simple_pendulum", "--t-end", "3", "--width", "1600", "--height", "500"]
    assert main([*args, "--out", str(wide)]) == 0
    image = QImage(str(wide))
    assert (image.width(), image.height()) == (1600, 500)
    # one side alone keeps the default figure's shape (1000 x 720)
    narrow = tmp_path / "narrow.png"
    assert (
        main(["export", "simple_pendulum", "--t-end", "3", "--width", "500", "--out", str(narrow)])
        == 0
    )
    assert (QImage(str(narrow)).width(), QImage(str(narrow)).height()) == (500, 360)
    # an SVG's size is its drawing's size
    svg = tmp_path / "big.svg"
    args = ["export", "simple_pendulum", "--t-end", "3", "--width", "2000", "--height", "1440"]
    assert main([*args, "--out", str(svg)]) == 0
    head = svg.read_text()[:600]
    assert 'viewBox="0 0 ' in head and "width=" in head
    assert "wrote" in capsys.readouterr().out


@pytest.mark.skipif(not HAVE_RSVG, reason="rsvg-convert not installed")
def test_an_svg_at_a_size_renders_at_that_size_with_its_curves(tmp_path):
    svg = tmp_path / "big.svg"
    args = ["export", "simple_pendulum", "--t-end", "3", "--width", "1500", "--height", "1000"]
    assert main([*args, "--out", str(svg)]) == 0
    png = tmp_path / "big.png"
    subprocess.run(["rsvg-convert", str(svg), "-o", str(png)], check=True)
    image = QImage(str(png))
    assert abs(image.width() - 1500) <= 2 and abs(image.height() - 1000) <= 2
    rgb = pixels(image)
    orange = (np.abs(rgb - np.array([0xE6, 0x55, 0x0D])).sum(axis=2) < 60).sum()
    assert orange > 2000  # the separatrix, drawn across the whole (scaled) plot


def test_export_command_refuses_options_that_do_not_fit(tmp_path, capsys):
    base = ["export", "simple_pendulum", "--t-end", "3"]
    assert main([*base, "--width", "0", "--out", str(tmp_path / "x.png")]) == 2
    assert "--width must be between 1 and" in capsys.readouterr().err
    assert main([*base, "--height", "20000", "--out", str(tmp_path / "x.png")]) == 2
    assert "--height must be between" in capsys.readouterr().err
    assert main([*base, "--width", "300", "--out", str(tmp_path / "x.csv")]) == 2
    assert "not a CSV table" in capsys.readouterr().err
    assert main([*base, "--every", "0.5", "--out", str(tmp_path / "x.svg")]) == 2
    assert "not a figure" in capsys.readouterr().err
    assert main([*base, "--points", "1", "--out", str(tmp_path / "x.csv")]) == 2
    assert "--points must be between 2" in capsys.readouterr().err
    assert main([*base, "--every", "-1", "--out", str(tmp_path / "x.csv")]) == 2
    assert "--every must be a positive time" in capsys.readouterr().err
    assert not list(tmp_path.iterdir())


def test_a_figure_is_laid_out_at_its_shape_and_scaled(qtbot):
    assert figure_layout((400, 300), (800, 600)) == ((400, 300), 2.0)
    (width, height), scale = figure_layout((400, 300), (1200, 400))
    assert scale == pytest.approx(4 / 3) and (width, height) == (900, 300)
    assert figure_layout((400, 300), (200, 100)) == ((200, 100), 1.0)  # never smaller text
    assert scaled_size((411, 538)) == (822, 1076)


def test_twice_the_size_is_the_same_picture_drawn_finer(qtbot, tmp_path):
    from explorer.builder import build
    from explorer.panels.phase_view import PhaseView
    from systems.scene import load_scene

    compiled = build(load_scene("simple_pendulum")).compiled
    view = PhaseView()
    qtbot.addWidget(view)
    view.resize(520, 420)
    view.set_system(compiled, compiled.initial_state())
    view.show()
    qtbot.waitExposed(view)
    target = view.export_target()
    before = (target.width(), target.height())
    small = QImage(str(export_widget(target, tmp_path / "one.png")))
    large = QImage(str(export_widget(target, tmp_path / "two.png", scaled_size(before))))
    assert (target.width(), target.height()) == before  # the panel got its size back
    assert (large.width(), large.height()) == (2 * small.width(), 2 * small.height())
    halved = large.scaled(small.width(), small.height())
    difference = np.abs(pixels(halved) - pixels(small)).max(axis=2)
    assert (difference > 96).mean() < 0.02  # the same layout, not a cut-out


# -- SVG decimated to the output resolution ----------------------------------------------------


def test_simplify_keeps_every_vertex_it_needs_and_no_more():
    rng = np.random.default_rng(3)
    x = np.cumsum(rng.normal(size=20_000)) * 0.05
    y = np.cumsum(rng.normal(size=20_000)) * 0.05
    x[5000] = np.nan
    keep = simplify(x, y, 0.25)
    assert keep[0] and keep[-1] and keep[4999] and keep[5000] and keep[5001]
    assert 100 < keep.sum() < 0.6 * len(x)
    # every dropped vertex lies within the tolerance of the kept chord that replaces it
    kept = np.flatnonzero(keep)
    for a, b in zip(kept[:-1], kept[1:], strict=True):
        if b - a < 2 or not np.isfinite(x[a]) or not np.isfinite(x[b]):
            continue
        ax, ay, dx, dy = x[a], y[a], x[b] - x[a], y[b] - y[a]
        px, py = x[a + 1 : b] - ax, y[a + 1 : b] - ay
        along = np.clip((px * dx + py * dy) / max(dx * dx + dy * dy, 1e-300), 0, 1)
        assert np.hypot(px - along * dx, py - along * dy).max() <= 0.25 + 1e-9
    assert simplify(x, y, 0.0).all()


def test_a_long_trajectory_makes_a_small_svg_that_draws_the_same(qtbot, tmp_path, double_pendulum):
    from explorer.panels.configuration_view import ConfigurationView
    from explorer.svg import write_svg

    built, compiled = double_pendulum
    store = long_store(built, compiled, 300_000, capacity=400_000)
    view = ConfigurationView()
    qtbot.addWidget(view)
    view.resize(1000, 720)
    view.set_system(compiled)
    view.show()
    qtbot.waitExposed(view)
    view.refresh(store)
    target = view.export_target()
    raw, small = tmp_path / "raw.svg", tmp_path / "small.svg"
    everything = write_svg(target, raw, tolerance=0.0)
    simplified = write_svg(target, small, tolerance=0.25)
    assert raw.stat().st_size > 3_000_000  # what the window wrote before (6.4 MB reported)
    assert small.stat().st_size < 400_000
    assert simplified["segments"] < everything["segments"] / 10
    assert simplified["curves"] == everything["curves"]
    if HAVE_RSVG:
        images = []
        for svg in (raw, small):
            png = svg.with_suffix(".png")
            subprocess.run(["rsvg-convert", str(svg), "-o", str(png)], check=True)
            images.append(pixels(QImage(str(png))))
        difference = np.abs(images[0] - images[1]).max(axis=2)
        assert (difference > 32).mean() < 0.03 and (difference > 128).mean() < 0.002


def test_the_window_store_bounds_a_figure_however_long_the_run(qtbot, tmp_path, double_pendulum):
    from explorer.panels.phase_view import PhaseView

    built, compiled = double_pendulum
    store = long_store(built, compiled, 200_000, capacity=1 << 15)
    assert len(store.main.t) <= 1 << 15
    view = PhaseView()
    qtbot.addWidget(view)
    view.resize(900, 700)
    view.set_system(compiled, compiled.initial_state())
    view.show()
    qtbot.waitExposed(view)
    view.refresh(store)
    svg = export_widget(view.export_target(), tmp_path / "phase.svg", (1800, 1400))
    assert svg.stat().st_size < 600_000


# -- CSV thinned by time -----------------------------------------------------------------------


def test_csv_rows_by_time():
    t = np.arange(0.0, 10.0001, 0.3)  # samples 0.3 apart
    every = csv_rows(t, every=1.0)
    # the first sample at or after 0, 1, 2, ... 9, and the last one
    assert t[every].tolist() == pytest.approx([0, 1.2, 2.1, 3.0, 4.2, 5.1, 6.0, 7.2, 8.1, 9.0, 9.9])
    points = csv_rows(t, points=5)
    assert len(points) == 5 and points[0] == 0 and points[-1] == len(t) - 1
    assert csv_rows(t).tolist() == list(range(len(t)))
    with pytest.raises(ValueError):
        csv_rows(t, every=1.0, points=3)
    with pytest.raises(ValueError):
        csv_rows(t, points=1)


def test_window_csv_leaves_out_gaps_and_thins(tmp_path, double_pendulum):
    built, compiled = double_pendulum
    store = long_store(built, compiled, 50_000, capacity=8192)  # thinned: gap rows inside
    main = store.main
    assert is_gap(main.y.data).any()
    whole = write_trajectories_csv(compiled, list(store), tmp_path / "all.csv")
    header, table = read_csv(whole)
    assert header[0] == "t" and np.isfinite(table).all()
    assert len(table) == (~is_gap(main.y.data)).sum()
    header, table = read_csv(
        write_trajectories_csv(compiled, list(store), tmp_path / "n.csv", points=200)
    )
    # where old samples were thinned, several times share one sample: written once
    assert 10 < len(table) <= 200 and np.all(np.diff(table[:, 0]) > 0)
    dense = long_store(built, compiled, 5000, capacity=1 << 17)
    assert not is_gap(dense.main.y.data).any()
    header, table = read_csv(
        write_trajectories_csv(compiled, list(dense), tmp_path / "dense.csv", points=200)
    )
    assert len(table) == 200 and np.all(np.diff(table[:, 0]) > 0)
    step = main.last_t / 50
    header, table = read_csv(
        write_trajectories_csv(compiled, list(store), tmp_path / "dt.csv", every=step)
    )
    assert 2 <= len(table) <= 51 and np.isfinite(table).all()
    step = dense.main.last_t / 50
    header, table = read_csv(
        write_trajectories_csv(compiled, list(dense), tmp_path / "dense_dt.csv", every=step)
    )
    assert len(table) == 51 and np.isfinite(table).all()
    assert np.all(table[:, 0] >= step * np.arange(51) - 1e-9)


def test_export_command_writes_csv_rows_as_run_does(tmp_path):
    out = tmp_path / "every.csv"
    args = ["export", "simple_pendulum", "--t-end", "10"]
    assert main([*args, "--every", "0.5", "--out", str(out)]) == 0
    header, table = read_csv(out)
    assert header == ["t", "theta", "theta_dot", "p_theta", "H"]
    assert len(table) == 21 and table[0, 0] == 0.0 and table[-1, 0] == pytest.approx(10.0)
    # the same rows, states and all, as run --every writes
    ran = tmp_path / "run.csv"
    assert (
        main(["run", "simple_pendulum", "--t-end", "10", "--every", "0.5", "--out", str(ran)]) == 0
    )
    _, run_table = read_csv(ran)
    assert run_table.shape == table.shape
    assert np.allclose(run_table, table, rtol=1e-12, atol=1e-12)
    points = tmp_path / "points.csv"
    assert main([*args, "--points", "7", "--out", str(points)]) == 0
    _, table = read_csv(points)
    assert len(table) == 7 and table[-1, 0] == pytest.approx(10.0)
    targets = np.linspace(0.0, 10.0, 7)
    assert np.all(table[:, 0] >= targets - 1e-12) and np.all(table[:, 0] < targets + 0.1)


# -- the dialog --------------------------------------------------------------------------------


def test_export_dialog_offers_twice_the_panel_and_returns_the_choices(qtbot):
    from explorer.export_dialog import ExportDialog

    dialog = ExportDialog((411, 538))
    qtbot.addWidget(dialog)
    assert (dialog.width_box.value(), dialog.height_box.value()) == (822, 1076)
    assert dialog.options() == ExportOptions("png", width=822, height=1076)
    dialog.width_box.setValue(411)  # the shape is kept
    assert dialog.height_box.value() == 538
    dialog.keep_shape.setChecked(False)
    dialog.height_box.setValue(300)
    assert dialog.options().size == (411, 300)
    dialog.format_combo.setCurrentIndex(dialog.format_combo.findData("svg"))
    assert dialog.options() == ExportOptions("svg", width=411, height=300)
    assert dialog.figure_group.isEnabled() and not dialog.table_group.isEnabled()
    dialog.format_combo.setCurrentIndex(dialog.format_combo.findData("csv"))
    assert not dialog.figure_group.isEnabled() and dialog.table_group.isEnabled()
    assert dialog.options() == ExportOptions("csv")
    dialog.every_rows.setChecked(True)
    dialog.every_box.setValue(0.25)
    assert dialog.options() == ExportOptions("csv", every=0.25)
    assert dialog.every_box.isEnabled() and not dialog.points_box.isEnabled()
    dialog.points_rows.setChecked(True)
    dialog.points_box.setValue(500)
    assert dialog.options() == ExportOptions("csv", points=500)
    assert dialog.options().suffix == ".csv" and "*.csv" in dialog.options().file_filter


def test_export_dialog_ask_returns_none_when_cancelled(qtbot):
    from PySide6.QtWidgets import QApplication

    from explorer.export_dialog import ExportDialog

    def answer(accept: bool) -> None:
        dialog = QApplication.activeModalWidget()
        (dialog.accept if accept else dialog.reject)()

    QTimer.singleShot(200, lambda: answer(True))
    chosen = ExportDialog.ask((300, 200), formats=("png", "svg"), format="svg")
    assert chosen == ExportOptions("svg", width=600, height=400)
    QTimer.singleShot(200, lambda: answer(False))
    assert ExportDialog.ask((300, 200)) is None


def test_export_options_are_checked():
    with pytest.raises(ValueError):
        ExportOptions("jpg")
    with pytest.raises(ValueError):
        ExportOptions("png", width=0, height=10)
    with pytest.raises(ValueError):
        ExportOptions("csv", every=math.inf)
    with pytest.raises(ValueError):
        ExportOptions("csv", every=1.0, points=10)
    assert ExportOptions("png", width=10).size is None
