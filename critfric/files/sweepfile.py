"""The sweep file: one HDF5 file, appended one point at a time, resumable.

Layout (``schema_version`` 1)::

    /            attrs: kind="sweep", critfric_version, schema_version, case_name,
                 case_source, case_toml (the effective case), grid (JSON: nu, size, element
                 and, sweeping the slip direction of a 3D body, slip_angle), count, notes (a
                 list of strings)
    /points/     parallel 1-D datasets, one row per finished point, in the order finished:
                 nu, size (NaN for an inline mesh), element, slip_angle (degrees; NaN: not
                 swept), h, n_dofs, n_contact, positive (n, count) and negative (n, count)
                 (lowest first, NaN-padded), r_positive (n, count) (3D: r of each positive
                 one), complex_count, seconds, status ("ok", "no-real-eigenvalue",
                 "failed: ...")
    /minima/     an angle sweep's minima over slip directions, one row per (nu, size,
                 element), in the order located: nu, size, element, slip_angle (where),
                 positive (the minimum; inf: no direction has one), r_positive, bracket_lo,
                 bracket_hi (degrees, unwrapped), evaluations, seconds, status
    /limits/     written at the end of a sweep: nu, element, family, limit, order, error,
                 n_sizes, status, slip_angle (NaN: none)

Files written before the slip_angle and r_positive columns read (and resume) as before.

Every write (:func:`open_sweep`, :func:`append_point`, :func:`write_limits`) changes a copy
of the file in memory, writes it whole to a temporary file beside it and renames that over
the file: HDF5 itself is not crash-safe (a process killed inside a write can leave a file that
no longer opens; a write that fails half way can crash it), plain writes and a rename are. So
a sweep killed at any moment keeps every point it had finished, readers never see a
half-written file, and a full disk (or quota, or file-size limit) is a :class:`WriteError`
that says how many points the unchanged file keeps, with nothing left behind. Under an
:class:`~critfric.files.safety.interrupt_guard` a Ctrl-C during a write comes after it. The
copy costs O(file size) per point: a few ms for thousands of points. The number of finished
rows is the length of ``points/status``, written last. Only the parent (or the Dask client)
writes.
"""

from __future__ import annotations

import io
import json
import math
import os
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import h5py
import numpy as np

from .._version import __version__
from ..errors import CaseError, WriteError
from .opening import kind_of, open_file, text_of
from .results import file_attrs
from .safety import NO_ROOM, check_output, held, write_whole
from .validate import SCHEMA_VERSION

