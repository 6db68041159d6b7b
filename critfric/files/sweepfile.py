"""The sweep file: one HDF5 file, appended one point at a time, resumable.

Layout (``schema_version`` 1)::

    /            attrs: kind="sweep", critfric_version, schema_version, case_name,
                 case_source, case_toml (the effective case), grid (JSON: nu, size, element),
                 count, notes (a list of strings)
    /points/     parallel 1-D datasets, one row per finished point, in the order finished:
                 nu, size (NaN for an inline mesh), element, h, n_dofs, n_contact,
                 positive (n, count) and negative (n, count) (lowest first, NaN-padded),
                 complex_count, seconds, status ("ok", "no-real-eigenvalue", "failed: ...")
    /limits/     written at the end of a sweep: nu, element, family, limit, order, error,
                 n_sizes, status

Every write (:func:`append_point`, :func:`write_limits`) goes to a copy of the file that then
replaces it atomically: HDF5 itself is not crash-safe (a process killed inside a write can
leave a file that no longer opens), a rename is. So a sweep killed at any moment keeps every
point it had finished, and readers never see a half-written file. The copy costs O(file size)
per point: a few ms for thousands of points. The number of finished rows is the length of
``points/status``, written last. Only the parent (or the Dask client) writes.
"""

from __future__ import annotations

import json
import math
import os
import shutil
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import h5py
import numpy as np

from .._version import __version__
from ..errors import CaseError, WriteError
from .results import file_attrs
from .safety import atomic_h5, check_output
from .validate import SCHEMA_VERSION

STR = h5py.string_dtype()
FLOAT_COLUMNS = ("nu", "size", "h", "seconds")
INT_COLUMNS = ("n_dofs", "n_contact", "complex_count")
STR_COLUMNS = ("element",)  # "status" is separate: it is written last


def open_sweep(path: Path, *, case, grid, force: bool = False) -> set[tuple]:
    """Create the sweep file, or check that an existing one is for the same case and grid;
    return the keys (element, size, nu) of the points already in it."""
    path = Path(path)
    toml, grid_json = case.to_toml(), json.dumps(grid.to_json())
    if path.is_dir():
        raise CaseError("is a directory; allowed: a file path for the sweep file",
                        file=str(path), key="--output")
    check_output(path, force=True, inputs=case.inputs())
    parent = path.parent if str(path.parent) else Path(".")
    if not parent.is_dir() or not os.access(parent, os.W_OK):
        raise CaseError(f"cannot write here: directory {str(parent)!r} does not exist or is not "
                        "writable",
                        file=str(path), key="--output")
    if path.exists() and not force:
        try:
            with h5py.File(path, "r") as f:
                kind = f.attrs.get("kind")
                same = f.attrs.get("case_toml") == toml and f.attrs.get("grid") == grid_json
        except OSError as exc:
            raise CaseError(f"exists and cannot be read as a sweep file ({exc}); pass --force "
                            "to overwrite it", file=str(path), key="--output") from None
        if kind != "sweep":
            raise CaseError("exists and is not a sweep file; pass --force to overwrite it",
                            file=str(path), key="--output")
        if not same:
            raise CaseError("was written for another case or grid (nu, size, element, "
                            "count, grading); pass --force to discard it and start over, or "
                            "choose another --output", file=str(path), key="--output")
        return {row_key(r) for r in read_sweep(path)["rows"]}
    count = int(case.solve["count"])

    def fill(f: h5py.File) -> None:
        f.attrs.update({
            "kind": "sweep", "critfric_version": __version__, "schema_version": SCHEMA_VERSION,
            "case_name": case.name, "case_source": case.source, "case_toml": toml,
            "grid": grid_json, "count": count,
            "notes": np.array(list(grid.notes), dtype=h5py.string_dtype()),
        })
        g = f.create_group("points")
        for name in FLOAT_COLUMNS:
            g.create_dataset(name, (0,), np.float64, maxshape=(None,), chunks=(256,))
        for name in INT_COLUMNS:
            g.create_dataset(name, (0,), np.int64, maxshape=(None,), chunks=(256,))
        for name in STR_COLUMNS + ("status",):
            g.create_dataset(name, (0,), STR, maxshape=(None,), chunks=(256,))
        for name in ("positive", "negative"):
            g.create_dataset(name, (0, count), np.float64, maxshape=(None, count),
                             chunks=(256, count), fillvalue=np.nan)

    atomic_h5(path, fill)
    return set()


