"""What a set of critfric files holds, one summary row per solve, sweep point, stability
analysis or path."""

from __future__ import annotations

from pathlib import Path

import h5py

from ..errors import CaseError
from .pathfile import read_path_summary
from .results import read_summary
from .stabilityfile import read_stability_summary
from .sweepfile import read_sweep


def summaries(paths) -> tuple[list[dict], list[tuple[Path, str]]]:
    """Rows (as ``critfric solve --json`` prints them, plus ``file``) of every solve file and
    every point of every sweep file in ``paths``, and of every stability file (as
    ``critfric stability --json``, plus ``file`` and ``kind`` = "stability") and of every path
    file (:func:`~critfric.files.pathfile.read_path_summary`, plus ``file`` and ``kind`` =
    "path"; :func:`~critfric.files.pathfile.path_table` prints them); and (path, why) for
    each path skipped (not a critfric file, or not a valid one)."""
    rows: list[dict] = []
    skipped: list[tuple[Path, str]] = []
    for path in map(Path, paths):
        try:
            with h5py.File(path, "r") as f:
                kind = f.attrs.get("kind")
        except (OSError, ValueError) as exc:
            reason = exc.strerror if isinstance(exc, OSError) and exc.strerror else "not HDF5"
            skipped.append((path, f"cannot read this file ({reason})"))
            continue
        try:
            if kind == "solve":
                rows.append({**read_summary(path), "file": str(path)})
            elif kind == "stability":
                rows.append({**read_stability_summary(path), "file": str(path),
                             "kind": "stability"})
            elif kind == "path":
                rows.append({**read_path_summary(path), "file": str(path), "kind": "path"})
            elif kind == "sweep":
                data = read_sweep(path)
                name = str(data["attrs"].get("case_name", ""))
                for r in data["rows"]:
                    rows.append({"case": name, "file": str(path), "complete": True,
                                 "warnings": [], "method": "sweep", **r})
            else:
                skipped.append((path, "not a critfric solve, sweep, stability or path file "
                                      "(an export's arrays, or another program's)"))
        except CaseError as exc:
            skipped.append((path, exc.detail))
    return rows, skipped
