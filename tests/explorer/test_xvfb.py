"""Smoke test in a real X window under Xvfb (CI installs it; skipped when absent)."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]

SCRIPT = """
import sys, time
from explorer.app import application, create_window
from PySide6.QtCore import QEventLoop
app = application()
assert app.platformName() == "xcb", app.platformName()
window = create_window("simple_pendulum")
window.show()
deadline = time.time() + 90
while time.time() < deadline:
    app.processEvents(QEventLoop.ProcessEventsFlag.AllEvents, 50)
    main = window.store.main
    if main is not None and len(main.t) > 30 and window.redraws > 5:
        break
else:
    sys.exit("no data arrived in the window")
assert window.isVisible() and window.windowHandle().isExposed()
image = window.grab().toImage()
assert image.width() > 600
window.close()
print("ok", len(window.store.main.t))
"""


@pytest.mark.xvfb
@pytest.mark.skipif(shutil.which("xvfb-run") is None, reason="Xvfb (xvfb-run) is not installed")
def test_window_in_a_real_x_server():
    env = {k: v for k, v in os.environ.items() if k not in ("QT_QPA_PLATFORM", "DISPLAY")}
    env["QT_QPA_PLATFORM"] = "xcb"
    result = subprocess.run(
        ["xvfb-run", "-a", "-s", "-screen 0 1600x1000x24", sys.executable, "-c", SCRIPT],
        capture_output=True,
        text=True,
        env=env,
        cwd=ROOT,
        timeout=240,
    )
    assert result.returncode == 0, result.stdout[-2000:] + result.stderr[-3000:]
    assert result.stdout.startswith("ok")
