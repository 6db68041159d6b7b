"""Figures of a 3D solve file without 3D rendering: each plotted mode on the contact face
Gamma_C, drawn in its plane coordinates s1 (along t1) and s2 (along t2 = n x t1), as in
:mod:`critfric.fem.contact3d`.

``contact_<mode>`` (for ``positive_0`` and ``negative_0``): on the left the tangential part
Phi_t = Phi_s s + Phi_e e of the eigenfunction (colour |Phi_t|, arrows its components along
t1 and t2, max |Phi| = 1), on the right the nodal normal contact force X (colour, max |X| = 1)
with the slip direction s of each contact node.
"""

from __future__ import annotations

import numpy as np
from matplotlib.collections import LineCollection
from matplotlib.figure import Figure
from matplotlib.tri import Triangulation

from ..files.export import SolveData
from .meshdraw import face_segments, split_triangles

ARROW_LENGTH = 0.1  # the longest arrow, as a fraction of the drawn face's extent
MAX_ARROWS = 600  # arrows drawn at most (every k-th contact node beyond), per panel
WIREFRAME_FACES = 1500  # above this many contact faces, their edges are not drawn
SHOWN = ("positive_0", "negative_0")  # the modes drawn, if stored


def contact_figures(data: SolveData) -> dict[str, Figure]:
    """``contact_<mode>`` of the lowest positive and negative modes stored in ``data``."""
    plane = _plane(data)
    return {f"contact_{name}": _contact_mode(data, name, plane) for name in SHOWN
            if name in data.modes}


def _plane(data: SolveData) -> dict:
    """The contact face in plane coordinates: the nodes drawn, their (s1, s2), the
    triangles and segments through them (local indices), and where the contact nodes are."""
    mesh = data.mesh
    faces = [np.asarray(mesh.faces[n]) for n in data.contact_edges if n in mesh.faces]
    faces = np.concatenate(faces) if faces else np.zeros((0, mesh.fe.facet_nodes), np.int64)
    nodes, local = np.unique(np.concatenate([faces.ravel(), data.contact_nodes]),
                             return_inverse=True)
    local = local.ravel()
    faces = local[:faces.size].reshape(faces.shape)
    t1 = data.tangent
    axes = np.column_stack([t1, np.cross(data.normal, t1)])
    uv = np.asarray(mesh.points, dtype=float)[nodes] @ axes
    uv -= uv.min(axis=0)
    if len(faces):
        tri = Triangulation(uv[:, 0], uv[:, 1], split_triangles(faces, mesh.element))
        wires = face_segments(faces, mesh.element, uv) if len(faces) <= WIREFRAME_FACES \
            else np.zeros((0, 2, 2))
    else:  # contact groups not named in the file: the nodes' Delaunay triangulation
        wires = np.zeros((0, 2, 2))
        try:
            tri = Triangulation(uv[:, 0], uv[:, 1])
        except (ValueError, RuntimeError):  # fewer than 3 nodes, or all on one line
            tri = None
    return {"nodes": nodes, "uv": uv, "axes": axes, "tri": tri, "wires": wires,
            "contact": local[faces.size:], "extent": float(np.ptp(uv, axis=0).max()) or 1.0}


