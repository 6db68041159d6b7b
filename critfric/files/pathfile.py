"""Path files: one self-describing HDF5 file per ``critfric path`` run (the solution curves
of the static problem (2.8) along a parameter, their pieces and events).

Layout (``schema_version`` as solve files, ``kind = "path"``; p = n_contact)::

    /                     attrs: kind, critfric_version, schema_version, case_name,
                          case_source, case_toml, case_text, title (the case's, "" if none),
                          parameter ("friction" or "load"), range (2,) float,
                          friction (the fixed friction of a load path; NaN: a friction path),
                          node (the contact node of the diagram), n_dofs, n_contact, seconds,
                          notes (UTF-8 strings), counts (JSON: curves, pieces, kinks, folds,
                          branches)
    /samples              (n_s,) parameter values sampled
    /contact/s            (p,) arc length of each contact node along Gamma_C
    /curves/<i>/          i = 0, 1, ...; attrs seed (JSON text: "start", {"value": t} or
                          {"value": t, "event": k})
        value (n,)        parameter value of each point, in the curve's order
        status (n, p)     int8 status codes of each contact node; attr legend (UTF-8
                          strings): code c is legend[c] (free, stuck, slip+, slip-, cone)
        Un, Ut, X, Y      (n, p) contact displacements and nodal contact forces
        piece (n,)        int, the index of the piece each point lies on
        pieces/state      (k, p) int8 status codes of each piece (attr legend, as status)
        pieces/start, pieces/end  (k,) parameter interval of each piece
        pieces/critical_positive, pieces/critical_negative  (k,) critical coefficients of
                          the piece's state (NaN: None)
        pieces/margin     (k,) critical_positive over the largest friction (NaN: None)
    /events/              m events: kind (m,) UTF-8 strings (kink, fold, branch), value (m,),
                          critical (m,) (NaN: None), unbounded (m,) bool; nodes, curves,
                          states (m,) UTF-8 strings, each the JSON text of a list
    /isolated/            q solutions on no curve: value (q,), status (q, p) with legend,
                          Un, Ut, X, Y (q, p)
    /mesh/...             as in a solve file (only when the result carries its mesh)

Every dataset has attrs units and long_name.
"""

from __future__ import annotations

import json
from pathlib import Path

import h5py
import numpy as np

from ..errors import CaseError
from ..fem.mesh import Mesh
from .opening import open_file
from .results import _describe, _strings, case_attrs, file_attrs, text_list, write_mesh
from .safety import atomic_h5, check_output
from .validate import POINT_VALUES

STATUS_WORDS = ("free", "stuck", "slip+", "slip-", "cone")  # the legend's first codes
COUNTS = ("curves", "pieces", "kinks", "folds", "branches")

#: units and long names of a path file's datasets, by the last part of their path
DESCRIPTIONS = {
    "samples": ("1", "parameter values sampled"),
    "s": ("length unit of the case", "arc length of each contact node along Gamma_C"),
    "value": ("1", "parameter value (friction coefficient or load factor)"),
    "status": ("1", "status code of each contact node (see attr legend)"),
    "state": ("1", "status code of each contact node on the piece (see attr legend)"),
    "Un": ("length unit of the case", "normal displacement of each contact node"),
    "Ut": ("length unit of the case", "tangential displacement of each contact node"),
    "X": ("force unit", "nodal normal contact force"),
    "Y": ("force unit", "nodal tangential contact force"),
    "piece": ("1", "index of the piece each point lies on"),
    "start": ("1", "parameter value where the piece starts"),
    "end": ("1", "parameter value where the piece ends"),
    "critical_positive": ("1", "lowest positive critical coefficient of the state (NaN: none)"),
    "critical_negative": ("1", "negative critical coefficient of lowest modulus (NaN: none)"),
    "margin": ("1", "critical_positive over the largest friction on the piece (NaN: none)"),
    "kind": ("1", "kink, fold or branch"),
    "critical": ("1", "critical coefficient of the singular state (NaN: none)"),
    "unbounded": ("1", "branch point reached only at infinity"),
    "nodes": ("1", "JSON list: contact nodes whose status changes"),
    "curves": ("1", "JSON list: curves meeting at the event"),
    "states": ("1", "JSON list: contact states meeting at the event"),
}


