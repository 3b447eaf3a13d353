"""The session recorder writes an opening as one line: ``open`` or ``new``, no edits.

*File > Open* (``MainWindow.open_file``) and *File > New scene* fill the editor and ask
for a build through ``scene_edited``, the editor's signal for a user's edit. The recorder
took that filling for edits and wrote ``edit title ...``, ``edit coordinates ...``,
``parameters ...`` (and a "drawing not recorded" comment) before the ``open FILE`` line
and after ``new``: a replay then typed the new scene into the old one before opening it.
Edits typed after an opening are still recorded.
"""

from __future__ import annotations

import shutil
from pathlib import Path

from systems.scene import SCENES_DIR

REPLAY_MS = 60000


def _actions(recorder) -> list[str]:
    """The recorded lines without the time marks."""
    return [text for text in recorder.lines if not text.startswith("run-until")]


def test_opening_a_file_or_a_new_scene_records_no_edits(qtbot, blank_window, tmp_path):
    from explorer.session import Recorder

    window = blank_window
    recorder = Recorder(window)
    window.open_scene("simple_pendulum")
    qtbot.waitUntil(lambda: window.compiled is not None, timeout=REPLAY_MS)
    path = Path(shutil.copy(SCENES_DIR / "harmonic_oscillator.toml", tmp_path / "spring.toml"))
    request = window.open_file(path)
    qtbot.waitUntil(lambda: window.built.request == request, timeout=REPLAY_MS)
    assert _actions(recorder) == ["open simple_pendulum", f"open {path}"]
    # an edit typed after the opening is the user's: it is recorded
    window.editor.initial_table.item(0, 1).setText("0.8")
    qtbot.waitUntil(lambda: len(_actions(recorder)) == 3, timeout=REPLAY_MS)
    assert _actions(recorder)[2] == "initial x=0.8"
    window.new_scene()
    qtbot.wait(50)
    assert _actions(recorder)[3:] == ["new"]
