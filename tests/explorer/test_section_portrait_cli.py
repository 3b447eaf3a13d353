"""``export SCENE --poincare --orbits N``: a section portrait, each orbit its own colour."""

from __future__ import annotations

from PySide6.QtGui import QColor, QImage

from explorer.cli import main
from explorer.commands.export_cmd import orbit_colour


def _has_colour(image: QImage, colour: str, tolerance: int = 12) -> bool:
    target = QColor(colour)
    for x in range(image.width()):
        for y in range(0, image.height()):
            c = image.pixelColor(x, y)
            if (
                abs(c.red() - target.red()) + abs(c.green() - target.green())
                + abs(c.blue() - target.blue()) <= tolerance
            ):  # fmt: skip
                return True
    return False


def test_henon_heiles_portrait_draws_every_orbit_in_its_colour(tmp_path, capsys):
    """12 orbits at E = 1/8: the summary counts them and their crossings and gives the
    energy error; the figure holds the first and the last orbit's colours (drawn in
    the section plot, not in the legend, which names six)."""
    out = tmp_path / "portrait.png"
    argv = ["export", "henon_heiles", "--poincare", "--orbits", "12", "--energy", "0.125"]
    assert main([*argv, "--t-end", "300", "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "12 orbits" in printed and "(taylor)" in printed and "energy error" in printed
    image = QImage(str(out))
    assert image.width() > 300
    colours = [orbit_colour(k, 12) for k in range(12)]
    assert len(set(colours)) == 12
    assert _has_colour(image, colours[11]) and _has_colour(image, colours[7])


def test_escaping_orbits_are_named_and_the_status_is_one(tmp_path, capsys):
    """Above the escape energy 1/6 the orbits run off: each is named as not trusted, the
    figure is still written, and the exit status says so."""
    out = tmp_path / "escape.png"
    argv = ["export", "henon_heiles", "--poincare", "--orbits", "4", "--energy", "0.2"]
    assert main([*argv, "--t-end", "100", "--out", str(out)]) == 1
    captured = capsys.readouterr()
    assert "not trusted" in captured.out and "runs off to infinity" in captured.err
    assert out.exists()


def test_portrait_options_user_errors(tmp_path, capsys):
    png = str(tmp_path / "x.png")
    assert main(["export", "henon_heiles", "--orbits", "5", "--out", png]) == 2
    assert "--poincare" in capsys.readouterr().err
    assert main(["export", "henon_heiles", "--energy", "0.1", "--out", png]) == 2
    assert "go with --orbits" in capsys.readouterr().err
    argv = ["export", "henon_heiles", "--poincare", "--orbits", "0", "--out", png]
    assert main(argv) == 2 and "between 1 and" in capsys.readouterr().err
    argv = ["export", "simple_pendulum", "--poincare", "--orbits", "5", "--out", png]
    assert main(argv) == 2 and "two degrees of freedom" in capsys.readouterr().err