def default_path_output(case) -> Path:
    return Path(f"{case.name}_path.h5")


def _plain(value):
    """numpy scalars and arrays in JSON text (seeds, event lists)."""
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    raise TypeError(f"{type(value).__name__} is not JSON")


def _json(value) -> str:
    return json.dumps(value, default=_plain)


def _nan(value) -> float:
    return np.nan if value is None else float(value)


def _codes(rows: list[list[str]], p: int, legend: list[str]) -> np.ndarray:
    """Status words (rows of p) as int8 codes into ``legend`` (grown by unknown words)."""
    out = np.zeros((len(rows), p), dtype=np.int8)
    for i, row in enumerate(rows):
        for j, word in enumerate(row):
            if word not in legend:
                legend.append(str(word))
            out[i, j] = legend.index(word)
    return out


def _write_codes(f: h5py.File, name: str, rows, p: int) -> None:
    legend = list(STATUS_WORDS)
    f[name] = _codes(rows, p, legend)
    f[name].attrs["legend"] = _strings(legend)


def _write_points(f: h5py.File, group: str, values, points, p: int) -> None:
    f[f"{group}/value"] = np.asarray(values, dtype=np.float64).reshape(-1)
    _write_codes(f, f"{group}/status", [q.status for q in points], p)
    for name in POINT_VALUES:
        f[f"{group}/{name}"] = np.array([np.asarray(getattr(q, name), dtype=np.float64)
                                         for q in points]).reshape(len(points), p)


def write_path(result, path: Path | str, *, force: bool = False) -> Path:
    """Write a :class:`critfric.multiplicity.pathresult.PathResult` to ``path`` (atomically)."""
    path = check_output(Path(path), force=force)
    p = int(result.n_contact)

    def fill(f: h5py.File) -> None:
        f.attrs.update({
            "kind": "path", **case_attrs(result.case), "title": result.case.title or "",
            "parameter": result.parameter,
            "range": np.array([float(v) for v in result.range]),
            "friction": _nan(result.friction), "node": int(result.node),
            "n_dofs": int(result.n_dofs), "n_contact": p, "seconds": float(result.seconds),
            "notes": _strings(result.notes), "counts": _json(result.counts()),
        })
        f["samples"] = np.asarray(result.samples, dtype=np.float64).reshape(-1)
        f["contact/s"] = np.asarray(result.s, dtype=np.float64).reshape(-1)
        f.create_group("curves")
        for i, curve in enumerate(result.curves):
            g = f.create_group(f"curves/{i}")
            g.attrs["seed"] = _json(curve.seed)
            _write_points(f, g.name, [q.value for q in curve.points], curve.points, p)
            g["piece"] = np.array([int(q.piece) for q in curve.points], dtype=np.int64)
            pieces = curve.pieces
            _write_codes(f, f"{g.name}/pieces/state", [c.state for c in pieces], p)
            columns = {"start": [c.start for c in pieces], "end": [c.end for c in pieces],
                       "critical_positive": [c.critical[0] for c in pieces],
                       "critical_negative": [c.critical[1] for c in pieces],
                       "margin": [c.margin for c in pieces]}
            for name, values in columns.items():
                g[f"pieces/{name}"] = np.array([_nan(v) for v in values], dtype=np.float64)
        events = result.events
        f["events/kind"] = _strings([e.kind for e in events])
        f["events/value"] = np.array([float(e.value) for e in events], dtype=np.float64)
        f["events/critical"] = np.array([_nan(e.critical) for e in events], dtype=np.float64)
        f["events/unbounded"] = np.array([bool(e.unbounded) for e in events], dtype=bool)
        for name in ("nodes", "curves", "states"):
            f[f"events/{name}"] = _strings([_json(getattr(e, name)) for e in events])
        _write_points(f, "/isolated", [t for t, _ in result.isolated],
                      [q for _, q in result.isolated], p)
        if result.mesh is not None:
            write_mesh(f, result.mesh, np.asarray(result.contact_nodes))
        f.visititems(_describe_path)

    return atomic_h5(path, fill)