@contextmanager
def _rewrite(path: Path) -> Iterator[h5py.File]:
    """A copy of the file opened for writing; it replaces the file (``os.replace``, atomic)
    only once written and closed, so a process killed at any moment leaves the old file or
    the new one, never a torn one (a stray ``.<name>.*.tmp`` at worst)."""
    tmp = None
    try:  # the temporary file is made inside: an interrupt right after it still removes it
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
        os.close(fd)
        shutil.copy(path, tmp)
        with h5py.File(tmp, "r+") as f:
            yield f
        os.replace(tmp, path)
    except OSError as exc:  # disk full, I/O error: the file keeps every point written before
        if tmp is not None:
            Path(tmp).unlink(missing_ok=True)
        raise WriteError(f"cannot add a point to {path} ({exc.strerror or exc}); the points "
                         "written before are kept: free some space and run the sweep again "
                         "to compute only the rest") from None
    except BaseException:
        if tmp is not None:
            Path(tmp).unlink(missing_ok=True)
        raise


def append_point(path: Path, row: dict) -> None:
    """Append one finished point: the only write of a point to the file (atomic)."""
    with _rewrite(Path(path)) as f:
        g = f["points"]
        n = len(g["status"])
        count = g["positive"].shape[1]
        for name in FLOAT_COLUMNS + INT_COLUMNS + STR_COLUMNS + ("positive", "negative"):
            g[name].resize(n + 1, axis=0)
        for name in FLOAT_COLUMNS:
            g[name][n] = math.nan if row[name] is None else row[name]
        for name in INT_COLUMNS + STR_COLUMNS:
            g[name][n] = row[name]
        for name in ("positive", "negative"):
            values = np.full(count, np.nan)
            values[: len(row[name])] = row[name][:count]
            g[name][n] = values
        g["status"].resize(n + 1, axis=0)
        g["status"][n] = row["status"]


def read_sweep(path: Path) -> dict:
    """Attributes, finished rows and limits of a sweep file."""
    path = Path(path)
    try:
        with h5py.File(path, "r") as f:
            attrs = file_attrs(f, "sweep", path)
            g = f["points"]
            n = len(g["status"])
            cols = {name: g[name][:n] for name in g}
            limits = _read_table(f["limits"]) if "limits" in f else []
    except (OSError, KeyError, ValueError, TypeError, IndexError) as exc:
        raise CaseError(f"cannot read this sweep file ({exc})", file=str(path)) from None
    rows = []
    for i in range(n):
        row = {name: _scalar(cols[name][i]) for name in FLOAT_COLUMNS + INT_COLUMNS
               + STR_COLUMNS + ("status",)}
        row["size"] = None if math.isnan(row["size"]) else row["size"]
        for name in ("positive", "negative"):
            v = cols[name][i]
            row[name] = [float(x) for x in v[np.isfinite(v)]]
        rows.append(row)
    return {"attrs": attrs, "rows": rows, "limits": limits}


def write_limits(path: Path, limits, grid=None, rows=None) -> None:
    """Replace the /limits table and, given the ``grid`` and its ``rows`` in grid order, the
    gridded view at the root (atomic): netCDF-4 style variables over named dimensions, so
    that ``xarray.open_dataset(path, engine="h5netcdf")`` reads the sweep as it was asked."""
    with _rewrite(Path(path)) as f:
        if "limits" in f:
            del f["limits"]
        g = f.create_group("limits")
        data = [lim.to_row() for lim in limits]
        for name in ("nu", "limit", "order", "error"):
            g[name] = np.array([d[name] for d in data], dtype=np.float64)
        g["n_sizes"] = np.array([d["n_sizes"] for d in data], dtype=np.int64)
        for name in ("element", "family", "status"):
            g.create_dataset(name, data=[d[name] for d in data], dtype=STR)
        if grid is not None and rows is not None:
            _write_grid(f, grid, rows)


