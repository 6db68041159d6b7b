"""Figures of a stability file: the root locus and the flutter modes.

``<file>_locus``: frequency |Im s| and growth rate Re s of the followed branches against the
signed friction, coalescences (flutter) and static critical coefficients (divergence)
marked. ``<file>_flutter_<direction>``: the real flutter mode at onset on the deformed mesh.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.collections import LineCollection
from matplotlib.figure import Figure

from ..errors import CaseError
from ..fem.mesh import Mesh
from ..files.opening import open_file
from ..files.results import file_attrs
from .meshdraw import segments as _segments

DIRECTIONS = ("positive", "negative")


def read_stability(path: Path) -> dict:
    """Every array and attribute the figures need, validated (CaseError otherwise)."""
    try:
        with open_file(path) as f:
            a = file_attrs(f, "stability", path)
            edges = {k: v[()] for k, v in f["mesh/edges"].items()} if "mesh/edges" in f else {}
            data = {"attrs": a, "friction": f["stability/friction"][()],
                    "frequency": f["stability/frequency"][()],
                    "growth": f["stability/growth"][()],
                    "mesh": Mesh(f["mesh/points"][()], f["mesh/cells"][()], str(a["element"]),
                                 edges),
                    "shapes": {d: f[f"flutter/{d}/shape"][()] for d in DIRECTIONS
                               if f"flutter/{d}/shape" in f}}
    except (OSError, KeyError, ValueError, TypeError) as exc:
        raise CaseError(f"cannot read this stability file ({exc})", file=str(path)) from None
    return data


def stability_figures(path: Path | str) -> dict[str, Figure]:
    """``locus`` and one ``flutter_<direction>`` per flutter onset found."""
    data = read_stability(Path(path))
    out = {"locus": _locus(data)}
    for d, shape in data["shapes"].items():
        out[f"flutter_{d}"] = _mode(data, d, shape)
    return out


def _title(a: dict) -> str:
    return (f"{a['case_name']}, {a['element']}, ν = {float(a['nu']):g}, "
            f"{int(a['n_dofs'])} DOFs")


def _locus(data: dict) -> Figure:
    a, fr = data["attrs"], data["friction"]
    fig = Figure(figsize=(7.2, 7.2), layout="constrained")
    top, bottom = fig.subplots(2, 1, sharex=True)
    for k in range(data["frequency"].shape[1]):
        color = f"C{k % 10}"
        top.plot(fr, data["frequency"][:, k], "-", color=color, lw=1.2)
        bottom.plot(fr, data["growth"][:, k], "-", color=color, lw=1.2)
    for d in DIRECTIONS:
        f = float(a[f"flutter_{d}"])
        if np.isfinite(f):
            w = np.sqrt(max(float(a[f"flutter_kappa_{d}"]), 0.0))
            top.plot([f], [w], "o", mfc="none", mec="k", ms=10, mew=1.5,
                     label="flutter onset (coalescence)" if d == "positive" else None)
            for ax in (top, bottom):
                ax.axvline(f, color="k", lw=0.8, ls=":")
            top.annotate(f"{f:.6g}", (f, w), textcoords="offset points", fontsize=8,
                         xytext=(8, 10) if f > 0 else (-8, 10),
                         ha="left" if f > 0 else "right")
        g = float(a[f"divergence_{d}"])
        if np.isfinite(g) and fr[0] <= g <= fr[-1]:
            for ax in (top, bottom):
                ax.axvline(g, color="tab:red", lw=0.8, ls="--",
                           label=("divergence (static coefficient)"
                                  if d == "positive" and ax is top else None))
    top.set_ylabel(r"frequency $|{\rm Im}\, s|$")
    bottom.set_ylabel(r"growth rate ${\rm Re}\, s$")
    bottom.set_xlabel(r"signed friction coefficient $f$ (< 0: sliding the other way)")
    top.set_title(f"Root locus of the sliding state ({_title(a)})", fontsize=9)
    handles = top.get_legend_handles_labels()
    bottom.legend(*handles, fontsize=8, loc="upper center", ncol=2, framealpha=0.9)
    for ax in (top, bottom):
        ax.grid(alpha=0.3)
    return fig


def _mode(data: dict, direction: str, shape: np.ndarray) -> Figure:
    a, mesh = data["attrs"], data["mesh"]
    extent = float(np.ptp(mesh.points, axis=0).max())
    moved = mesh.points + 0.1 * extent * shape
    fig = Figure(figsize=(6.4, 6.4), layout="constrained")
    ax = fig.subplots()
    ax.add_collection(LineCollection(_segments(mesh, mesh.points), colors="0.85", lw=0.3))
    ax.add_collection(LineCollection(_segments(mesh, moved), colors="tab:blue", lw=0.4))
    ax.autoscale_view()
    ax.set_aspect("equal")
    ax.set_xlabel("x")
    ax.set_ylabel("y")
    f = float(a[f"flutter_{direction}"])
    w = np.sqrt(max(float(a[f"flutter_kappa_{direction}"]), 0.0))
    ax.set_title(f"Flutter mode at onset, {direction} sliding, f = {f:.8g}, "
                 f"ω = {w:.6g}\n({_title(a)}; grey: undeformed, blue: x + 0.1 L φ)",
                 fontsize=9)
    return fig
