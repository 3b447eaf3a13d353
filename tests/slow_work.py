"""Stand-ins for slow symbolic work, run in worker processes (``systems.processes``).

A worker imports a function by its module and name, so a test's monkeypatch of the
window's process does not reach it: tests put these in place of the real functions
instead (``monkeypatch.setattr(explorer.builder, "build_code", crawl_then_derive)``).
This module imports neither Qt nor pytest, so workers stay light. ``gone(pid)`` tells
whether a worker has ended.
"""

from __future__ import annotations

import time

CRAWL_SECONDS = 60.0


def crawl(seconds: float = CRAWL_SECONDS) -> None:
    """Pure Python for ``seconds`` of CPU time, as sympy is."""
    end = time.process_time() + seconds
    while time.process_time() < end:
        sum(range(1000))


def crawl_then_derive(source):
    """``systems.sources.build_code`` after a long crawl."""
    from systems.sources import build_code

    crawl()
    return build_code(source)


def crawl_if_three_coordinates(source):
    """``build_code``, crawling first for a scene of three coordinates."""
    from systems.scene import Scene
    from systems.sources import build_code

    if isinstance(source, Scene) and len(source.coordinates) == 3 or "theta3" in str(source):
        crawl()
    return build_code(source)


def gone(pid: int) -> bool:
    """Whether process ``pid`` has ended (a zombie not yet reaped counts as ended)."""
    import os

    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return True
    try:
        with open(f"/proc/{pid}/stat") as stat:
            return stat.read().split(") ")[1].startswith("Z")
    except OSError:
        return True


def crawl_describing(mechanics) -> str:
    """``explorer.builder.describe`` that never ends by itself."""
    crawl()
    return ""
