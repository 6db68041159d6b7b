"""Result files: one self-describing HDF5 file per solve, written atomically.

Layout (``schema_version`` 2 for a 2D body, 3 for a 3D one; d = 2 or 3 its dimension)::

    /                   attrs: kind="solve", critfric_version, schema_version, case_name,
                        case_source, case_toml (the effective case, re-runnable), case_text
                        (the file as given), nu, E, element, size, h, n_dofs, n_contact,
                        method (asked), solver (used), backend (linear solver), shift,
                        count, gamma, tol, real_tol, infinite_tol, residual_tol, applications,
                        n_infinite, seconds, timings (JSON), warnings (JSON), notes (JSON),
                        dim, normal (d,), tangent (d,) (2D: t = (-n2, n1); 3D: t1, the
                        direction of slip angle 0); 3D: law (of the slip direction: "rate" or
                        "frozen"), slip_angle ([solve] slip_angle, degrees)
    /eigen/alpha        complex, every finite eigenvalue computed, sorted by modulus
    /eigen/r            3D: r of each eigenvalue of /eigen/alpha, in [0, 1] (0: the pair
                        is an exact static branch of both laws)
    /critical/positive  real eigenvalues > 0, sorted
    /critical/negative  real eigenvalues < 0, sorted by |alpha|
    /modes/<name>       name = positive_0, negative_0, ...; datasets phi (n_nodes, d),
                        theta_n (p,), theta_t (p,) (nodal contact forces X = F(theta_n),
                        Y = F(theta_t), Y along t in 2D and along each node's slip direction
                        s in 3D); attrs alpha, residual, r
    /mesh/points (n, d), /mesh/cells (n_cells, n_local) attrs element,
    /mesh/contact_nodes (p,), /mesh/edges/<name> (n_facets, 2 or 3) (2D),
    /mesh/faces/<name> (n_faces, 3, 6, 4 or 9) (3D, gmsh's node order), /mesh/slip (p, 3)
    (3D: the unit slip direction s of each contact node)
"""

from __future__ import annotations

import json
from pathlib import Path

import h5py
import numpy as np

from .._version import __version__
from ..errors import CaseError
from ..fem.contact3d import plane_axes, slip_directions
from ..solvers.eigen import INFINITE_TOL, RESIDUAL_TOL
from ..solvers.from_case import plane_positions, slip_angles
from . import validate
from .opening import kind_of, open_file
from .safety import atomic_h5, check_output
from .validate import SCHEMA_VERSION, SOLID_VERSION


def default_output(case) -> Path:
    return Path(case.output["file"] or f"{case.name}.h5")


def write_result(result, path: Path | str, *, force: bool = False) -> Path:
    """Write a :class:`critfric.solve.Result` to ``path`` (atomically)."""
    path = check_output(Path(path), force=force)
    case, s = result.case, result.case.solve
    dim = result.mesh.dim

    def fill(f: h5py.File) -> None:
        a = f.attrs
        a.update({
            "kind": "solve", **case_attrs(case, dim), "nu": result.nu, "E": result.E,
            "element": result.element,
            "size": np.nan if result.size is None else result.size, "h": result.h,
            "n_dofs": result.n_dofs, "n_contact": result.n_contact, "method": s["method"],
            "solver": result.solver, "backend": result.backend, "complete": result.complete,
            "shift": s["shift"], "count": s["count"],
            "gamma": s["gamma"], "tol": s["tol"], "real_tol": s["real_tol"],
            "infinite_tol": INFINITE_TOL, "residual_tol": RESIDUAL_TOL,
            "applications": result.applications, "n_infinite": result.n_infinite,
            "seconds": result.seconds,
            **{f"seconds_{stage}": float(s) for stage, s in result.timings.items()},
            "warnings": _strings(result.warnings), "notes": _strings(result.notes),
            "dim": dim, **_frame_attrs(result),
        })
        f["eigen/alpha"] = result.alpha.astype(np.complex128)
        if dim == 3:
            f["eigen/r"] = _r(result)
        f["critical/positive"] = np.asarray(result.positive, dtype=np.float64)
        f["critical/negative"] = np.asarray(result.negative, dtype=np.float64)
        modes = f.create_group("modes")
        counters = {"positive": 0, "negative": 0}
        if case.output["modes"]:
            for mode in result.modes:
                family = "positive" if mode["alpha"] > 0 else "negative"
                g = modes.create_group(f"{family}_{counters[family]}")
                counters[family] += 1
                g["phi"], g["theta_n"], g["theta_t"] = mode["phi"], mode["theta_n"], mode["theta_t"]
                g.attrs["alpha"], g.attrs["residual"] = mode["alpha"], mode["residual"]
                g.attrs["r"] = float(mode.get("r", 0.0))
        write_mesh(f, result.mesh, result.contact_nodes,
                   slip=result_slip(result) if dim == 3 else None)

    def described(f: h5py.File) -> None:
        fill(f)
        f.visititems(lambda name, obj: _describe(name, obj, dim=dim))

    return atomic_h5(path, described)


