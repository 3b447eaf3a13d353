"""PNG, SVG and CSV out of the window and the `export` command, checked for content."""

from __future__ import annotations

import csv
import os
import shutil
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest
from PySide6.QtGui import QColor, QImage

from explorer.cli import main
from tests.explorer.conftest import wait_for_points

ROOT = Path(__file__).resolve().parents[2]
SVG = "{http://www.w3.org/2000/svg}"


def _colour_pixels(image: QImage, colour: str, tolerance: int = 40) -> int:
    """How many pixels are close to ``colour`` (sampled on a grid)."""
    target = QColor(colour)
    count = 0
    for x in range(0, image.width(), 2):
        for y in range(0, image.height(), 2):
            c = image.pixelColor(x, y)
            if (
                abs(c.red() - target.red())
                + abs(c.green() - target.green())
                + abs(c.blue() - target.blue())
                < tolerance
            ):
                count += 1
    return count


def _svg_paths(path: Path, data_only: bool = False) -> list[str]:
    """The ``d`` of every path; with ``data_only`` only those drawn in pixel units (our
    data curves), not with a non-scaling stroke under a data-to-pixel transform."""
    root = ET.parse(path).getroot()
    return [
        element.get("d", "")
        for element in root.iter(f"{SVG}path")
        if not (data_only and element.get("vector-effect", "none") != "none")
    ]


def test_window_exports_png_svg_csv(qtbot, window, tmp_path):
    wait_for_points(qtbot, window, 40)
    window.phase_view.launch_at(0.3, 5.0)  # a rotating orbit beyond the separatrix
    wait_for_points(qtbot, window, 20, key=1)
    png = window.export_panel("phase", tmp_path / "phase.png")
    image = QImage(str(png))
    assert image.width() > 300 and image.height() > 200
    assert _colour_pixels(image, "#e6550d") > 100  # the separatrix
    assert _colour_pixels(image, "#1f77b4") > 20  # the orbit
    svg = window.export_panel("phase", tmp_path / "phase.svg")
    paths = _svg_paths(svg, data_only=True)
    long_paths = [d for d in paths if d.count("L") > 50]
    assert len(long_paths) >= 5  # level sets, separatrix, orbits as vector paths
    for key in ("configuration", "conserved"):
        assert QImage(str(window.export_panel(key, tmp_path / f"{key}.png"))).width() > 100
        assert _svg_paths(window.export_panel(key, tmp_path / f"{key}.svg"))
    path = window.export_csv(tmp_path / "orbits.csv")
    with path.open() as handle:
        rows = list(csv.reader(handle))
    assert rows[0] == ["orbit", "t", "theta", "theta_dot", "p_theta", "H"]
    table = np.array(rows[1:], dtype=float)
    assert set(table[:, 0]) == {1.0, 2.0}
    main = table[table[:, 0] == 1]
    m, g, l = window.compiled.parameters
    # columns agree with each other: p = m l^2 theta_dot and H = p^2/(2 m l^2) - m g l cos
    assert np.allclose(main[:, 4], m * l**2 * main[:, 3])
    H = main[:, 4] ** 2 / (2 * m * l**2) - m * g * l * np.cos(main[:, 2])
    assert np.allclose(main[:, 5], H)
    assert np.ptp(main[:, 5]) < 1e-5 * abs(main[0, 5])


@pytest.mark.skipif(shutil.which("rsvg-convert") is None, reason="rsvg-convert not installed")
def test_svg_renders_with_its_curves_in_a_real_renderer(qtbot, window, tmp_path):
    wait_for_points(qtbot, window, 20)
    svg = window.export_panel("phase", tmp_path / "phase.svg")
    png = tmp_path / "rendered.png"
    subprocess.run(["rsvg-convert", str(svg), "-o", str(png)], check=True)
    image = QImage(str(png))
    assert _colour_pixels(image, "#e6550d") > 100  # the separatrix, drawn by librsvg
    # nothing is drawn outside the plot: the left edge of the picture stays white
    strip = [image.pixelColor(1, y).lightness() for y in range(0, image.height(), 4)]
    assert min(strip) > 200


def test_export_command_writes_png_and_svg(tmp_path, capsys):
    out = tmp_path / "pendulum.png"
    assert (
        main(["export", "simple_pendulum", "--panel", "phase", "--t-end", "3", "--out", str(out)])
        == 0
    )
    assert QImage(str(out)).width() > 300
    assert "wrote" in capsys.readouterr().out
    svg = tmp_path / "double.svg"
    assert (
        main(
            [
                "export",
                "double_pendulum",
                "--panel",
                "configuration",
                "--t-end",
                "2",
                "--out",
                str(svg),
            ]
        )
        == 0
    )
    assert any(d.count("L") > 20 for d in _svg_paths(svg))
    section = tmp_path / "section.png"
    assert (
        main(["export", "henon_heiles", "--poincare", "--t-end", "300", "--out", str(section)]) == 0
    )
    assert QImage(str(section)).width() > 300


def test_a_driven_systems_stroboscopic_section_is_exported(tmp_path):
    from explorer.builder import build
    from explorer.headless import integrate
    from systems.chaos.bifurcation import drive_period
    from systems.scene import load_scene

    built = build(load_scene("driven_damped_pendulum"))
    period = drive_period(built.compiled)
    points = integrate(built, 50 * period + 0.5, strobe=period).main.events.data
    alone = integrate(built, 50 * period, times=period * np.arange(1, 51)).main.y.data[1:]
    assert points.shape == (50, 2) and np.allclose(points, alone, rtol=0, atol=1e-8)
    out = tmp_path / "strobe.png"
    argv = ["export", "driven_damped_pendulum", "--poincare", "--t-end", "200", "--out", str(out)]
    assert main(argv) == 0 and QImage(str(out)).width() > 300


def test_export_command_user_errors(tmp_path, capsys):
    assert main(["export", "simple_pendulum", "--out", str(tmp_path / "x.jpg")]) == 2
    assert "must end in .png or .svg" in capsys.readouterr().err
    assert main(["export", "no_such_scene", "--out", str(tmp_path / "x.png")]) == 2
    assert "no catalogue scene" in capsys.readouterr().err
    assert main(["export", "simple_pendulum", "--poincare", "--out", str(tmp_path / "x.png")]) == 2
    assert "two degrees of freedom" in capsys.readouterr().err


def test_no_display_prints_a_clear_message():
    env = {
        k: v
        for k, v in os.environ.items()
        if k not in ("DISPLAY", "WAYLAND_DISPLAY", "QT_QPA_PLATFORM")
    }
    result = subprocess.run(
        [sys.executable, str(ROOT / "main.py")],
        capture_output=True,
        text=True,
        env=env,
        cwd=ROOT,
        timeout=60,
    )
    assert result.returncode == 2
    assert "needs a display" in result.stderr
    assert "QT_QPA_PLATFORM=offscreen" in result.stderr and "export" in result.stderr
    assert "Aborted" not in result.stderr and "qt.qpa" not in result.stderr


def test_open_command_rejects_an_unknown_scene_before_any_window(capsys):
    assert main(["open", "no_such_scene"]) == 2
    assert "no catalogue scene or file named 'no_such_scene'" in capsys.readouterr().err
