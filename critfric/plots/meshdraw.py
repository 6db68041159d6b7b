"""A mesh as straight pieces for matplotlib: cell edges as segments, cells as triangles; the
same for the boundary faces of a 3D mesh (triangles or quadrangles: the 2D elements)."""

from __future__ import annotations

import numpy as np

from ..fem.elements import get_element

# linear sub-triangles of each element's cell, through its P2/Q2 nodes
_TRIS = {"P1": [(0, 1, 2)], "P2": [(0, 3, 5), (3, 1, 4), (5, 4, 2), (3, 4, 5)],
         "Q1": [(0, 1, 2), (0, 2, 3)],
         "Q2": [(0, 4, 8), (0, 8, 7), (4, 1, 5), (4, 5, 8), (8, 5, 2), (8, 2, 6), (7, 8, 6),
                (7, 6, 3)]}


def triangles(mesh) -> np.ndarray:
    """The cells split into straight triangles for drawing (P2/Q2 through their nodes)."""
    return split_triangles(mesh.cells, mesh.element)


def split_triangles(cells, element: str) -> np.ndarray:
    """Cells of the 2D ``element`` (or the boundary faces of a 3D mesh of that name, in the
    facet element's node order) split into straight triangles (k * n_sub, 3)."""
    return np.asarray(cells)[:, np.array(_TRIS[element])].reshape(-1, 3)


def segments(mesh, points) -> np.ndarray:
    """Every cell edge as straight segments (a P2/Q2 edge as two, through its midpoint)."""
    return edge_segments(mesh.cells, mesh.fe.edges, points)


def face_segments(faces, element: str, points) -> np.ndarray:
    """Every edge of the boundary ``faces`` of a 3D mesh of ``element`` as straight segments
    (n_segments, 2, points' width)."""
    return edge_segments(faces, get_element(element, 2).edges, points)


def edge_segments(cells, local, points) -> np.ndarray:
    """The edges ``local`` (n_edges, 2 or 3: end, end[, mid]) of each of ``cells``, each
    drawn once, as straight segments (a second-order edge as two, through its midpoint)."""
    if local.shape[1] == 3:
        local = local[:, [0, 2, 2, 1]].reshape(-1, 2)
    pairs = np.asarray(cells)[:, local].reshape(-1, 2)
    pairs = np.unique(np.sort(pairs, axis=1), axis=0)
    return points[pairs]  # (n_segments, 2, dim)
