"""Checks of a critfric HDF5 file before any of it is used: its kind, its root attributes and
every dataset a reader touches (dtype, shape, finite values, indices in range, and sizes the
file can hold). A file from someone else that fails any of them is a CaseError naming the
file and the dataset or attribute, never a traceback or a huge allocation."""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

import h5py
import numpy as np

from ..errors import CaseError
from ..fem.contact3d import LAWS
from ..fem.elements import NAMES, get_element
from ..fem.mesh import MAX_GROUP_NAME, group_name_ok
from .opening import check_storage, text_of

SCHEMA_VERSION = 2  # the layout of the 2D files critfric writes (solve, sweep, stability, path)
SOLID_VERSION = 3  # the layout of a 3D solve file: points (n, 3), faces, r, slip directions
NEWEST_VERSION = SOLID_VERSION  # the newest layout this version reads
UNIT_TOL = 1e-6  # a stored unit vector's length may differ from 1 by this (and a dot by this)
SLACK_BYTES = 1 << 20  # a dataset may declare at most 4 x the file's size plus this

# root attributes: name -> kind ("int", "float", "str", "toml", "texts", "json", "element");
# every text must be printable (a file from elsewhere must not reach the terminal with control
# characters), apart from the line breaks and tabs of a TOML text
SOLVE_ATTRS = {"nu": "float", "E": "float", "h": "float", "n_dofs": "int", "n_contact": "int",
               "seconds": "float", "element": "element", "case_name": "str", "solver": "str",
               "case_toml": "toml", "warnings": "texts", "notes": "texts"}
SWEEP_ATTRS = {"case_name": "str", "case_toml": "toml", "grid": "json", "count": "int"}
STABILITY_ATTRS = {"nu": "float", "E": "float", "density": "float", "h": "float",
                   "n_dofs": "int", "n_contact": "int", "modes": "int", "seconds": "float",
                   "element": "element", "case_name": "str", "case_toml": "toml",
                   "warnings": "texts", "notes": "texts",
                   **{f"{what}_{d}": "number" for what in ("flutter", "divergence")
                      for d in ("positive", "negative")}}
PATH_ATTRS = {"case_name": "str", "case_toml": "toml", "parameter": "str", "range": "range",
              "friction": "number", "node": "int", "n_dofs": "int", "n_contact": "int",
              "seconds": "float", "notes": "texts", "counts": "json"}
KIND_WORDS = {"str": "printable text", "toml": "TOML text (printable characters and line breaks)",
              "texts": "a list of printable texts", "json": "JSON (with printable strings)",
              "element": "an element name", "float": "a finite number", "int": "an integer"}
ATTRS = {"solve": SOLVE_ATTRS, "sweep": SWEEP_ATTRS, "stability": STABILITY_ATTRS,
         "path": PATH_ATTRS}
PARAMETERS = ("friction", "load")  # as critfric.multiplicity.pathresult
EVENT_KINDS = ("kink", "fold", "branch")
POINT_VALUES = ("Un", "Ut", "X", "Y")  # (n, p) datasets of a path file's points
MODE_NAME = re.compile(r"(positive|negative)_[0-9]{1,9}")  # the groups of a solve file's modes


