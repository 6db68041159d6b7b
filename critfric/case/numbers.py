"""Numbers typed as text (ranges and lists on the command line): plain ASCII only.

Python's ``float`` and ``int`` also read full-width and other Unicode digits, ``_``
separators, ``nan`` and ``inf``; a value that only looks like a number (``０.３``, ``−1``
with a minus sign that is not ``-``, a superscript ``³``) is refused with the characters
named, never guessed. Allowed: ASCII digits, ``.``, ``e``/``E``, ``+`` and ``-``.
"""

from __future__ import annotations

import math
import re
import unicodedata

from ..errors import CaseError

PLAIN_NUMBER = "a plain number: ASCII digits 0-9, '.', 'e', '+', '-' (e.g. 0.25, -2, 1e-3)"
FINITE_NUMBER = "a finite " + PLAIN_NUMBER.removeprefix("a ")
PLAIN_INTEGER = "a plain integer: ASCII digits 0-9 (e.g. 11)"
SIGNED_INTEGER = "a plain integer: ASCII digits 0-9 and a sign (e.g. 11, -1)"
MAX_CHARS = 64  # longer text is no number a user meant
_NUMBER = re.compile(r"[+-]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][+-]?[0-9]+)?")
_INTEGER = re.compile(r"\+?[0-9]+")
_SIGNED = re.compile(r"[+-]?[0-9]+")


def shown(text: str) -> str:
    """``text`` quoted (cut at 40 characters), with its non-ASCII or unprintable characters
    named: U+2212 MINUS SIGN looks like '-' but is not."""
    text = str(text)
    odd = [c for c in dict.fromkeys(text) if not (c.isascii() and c.isprintable())]
    names = ", ".join(f"U+{ord(c):04X} {unicodedata.name(c, 'unnamed character')}"
                      for c in odd[:3]) + (", ..." if len(odd) > 3 else "")
    return repr(text[:40] + ("..." if len(text) > 40 else "")) + (
        f" (contains {names})" if odd else "")


def _got(text: str, within: str | None) -> str:
    whole = f" in {str(within)[:60]!r}" if within not in (None, text) else ""
    return f"got {shown(text)}{whole}"


def _bare(text: str, spaces: bool) -> str:
    return str(text).strip(" \t") if spaces else str(text)


def plain_number(text: str, key: str, *, allowed: str = PLAIN_NUMBER,
                 within: str | None = None, spaces: bool = True) -> float:
    """The finite float written as ``text`` (ASCII spaces around it allowed if ``spaces``:
    a part of a list), else a :class:`CaseError` naming ``key``, the value (and the whole
    option value ``within`` that it is part of) and ``allowed``."""
    s = _bare(text, spaces)
    if len(s) > MAX_CHARS or not _NUMBER.fullmatch(s):
        raise CaseError(f"{_got(text, within)}; allowed: {allowed}", key=key)
    value = float(s)
    if not math.isfinite(value):  # 1e999
        raise CaseError(f"{_got(text, within)}, beyond the largest float; allowed: {allowed}",
                        key=key)
    return value


def plain_integer(text: str, key: str, *, allowed: str = PLAIN_INTEGER,
                  within: str | None = None, spaces: bool = True, signed: bool = False) -> int:
    """The non-negative integer (any integer if ``signed``: the caller checks its range)
    written as ``text`` in ASCII digits, else a :class:`CaseError` as :func:`plain_number`
    gives."""
    s = _bare(text, spaces)
    if len(s) > MAX_CHARS or not (_SIGNED if signed else _INTEGER).fullmatch(s):
        raise CaseError(f"{_got(text, within)}; allowed: {allowed}", key=key)
    return int(s)
