"""Consistent nodal loads: tractions on boundary facets and body forces."""

from __future__ import annotations

import numpy as np

from ..errors import CaseError
from .assembly import cell_geometry
from .elements import facet_quadrature, facet_shape
from .mesh import Mesh


def traction_load(mesh: Mesh, edge_name: str, traction) -> np.ndarray:
    """Consistent nodal load (2 * n_nodes,) of a constant traction vector on edge group
    ``edge_name`` (facets (n, 2): end, end or (n, 3): end, end, midpoint)."""
    if edge_name not in mesh.edges:
        raise CaseError(
            f"unknown edge group {edge_name!r}; mesh has: {', '.join(sorted(mesh.edges)) or 'none'}"
        )
    facets = np.asarray(mesh.edges[edge_name], dtype=np.int64)
    if facets.ndim != 2 or facets.shape[1] not in (2, 3):
        raise CaseError(f"edge group {edge_name!r} has shape {facets.shape}; need (n, 2) or (n, 3)")
    return facet_load(mesh, facets, np.asarray(traction, dtype=float).reshape(2))


def body_force_load(mesh: Mesh, f) -> np.ndarray:
    """Consistent nodal load (2 * n_nodes,) of a constant body force ``f`` (force / area)."""
    element = mesh.fe
    xi, w = element.quadrature()
    values, det, _ = cell_geometry(mesh, xi)
    weights = np.einsum("cq,q,aq->ca", det, w, values)  # int N_a dx per cell node
    return _scatter(mesh.n_nodes, np.asarray(mesh.cells), weights, f)


def _scatter(n_nodes: int, nodes: np.ndarray, weights: np.ndarray, vector) -> np.ndarray:
    """Sum ``weights[e, a] * vector`` into the interleaved load at node ``nodes[e, a]``."""
    vector = np.asarray(vector, dtype=float).reshape(2)
    nodal = np.bincount(nodes.ravel(), weights=weights.ravel(), minlength=n_nodes)
    return (nodal[:, None] * vector).ravel()



def boundary_facets(mesh: Mesh) -> tuple[np.ndarray, np.ndarray]:
    """Every boundary facet (k, 2) or (k, 3) (end, end[, mid]) and its outward unit normal."""
    local = mesh.fe.edges  # (n_vertices, end end[ mid])
    facets = np.asarray(mesh.cells)[:, local].reshape(-1, local.shape[1])
    keys = np.sort(facets[:, :2], axis=1)
    _, inverse, count = np.unique(keys, axis=0, return_inverse=True, return_counts=True)
    facets = facets[count[inverse.ravel()] == 1]
    d = mesh.points[facets[:, 1]] - mesh.points[facets[:, 0]]  # cells are counterclockwise
    normal = np.column_stack([d[:, 1], -d[:, 0]]) / np.linalg.norm(d, axis=1)[:, None]
    return facets, normal


def facets_in(facets: np.ndarray, mesh: Mesh, names) -> np.ndarray:
    """Mask of the facets that belong to the edge groups ``names``."""
    groups = np.concatenate([np.sort(mesh.edges[n][:, :2], axis=1) for n in names])
    keys = np.sort(facets[:, :2], axis=1) @ np.array([mesh.n_nodes, 1])
    return np.isin(keys, groups @ np.array([mesh.n_nodes, 1]))


def facet_load(mesh: Mesh, facets: np.ndarray, traction) -> np.ndarray:
    """Consistent nodal load (2 n_nodes,) of a traction (2,) or (k, 2) constant on each of
    the ``facets`` (k, 2 or 3: end, end[, mid])."""
    order = facets.shape[1] - 1
    s, w = facet_quadrature(order)
    values, derivs = facet_shape(s, order)  # (n_fnodes, n_qp)
    X = np.asarray(mesh.points, dtype=float)[facets]  # (k, n_fnodes, 2)
    jac = np.linalg.norm(np.einsum("fai,aq->fqi", X, derivs), axis=-1)  # |dx/ds|
    weights = np.einsum("fq,q,aq->fa", jac, w, values)  # int N_a ds on each facet
    traction = np.broadcast_to(np.asarray(traction, dtype=float), (len(facets), 2))
    out = np.zeros((mesh.n_nodes, 2))
    for k in range(2):  # x and y components
        out[:, k] = np.bincount(facets.ravel(), (weights * traction[:, k:k + 1]).ravel(),
                                minlength=mesh.n_nodes)
    return out.ravel()
