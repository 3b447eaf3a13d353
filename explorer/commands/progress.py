"""A progress bar on the terminal for the long commands (``chaosmap``, ``bifurcation``):
``rich``'s, on stderr, and only when stderr is a terminal and the output is not
``--json`` (a pipe, a log file or a JSON reader gets no bar)."""

from __future__ import annotations

import contextlib
import sys
from collections.abc import Callable, Iterator
from typing import TextIO


@contextlib.contextmanager
def terminal_progress(
    label: str, *, json_output: bool = False, stream: TextIO | None = None
) -> Iterator[Callable[[int, int], None] | None]:
    """A ``progress(done, total)`` callback drawing a bar on ``stream`` (default
    ``sys.stderr``), or None where no bar is drawn: ``json_output``, or a stream that is
    not a terminal. The bar stays on the terminal, complete, when the block ends."""
    stream = sys.stderr if stream is None else stream
    isatty = getattr(stream, "isatty", None)
    if json_output or not (callable(isatty) and isatty()):
        yield None
        return
    from rich.console import Console
    from rich.progress import (
        BarColumn,
        MofNCompleteColumn,
        Progress,
        TextColumn,
        TimeElapsedColumn,
        TimeRemainingColumn,
    )

    console = Console(file=stream, force_terminal=True)
    columns = (
        TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(),
        TimeElapsedColumn(), TextColumn("left"), TimeRemainingColumn(),
    )  # fmt: skip
    with Progress(*columns, console=console, transient=False) as bar:
        task = bar.add_task(label, total=None)

        def progress(done: int, total: int) -> None:
            bar.update(task, completed=done, total=total)

        yield progress
