"""The typer app and what its commands share: the options of every computing command and the
formatting of short lists of values. The commands live in :mod:`.app` and :mod:`.pathcmd`."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from ..files.safety import check_output, interrupt_guard, output_lock
from .failures import say

app = typer.Typer(
    add_completion=True,
    rich_markup_mode=None,
    no_args_is_help=True,
    pretty_exceptions_show_locals=False,
    help="Critical friction coefficients of Coulomb frictional contact (plane strain).",
)


MaxDofs = Annotated[int | None, typer.Option(
    "--max-dofs", min=1, help="Refuse meshes above this many DOFs [default: what memory allows].")]
TrustGeo = Annotated[bool, typer.Option(
    "--trust-geo", help="Mesh a .geo script even if it can run programs or touch other files.")]


def fmt_values(values, n: int = 4) -> str:
    """The first ``n`` values (10 significant digits) and how many more."""
    shown = ", ".join(f"{v:.10g}" for v in list(values)[:n])
    more = len(values) - n
    return (shown + (f", ... (+{more})" if more > 0 else "")) or "-"


def computed_and_written(path: Path, *, force: bool, inputs, compute, write, ending):
    """Refuse ``path`` before anything is computed (it exists without --force, or it is one of
    the ``inputs``), then, under a lock and a Ctrl-C guard, ``compute()`` the result and
    ``write(result, path, force=force)`` it: a Ctrl-C before the write leaves nothing, one
    during the write comes after it. ``ending.kept`` says the file is written."""
    path = check_output(path, force=force, inputs=inputs)
    with interrupt_guard() as interrupted, output_lock(path):
        check_output(path, force=force)  # again: another run may have written it
        result = compute()
        interrupted.check()  # a Ctrl-C that Python swallowed: still nothing written
        with interrupted.deferred():  # a Ctrl-C during the write comes after it
            write(result, path, force=force)
            ending.kept = f"the result is written to {path}"
    return path, result


def figures_and_notes(path: Path, result, *, plot: bool) -> None:
    """Write the figures of ``path`` if asked, then say the result's notes and warnings."""
    if plot:
        from ..plots.figures import plot_file

        for png in plot_file(path):
            say(f"wrote {png}")
    for note in result.notes:
        say(f"critfric: note: {note}")
    for warning in getattr(result, "warnings", []):
        say(f"critfric: warning: {warning}")
