"""The PySide6 6.12 / Python 3.11 singleton refcount workaround keeps the process alive."""

import subprocess
import sys

SCRIPT = """
import os
os.environ["QT_QPA_PLATFORM"] = "offscreen"
import explorer  # applies the workaround
from PySide6.QtCore import QCoreApplication, QObject, QTimer, Signal
app = QCoreApplication([])
class Emitter(QObject):
    happened = Signal()
timer, emitter = QTimer(), Emitter()
for _ in range(200_000):
    timer.setInterval(5)  # a void method: releases a reference to None on 6.12 / 3.11
    emitter.happened.emit()  # releases a reference to True or False
print("alive")
"""


def test_many_void_calls_and_emits_do_not_abort():
    result = subprocess.run(
        [sys.executable, "-c", SCRIPT], capture_output=True, text=True, timeout=120
    )
    assert result.returncode == 0, result.stderr[-2000:]
    assert result.stdout.strip() == "alive"