def check(f: h5py.File, kind: str, path: Path) -> None:
    """Refuse a file whose attributes or datasets are not those of a critfric ``kind`` file."""
    size = path.stat().st_size

    def bad(where: str, what: str) -> CaseError:
        return CaseError(f"{where}: {what}; not a valid critfric {kind} file (was it "
                         "written by critfric, and is it whole?)", file=str(path))

    check_storage(f, bad, size)
    version = f.attrs.get("schema_version")
    if not _attr_ok(version, "int") or not 1 <= int(version) <= NEWEST_VERSION:
        raise bad("attribute 'schema_version'", f"{version!r}; this critfric reads versions 1 "
                  f"to {NEWEST_VERSION} (a newer critfric wrote it?)")
    version = int(version)
    for name, want in ATTRS[kind].items():
        if not _attr_ok(f.attrs.get(name), want):
            raise bad(f"attribute {name!r}", f"missing or not {KIND_WORDS.get(want, want)}")

    def dataset(name: str, dtype: str, ndim: int, width=None) -> np.ndarray:
        obj = f.get(name)
        if not isinstance(obj, h5py.Dataset):
            raise bad(f"dataset {name!r}", "missing")
        if obj.ndim != ndim or (width is not None and obj.shape[-1] != width):
            raise bad(f"dataset {name!r}", f"shape {obj.shape}")
        if obj.dtype.kind not in dtype:
            raise bad(f"dataset {name!r}", f"dtype {obj.dtype}")
        if obj.size * obj.dtype.itemsize > 4 * size + SLACK_BYTES:
            raise bad(f"dataset {name!r}", f"declares {obj.size} values, more than the file "
                      "holds")
        return obj[()]

    if kind == "path":
        _check_path(f, dataset, bad, version)
    elif kind in ("solve", "stability"):
        n, arrays = _mesh(f, dataset, bad, str(f.attrs["element"]), version)
        dim = arrays["mesh/points"].shape[1]
        p = len(arrays["mesh/contact_nodes"])
        if int(f.attrs["n_contact"]) != p:
            raise bad("attribute 'n_contact'", f"{int(f.attrs['n_contact'])}, but the mesh has "
                      f"{p} contact nodes")
        if kind == "solve":
            arrays.update({"critical/positive": dataset("critical/positive", "f", 1),
                           "critical/negative": dataset("critical/negative", "f", 1),
                           "eigen/alpha": dataset("eigen/alpha", "fc", 1)})
            _check_frame(f, dataset, bad, arrays, dim)
        else:
            n_modes = int(f.attrs["modes"])
            friction = dataset("stability/friction", "f", 1)
            arrays.update({"stability/friction": friction,
                           "stability/frequencies": dataset("stability/frequencies", "f", 1)})
            for name in ("kappa", "growth", "frequency"):
                values = dataset(f"stability/{name}", "fc", 2, n_modes)
                if len(values) != len(friction):
                    raise bad(f"dataset 'stability/{name}'", f"{len(values)} rows for "
                              f"{len(friction)} friction values")
                arrays[f"stability/{name}"] = values[np.isfinite(values)]  # NaN: lost branch
            for d in ("positive", "negative"):
                if f"flutter/{d}" in f:
                    arrays[f"flutter/{d}/shape"] = dataset(f"flutter/{d}/shape", "f", 2, dim)
                    if len(arrays[f"flutter/{d}/shape"]) != n:
                        raise bad(f"dataset 'flutter/{d}/shape'", f"not {n} rows")
        modes = f.get("modes")
        for name in (modes.keys() if isinstance(modes, h5py.Group) else []):
            if kind == "solve" and not (MODE_NAME.fullmatch(name)
                                        and isinstance(modes[name], h5py.Group)):
                raise bad(f"group 'modes/{name}'", "not a mode (positive_<k> or negative_<k>)")
            arrays[f"modes/{name}/phi"] = dataset(f"modes/{name}/phi", "f", 2, dim)
            for attr, bounds in (("alpha", None), ("r", (0.0, 1.0))):
                if kind == "solve" and not _number_ok(f[f"modes/{name}"].attrs.get(attr),
                                                      bounds, optional=attr == "r"):
                    raise bad(f"attribute {attr!r} of group 'modes/{name}'",
                              "missing or not a finite number"
                              + (" in [0, 1]" if bounds else ""))
            for part in ("theta_n", "theta_t"):
                arrays[f"modes/{name}/{part}"] = dataset(f"modes/{name}/{part}", "f", 1)
                p = len(arrays["mesh/contact_nodes"])
                if len(arrays[f"modes/{name}/{part}"]) != p:
                    raise bad(f"dataset 'modes/{name}/{part}'", f"not {p} values (one per "
                              "contact node)")
            if len(arrays[f"modes/{name}/phi"]) != n:
                raise bad(f"dataset 'modes/{name}/phi'", f"{len(arrays[f'modes/{name}/phi'])} "
                          f"rows for {n} nodes")
        _finite_indices(arrays, n, bad)
    else:
        count = int(f.attrs["count"])
        rows = None
        for name in ("nu", "size", "h", "seconds", "n_dofs", "n_contact", "complex_count",
                     "element", "status", "positive", "negative"):
            kinds = {"element": "OSU", "status": "OSU", "n_dofs": "iu", "n_contact": "iu",
                     "complex_count": "iu"}.get(name, "f")
            ndim = 2 if name in ("positive", "negative") else 1
            values = dataset(f"points/{name}", kinds, ndim, count if ndim == 2 else None)
            rows = len(values) if rows is None else rows
            if len(values) != rows:
                raise bad(f"dataset 'points/{name}'", f"{len(values)} rows, not {rows}")
            if name == "element" and not all(text_of(v) in NAMES for v in values):
                raise bad("dataset 'points/element'", "an unknown element")
            if name == "nu" and not np.all(np.isfinite(values)):
                raise bad("dataset 'points/nu'", "values that are not finite")