STR = h5py.string_dtype()
FLOAT_COLUMNS = ("nu", "size", "h", "seconds")
INT_COLUMNS = ("n_dofs", "n_contact", "complex_count")
STR_COLUMNS = ("element",)  # "status" is separate: it is written last
FAMILIES = ("positive", "negative", "r_positive")  # (n, count) columns
MINIMUM_FLOATS = ("nu", "size", "slip_angle", "positive", "r_positive", "bracket_lo",
                  "bracket_hi", "seconds")


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
            with open_file(path) as f:
                kind = kind_of(f)
                same = _same_text(f.attrs.get("case_toml"), toml) \
                    and _same_text(f.attrs.get("grid"), grid_json)
        except OSError as exc:
            raise CaseError(f"exists and cannot be read as a sweep file ({exc}); pass --force "
                            "to overwrite it", file=str(path), key="--output") from None
        if kind != "sweep":
            raise CaseError("exists and is not a sweep file; pass --force to overwrite it",
                            file=str(path), key="--output")
        if not same:
            raise CaseError("was written for another case or grid (nu, size, element, "
                            "slip angle, count, grading); pass --force to discard it and start "
                            "over, or "
                            "choose another --output", file=str(path), key="--output")
        rows = read_sweep(path)["rows"]
        with open_file(path) as f:
            fixed = [f"{g}/{name}" for g in ("points", "minima") if g in f
                     for name, ds in f[g].items() if not _growable(ds)]
        if fixed:
            raise CaseError(f"dataset {fixed[0]!r} cannot grow (critfric writes resizable "
                            "columns): not a sweep file critfric wrote; pass --force to "
                            "overwrite it", file=str(path), key="--output")
        return {row_key(r) for r in rows}
    count = int(case.solve["count"])

    def fill(f: h5py.File) -> None:
        f.attrs.update({
            "kind": "sweep", "critfric_version": __version__, "schema_version": SCHEMA_VERSION,
            "case_name": case.name, "case_source": case.source, "case_toml": toml,
            "grid": grid_json, "count": count,
            "notes": np.array(list(grid.notes), dtype=h5py.string_dtype()),
        })
        g = f.create_group("points")
        for name in FLOAT_COLUMNS + ("slip_angle",):
            g.create_dataset(name, (0,), np.float64, maxshape=(None,), chunks=(256,))
        for name in INT_COLUMNS:
            g.create_dataset(name, (0,), np.int64, maxshape=(None,), chunks=(256,))
        for name in STR_COLUMNS + ("status",):
            g.create_dataset(name, (0,), STR, maxshape=(None,), chunks=(256,))
        for name in FAMILIES:
            g.create_dataset(name, (0, count), np.float64, maxshape=(None, count),
                             chunks=(256, count), fillvalue=np.nan)

    with held():
        buffer = io.BytesIO()
        with h5py.File(buffer, "w") as f:
            fill(f)
        _replace(path, buffer.getbuffer(), "create", "nothing was written (no point was "
                 "computed yet)")
    return set()


def _growable(ds) -> bool:
    """Whether ``ds`` is a column :func:`append_point` can extend (chunked, unlimited)."""
    return isinstance(ds, h5py.Dataset) and ds.chunks is not None and ds.maxshape[0] is None


def _same_text(value, text: str) -> bool:
    """Whether an attribute is the string ``text`` (an array or a number is not)."""
    return isinstance(value, (str, bytes)) and text_of(value) == text


@contextmanager
def _rewrite(path: Path, what: str = "add a point to") -> Iterator[h5py.File]:
    """The file, copied into memory and opened for writing; once closed, the new bytes
    replace the file (:func:`_replace`), so a process killed at any moment leaves the old
    file or the new one, never a torn one, and a failed write leaves the old one."""
    with held():
        try:
            data = path.read_bytes()
        except OSError as exc:
            raise WriteError(f"cannot {what} {path}: reading it failed "
                             f"({exc.strerror or exc})") from None
        buffer = io.BytesIO(data)
        with h5py.File(buffer, "r+") as f:
            kept = _kept(f)
            yield f
        _replace(path, buffer.getbuffer(), what, kept)


def _kept(f: h5py.File) -> str:
    """What a sweep file holds, said when a write to it fails."""
    points = len(f["points/status"]) if "points/status" in f else 0
    minima = len(f["minima/status"]) if "minima/status" in f else 0
    what = f"{points} point{'s' * (points != 1)}" + (
        f" and {minima} minim{'a' if minima != 1 else 'um'} over directions" if minima else "")
    return f"the file is unchanged, its {what} {'is' if what == '1 point' else 'are'} safe"


def _replace(path: Path, data, what: str, kept: str) -> None:
    """:func:`~critfric.files.safety.write_whole` of ``data`` over ``path`` (its permissions
    kept); a failure leaves ``path`` as it was and is a one-line :class:`WriteError` that says
    what the file keeps (``kept``)."""
    try:
        write_whole(path, data, keep_mode=True)
    except OSError as exc:
        why = exc.strerror or str(exc)
        if exc.errno in NO_ROOM:
            raise WriteError(f"cannot {what} {path}: the disk is full ({why}); {kept}: free "
                             "some space and run the sweep again to compute only the rest"
                             ) from None
        raise WriteError(f"cannot {what} {path} ({why}); {kept}: run the sweep again to "
                         "compute only the rest") from None


