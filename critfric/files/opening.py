"""Opening an HDF5 file from elsewhere: refused unopened unless a regular file, then walked
before anything of it is read, so that it can name nothing outside itself (no soft or external
link, no dataset stored in other files) and cannot loop. :mod:`.validate` then checks what a
critfric file of its kind holds."""

from __future__ import annotations

import math
import os
import stat
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import h5py
import numpy as np

from ..errors import CaseError

MAX_LINKS = 100_000  # objects a file may name (a solve file: ~20 + 4 per mode)


@contextmanager
def open_file(path: Path | str) -> Iterator[h5py.File]:
    """The HDF5 file at ``path``, open to read (a context); refused unless it is a regular
    file, checked on the descriptor it is read through (a pipe would block the open for
    ever, and one swapped in after a check by name would too)."""
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_NOCTTY", 0))
    except (OSError, ValueError) as exc:
        why = exc.strerror if isinstance(exc, OSError) and exc.strerror else str(exc)
        raise CaseError(f"cannot read this file ({why})", file=str(path)) from None
    with os.fdopen(fd, "rb") as raw:
        if not stat.S_ISREG(os.fstat(fd).st_mode):
            raise CaseError("not a regular file (a directory, pipe or device); allowed: a "
                            "file critfric wrote", file=str(path))
        os.set_blocking(fd, True)
        with h5py.File(raw, "r") as f:
            yield f


def kind_of(f: h5py.File) -> str | None:
    """The file's root attribute ``kind`` if it is a short printable text, else None."""
    value = f.attrs.get("kind")
    if isinstance(value, np.ndarray) and value.shape == ():
        value = value.item()
    if not isinstance(value, (str, bytes)) or len(value) > 64:
        return None
    text = text_of(value)
    return text if text.isprintable() else None


def check_storage(f: h5py.File, bad, size: int) -> None:
    """Refuse a file that names anything outside itself, loops or expands: every link a hard
    link (no soft or external link), no dataset stored in other files (external storage,
    virtual datasets) or through a filter (critfric writes none: a compressed chunk can
    expand a small file into gigabytes), no chunk larger than the file of ``size`` bytes could
    fill, at most MAX_LINKS objects. Nothing of the file is read before this passed."""
    count = 0
    most = 4 * size + (1 << 20)

    def visit(name: str, link) -> tuple[str, str] | None:  # a problem stops the walk
        nonlocal count
        count += 1
        if count > MAX_LINKS:
            return "the file", f"more than {MAX_LINKS} objects"
        if not isinstance(link, h5py.HardLink):
            what = {"SoftLink": "a soft link", "ExternalLink": "an external link"}.get(
                type(link).__name__, "not a hard link")
            return f"link {name!r}", f"{what} (a critfric file holds only its own data)"
        try:  # no exception may leave the callback (h5py's lock)
            obj = f.get(name)
            if not isinstance(obj, h5py.Dataset):
                return None
            plist = obj.id.get_create_plist()
            if obj.is_virtual or plist.get_external_count() > 0:
                return f"dataset {name!r}", "stored in other files"
            if plist.get_nfilters() > 0:
                return f"dataset {name!r}", "compressed or filtered (critfric writes neither)"
            if obj.chunks and math.prod(obj.chunks) * obj.dtype.itemsize > most:
                return f"dataset {name!r}", f"chunks of {obj.chunks}, more than the file holds"
        except Exception as exc:  # noqa: BLE001  (anything h5py raises on a broken object)
            return f"object {name!r}", f"cannot be read ({type(exc).__name__})"
        return None

    try:
        problem = f.visititems_links(visit)
    except Exception as exc:  # noqa: BLE001  (a name h5py cannot decode, a broken link)
        raise bad("the file", f"its structure cannot be read ({type(exc).__name__})") from None
    if problem is not None:
        raise bad(*problem)


def text_of(value) -> str:
    """An attribute's text (bytes decoded)."""
    return value.decode(errors="replace") if isinstance(value, bytes) else str(value)