def _mesh(f: h5py.File, dataset, bad, element: str, version: int) -> tuple[int, dict]:
    """The number of nodes and the /mesh arrays (points (n, 2 or 3), cells of ``element`` in
    that dimension, contact nodes, edges in 2D or faces in 3D, slip directions if stored)."""
    obj = f.get("mesh/points")
    dim = obj.shape[1] if isinstance(obj, h5py.Dataset) and obj.ndim == 2 else 2
    if dim not in (2, 3):
        raise bad("dataset 'mesh/points'", f"shape {obj.shape}; points have 2 or 3 coordinates")
    if dim == 3 and version < SOLID_VERSION:
        raise bad("dataset 'mesh/points'", f"3D points in a version-{version} file (3D files "
                  f"are version {SOLID_VERSION} or later)")
    declared = f.attrs.get("dim")
    if declared is not None and not (_attr_ok(declared, "int") and int(declared) == dim):
        raise bad("attribute 'dim'", f"{declared!r}, but the points have {dim} coordinates")
    points = dataset("mesh/points", "f", 2, dim)
    spec = get_element(element, dim)
    arrays = {"mesh/points": points,
              "mesh/cells": dataset("mesh/cells", "iu", 2, spec.n_local),
              "mesh/contact_nodes": dataset("mesh/contact_nodes", "iu", 1)}
    for kind, other in (("edges", "faces"), ("faces", "edges")):
        groups = f.get(f"mesh/{kind}")
        names = list(groups.keys()) if isinstance(groups, h5py.Group) else []
        if names and kind == ("faces" if dim == 2 else "edges"):
            raise bad(f"group 'mesh/{kind}'", f"boundary {kind} in a {dim}D mesh (its boundary "
                      f"groups are {other if dim == 2 else kind})")
        for name in names:
            if not group_name_ok(name):
                raise bad(f"a group of 'mesh/{kind}'", f"name {name[:MAX_GROUP_NAME]!r}, not "
                          "printable text")
            arrays[f"mesh/{kind}/{name}"] = dataset(f"mesh/{kind}/{name}", "iu", 2,
                                                    spec.facet_nodes)
    if "mesh/slip" in f:
        slip = dataset("mesh/slip", "f", 2, 3)
        if dim != 3 or len(slip) != len(arrays["mesh/contact_nodes"]):
            raise bad("dataset 'mesh/slip'", f"{len(slip)} slip directions for "
                      f"{len(arrays['mesh/contact_nodes'])} contact nodes of a {dim}D mesh")
        arrays["mesh/slip"] = slip
    return len(points), arrays


def _check_frame(f: h5py.File, dataset, bad, arrays: dict, dim: int) -> None:
    """The frame attributes of a solve file (normal, tangent: unit, orthogonal, ``dim``
    components) and, in 3D, its law, slip angle, slip directions and r of each eigenvalue."""
    frame = {}
    for name in ("normal", "tangent"):
        value = f.attrs.get(name)
        if not (isinstance(value, np.ndarray) and value.shape == (dim,)
                and value.dtype.kind in "fiu" and np.all(np.isfinite(value))
                and abs(np.linalg.norm(value) - 1.0) <= UNIT_TOL):
            raise bad(f"attribute {name!r}", f"missing or not a unit vector of {dim} numbers")
        frame[name] = value.astype(float)
    if abs(frame["normal"] @ frame["tangent"]) > UNIT_TOL:
        raise bad("attribute 'tangent'", "not orthogonal to the normal")
    if dim == 2:
        return
    if text_of(f.attrs.get("law", "")) not in LAWS:
        raise bad("attribute 'law'", "missing or not one of " + ", ".join(LAWS))
    if not _attr_ok(f.attrs.get("slip_angle"), "float"):
        raise bad("attribute 'slip_angle'", "missing or not a finite number")
    if "mesh/slip" not in arrays:
        raise bad("dataset 'mesh/slip'", "missing")
    slip = arrays["mesh/slip"]
    if not np.all(np.isfinite(slip)) or np.any(
            np.abs(np.linalg.norm(slip, axis=1) - 1.0) > UNIT_TOL) or np.any(
            np.abs(slip @ frame["normal"]) > UNIT_TOL):
        raise bad("dataset 'mesh/slip'", "not unit vectors in the contact plane")
    r = dataset("eigen/r", "f", 1)
    if len(r) != len(arrays["eigen/alpha"]):
        raise bad("dataset 'eigen/r'", f"{len(r)} values for {len(arrays['eigen/alpha'])} "
                  "eigenvalues")
    if not np.all((r >= 0) & (r <= 1)):  # NaN fails too
        raise bad("dataset 'eigen/r'", "values outside [0, 1]")
    arrays["eigen/r"] = r


