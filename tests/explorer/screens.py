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


def _config(size: tuple[int, int], folder: Path) -> Path:
    width, height = size
    config = Path(folder) / f"screen-{width}x{height}.json"
    screen = {"name": "test", "x": 0, "y": 0, "width": width, "height": height}
    config.write_text(json.dumps({"screens": [{**screen, "logicalDpi": 96, "dpr": 1}]}))
    return config


def _start(script: str, arguments: list[str], size: tuple[int, int], folder: Path):
    env = {
        **os.environ,
        "QT_QPA_PLATFORM": f"offscreen:configfile={_config(size, folder)}",
        "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]),
    }
    return subprocess.Popen(
        [sys.executable, script, *arguments],
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        cwd=ROOT,
    )


def _report(process: subprocess.Popen) -> dict:
    try:
        out, err = process.communicate(timeout=600)
    except subprocess.TimeoutExpired:
        process.kill()
        out, err = process.communicate()
    assert process.returncode == 0, err[-3000:]
    return json.loads(out.strip().splitlines()[-1])


def measure_on_screen(script: str, arguments: list[str], size: tuple[int, int], folder: Path):
    """Run ``script`` with ``arguments`` on a ``size`` screen (96 dpi, ratio 1); its last
    line of output, read as JSON."""
    return _report(_start(script, arguments, size, folder))


def spin(app, condition, seconds: float) -> None:
    """Process events until ``condition()`` or ``seconds`` have passed (in the script)."""
    deadline = time.monotonic() + seconds
    while not condition() and time.monotonic() < deadline:
        app.processEvents()
        time.sleep(0.02)


def measure_screens(script: str, sizes, folder: Path, arguments: list[str] | None = None) -> dict:
    """``measure_on_screen(script, arguments or [folder], size, folder)`` for each of
    ``sizes``, by size: the processes run at the same time (each mostly waits for its
    window to lay out, paint and compute)."""
    arguments = [str(folder)] if arguments is None else arguments
    started = {size: _start(script, arguments, size, folder) for size in sizes}
    try:
        return {size: _report(process) for size, process in started.items()}
    finally:
        for process in started.values():
            if process.poll() is None:
                process.kill()
                process.wait()
