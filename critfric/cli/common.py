"""The typer app and what its commands share: the options of every computing command and the
formatting of short lists of values. The commands live in :mod:`.app` and :mod:`.pathcmd`."""

from __future__ import annotations

from typing import Annotated

import typer

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
