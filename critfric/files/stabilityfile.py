"""Stability files: one self-describing HDF5 file per ``critfric stability`` run.

Layout (``schema_version`` as solve files, ``kind = "stability"``)::

    /                     attrs: kind, critfric_version, schema_version, case_name,
                          case_source, case_toml, case_text, nu, E, density, element, size,
                          h, n_dofs, n_contact, modes, steps, backend, seconds,
                          seconds_<stage>, warnings, notes, normal, tangent,
                          flutter_positive, flutter_negative (signed friction, NaN: none
                          found), flutter_kappa_positive/negative, divergence_positive,
                          divergence_negative (the static coefficients, NaN: none),
                          complex_tol, fold_tol
    /stability/friction   (n_f,) signed friction, ascending
    /stability/kappa      (n_f, modes) complex kappa = -s^2 of the followed branches
    /stability/growth     (n_f, modes) Re s >= 0;  /stability/frequency  (n_f, modes) |Im s|
    /stability/frequencies (modes,) omega_k at friction 0
    /flutter/<direction>/shape (n_nodes, 2) the flutter mode at onset, attrs friction, kappa
    /mesh/...             as in a solve file
"""

from __future__ import annotations

from pathlib import Path

import h5py
import numpy as np

from ..errors import CaseError
from ..stability.analysis import first_instability
from ..stability.fold import FOLD_TOL
from ..stability.locus import COMPLEX_TOL
from .opening import open_file
from .results import _describe, _strings, case_attrs, file_attrs, text_list, write_mesh
from .safety import atomic_h5, check_output

DIRECTIONS = ("positive", "negative")


def default_stability_output(case) -> Path:
    return Path(f"{case.name}_stability.h5")


def write_stability(result, path: Path | str, *, force: bool = False) -> Path:
    """Write a :class:`critfric.stability.StabilityResult` to ``path`` (atomically)."""
    path = check_output(Path(path), force=force)
    nan = lambda v: np.nan if v is None else float(v)

    def fill(f: h5py.File) -> None:
        f.attrs.update({
            "kind": "stability", **case_attrs(result.case), "nu": result.nu, "E": result.E,
            "density": result.density, "element": result.element,
            "size": nan(result.size), "h": result.h, "n_dofs": result.n_dofs,
            "n_contact": len(result.contact_nodes), "modes": result.modes,
            "steps": result.case.stability["steps"], "backend": result.backend,
            "seconds": result.seconds,
            **{f"seconds_{stage}": float(s) for stage, s in result.timings.items()},
            "warnings": _strings(result.warnings), "notes": _strings(result.notes),
            "normal": result.normal,
            "tangent": np.array([-result.normal[1], result.normal[0]]),
            "complex_tol": COMPLEX_TOL, "fold_tol": FOLD_TOL,
            **{f"flutter_{d}": nan(result.flutter[d]) for d in DIRECTIONS},
            **{f"flutter_kappa_{d}": nan(result.flutter_kappa[d]) for d in DIRECTIONS},
            **{f"divergence_{d}": nan(result.divergence[d]) for d in DIRECTIONS},
        })
        f["stability/friction"] = result.friction
        f["stability/kappa"] = result.kappa.astype(np.complex128)
        f["stability/growth"] = result.growth()
        f["stability/frequency"] = result.frequency()
        f["stability/frequencies"] = result.frequencies
        for d, shape in result.flutter_modes.items():
            f[f"flutter/{d}/shape"] = shape
            f[f"flutter/{d}"].attrs.update({"friction": result.flutter[d],
                                             "kappa": result.flutter_kappa[d]})
        write_mesh(f, result.mesh, result.contact_nodes)
        f.visititems(_describe)

    return atomic_h5(path, fill)


def read_stability_summary(path: Path | str) -> dict:
    """The JSON-style summary of a stability file (as ``critfric stability --json``)."""
    path = Path(path)
    try:
        with open_file(path) as f:
            a = file_attrs(f, "stability", path)
            opt = lambda k: None if np.isnan(a[k]) else float(a[k])
            flutter = {d: opt(f"flutter_{d}") for d in DIRECTIONS}
            divergence = {d: opt(f"divergence_{d}") for d in DIRECTIONS}
            friction = f["stability/friction"][()]
            size = float(a["size"])
            return {
                "case": str(a["case_name"]), "flutter": flutter, "divergence": divergence,
                "first": {d: first_instability(flutter[d], divergence[d]) for d in DIRECTIONS},
                "frequencies": f["stability/frequencies"][()].tolist(),
                "friction_range": [float(friction[0]), float(friction[-1])],
                "modes": int(a["modes"]), "n_dofs": int(a["n_dofs"]),
                "n_contact": int(a["n_contact"]), "element": str(a["element"]),
                "nu": float(a["nu"]), "density": float(a["density"]), "h": float(a["h"]),
                "size": None if np.isnan(size) else size,
                "backend": str(a.get("backend", "scipy")), "seconds": float(a["seconds"]),
                "warnings": text_list(a["warnings"]),
            }
    except (OSError, KeyError, ValueError, TypeError, IndexError) as exc:
        raise CaseError(f"cannot read this stability file ({exc})", file=str(path)) from None