def _contact_mode(data: SolveData, name: str, plane: dict) -> Figure:
    mode = data.modes[name]
    phi = np.asarray(mode["phi"], dtype=float)
    peak = np.max(np.linalg.norm(phi, axis=1))
    phi = phi / peak if peak > 0 else phi
    tangential = phi[plane["nodes"]] @ plane["axes"]  # (Phi . t1, Phi . t2) = Phi_t in-plane
    size = np.linalg.norm(tangential, axis=1)
    uv, at = plane["uv"], plane["contact"]
    fig = Figure(figsize=(13.6, 5.6))
    left, right = fig.subplots(1, 2)
    for ax in (left, right):
        ax.add_collection(LineCollection(plane["wires"], colors="0.75", lw=0.4))
        if not len(plane["wires"]):  # (what autoscale needs when no wire is drawn)
            ax.update_datalim(uv)
    if plane["tri"] is not None:
        shade = left.tripcolor(plane["tri"], size, shading="gouraud", cmap="viridis",
                               vmin=0.0)
    else:
        shade = left.scatter(uv[:, 0], uv[:, 1], c=size, cmap="viridis", vmin=0.0)
    fig.colorbar(shade, ax=left, shrink=0.85, label=r"$|\Phi_t|$ (max $|\Phi|$ = 1)")
    top = float(size[at].max()) if len(at) else 0.0
    _arrows(left, uv[at], tangential[at], top, ARROW_LENGTH * plane["extent"], color="white",
            edge="black",
            label=r"$\Phi_s\,s + \Phi_e\,e$ on $(t_1, t_2)$")
    force = np.asarray(mode["theta_n"], dtype=float)
    scale = np.max(np.abs(force)) or 1.0
    dots = right.scatter(uv[at, 0], uv[at, 1], c=force / scale, cmap="coolwarm", vmin=-1.0,
                         vmax=1.0, s=min(28.0, 2e4 / max(len(at), 1)), edgecolors="0.3",
                         linewidths=0.4, zorder=3)
    fig.colorbar(dots, ax=right, shrink=0.85, label="normal contact force X (max |X| = 1)")
    slip = np.asarray(data.slip, dtype=float) @ plane["axes"]
    spacing = plane["extent"] / np.sqrt(min(max(len(at), 1), MAX_ARROWS))  # of the arrows
    _arrows(right, uv[at], slip, 1.0, min(0.6 * ARROW_LENGTH * plane["extent"], 0.7 * spacing),
            color="0.35", edge=None,
            label="slip direction s (Y = α γ X along s)")
    t1, t2 = plane["axes"].T
    r, law = mode.get("r", 0.0), data.attrs.get("law", "rate")
    for ax, what in ((left, "tangential eigenfunction"), (right, "normal contact force")):
        ax.set_aspect("equal")
        ax.margins(ARROW_LENGTH + 0.02)  # room for the arrows at the edges
        ax.autoscale_view()
        ax.set_xlabel(f"$s_1$ along $t_1$ = {_vector(t1)}")
        ax.set_ylabel(f"$s_2$ along $t_2 = n \\times t_1$ = {_vector(t2)}")
        ax.set_title(f"{what} on Γ_C", fontsize=9)
        ax.legend(fontsize=8, loc="upper center", bbox_to_anchor=(0.5, -0.12))
    a = data.attrs
    fig.suptitle(f"{a.get('case_name', '')}, {a['element']}, ν = {float(a['nu']):g}: "
                 f"{name.replace('_', ' ')}, α = {mode['alpha']:.6g}, r = {r:.3g} "
                 f"({law} law, slip angle {float(a.get('slip_angle', 0.0)):g}°); "
                 f"n = {_vector(data.normal)}", fontsize=10)
    return fig


def _arrows(ax, at: np.ndarray, vectors: np.ndarray, top: float, length: float, *, color,
            edge, label: str) -> None:
    """``vectors`` (k, 2) drawn from ``at`` (at most MAX_ARROWS of them), one of length
    ``top`` as ``length`` in the axes' units."""
    if not len(at):
        return
    step = -(-len(at) // MAX_ARROWS)
    at, vectors = at[::step], vectors[::step]
    scale = top / length if top > 0 else 1.0
    ax.quiver(at[:, 0], at[:, 1], vectors[:, 0], vectors[:, 1], angles="xy",
              scale_units="xy", scale=scale, color=color, edgecolor=edge,
              linewidth=0.5 if edge else 0.0, width=0.004, zorder=4, label=label)


def _vector(v: np.ndarray) -> str:
    """A unit vector as short text, its round-off zeros (and -0) shown as 0."""
    return "(" + ", ".join(f"{x:.3g}" for x in np.where(np.abs(v) < 1e-12, 0.0, v)) + ")"