def _describe_path(name: str, obj) -> None:
    if name.startswith("mesh/"):
        _describe(name, obj)
    elif isinstance(obj, h5py.Dataset):
        units, long_name = DESCRIPTIONS[name.rsplit("/", 1)[-1]]
        obj.attrs.update({"units": units, "long_name": long_name})


def _words(dataset) -> list[list[str]]:
    legend = text_list(dataset.attrs["legend"])
    return [[legend[c] for c in row] for row in dataset[()].tolist()]


def _opt(value: float) -> float | None:
    return None if np.isnan(value) else float(value)


def _points(g) -> list[dict]:
    """The points of a curve group or of /isolated, as PathPoint.to_json gives them."""
    values = g["value"][()].tolist()
    status = _words(g["status"])
    arrays = {name: g[name][()] for name in POINT_VALUES}
    return [{"value": v, "status": status[i], **{n: a[i].tolist() for n, a in arrays.items()}}
            for i, v in enumerate(values)]


def _texts(dataset) -> list[str]:
    return [v.decode() if isinstance(v, bytes) else str(v) for v in dataset[()].tolist()]


def read_path(path: Path | str) -> dict:
    """A path file as ``PathResult.to_json()`` gives it (each curve point also with its
    ``piece``), plus "s" and "samples" (lists), "case_name", "title", "counts", "mesh" (a
    :class:`~critfric.fem.mesh.Mesh`, or None) and "contact_nodes" (a list, or None).
    Validated first: a malformed file is a CaseError naming the file and what is wrong."""
    path = Path(path)
    try:
        with open_file(path) as f:
            a = file_attrs(f, "path", path)
            curves = []
            for i in range(len(f["curves"])):
                g = f[f"curves/{i}"]
                points = _points(g)
                for q, k in zip(points, g["piece"][()].tolist()):
                    q["piece"] = k
                pc = g["pieces"]
                states = _words(pc["state"])
                cols = {k: pc[k][()].tolist() for k in ("start", "end", "critical_positive",
                                                         "critical_negative", "margin")}
                pieces = [{"state": states[j], "start": cols["start"][j],
                           "end": cols["end"][j],
                           "critical": {"positive": _opt(cols["critical_positive"][j]),
                                        "negative": _opt(cols["critical_negative"][j])},
                           "margin": _opt(cols["margin"][j])} for j in range(len(states))]
                curves.append({"seed": json.loads(_text(g.attrs["seed"])), "points": points,
                               "pieces": pieces})
            e = f["events"]
            lists = {k: [json.loads(t) for t in _texts(e[k])] for k in ("nodes", "curves",
                                                                          "states")}
            events = [{"kind": kind, "value": value, "nodes": lists["nodes"][j],
                       "critical": _opt(critical), "curves": lists["curves"][j],
                       "states": lists["states"][j], "unbounded": bool(unbounded)}
                      for j, (kind, value, critical, unbounded) in enumerate(zip(
                          _texts(e["kind"]), e["value"][()].tolist(),
                          e["critical"][()].tolist(), e["unbounded"][()].tolist()))]
            mesh = nodes = None
            if "mesh" in f:
                edges = {k: v[()] for k, v in f["mesh/edges"].items()} \
                    if "mesh/edges" in f else {}
                mesh = Mesh(f["mesh/points"][()], f["mesh/cells"][()],
                            _text(f["mesh/cells"].attrs["element"]), edges)
                nodes = f["mesh/contact_nodes"][()].tolist()
            return {
                "parameter": str(a["parameter"]), "range": [float(v) for v in a["range"]],
                "friction": _opt(float(a["friction"])), "curves": curves, "events": events,
                "isolated": _points(f["isolated"]), "node": int(a["node"]),
                "n_dofs": int(a["n_dofs"]), "n_contact": int(a["n_contact"]),
                "seconds": float(a["seconds"]), "notes": text_list(a["notes"]),
                "s": f["contact/s"][()].tolist(), "samples": f["samples"][()].tolist(),
                "case_name": str(a["case_name"]), "title": str(a.get("title", "")),
                "counts": json.loads(a["counts"]), "mesh": mesh, "contact_nodes": nodes,
            }
    except (OSError, KeyError, ValueError, TypeError, IndexError) as exc:
        raise CaseError(f"cannot read this path file ({exc})", file=str(path)) from None


