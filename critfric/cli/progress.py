"""A progress bar for sweeps on stderr (rich): points done, rate, time left.

Used only by the command line; a disabled bar is a no-op callback.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from contextlib import contextmanager


@contextmanager
def progress_bar(*, enabled: bool, label: str = "sweep") -> Iterator[Callable]:
    """Yield ``on_point(row, done, total)`` that advances a bar on stderr when ``enabled``."""
    if not enabled:
        yield lambda row, done, total: None
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

    columns = (TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(),
               TextColumn("points  {task.fields[rate]}  elapsed"), TimeElapsedColumn(),
               TextColumn("left"), TimeRemainingColumn())
    with Progress(*columns, console=Console(stderr=True), transient=False) as bar:
        task = bar.add_task(label, total=None, rate="")
        state = {"start": None}

        def on_point(row, done, total):
            if row is None:  # the points already in the file
                bar.reset(task, total=total, completed=done)
                state["start"] = (bar.get_time(), done)
                return
            t0, d0 = state["start"] or (bar.get_time(), 0)
            elapsed = bar.get_time() - t0
            rate = (done - d0) / elapsed if elapsed > 0 else 0.0
            bar.update(task, total=total, completed=done, rate=f"{rate:.2f}/s")

        yield on_point
