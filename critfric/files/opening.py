"""Opening an HDF5 file from elsewhere: refused unopened unless a regular file, then walked
before anything of it is read, so that it can name nothing outside itself (no soft or external
link, no dataset stored in other files) and cannot loop. :mod:`.validate` then checks what a
critfric file of its kind holds."""

from __future__ import annotations

import stat
from pathlib import Path

import h5py
import numpy as np

from ..errors import CaseError

MAX_LINKS = 100_000  # objects a file may name (a solve file: ~20 + 4 per mode)


def open_file(path: Path | str) -> h5py.File:
    """The HDF5 file at ``path``, opened to read; refused unopened unless it is a regular
    file (opening a pipe would wait for a writer forever)."""
    try:
        mode = Path(path).stat().st_mode
    except OSError as exc:
        raise CaseError(f"cannot read this file ({exc.strerror or exc})", file=str(path)
                        ) from None
    if not stat.S_ISREG(mode):
        raise CaseError("not a regular file (a directory, pipe or device); allowed: a file "
                        "critfric wrote", file=str(path))
    return h5py.File(path, "r")


def kind_of(f: h5py.File) -> str | None:
    """The file's root attribute ``kind`` if it is a short printable text, else None."""
    value = f.attrs.get("kind")
    if isinstance(value, np.ndarray) and value.shape == ():
        value = value.item()
    if not isinstance(value, (str, bytes)) or len(value) > 64:
        return None
    text = _text(value)
    return text if text.isprintable() else None


def check_storage(f: h5py.File, bad) -> None:
    """Refuse a file that names anything outside itself or loops: every link a hard link
    (no soft or external link), no dataset stored in other files (external storage, virtual
    datasets), at most MAX_LINKS objects. Nothing of the file is read before this passed."""
    count = 0

    def visit(name: str, link) -> tuple[str, str] | None:  # a problem stops the walk
        nonlocal count
        count += 1
        if count > MAX_LINKS:
            return "the file", f"more than {MAX_LINKS} objects"
        if not isinstance(link, h5py.HardLink):
            what = {"SoftLink": "a soft link", "ExternalLink": "an external link"}.get(
                type(link).__name__, "not a hard link")
            return f"link {name!r}", f"{what} (a critfric file holds only its own data)"
        try:  # an exception must not leave the callback (h5py's lock)
            obj = f.get(name)
            outside = isinstance(obj, h5py.Dataset) and (
                obj.is_virtual or obj.id.get_create_plist().get_external_count() > 0)
        except (RuntimeError, OSError, KeyError, ValueError, TypeError) as exc:
            return f"object {name!r}", f"cannot be read ({exc})"
        return (f"dataset {name!r}", "stored in other files") if outside else None

    try:
        problem = f.visititems_links(visit)
    except (RuntimeError, OSError, KeyError, ValueError, TypeError) as exc:
        raise bad("the file", f"its structure cannot be read ({exc})") from None
    if problem is not None:
        raise bad(*problem)


def _text(value) -> str:
    return value.decode(errors="replace") if isinstance(value, bytes) else str(value)