def _text(value) -> str:
    return value.decode() if isinstance(value, bytes) else str(value)


def read_path_summary(path: Path | str) -> dict:
    """One row of ``critfric table``: the case, the parameter and its range, the fixed
    friction (None on a friction path), sizes, the counts, the branch points (value,
    critical coefficient, unbounded) and the seconds."""
    path = Path(path)
    try:
        with open_file(path) as f:
            a = file_attrs(f, "path", path)
            e = f["events"]
            branches = [{"value": v, "critical": _opt(c), "unbounded": bool(u)}
                        for k, v, c, u in zip(_texts(e["kind"]), e["value"][()].tolist(),
                                              e["critical"][()].tolist(),
                                              e["unbounded"][()].tolist()) if k == "branch"]
            counts = json.loads(a["counts"])
            return {
                "case": str(a["case_name"]), "parameter": str(a["parameter"]),
                "range": [float(v) for v in a["range"]],
                "friction": _opt(float(a["friction"])), "n_dofs": int(a["n_dofs"]),
                "n_contact": int(a["n_contact"]),
                "counts": {k: int(counts.get(k, 0)) for k in COUNTS},
                "isolated": len(f["isolated/value"]), "branch_points": branches,
                "seconds": float(a["seconds"]), "notes": text_list(a["notes"]),
            }
    except (OSError, KeyError, ValueError, TypeError, IndexError, AttributeError) as exc:
        raise CaseError(f"cannot read this path file ({exc})", file=str(path)) from None


def path_table(rows: list[dict]) -> str:
    """The text table of path rows (:func:`read_path_summary`), for ``critfric table``."""
    head = f"{'case':<16} {'parameter':<9} {'range':>19} {'friction':>10} {'n_dofs':>8} " \
           f"{'p':>5} {'curves':>6} {'pieces':>6} {'kinks':>5} {'folds':>5} " \
           f"{'branches':>8} {'isolated':>8} {'branch points':<28} {'seconds':>8}"
    lines = [head, "-" * len(head)]
    for r in rows:
        c = r["counts"]
        lo, hi = r["range"]
        span = f"{lo:.6g} .. {hi:.6g}"
        friction = "-" if r["friction"] is None else f"{r['friction']:.6g}"
        points = [f"{b['value']:.8g}" + (" (at inf)" if b["unbounded"] else "")
                  for b in r["branch_points"]]
        shown = ", ".join(points[:3]) + (f", ... (+{len(points) - 3})" if len(points) > 3
                                         else "")
        lines.append(f"{r['case']:<16} {r['parameter']:<9} {span:>19} {friction:>10} "
                     f"{r['n_dofs']:>8d} {r['n_contact']:>5d} {c['curves']:>6d} "
                     f"{c['pieces']:>6d} {c['kinks']:>5d} {c['folds']:>5d} "
                     f"{c['branches']:>8d} {r['isolated']:>8d} {shown or 'none':<28} "
                     f"{r['seconds']:>8.2f}")
    return "\n".join(lines)