def append_point(path: Path, row: dict) -> None:
    """Append one finished point: the only write of a point to the file (atomic)."""
    with _rewrite(Path(path)) as f:
        g = f["points"]
        n = len(g["status"])
        count = g["positive"].shape[1]
        floats = FLOAT_COLUMNS + (("slip_angle",) if "slip_angle" in g else ())
        families = [name for name in FAMILIES if name in g]  # older files: two
        for name in floats + INT_COLUMNS + STR_COLUMNS + tuple(families):
            g[name].resize(n + 1, axis=0)
        for name in floats:
            value = row.get(name)
            g[name][n] = math.nan if value is None else value
        for name in INT_COLUMNS + STR_COLUMNS:
            g[name][n] = row[name]
        for name in families:
            given = row.get(name) or []
            values = np.full(count, np.nan)
            values[: len(given)] = given[:count]
            g[name][n] = values
        g["status"].resize(n + 1, axis=0)
        g["status"][n] = row["status"]


def append_minimum(path: Path, minimum: dict) -> None:
    """Append one minimum over slip directions (a row of /minima, created by the first;
    atomic)."""
    with _rewrite(Path(path), "add a minimum over directions to") as f:
        if "minima" not in f:
            g = f.create_group("minima")
            for name in MINIMUM_FLOATS:
                g.create_dataset(name, (0,), np.float64, maxshape=(None,), chunks=(64,))
            g.create_dataset("evaluations", (0,), np.int64, maxshape=(None,), chunks=(64,))
            for name in ("element", "status"):
                g.create_dataset(name, (0,), STR, maxshape=(None,), chunks=(64,))
        g = f["minima"]
        n = len(g["status"])
        for name in MINIMUM_FLOATS + ("evaluations", "element", "status"):
            g[name].resize(n + 1, axis=0)
        for name in MINIMUM_FLOATS:
            g[name][n] = math.nan if minimum[name] is None else minimum[name]
        g["evaluations"][n] = minimum["evaluations"]
        g["element"][n] = minimum["element"]
        g["status"][n] = minimum["status"]  # last: the count of rows


def read_sweep(path: Path) -> dict:
    """Attributes, finished rows and limits of a sweep file."""
    path = Path(path)
    try:
        with open_file(path) as f:
            attrs = file_attrs(f, "sweep", path)
            g = f["points"]
            n = len(g["status"])
            _check_columns(f, n, path.stat().st_size)
            cols = {name: g[name][:n] for name in g}
            limits = _read_table(f["limits"]) if "limits" in f else []
            minima = _read_minima(f["minima"]) if "minima" in f else []
        rows = []
        for i in range(n):
            row = {name: _scalar(cols[name][i]) for name in FLOAT_COLUMNS + INT_COLUMNS
                   + STR_COLUMNS + ("status",)}
            row["size"] = None if math.isnan(row["size"]) else row["size"]
            angle = float(cols["slip_angle"][i]) if "slip_angle" in cols else math.nan
            row["slip_angle"] = angle if math.isfinite(angle) else None
            for name in FAMILIES:
                v = cols[name][i] if name in cols else np.zeros(0)
                row[name] = [float(x) for x in v[np.isfinite(v)]]
            rows.append(row)
    except (OSError, KeyError, ValueError, TypeError, IndexError) as exc:
        raise CaseError(f"cannot read this sweep file ({exc})", file=str(path)) from None
    for lim in limits:
        angle = lim.get("slip_angle", math.nan)
        lim["slip_angle"] = angle if math.isfinite(angle) else None
    return {"attrs": attrs, "rows": rows, "limits": limits, "minima": minima}


