"""The 3D contact plane: contact nodes, the outward normal, slip directions, the n/s/e basis.

Gamma_C is one planar set of boundary faces with outward unit normal n. Its in-plane axes:
t1 = the unit projection of e_x on the plane (of e_y where e_x is normal to it:
|n x e_x| < AXIS_TOL) and t2 = n x t1. A slip angle theta (degrees) gives the slip direction
s = cos(theta) t1 + sin(theta) t2, and e = n x s; (n, s, e) is a right-handed orthonormal basis.

Agreement with 2D: for a body extruded along z, n = (n1, n2, 0) and 2D's tangent is
t = (-n2, n1) = e_z x n, while t1 = -sign(n2) t (t1 = e_y when n = +-e_x, then t1 = +-t).
So for a contact face below the body (n2 < 0, e.g. n = -e_y) or n = +e_x, slip angle 0 is
2D's gamma = +1 and 180 is gamma = -1; for n2 > 0 or n = -e_x it is the other way round.

:func:`contact_system3d` rotates each contact node's three DOFs into its own (n, s_i, e_i)
basis and restricts the stiffness parts to the free DOFs (every DOF of a node on a Dirichlet
face is fixed): a :class:`.contact.ContactSystem` with ``cn``, ``ct`` (the s DOFs), ``ce`` and
``slip``. The slip law of 2D then holds on the s DOF; the e DOF is clamped or free according
to the contact status and the slip law (:mod:`critfric.solvers.eigenproblem`).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from ..errors import CaseError
from .arrays import ranges
from .contact import (
    STRAIGHT_TOL,
    ContactSystem,
    Layout,
    _split_free,
    contact_frames,
    frame_rotation,
    summed_alike,
)
from .mesh import Mesh

LAWS = ("rate", "frozen")  # 3D slip laws of the e DOF at slipping nodes (the first: default)
AXIS_TOL = 1e-6  # e_x counts as normal to Gamma_C when |n x e_x| < AXIS_TOL (t1 from e_y)
SORT_DIGITS = 9  # contact nodes are sorted along t1, then t2, rounded to this relative digit


def plane_axes(normal: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(t1, t2) of a unit normal: the unit projection of e_x on the plane (of e_y when
    |n x e_x| < AXIS_TOL) and n x t1."""
    normal = np.asarray(normal, dtype=float)
    axis = np.eye(3)[1 if np.linalg.norm(np.cross(normal, np.eye(3)[0])) < AXIS_TOL else 0]
    t1 = axis - (axis @ normal) * normal
    t1 /= np.linalg.norm(t1)
    return t1, np.cross(normal, t1)


