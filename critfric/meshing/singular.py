"""The singular points of the eigenproblem (3.2) on a polygon: where graded meshes refine.

The eigenfunctions of (3.2) are singular (r^lambda with lambda < 1, r the distance) at

- the two ends of the contact run Gamma_C (contact meets another condition);
- the junctions between contact states along Gamma_C given by ``[contact] rules`` (a slipping
  node next to a stuck or free one, or slip + next to slip -): they lie inside an edge, so the
  mesh gets a point there (a node exactly at the junction);
- corners where the boundary condition changes (Dirichlet meets traction-free or contact);
- re-entrant corners (interior angle above 180 degrees), whatever their conditions.

Convex corners between two edges of the same condition are regular and are not listed.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import CaseError
from .geometry import REL_TOL, Polygon, collinear_run

#: kinds of singular point, in the order they are looked for
KINDS = ("contact end", "state junction", "condition change", "re-entrant corner")


@dataclass(frozen=True)
class SingularPoints:
    """Singular points of one polygon and boundary; arrays have one row a point.

    points : (k, 2) coordinates.
    kind   : what each point is (one of ``KINDS``; a contact end is also a condition change).
    angle  : interior angle of the body there (pi for a junction inside an edge).
    vertex : polygon vertex index, or -1 for a junction inside edge ``edge``.
    edge   : polygon edge holding a junction (-1 for a vertex).
    run_length : length of the contact run Gamma_C.
    """

    points: np.ndarray
    kind: tuple[str, ...]
    angle: np.ndarray
    vertex: np.ndarray
    edge: np.ndarray
    run_length: float

    def __len__(self) -> int:
        return len(self.points)

    @property
    def junctions(self) -> np.ndarray:
        """Indices of the points inside an edge (embedded in the mesh)."""
        return np.flatnonzero(self.vertex < 0)


def interior_angles(vertices: np.ndarray) -> np.ndarray:
    """(nv,) interior angle at each vertex of a counterclockwise polygon, in (0, 2 pi)."""
    v = np.asarray(vertices, dtype=float)
    d_in = v - np.roll(v, 1, axis=0)
    d_out = np.roll(v, -1, axis=0) - v
    cross = d_in[:, 0] * d_out[:, 1] - d_in[:, 1] * d_out[:, 0]
    turn = np.arctan2(cross, np.einsum("ij,ij->i", d_in, d_out))  # left turn > 0
    return math.pi - turn


def contact_run(poly: Polygon, contact) -> tuple[np.ndarray, np.ndarray, float]:
    """(start, unit tangent t, length) of Gamma_C, ``start`` being its end where the arc
    length s along t (the counterclockwise direction, as in ``[contact] rules``) is 0."""
    names = [contact] if isinstance(contact, str) else list(contact)
    unknown = sorted(set(names) - set(poly.edge_names))
    if unknown:
        raise CaseError(f"unknown edge name(s) {unknown}; edges are {list(poly.group_names)}",
                        key="boundary.contact")
    seg = poly.segments[poly.edge_indices(names)]
    start, end, _ = collinear_run(seg, key="boundary.contact")
    first = seg[0, 1] - seg[0, 0]
    t = first / np.linalg.norm(first)  # counterclockwise: the body on the left, n = -t^perp
    if (end - start) @ t < 0:
        start, end = end, start
    return start, t, float(np.linalg.norm(end - start))


def state_junctions(rules, default: str, gamma: float, length: float) -> np.ndarray:
    """Arc lengths s in (0, length) where the contact state of ``[contact] rules`` changes
    (status, or slip sign), as ``critfric.solvers.from_case.contact_state`` assigns it."""
    rules = list(rules or [])
    if not rules:
        return np.zeros(0)
    cut = np.unique([float(r[k]) for r in rules for k in ("from", "to")])
    cut = cut[(cut > REL_TOL * length) & (cut < (1 - REL_TOL) * length)]
    if len(cut) == 0:
        return cut
    eps = 1e-7 * length
    s = np.concatenate([cut - eps, cut + eps])  # just before and just after each cut
    status = np.full(len(s), default, dtype=object)
    sign = np.full(len(s), float(gamma))
    for rule in rules:  # a handful of rules, vectorized over the points
        inside = (s >= rule["from"]) & (s <= rule["to"])
        status[inside] = rule["status"]
        if rule["status"] == "slip":
            sign[inside] = rule["gamma"]
    sign = np.where(status == "slip", sign, 0.0)
    k = len(cut)
    changed = (status[:k] != status[k:]) | (sign[:k] != sign[k:])
    return cut[changed]


def singular_points(poly: Polygon, contact, dirichlet=(), junctions=()) -> SingularPoints:
    """The singular points of ``poly`` with contact edges ``contact``, Dirichlet edges
    ``dirichlet`` (the others traction-free) and state junctions at arc lengths ``junctions``
    along Gamma_C (see :func:`state_junctions`)."""
    contact = [contact] if isinstance(contact, str) else list(contact)
    start, t, length = contact_run(poly, contact)
    v = poly.vertices
    nv = poly.n_vertices
    scale = float(np.ptp(v, axis=0).max())
    cond = np.array(["C" if n in contact else "D" if n in set(dirichlet) else "N"
                     for n in poly.edge_names])
    angle = interior_angles(v)
    change = cond != np.roll(cond, 1)  # vertex i joins edge i-1 and edge i
    reentrant = angle > math.pi * (1 + 1e-9)
    ends = np.zeros(nv, dtype=bool)
    for p in (start, start + length * t):
        ends[np.argmin(np.linalg.norm(v - p, axis=1))] = True
    at = np.flatnonzero(change | reentrant | ends)
    kinds = ["contact end" if ends[i] else "condition change" if change[i]
             else "re-entrant corner" for i in at]
    points, angles = [v[at]], [angle[at]]
    vertex, edge = [at], [np.full(len(at), -1)]

    s = np.unique(np.asarray(junctions, dtype=float))
    if len(s):
        if np.any((s <= 0) | (s >= length)):
            raise CaseError(f"state junctions must lie inside Gamma_C (0, {length:g}), got "
                            f"{s.tolist()}", key="contact.rules")
        xy = start + s[:, None] * t
        dist = np.linalg.norm(xy[:, None, :] - v[None], axis=-1)  # (j, nv)
        near = dist.min(axis=1) <= 1e-9 * scale
        on_vertex = np.argmin(dist, axis=1)
        new = np.setdiff1d(on_vertex[near], at)  # a junction at a vertex: that vertex
        points.append(v[new])
        angles.append(angle[new])
        vertex.append(new)
        edge.append(np.full(len(new), -1))
        kinds += ["state junction"] * len(new)
        xy = xy[~near]
        seg = poly.segments[poly.edge_indices(contact)]
        idx = poly.edge_indices(contact)
        a, b = seg[:, 0], seg[:, 1]
        along = np.einsum("jk,mk->jm", xy, b - a) - np.einsum("mk,mk->m", a, b - a)
        frac = along / np.einsum("mk,mk->m", b - a, b - a)
        holder = np.argmax((frac > 0) & (frac < 1), axis=1)
        points.append(xy)
        angles.append(np.full(len(xy), math.pi))
        vertex.append(np.full(len(xy), -1))
        edge.append(idx[holder])
        kinds += ["state junction"] * len(xy)
    return SingularPoints(np.concatenate(points), tuple(kinds), np.concatenate(angles),
                          np.concatenate(vertex).astype(np.int64),
                          np.concatenate(edge).astype(np.int64), length)


def split_at_junctions(poly: Polygon, sing: SingularPoints) -> tuple[Polygon, np.ndarray]:
    """``poly`` with a vertex at every junction inside an edge (the edge's two parts keep its
    name), and the vertex index of every singular point in it."""
    inside = sing.junctions
    v, names = poly.vertices, list(poly.edge_names)
    # a junction's position along its edge orders it among the vertices
    a = v[sing.edge[inside]]
    key = np.concatenate([np.arange(poly.n_vertices, dtype=float),
                          sing.edge[inside] + np.linalg.norm(sing.points[inside] - a, axis=1)
                          / np.linalg.norm(v[(sing.edge[inside] + 1) % poly.n_vertices] - a,
                                           axis=1)])
    order = np.argsort(key, kind="stable")
    owner = np.concatenate([np.arange(poly.n_vertices), sing.edge[inside]])  # edge after it
    vertices = np.concatenate([v, sing.points[inside]])[order]
    where = np.empty(len(order), dtype=np.int64)
    where[order] = np.arange(len(order))
    index = sing.vertex.copy()
    index[sing.vertex >= 0] = where[sing.vertex[sing.vertex >= 0]]
    index[inside] = where[poly.n_vertices + np.arange(len(inside))]
    return Polygon(vertices, tuple(names[i] for i in owner[order])), index
