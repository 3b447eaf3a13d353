"""Every ```python block of docs/api.md runs, in order, in one fresh namespace, and its
checks hold (each block asserts what the page says it shows)."""

from __future__ import annotations

import os
import re
from pathlib import Path

import pytest

DOC = Path(__file__).resolve().parents[2] / "docs" / "api.md"


def blocks(text: str) -> list[tuple[int, str]]:
    """(line, code) of each fenced python block of ``text``."""
    found = []
    for match in re.finditer(r"^```python\n(.*?)^```", text, flags=re.M | re.S):
        found.append((text.count("\n", 0, match.start()) + 2, match.group(1)))
    return found


def test_the_page_has_a_block_for_every_call():
    code = "\n".join(code for _, code in blocks(DOC.read_text(encoding="utf-8")))
    for call in (
        "pe.load(", ".derive()", ".run(", ".section(", ".lyapunov(", ".chaosmap(",
        ".bifurcation(", ".plot(",
    ):  # fmt: skip
        assert call in code, call


def test_every_block_runs_in_order(tmp_path, monkeypatch):
    assert os.environ.get("PHASE_EXPLORER_CACHE")  # the test session's own (tests/conftest.py)
    monkeypatch.chdir(tmp_path)  # a block that writes a file writes it here
    namespace: dict = {"__name__": "api_docs"}
    found = blocks(DOC.read_text(encoding="utf-8"))
    assert len(found) >= 8
    for line, code in found:
        try:
            exec(compile(code, f"{DOC}:{line}", "exec"), namespace)
        except Exception as exc:  # name the block that failed
            pytest.fail(f"docs/api.md, the block at line {line}: {type(exc).__name__}: {exc}")
    assert namespace["pe"].__name__ == "phase_explorer"


def test_the_figures_are_png():
    import phase_explorer as pe

    orbit = pe.load("harmonic_oscillator").run(t_end=5, samples=50)
    png = orbit.plot()._repr_png_()
    assert png[:8] == b"\x89PNG\r\n\x1a\n"
