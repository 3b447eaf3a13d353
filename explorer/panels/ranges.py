"""Plot ranges for a scene: ``systems.view_ranges``, which the chaos maps and the Python API
share."""

from __future__ import annotations

from systems.view_ranges import axis_range, phase_ranges

__all__ = ["axis_range", "phase_ranges"]