def write_mesh(f: h5py.File, mesh, contact_nodes, slip=None) -> None:
    """The /mesh group: points, cells (attr element), contact nodes, named edges (2D) or
    faces (3D) and, if given, the slip directions (p, 3) of the contact nodes."""
    f["mesh/points"] = mesh.points
    f["mesh/cells"] = mesh.cells
    f["mesh/cells"].attrs["element"] = mesh.element
    f["mesh/contact_nodes"] = contact_nodes
    for name, facets in mesh.edges.items():
        f[f"mesh/edges/{name}"] = facets
    for name, facets in mesh.faces.items():
        f[f"mesh/faces/{name}"] = facets
    if slip is not None:
        f["mesh/slip"] = np.asarray(slip, dtype=np.float64)


def case_attrs(case, dim: int = 2) -> dict:
    """Root attributes that make a file re-runnable: the case as given and as run, and the
    schema version of a file of a ``dim``-dimensional body."""
    return {"critfric_version": __version__,
            "schema_version": SOLID_VERSION if dim == 3 else SCHEMA_VERSION,
            "case_name": case.name, "case_source": case.source, "case_toml": case.to_toml(),
            "case_text": case.text}


def _frame_attrs(result) -> dict:
    """normal and tangent of Gamma_C (2D: t = (-n2, n1); 3D: t1) and the 3D slip settings."""
    normal = np.asarray(result.normal, dtype=np.float64)
    if result.mesh.dim == 2:
        return {"normal": normal, "tangent": np.array([-normal[1], normal[0]])}
    return {"normal": normal, "tangent": plane_axes(normal)[0], "law": str(result.law),
            "slip_angle": float(result.slip_angle)}


def _r(result) -> np.ndarray:
    """r of each eigenvalue of ``result.alpha`` (zeros where the solver gave none)."""
    r = getattr(result, "r", None)
    return np.zeros(len(result.alpha)) if r is None else np.asarray(r, dtype=np.float64)


def result_slip(result) -> np.ndarray:
    """(p, 3) slip directions of a 3D result's contact nodes: ``result.slip`` if it carries
    them, else made again from its case as the solve made them ([solve] slip_angle and the
    slip_angle of [contact] rules, at the nodes' positions in the contact plane)."""
    slip = getattr(result, "slip", None)
    if slip is not None:
        return np.asarray(slip, dtype=np.float64)
    nodes = np.asarray(result.contact_nodes)
    normal = np.asarray(result.normal, dtype=np.float64)
    t1 = plane_axes(normal)[0]
    positions = plane_positions(result.mesh.points, nodes, normal, t1)
    return slip_directions(normal, t1, len(nodes), angle=slip_angles(result.case, nodes,
                                                                      positions))


#: units and long names of a solve file's datasets, by the last part of their path
DESCRIPTIONS = {
    "alpha": ("1", "every finite eigenvalue of (3.2), complex, by modulus"),
    "positive": ("1", "positive critical friction coefficients, ascending"),
    "negative": ("1", "negative critical coefficients (|alpha| for the opposite slip)"),
    "points": ("length unit of the case", "node coordinates (x, y)"),
    "cells": ("1", "node indices of each cell, gmsh local order"),
    "contact_nodes": ("1", "node indices of the contact nodes, along the tangent"),
    "phi": ("1", "eigenfunction Phi at the nodes (x, y), max |Phi| = 1"),
    "theta_n": ("force unit", "nodal normal contact force X = F(theta_n) of the mode"),
    "theta_t": ("force unit", "nodal tangential contact force Y = F(theta_t) of the mode"),
    "friction": ("1", "signed friction coefficient of the followed branches, ascending"),
    "kappa": ("(rad / time unit)^2", "kappa = -s^2 of each followed branch (complex)"),
    "growth": ("1 / time unit", "growth rate Re s >= 0 of each branch"),
    "frequency": ("rad / time unit", "angular frequency |Im s| of each branch"),
    "frequencies": ("rad / time unit", "free-vibration frequencies at friction 0, ascending"),
    "shape": ("1", "flutter mode at onset, nodal (x, y), max |phi| = 1"),
    "r": ("1", "r of each eigenvalue: 0 for an exact static branch of both slip laws"),
    "slip": ("1", "unit slip direction s of each contact node (x, y, z)"),
}


