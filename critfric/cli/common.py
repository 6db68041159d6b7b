"""The typer app and what its commands share: the options of every computing command and the
formatting of short lists of values. The commands live in :mod:`.app` and :mod:`.pathcmd`."""

from __future__ import annotations

import inspect
import types
import typing
from pathlib import Path
from typing import Annotated

import typer
from typer.core import TyperGroup
from typer.models import ParameterInfo

from ..case.numbers import FINITE_NUMBER, SIGNED_INTEGER, plain_integer, plain_number, shown
from ..errors import CaseError
from ..files.safety import check_output, interrupt_guard, output_lock
from .failures import one_line_usage_errors, say


def plain_parser(kind: type, low=None, high=None):
    """The parser of an int or float option: plain ASCII digits only (no ``_``, Unicode
    digits, ``nan``, ``inf`` or spaces), within [``low``, ``high``]; anything else is a
    usage error (exit 2) naming the option, the value (escaped) and what is allowed."""
    bounds = " and ".join(f"{op} {v:g}" for op, v in ((">=", low), ("<=", high)) if v is not None)
    allowed = (SIGNED_INTEGER if kind is int else FINITE_NUMBER) + (
        f", {bounds}" if bounds else "")

    def parse(value):
        try:
            if isinstance(value, int | float):  # a default
                number = kind(value)
            elif kind is int:
                number = plain_integer(value, "", allowed=allowed, spaces=False, signed=True)
            else:
                number = plain_number(value, "", allowed=allowed, spaces=False)
            if (low is not None and number < low) or (high is not None and number > high):
                raise CaseError(f"got {shown(value)}; allowed: "
                                f"{'an integer' if kind is int else 'a number'} {bounds}")
        except CaseError as exc:
            raise typer.BadParameter(exc.detail) from None  # typer names the option
        return number

    return parse


def _number_kind(annotation) -> type | None:
    """int or float if ``annotation`` is one of them (or it or None), else None."""
    if typing.get_origin(annotation) is Annotated:
        annotation = typing.get_args(annotation)[0]
    if typing.get_origin(annotation) in (typing.Union, types.UnionType):
        kinds = [a for a in typing.get_args(annotation) if a is not type(None)]
        annotation = kinds[0] if len(kinds) == 1 else None
    return annotation if annotation in (int, float) else None


def _numeric_options(function):
    """(flag, kind, the ParameterInfos) of each int or float option of ``function``."""
    hints = typing.get_type_hints(function, include_extras=True)
    for name, parameter in inspect.signature(function).parameters.items():
        kind = _number_kind(hints.get(name))
        infos = [i for i in (parameter.default, *getattr(hints.get(name), "__metadata__", ()))
                 if isinstance(i, ParameterInfo)]
        if kind and infos:
            flags = [d for i in infos for d in (i.param_decls or ()) if d.startswith("--")]
            yield (flags or ["--" + name.replace("_", "-")])[0], kind, infos


class OneLineGroup(TyperGroup):
    """The command group: its own and its commands' usage errors are one line each."""

    def make_context(self, *args, **kwargs):
        with one_line_usage_errors():
            return super().make_context(*args, **kwargs)

    def invoke(self, ctx):
        with one_line_usage_errors():
            return super().invoke(ctx)


class PlainNumbersApp(typer.Typer):
    """A typer app whose commands' int and float options all read plain ASCII numbers
    through :func:`plain_parser`, a later option included."""

    def command(self, *args, **kwargs):
        register = super().command(*args, **kwargs)

        def decorator(function):
            for _, kind, infos in _numeric_options(function):
                for info in infos:
                    if info.parser is None and getattr(info, "click_type", None) is None:
                        info.parser = plain_parser(kind, info.min, info.max)
            return register(function)

        return decorator


def number_options(typer_app: typer.Typer) -> list[tuple[str, str]]:
    """(command, option) of every int or float option of the app's commands."""
    return [(c.name or c.callback.__name__.replace("_", "-"), flag)
            for c in typer_app.registered_commands for flag, _, _ in _numeric_options(c.callback)]


app = PlainNumbersApp(
    cls=OneLineGroup,
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