#: the gridded view: name -> (dimensions, units, long name)
GRID_VARIABLES = {
    "positive": (("element", "size", "nu", "rank"), "1",
                 "lowest positive critical friction coefficients (NaN: none)"),
    "negative": (("element", "size", "nu", "rank"), "1",
                 "negative critical coefficients, by modulus (NaN: none)"),
    "h": (("element", "size", "nu"), "length unit of the case", "largest cell diameter"),
    "n_dofs": (("element", "size", "nu"), "1", "free degrees of freedom"),
    "n_contact": (("element", "size", "nu"), "1", "contact nodes"),
    "seconds": (("element", "size", "nu"), "s", "wall time of the point"),
    "status": (("element", "size", "nu"), "", "ok, no-real-eigenvalue or failed: ..."),
}
COORDINATES = {"nu": ("1", "Poisson ratio"), "size": ("length unit of the case",
                                                      "target mesh size (NaN: inline mesh)"),
               "element": ("", "finite element"), "rank": ("1", "rank in the family, lowest 0")}


def _write_grid(f: h5py.File, grid, rows: list[dict]) -> None:
    _points_in_order(f["points"], [row_key(r) for r in rows])
    for name in list(GRID_VARIABLES) + list(COORDINATES):
        if name in f:
            del f[name]
    count = f["points/positive"].shape[1]
    values = {"nu": np.asarray(grid.nu, dtype=np.float64),
              "size": np.array([math.nan if s is None else s for s in grid.size]),
              "element": np.array(grid.element, dtype=object),
              "rank": np.arange(count, dtype=np.int64)}
    shape = (len(grid.element), len(grid.size), len(grid.nu))
    for name, v in values.items():
        ds = f.create_dataset(name, data=v, dtype=STR if name == "element" else v.dtype)
        ds.make_scale(name)
        ds.attrs.update({"units": COORDINATES[name][0], "long_name": COORDINATES[name][1]})
    data = {}
    for name in GRID_VARIABLES:
        dims = GRID_VARIABLES[name][0]
        full = shape + ((count,) if "rank" in dims else ())
        data[name] = np.full(full, "" if name == "status" else math.nan,
                             dtype=object if name == "status" else np.float64)
    for i, row in enumerate(rows):  # rows in grid order: element, size, nu
        at = np.unravel_index(i, shape)
        for name in ("h", "n_dofs", "n_contact", "seconds", "status"):
            data[name][at] = math.nan if row[name] is None else row[name]
        for name in ("positive", "negative"):
            data[name][at][: len(row[name][:count])] = row[name][:count]
    for name, (dims, units, long_name) in GRID_VARIABLES.items():
        ds = f.create_dataset(name, data=data[name], dtype=STR if name == "status" else None)
        ds.attrs.update({"units": units, "long_name": long_name})
        for axis, dim in enumerate(dims):
            ds.dims[axis].attach_scale(f[dim])


def _points_in_order(g: h5py.Group, keys: list[tuple]) -> None:
    """Reorder the point table (written in the order points finished) into ``keys``' order
    (the grid's); points not in ``keys`` keep their order after them."""
    n = len(g["status"])
    size = g["size"][:n]
    element = [e.decode() if isinstance(e, bytes) else str(e) for e in g["element"][:n]]
    stored = {(element[i], -1.0 if math.isnan(size[i]) else float(size[i]),
               float(g["nu"][i])): i for i in range(n)}
    first = [stored[k] for k in keys if k in stored]
    order = first + sorted(set(range(n)) - set(first))
    if order == list(range(n)):
        return
    for name in g:
        g[name][:n] = g[name][:n][order]


def _read_table(g) -> list[dict]:
    names = list(g)
    n = len(g[names[0]]) if names else 0
    cols = {name: g[name][()] for name in names}
    return [{name: _scalar(cols[name][i]) for name in names} for i in range(n)]


def _scalar(v):
    if isinstance(v, bytes):
        return v.decode()
    if isinstance(v, np.integer):
        return int(v)
    if isinstance(v, np.floating):
        return float(v)
    return v


def row_key(row: dict) -> tuple:
    """(element, size or -1, nu): what identifies a sweep row (and a sweep point)."""
    return (row["element"], -1.0 if row["size"] is None else row["size"], row["nu"])