def _strings(values: list[str]) -> np.ndarray:
    """A list of texts as a plain HDF5 attribute (an array of UTF-8 strings, empty allowed)."""
    return np.array(list(values), dtype=h5py.string_dtype())


def text_list(value) -> list[str]:
    """An attribute written by :func:`_strings` (or, in version-1 files, as JSON) as a list."""
    if isinstance(value, (str, bytes)):
        return [str(v) for v in json.loads(value)]
    return [v.decode() if isinstance(v, bytes) else str(v) for v in np.atleast_1d(value)]


def _describe(name: str, obj, dim: int = 2) -> None:
    if isinstance(obj, h5py.Dataset):
        group, _, leaf = name.rpartition("/")
        if group in ("mesh/edges", "mesh/faces"):
            kind = "edge" if group == "mesh/edges" else "face group"
            units, long_name = "1", f"node indices of the facets of boundary {kind} {leaf!r}"
        else:
            units, long_name = DESCRIPTIONS.get(
                leaf, ("1", f"node indices of the facets of boundary edge {leaf!r}"))
        if dim == 3:  # the texts name the 2D coordinates
            long_name = long_name.replace("(x, y)", "(x, y, z)")
        obj.attrs.update({"units": units, "long_name": long_name})


def file_attrs(f: h5py.File, kind: str, path: Path) -> dict:
    """The root attributes of a critfric file of ``kind`` ("solve", "sweep"), strings as str;
    a file of another kind is a CaseError."""
    if kind_of(f) != kind:
        raise CaseError(f"is not a critfric {kind} file (no kind = '{kind}' attribute)",
                        file=str(path))
    validate.check(f, kind, Path(path))
    return {k: (v.decode() if isinstance(v, bytes) else v) for k, v in f.attrs.items()}


def read_summary(path: Path | str) -> dict:
    """The JSON-style summary of a solve file (as ``critfric solve --json`` prints it)."""
    path = Path(path)
    try:
        with open_file(path) as f:
            a = file_attrs(f, "solve", path)
            alpha = f["eigen/alpha"][()]
            pos, neg = f["critical/positive"][()], f["critical/negative"][()]
            size = float(a["size"])
            return {
                "case": str(a["case_name"]), "positive": pos.tolist(),
                "negative": neg.tolist(),
                "complex_count": int(len(alpha) - len(pos) - len(neg)),
                "n_dofs": int(a["n_dofs"]), "n_contact": int(a["n_contact"]),
                "element": str(a["element"]), "nu": float(a["nu"]), "h": float(a["h"]),
                "size": None if np.isnan(size) else size, "method": str(a["solver"]),
                "backend": str(a.get("backend", "scipy")),
                "complete": bool(a.get("complete", True)),
                "seconds": float(a["seconds"]), "warnings": text_list(a["warnings"]),
                **(_solid_summary(a, alpha, f["eigen/r"][()], pos, neg)
                   if f["mesh/points"].shape[1] == 3 else {}),
            }
    except (OSError, KeyError, ValueError, TypeError, IndexError) as exc:
        raise CaseError(f"cannot read this result file ({exc})", file=str(path)) from None


def _solid_summary(a: dict, alpha, r, positive, negative) -> dict:
    """The 3D keys of a summary (as :meth:`critfric.solve.Result.summary` gives them)."""
    return {"dim": 3, "law": str(a["law"]), "slip_angle": float(a["slip_angle"]),
            "r_positive": r_of(alpha, r, positive).tolist(),
            "r_negative": r_of(alpha, r, negative).tolist()}


def r_of(alpha: np.ndarray, r: np.ndarray, values: np.ndarray) -> np.ndarray:
    """r of each of ``values`` (real eigenvalues of ``alpha``, with ``r`` aligned to it):
    that of the real eigenvalue of ``alpha`` nearest to it (zeros if it has none)."""
    values = np.asarray(values, dtype=float)
    real = np.flatnonzero(np.asarray(alpha).imag == 0)
    if not len(real) or not len(values):
        return np.zeros(len(values))
    order = real[np.argsort(alpha.real[real], kind="stable")]
    x = alpha.real[order]
    above = np.searchsorted(x, values).clip(0, len(x) - 1)
    below = (above - 1).clip(0)
    nearer = np.abs(x[below] - values) < np.abs(x[above] - values)
    return np.asarray(r, dtype=float)[order[np.where(nearer, below, above)]]
