"""What the window remembers between sessions: recent files, the last folder used and the
panels shown in presentation mode.

Kept in one small JSON file, ``preferences.json``, in ``PHASE_EXPLORER_CONFIG`` when it
is set (the tests point it at a temporary folder), else in the platform's configuration
folder (``~/.config/phase-explorer`` on Linux). A file that cannot be read is treated as
empty and one that cannot be written is skipped: preferences never stop the program.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

RECENT_LIMIT = 8
PRESENTATION_PANELS = ("configuration", "conserved")
"""The docks presentation mode shows beside the phase plane until the user chooses."""


def config_dir() -> Path:
    """The folder of the preferences file (not created here)."""
    configured = os.environ.get("PHASE_EXPLORER_CONFIG")
    if configured:
        return Path(configured)
    base = os.environ.get("XDG_CONFIG_HOME") or Path.home() / ".config"
    return Path(base) / "phase-explorer"


class Preferences:
    """Recent scene files (newest first) and the folder file dialogs start in."""

    def __init__(self, path: Path | None = None):
        self.path = path or config_dir() / "preferences.json"
        self._data: dict = {}
        from systems.files import read_file

        try:  # a pipe or a device in its place is ignored, not waited on (read_file)
            data = json.loads(read_file(self.path, 2**20).decode("utf-8"))
            if isinstance(data, dict):
                self._data = data
        except (OSError, ValueError):
            pass

    @property
    def recent(self) -> list[str]:
        """Recent scene files that still exist, newest first."""
        items = self._data.get("recent", [])
        if not isinstance(items, list):
            return []
        return [p for p in items if isinstance(p, str) and Path(p).is_file()][:RECENT_LIMIT]

    def add_recent(self, path: str | Path) -> None:
        """Put ``path`` first in the recent files and remember its folder."""
        path = str(Path(path).resolve())
        self._data["recent"] = [path] + [p for p in self.recent if p != path]
        self._data["recent"] = self._data["recent"][:RECENT_LIMIT]
        self._data["folder"] = str(Path(path).parent)
        self._save()

    def clear_recent(self) -> None:
        self._data["recent"] = []
        self._save()

    @property
    def folder(self) -> str:
        """The folder of the last scene opened or saved, or the working directory."""
        folder = self._data.get("folder")
        if isinstance(folder, str) and Path(folder).is_dir():
            return folder
        return str(Path.cwd())

    @property
    def presentation_panels(self) -> tuple[str, ...]:
        """The dock keys presentation mode shows (View > Presentation panels)."""
        panels = self._data.get("presentation_panels")
        if not isinstance(panels, list) or not all(isinstance(p, str) for p in panels):
            return PRESENTATION_PANELS
        return tuple(panels)

    def set_presentation_panels(self, panels: tuple[str, ...] | list[str]) -> None:
        """Remember the dock keys presentation mode shows."""
        self._data["presentation_panels"] = list(panels)
        self._save()

    def _save(self) -> None:
        from systems.files import atomic_path

        try:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            with atomic_path(self.path) as temporary:
                temporary.write_text(json.dumps(self._data, indent=1), encoding="utf-8")
        except OSError:
            pass