def _finite_indices(arrays: dict, n: int, bad) -> None:
    """Floats finite, node indices in [0, n), at least one cell."""
    for name, values in arrays.items():
        if values.dtype.kind in "fc" and not np.all(np.isfinite(values)):
            raise bad(f"dataset {name!r}", "values that are not finite")
        if values.dtype.kind in "iu" and values.size and (values.min() < 0
                                                          or values.max() >= n):
            raise bad(f"dataset {name!r}", f"node indices outside [0, {n})")
    if not len(arrays["mesh/cells"]):
        raise bad("dataset 'mesh/cells'", "no cell")


def _check_path(f: h5py.File, dataset, bad, version: int) -> None:
    """The datasets of a path file (layout in files/pathfile.py): every curve's points and
    pieces, the events, the isolated solutions, the arc lengths and the mesh if stored."""
    p, node = int(f.attrs["n_contact"]), int(f.attrs["node"])
    if p < 0 or not (0 <= node < p or node == p == 0):
        raise bad("attribute 'node'", f"{node}, not a contact node of [0, {p})")
    if text_of(f.attrs["parameter"]) not in PARAMETERS:
        raise bad("attribute 'parameter'", "not one of " + ", ".join(PARAMETERS))
    finite = {"samples": dataset("samples", "f", 1)}
    finite["contact/s"] = dataset("contact/s", "f", 1)
    if len(finite["contact/s"]) != p:
        raise bad("dataset 'contact/s'", f"{len(finite['contact/s'])} values for {p} contact "
                  "nodes")

    def rows(name: str, dtype: str, n: int, width=None) -> np.ndarray:
        values = dataset(name, dtype, 1 if width is None else 2, width)
        if len(values) != n:
            raise bad(f"dataset {name!r}", f"{len(values)} rows, not {n}")
        return values

    def codes(name: str, n: int) -> None:
        values, legend = rows(name, "iu", n, p), f[name].attrs.get("legend")
        if not (isinstance(legend, np.ndarray) and legend.ndim == 1
                and legend.dtype.kind in "OSU"):
            raise bad(f"attribute 'legend' of dataset {name!r}", "missing or not texts")
        if values.size and (values.min() < 0 or values.max() >= len(legend)):
            raise bad(f"dataset {name!r}", f"codes outside [0, {len(legend)}) of its legend")

    def points(group: str) -> int:
        value = dataset(f"{group}/value", "f", 1)
        finite[f"{group}/value"] = value
        codes(f"{group}/status", len(value))
        for name in POINT_VALUES:
            finite[f"{group}/{name}"] = rows(f"{group}/{name}", "f", len(value), p)
        return len(value)

    def optional(name: str, n: int, infinite: bool = False) -> None:  # NaN: None
        values = rows(name, "f", n)  # infinite: +inf allowed (a margin at friction 0)
        if np.any(np.isneginf(values) if infinite else np.isinf(values)):
            raise bad(f"dataset {name!r}", "infinite values")

    curves = f.get("curves")
    if not isinstance(curves, h5py.Group) or sorted(curves.keys(), key=lambda k: (
            len(k), k)) != [str(i) for i in range(len(curves))]:
        raise bad("group 'curves'", "missing, or not numbered 0, 1, ...")
    for i in range(len(curves)):
        g = f"curves/{i}"
        if not _attr_ok(f[g].attrs.get("seed"), "json"):
            raise bad(f"attribute 'seed' of group {g!r}", "missing or not JSON")
        n = points(g)
        k = len(dataset(f"{g}/pieces/start", "f", 1))
        for name in ("start", "end"):
            finite[f"{g}/pieces/{name}"] = rows(f"{g}/pieces/{name}", "f", k)
        for name in ("critical_positive", "critical_negative", "margin"):
            optional(f"{g}/pieces/{name}", k, infinite=name == "margin")
        codes(f"{g}/pieces/state", k)
        piece = rows(f"{g}/piece", "iu", n)
        if piece.size and (piece.min() < 0 or piece.max() >= k):
            raise bad(f"dataset '{g}/piece'", f"pieces outside [0, {k})")
    finite["events/value"] = dataset("events/value", "f", 1)
    m = len(finite["events/value"])
    optional("events/critical", m)
    rows("events/unbounded", "b", m)
    if not all(text_of(v) in EVENT_KINDS for v in rows("events/kind", "OSU", m)):
        raise bad("dataset 'events/kind'", "not one of " + ", ".join(EVENT_KINDS))
    for name, bound in (("nodes", p), ("curves", len(curves)), ("states", None)):
        for text in rows(f"events/{name}", "OSU", m):
            if not _json_list(text_of(text), bound, p):
                raise bad(f"dataset 'events/{name}'", "an entry that is not a JSON list of "
                          + ("status lists" if bound is None else f"indices in [0, {bound})"))
    points("isolated")
    for name, values in finite.items():
        if not np.all(np.isfinite(values)):
            raise bad(f"dataset {name!r}", "values that are not finite")
    if "mesh" in f:
        element = f["mesh/cells"].attrs.get("element") if "mesh/cells" in f else None
        if not _attr_ok(element, "element"):
            raise bad("attribute 'element' of dataset 'mesh/cells'", "missing or unknown")
        n, arrays = _mesh(f, dataset, bad, text_of(element), version)
        if len(arrays["mesh/contact_nodes"]) != p:
            raise bad("dataset 'mesh/contact_nodes'", f"not {p} nodes")
        _finite_indices(arrays, n, bad)