def _check_columns(f: h5py.File, n: int, size: int) -> None:
    """Refuse (ValueError) the slip-angle columns and /minima of a file unless they are what
    this module writes: 1-D columns of n rows (r_positive: (n, count)) of the right kinds,
    and no dataset declaring more than the file could hold."""
    g, count = f["points"], f["points/positive"].shape[1]
    want = {"points/slip_angle": ("f", (n,)), "points/r_positive": ("f", (n, count))}
    minima = f.get("minima")
    if minima is not None:
        rows = len(minima["status"])
        want.update({f"minima/{name}": ("f", (rows,)) for name in MINIMUM_FLOATS})
        want.update({"minima/evaluations": ("iu", (rows,)), "minima/element": ("OSU", (rows,)),
                     "minima/status": ("OSU", (rows,))})
    for name, (kinds, shape) in want.items():
        if name.startswith("points/") and name.split("/")[1] not in g:
            continue  # a file written before these columns
        ds = f[name]
        if not isinstance(ds, h5py.Dataset) or ds.dtype.kind not in kinds:
            raise ValueError(f"dataset {name!r} is not a column of {kinds!r} values")
        if ds.shape[:1] < shape[:1] or ds.shape[1:] != shape[1:]:
            raise ValueError(f"dataset {name!r} has shape {ds.shape}, not {shape}")
        if ds.size * ds.dtype.itemsize > 4 * size + (1 << 20):
            raise ValueError(f"dataset {name!r} declares more values than the file holds")


def _read_minima(g) -> list[dict]:
    """The rows of /minima (every column as long as status: one row a minimum)."""
    n = len(g["status"])
    cols = {name: g[name][:n] for name in MINIMUM_FLOATS + ("evaluations", "element",
                                                            "status")}
    if any(len(v) != n for v in cols.values()):
        raise ValueError("the /minima columns differ in length")
    out = [{name: _scalar(cols[name][i]) for name in cols} for i in range(n)]
    for m in out:
        m["size"] = None if math.isnan(m["size"]) else m["size"]
    return out


def write_limits(path: Path, limits, grid=None, rows=None, minima=()) -> None:
    """Replace the /limits table and, given the ``grid`` and its ``rows`` in grid order, the
    gridded view at the root (atomic): netCDF-4 style variables over named dimensions, so
    that ``xarray.open_dataset(path, engine="h5netcdf")`` reads the sweep as it was asked
    (with ``minima``, also the minimum over slip directions and its angle)."""
    with _rewrite(Path(path), "write the h -> 0 limits to") as f:
        if "limits" in f:
            del f["limits"]
        g = f.create_group("limits")
        data = [lim.to_row() for lim in limits]
        for name in ("nu", "limit", "order", "error", "slip_angle"):
            g[name] = np.array([d[name] for d in data], dtype=np.float64)
        g["n_sizes"] = np.array([d["n_sizes"] for d in data], dtype=np.int64)
        for name in ("element", "family", "status"):
            g.create_dataset(name, data=[d[name] for d in data], dtype=STR)
        if grid is not None and rows is not None:
            _write_grid(f, grid, rows, minima)


#: the gridded view: name -> (dimensions, units, long name); a sweep over slip angles has
#: the dimension slip_angle before nu, and the variables of ANGLE_VARIABLES
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
ANGLE_VARIABLES = {
    "r_positive": (("element", "size", "nu", "rank"), "1",
                   "r of each lowest positive coefficient (0: an exact static branch)"),
}
#: the minima over slip directions (no slip_angle dimension)
MINIMUM_VARIABLES = {
    "minimum": (("element", "size", "nu"), "1", ("minimum over slip directions of the lowest "
                "positive critical coefficient (inf: no direction has one)")),
    "minimum_slip_angle": (("element", "size", "nu"), "degree",
                           "slip angle of the minimum over directions"),
}
COORDINATES = {"nu": ("1", "Poisson ratio"), "size": ("length unit of the case",
                                                      "target mesh size (NaN: inline mesh)"),
               "element": ("", "finite element"), "rank": ("1", "rank in the family, lowest 0"),
               "slip_angle": ("degree", ("slip angle, from t1 towards t2 = n x t1 in the "
                                         "contact plane"))}


