"""The one place where errors become messages and exit codes.

A :class:`CritfricError` becomes ``critfric: error: <message>`` on stderr and its exit code
(2 for bad input, 1 for a numerical or I/O failure), and so does a usage error of the
command-line parser (an unknown option, a value out of range: exit 2); Ctrl-C becomes ``critfric: interrupted``
with what was kept, and exit code 130; SIGTERM (under a command's interrupt guard) the same
with ``critfric: terminated`` and exit code 143.
"""

from __future__ import annotations

import sys
from collections.abc import Iterator
from contextlib import contextmanager

import typer

from ..errors import CritfricError
from ..files.safety import Terminated

INTERRUPTED = 130  # the shell's code for a process ended by SIGINT
TERMINATED = 143  # ... and by SIGTERM
_SAID = {"interrupted": False}


def said_interrupted() -> bool:
    """Whether a command already said it was interrupted."""
    return _SAID["interrupted"]


_VERBOSITY = {"level": 1}  # 0: errors only (-q), 1: notes and written files, 2: timings (-v)


def set_verbosity(level: int) -> None:
    _VERBOSITY["level"] = level


def verbosity() -> int:
    return _VERBOSITY["level"]


def say(message: str, level: int = 1) -> None:
    """One line on stderr (notes, warnings, written files), if the verbosity asks for it;
    control characters (from a file name, a case or a mesh) escaped, never sent."""
    if level <= _VERBOSITY["level"]:
        typer.echo(printable(message), err=True)


def printable(text: str) -> str:
    """``text`` with every non-printable character but line breaks as its Python escape."""
    return "".join(c if c.isprintable() or c == "\n" else repr(c)[1:-1] for c in text)


# the parser's usage errors, from the click typer runs on (its own copy in typer 0.20+)
USAGE_ERROR = next(c for c in typer.BadParameter.__mro__ if c.__name__ == "UsageError")
HELP_SCREEN = getattr(sys.modules[USAGE_ERROR.__module__], "NoArgsIsHelpError", ())


@contextmanager
def one_line_usage_errors() -> Iterator[None]:
    """A usage error of the command-line parser as one ``critfric: error:`` line (exit 2),
    with the command whose ``--help`` lists what is allowed; a help screen stays one."""
    try:
        yield
    except HELP_SCREEN:
        raise
    except USAGE_ERROR as exc:
        where = exc.ctx.command_path if exc.ctx is not None else "critfric"
        say(f"critfric: error: {exc.format_message()} (see '{where} --help')",
            level=0)
        raise typer.Exit(exc.exit_code) from None


class Ending:
    """What a Ctrl-C now would leave behind; a command updates ``kept`` as it writes."""

    def __init__(self, kept: str):
        self.kept = kept


@contextmanager
def reported(kept: str = "nothing was written") -> Iterator[Ending]:
    """Run a command's body (all of it, its printing included); turn its failures into a
    message and an exit code.

    kept: what an interruption leaves behind, said after ``critfric: interrupted:``; the
    body can change it (``ending.kept = ...``) once it has written something.
    """
    ending = Ending(kept)
    try:
        yield ending
    except CritfricError as exc:
        say(f"critfric: error: {exc}", level=0)
        raise typer.Exit(exc.exit_code) from None
    except MemoryError:  # past the memory guard's estimate: a message, not a traceback
        say(f"critfric: error: out of memory ({ending.kept}); use a coarser mesh, the fast "
            "extra (PARDISO needs less), or a machine with more memory", level=0)
        raise typer.Exit(1) from None
    except KeyboardInterrupt as exc:  # typer would exit 130 without a word
        term = isinstance(exc, Terminated)
        say(f"critfric: {'terminated' if term else 'interrupted'}: {ending.kept}", level=0)
        _SAID["interrupted"] = True
        raise typer.Exit(TERMINATED if term else INTERRUPTED) from None
