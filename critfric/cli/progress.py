"""Sweep progress on stderr: a bar on a terminal (rich); on anything else (a batch job's log,
CI) one line per finished point with the elapsed time and an estimate of what remains.

Used only by the command line; ``quiet`` makes it a no-op callback.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from contextlib import contextmanager


def progress_lines(write: Callable[[str], None]) -> Callable:
    """``on_point(row, done, total)`` writing one line per finished point."""
    import time

    state = {"start": None}

    def on_point(row, done, total):
        now = time.monotonic()
        if row is None:  # the points already in the file
            state["start"] = (now, done)
            if done:
                write(f"critfric: sweep: {done} of {total} points already in the file")
            return
        t0, d0 = state["start"] or (now, 0)
        elapsed = now - t0
        left = elapsed / (done - d0) * (total - done) if done > d0 else float("nan")
        best = f"{row['positive'][0]:.10g}" if row.get("positive") else "none"
        size = "" if row.get("size") is None else f", h = {row['size']:g}"
        write(f"critfric: sweep: point {done}/{total} (nu = {row['nu']:g}, {row['element']}"
              f"{size}): {row['status']}, lowest > 0: {best}; {elapsed:.1f} s elapsed, "
              f"about {left:.0f} s left")

    return on_point


@contextmanager
def progress_bar(*, enabled: bool, label: str = "sweep",
                 terminal: bool = True) -> Iterator[Callable]:
    """Yield ``on_point(row, done, total)``: a bar on stderr when ``enabled`` and
    ``terminal``, plain lines when ``enabled`` only, nothing otherwise."""
    if not enabled:
        yield lambda row, done, total: None
        return
    if not terminal:
        import sys

        yield progress_lines(lambda line: print(line, file=sys.stderr, flush=True))
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