def _json_list(text: str, bound: int | None, p: int) -> bool:
    """A JSON list of indices in [0, bound), or (bound None) of lists of p status words."""
    try:
        value = json.loads(text)
    except ValueError:
        return False
    if not isinstance(value, list):
        return False
    if bound is None:
        return all(isinstance(s, list) and len(s) == p and all(isinstance(w, str) for w in s)
                   for s in value)
    return all(isinstance(v, int) and not isinstance(v, bool) and 0 <= v < bound
               for v in value)


def _number_ok(value, bounds, *, optional: bool = False) -> bool:
    """A finite number (within ``bounds`` if given), or absent when ``optional``."""
    if value is None:
        return optional
    if not _attr_ok(value, "float"):
        return False
    return bounds is None or bounds[0] <= float(value) <= bounds[1]


def _attr_ok(value, want: str) -> bool:
    if value is None:
        return False
    if isinstance(value, np.ndarray) and value.shape == ():
        value = value.item()
    if want == "texts":  # a list of strings; JSON text in version-1 files
        if isinstance(value, np.ndarray):
            return value.ndim == 1 and value.dtype.kind in "OSU" \
                and all(_printable(v) for v in value.tolist())
        want = "json"
    if want == "range":  # two finite floats
        return isinstance(value, np.ndarray) and value.shape == (2,) \
            and value.dtype.kind == "f" and bool(np.all(np.isfinite(value)))
    if want == "number":  # a float, NaN allowed (none)
        return isinstance(value, (float, np.floating)) and not math.isinf(float(value))
    if want == "int":
        return isinstance(value, (int, np.integer)) and not isinstance(value, bool)
    if want == "float":
        return isinstance(value, (int, float, np.integer, np.floating)) \
            and not isinstance(value, bool) and math.isfinite(float(value))
    if not isinstance(value, (str, bytes)):
        return False
    text = text_of(value)
    if want == "element":
        return text in NAMES
    if want == "toml":
        return _printable(text.replace("\n", " ").replace("\t", " ").replace("\r", " "))
    if want == "json":
        try:
            return _printable(json.loads(text))
        except ValueError:
            return False
    return _printable(text)


def _printable(value) -> bool:
    """True if every string in ``value`` (a string, bytes, or JSON data) is printable."""
    if isinstance(value, bytes):
        value = text_of(value)
    if isinstance(value, str):
        return value.isprintable()
    if isinstance(value, dict):
        return all(_printable(k) and _printable(v) for k, v in value.items())
    if isinstance(value, list):
        return all(_printable(v) for v in value)
    return True