def contact_plane(mesh: Mesh, contact: list[str], dirichlet_nodes: np.ndarray,
                  *, source: str = "") -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Contact nodes (sorted along t1, then t2), the outward normal n and t1 of Gamma_C:
    :class:`CaseError` (key ``boundary.contact``) unless the faces ``contact`` are one plane
    with the body on one side."""
    faces = np.concatenate([mesh.faces[name] for name in contact])
    on_plane = np.unique(faces)
    pts = np.asarray(mesh.points, dtype=float)[on_plane]
    start = pts[np.argmax(np.linalg.norm(pts - pts[0], axis=1))]  # an end of the set
    far = pts[np.argmax(np.linalg.norm(pts - start, axis=1))]  # the farthest from it
    length = np.linalg.norm(far - start)
    line = (far - start) / length if length > 0 else far - start
    across = (pts - start) - np.outer((pts - start) @ line, line)
    width = np.linalg.norm(across, axis=1)
    third = int(np.argmax(width))
    if not width[third] > STRAIGHT_TOL * length:
        raise CaseError(f"the contact faces {contact} have zero area (their nodes are on one "
                        "line or one point)", file=source, key="boundary.contact")
    normal = np.cross(line, across[third])
    normal /= np.linalg.norm(normal)
    offset = (pts - start) @ normal
    if np.max(np.abs(offset)) > STRAIGHT_TOL * length:
        raise CaseError(
            f"faces {contact} are not one plane (a node is {np.max(np.abs(offset)):.3g} off "
            "the plane of the others); allowed: coplanar faces only",
            file=source, key="boundary.contact")
    # Orient n outwards: cells with a face on Gamma_C lie on the inner side.
    on = np.zeros(mesh.n_nodes, dtype=bool)
    on[on_plane] = True
    cells = np.asarray(mesh.cells)
    touching = on[cells].sum(axis=1) >= 3
    side = (np.asarray(mesh.points, dtype=float)[cells[touching]].mean(axis=1) - start) @ normal
    if touching.sum() == 0 or not (np.all(side > 0) or np.all(side < 0)):
        raise CaseError(f"faces {contact} are not on the boundary of the body (cells on both "
                        "sides)", file=source, key="boundary.contact")
    if side[0] > 0:
        normal = -normal
    t1, t2 = plane_axes(normal)
    nodes = np.setdiff1d(on_plane, dirichlet_nodes)
    if len(nodes) == 0:
        raise CaseError("the contact boundary has no node that is not also on a Dirichlet "
                        "face; allowed: a contact face with at least one free node",
                        file=source, key="boundary.contact")
    x = np.asarray(mesh.points, dtype=float)[nodes] - start
    key = np.round(np.column_stack([x @ t1, x @ t2]) / length, SORT_DIGITS)
    return nodes[np.lexsort((key[:, 1], key[:, 0]))], normal, t1


def slip_directions(normal: np.ndarray, t1: np.ndarray, count: int, *, angle=0.0,
                    direction=None, source: str = "") -> np.ndarray:
    """(count, 3) unit slip directions in the plane of ``normal``: from ``angle`` (degrees
    from t1 towards t2 = n x t1; one value or one per contact node) or, if given, from
    ``direction`` ((3,) or (count, 3) vectors, projected on the plane)."""
    normal = np.asarray(normal, dtype=float)
    if direction is not None:
        d = np.broadcast_to(np.asarray(direction, dtype=float), (count, 3)) if np.ndim(
            direction) == 1 else np.asarray(direction, dtype=float)
        if d.shape != (count, 3) or not np.all(np.isfinite(d)):
            raise CaseError(f"got slip directions of shape {np.shape(direction)}; allowed: one "
                            f"finite 3-vector, or one for each of the {count} contact nodes",
                            file=source, key="contact.direction")
        s = d - np.outer(d @ normal, normal)
        size = np.linalg.norm(s, axis=1)
        bad = ~(size > AXIS_TOL * np.linalg.norm(d, axis=1))
        if bad.any():
            raise CaseError(f"the slip direction {d[bad][0].tolist()} is normal to the contact "
                            f"plane (n = {normal.tolist()}); allowed: a direction with a part "
                            "in the plane", file=source, key="contact.direction")
        return s / size[:, None]
    theta = np.asarray(angle, dtype=float)
    if theta.ndim > 1 or theta.size not in (1, count) or not np.all(np.isfinite(theta)):
        raise CaseError(f"got {theta.size} slip angle(s) for {count} contact nodes; allowed: "
                        "one finite angle in degrees, or one per contact node",
                        file=source, key="contact.angle")
    c, s = _cos_sin_degrees(np.broadcast_to(theta.ravel(), (count,)))
    return c[:, None] * t1 + s[:, None] * np.cross(normal, t1)


def _cos_sin_degrees(theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """cos and sin of angles in degrees, exact at the multiples of 90 (so that 0 and 180
    give +-t1 exactly)."""
    quarter = np.round(theta / 90.0)
    exact = quarter * 90.0 == theta
    k = np.mod(quarter, 4).astype(int)
    rad = np.radians(theta)
    c = np.where(exact, np.array([1.0, 0.0, -1.0, 0.0])[k], np.cos(rad))
    s = np.where(exact, np.array([0.0, 1.0, 0.0, -1.0])[k], np.sin(rad))
    return c, s


def contact_layout3d(mesh: Mesh, *, contact: list[str], dirichlet: list[str], angle=0.0,
                     direction=None, source: str = "") -> Layout:
    """The contact nodes, plane and slip directions of a 3D mesh, and its Dirichlet DOFs (all
    three DOFs of every node on the faces ``dirichlet``)."""
    for key, names in (("boundary.contact", contact), ("boundary.dirichlet", dirichlet)):
        missing = [n for n in names if n not in mesh.faces or len(mesh.faces[n]) == 0]
        if missing:
            raise CaseError(f"face {missing[0]!r} has no mesh facet; known faces: "
                            + ", ".join(sorted(mesh.faces)), file=source, key=key)
    parts = [np.asarray(mesh.faces[name]).ravel() for name in dirichlet]
    dirichlet_nodes = np.unique(np.concatenate(parts)) if parts else np.zeros(0, np.int64)
    nodes, normal, t1 = contact_plane(mesh, contact, dirichlet_nodes, source=source)
    slip = slip_directions(normal, t1, len(nodes), angle=angle, direction=direction,
                           source=source)
    fixed = np.zeros(3 * mesh.n_nodes, dtype=bool)
    fixed[(3 * dirichlet_nodes[:, None] + np.arange(3)).ravel()] = True
    return Layout(nodes, normal, t1, fixed, dim=3, slip=slip)


def contact_system3d(mesh: Mesh, K_lam: sp.spmatrix, K_G: sp.spmatrix, *,
                     contact: list[str], dirichlet: list[str], angle=0.0, direction=None,
                     source: str = "", layout: Layout | None = None) -> ContactSystem:
    """:func:`contact_layout3d` (or ``layout``, made by it) and the stiffness parts (over
    3 * n_nodes interleaved DOFs) in the n/s/e basis, restricted to the free DOFs."""
    if mesh.dim != 3:
        raise CaseError(f"contact_system3d needs a 3D mesh, got points of dimension {mesh.dim}",
                        file=source, key="mesh")
    if layout is None:
        layout = contact_layout3d(mesh, contact=contact, dirichlet=dirichlet, angle=angle,
                                  direction=direction, source=source)
    nodes, fixed, position = layout.nodes, layout.fixed, layout.position
    frames = contact_frames(layout.normal, layout.slip)
    try:  # parts of one sparsity made of full 3 x 3 node blocks: one pass for both
        groups = [rotated_frames(K_lam, nodes, frames, K_G)]
    except ValueError:
        groups = [rotated_frames(K, nodes, frames) for K in (K_lam, K_G)]
    parts, coupling = zip(*(ff_fd for mats in groups for ff_fd in _split_free(mats, fixed)))
    return ContactSystem(mesh=mesh, free=layout.free, nodes=nodes, normal=layout.normal,
                         tangent=layout.tangent, cn=position[3 * nodes],
                         ct=position[3 * nodes + 1], K_lam=parts[0], K_G=parts[1],
                         fixed=np.flatnonzero(fixed), D_lam=coupling[0], D_G=coupling[1],
                         ce=position[3 * nodes + 2], slip=layout.slip)


def rotated_frames(K: sp.spmatrix, nodes: np.ndarray, frames: np.ndarray, *others) -> list:
    """Q^T A Q (Q: :func:`.contact.frame_rotation`) for K and every matrix of ``others``, as
    sorted CSR. Where K is made of full d x d node blocks at the contact nodes (an assembled
    stiffness) the rows, then the columns, of each contact node are combined in place, and
    the matrices keep K's sparsity (ValueError if ``others`` have another); otherwise K alone
    is rotated by sparse products (``others`` must be empty)."""
    d = frames.shape[1]
    mats = summed_alike([K, *others], "rotated_frames", copy=True)  # combined in place below
    ip, col = mats[0].indptr, mats[0].indices
    entries = _block_entries(ip, col, np.asarray(nodes), d, K.shape[1])
    if entries is None:
        if others:
            raise ValueError("rotated_frames: not full node blocks; rotate one matrix at a time")
        Q = frame_rotation(K.shape[0] // d, nodes, frames)
        A = (Q.T @ mats[0] @ Q).tocsr()
        A.sort_indices()
        return [A]
    rows, row_node, cols, col_node = entries
    for A in mats:
        for e, which in ((rows, row_node), (cols, col_node)):
            x = A.data[e]  # (d, k): the d components of k entry groups
            R = frames[which]  # (k, d, d): rows b, xyz components a
            A.data[e] = np.einsum("kba,ak->bk", R, x)
    return mats


def _block_entries(ip: np.ndarray, col: np.ndarray, nodes: np.ndarray, d: int, n_cols: int):
    """Where a sorted CSR pattern holds full d x d blocks at the contact nodes: the entries
    (d, k) of the rows d i + a (a = 0 .. d-1) with their node's index in ``nodes``, and the
    same for the columns; None otherwise."""
    length = ip[d * nodes + 1] - ip[d * nodes]
    first = ranges(ip[d * nodes], length)  # entries of the rows d i
    offsets = np.concatenate([[0], np.cumsum(length)])[:-1]
    within = np.arange(len(first)) - np.repeat(offsets, length)
    rows = np.empty((d, len(first)), dtype=np.int64)
    for a in range(d):
        if np.any(ip[d * nodes + a + 1] - ip[d * nodes + a] != length):
            return None
        rows[a] = np.repeat(ip[d * nodes + a], length) + within
        if not np.array_equal(col[rows[a]], col[first]):
            return None
    which = np.full(n_cols // d + 1, -1)
    which[nodes] = np.arange(len(nodes))
    in_contact = which[col // d] >= 0
    starts = np.flatnonzero(in_contact & (col % d == 0))
    if np.count_nonzero(in_contact) != d * len(starts) or np.any(starts + d - 1 >= len(col)):
        return None
    cols = starts + np.arange(d)[:, None]
    row_of = np.searchsorted(ip, cols, side="right") - 1
    if np.any(col[cols] != col[starts] + np.arange(d)[:, None]) or np.any(row_of != row_of[0]):
        return None
    return (rows, np.repeat(np.arange(len(nodes)), length), cols, which[col[starts] // d])
