"""The project's exception types.

Every error the library raises on purpose is a :class:`CritfricError`. The CLI turns
:class:`CaseError` (bad input: a case file, an option, an output path) into exit code 2 and
:class:`SolverError` (a numerical failure) into exit code 1. The library never prints or exits.
"""

from __future__ import annotations


class CritfricError(Exception):
    """Base class of every error critfric raises on purpose."""

    exit_code = 1


class CaseError(CritfricError):
    """Bad input: the message names the file, the dotted key, the value and what is allowed."""

    exit_code = 2

    def __init__(self, message: str, *, file: str | None = None, key: str | None = None):
        self.file = file
        self.key = key
        self.detail = message
        where = ": ".join(part for part in (file, f"[{key}]" if key else None) if part)
        super().__init__(f"{where}: {message}" if where else message)

    def located(self, file: str) -> CaseError:
        """This error, naming ``file`` if it named no file yet."""
        return self if self.file else CaseError(self.detail, file=file, key=self.key)


class SolverError(CritfricError):
    """A numerical stage failed: the message says what failed and what to try."""

    exit_code = 1


class WriteError(CritfricError):
    """An output could not be written (disk full, I/O error): nothing was changed."""

    exit_code = 1