def _write_grid(f: h5py.File, grid, rows: list[dict], minima=()) -> None:
    _points_in_order(f["points"], [row_key(r) for r in rows])
    for name in [*GRID_VARIABLES, *ANGLE_VARIABLES, *MINIMUM_VARIABLES, *COORDINATES]:
        if name in f:
            del f[name]
    angles = grid.slip_angle is not None
    count = f["points/positive"].shape[1]
    values = {"nu": np.asarray(grid.nu, dtype=np.float64),
              "size": np.array([math.nan if s is None else s for s in grid.size]),
              "element": np.array(grid.element, dtype=object),
              "rank": np.arange(count, dtype=np.int64)}
    if angles:
        values["slip_angle"] = np.asarray(grid.slip_angle, dtype=np.float64)
    for name, v in values.items():
        ds = f.create_dataset(name, data=v, dtype=STR if name == "element" else v.dtype)
        ds.make_scale(name)
        ds.attrs.update({"units": COORDINATES[name][0], "long_name": COORDINATES[name][1]})
    variables = {name: (dims[:2] + ("slip_angle",) + dims[2:] if angles else dims, *rest)
                 for name, (dims, *rest) in {**GRID_VARIABLES,
                                             **(ANGLE_VARIABLES if angles else {})}.items()}
    variables.update(MINIMUM_VARIABLES if minima else {})
    data = {}
    for name, (dims, _, _) in variables.items():
        text = name == "status"
        data[name] = np.full(tuple(len(values[d]) for d in dims), "" if text else math.nan,
                             dtype=object if text else np.float64)
    shape = data["h"].shape
    for i, row in enumerate(rows):  # rows in grid order: element, size[, slip angle], nu
        at = np.unravel_index(i, shape)
        for name in ("h", "n_dofs", "n_contact", "seconds", "status"):
            data[name][at] = math.nan if row[name] is None else row[name]
        for name in ("positive", "negative", "r_positive"):
            if name in data:
                data[name][at][: len(row[name][:count])] = row[name][:count]
    for m in minima:
        if m["element"] in grid.element and m["size"] in grid.size and m["nu"] in grid.nu:
            at = (grid.element.index(m["element"]), grid.size.index(m["size"]),
                  grid.nu.index(m["nu"]))
            data["minimum"][at], data["minimum_slip_angle"][at] = m["positive"], m["slip_angle"]
    for name, (dims, units, long_name) in variables.items():
        ds = f.create_dataset(name, data=data[name], dtype=STR if name == "status" else None)
        ds.attrs.update({"units": units, "long_name": long_name})
        for axis, dim in enumerate(dims):
            ds.dims[axis].attach_scale(f[dim])


def _points_in_order(g: h5py.Group, keys: list[tuple]) -> None:
    """Reorder the point table (written in the order points finished) into ``keys``' order
    (the grid's); points not in ``keys`` keep their order after them."""
    n = len(g["status"])
    size, nu = g["size"][:n], g["nu"][:n]
    angle = g["slip_angle"][:n] if "slip_angle" in g else np.full(n, np.nan)
    element = [e.decode() if isinstance(e, bytes) else str(e) for e in g["element"][:n]]
    stored = {}
    for i in range(n):
        key = (element[i], -1.0 if math.isnan(size[i]) else float(size[i]), float(nu[i]))
        stored[key + ((float(angle[i]),) if math.isfinite(angle[i]) else ())] = i
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
    """(element, size or -1, nu[, slip angle]): what identifies a sweep row (and a sweep
    point, :attr:`critfric.sweep.grid.Point.key`)."""
    key = (row["element"], -1.0 if row["size"] is None else row["size"], row["nu"])
    angle = row.get("slip_angle")
    return key if angle is None else key + (angle,)
