"""Run a measuring script in a process whose offscreen screen has a given size.

Qt's offscreen platform takes its screens from a JSON file (``offscreen:configfile=``);
the size is fixed when the application starts, so each size gets a process of its own.
The script prints one JSON object as its last line of output, which is returned.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def measure_on_screen(script: str, arguments: list[str], size: tuple[int, int], folder: Path):
    """Run ``script`` with ``arguments`` on a ``size`` screen (96 dpi, ratio 1); its last
    line of output, read as JSON."""
    width, height = size
    config = Path(folder) / f"screen-{width}x{height}.json"
    screen = {"name": "test", "x": 0, "y": 0, "width": width, "height": height}
    config.write_text(json.dumps({"screens": [{**screen, "logicalDpi": 96, "dpr": 1}]}))
    env = {
        **os.environ,
        "QT_QPA_PLATFORM": f"offscreen:configfile={config}",
        "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]),
    }
    done = subprocess.run(
        [sys.executable, script, *arguments],
        env=env,
        capture_output=True,
        text=True,
        timeout=600,
        cwd=ROOT,
    )
    assert done.returncode == 0, done.stderr[-3000:]
    return json.loads(done.stdout.strip().splitlines()[-1])


def spin(app, condition, seconds: float) -> None:
    """Process events until ``condition()`` or ``seconds`` have passed (in the script)."""
    deadline = time.monotonic() + seconds
    while not condition() and time.monotonic() < deadline:
        app.processEvents()
        time.sleep(0.02)


def measure_screens(script: str, sizes, folder: Path) -> dict:
    """``measure_on_screen(script, [folder], size, folder)`` for each of ``sizes``, by size."""
    return {size: measure_on_screen(script, [str(folder)], size, folder) for size in sizes}
