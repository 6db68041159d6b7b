"""A mesh as straight pieces for matplotlib: cell edges as segments, cells as triangles."""

from __future__ import annotations

import numpy as np

# linear sub-triangles of each element's cell, through its P2/Q2 nodes
_TRIS = {"P1": [(0, 1, 2)], "P2": [(0, 3, 5), (3, 1, 4), (5, 4, 2), (3, 4, 5)],
         "Q1": [(0, 1, 2), (0, 2, 3)],
         "Q2": [(0, 4, 8), (0, 8, 7), (4, 1, 5), (4, 5, 8), (8, 5, 2), (8, 2, 6), (7, 8, 6),
                (7, 6, 3)]}


def triangles(mesh) -> np.ndarray:
    """The cells split into straight triangles for drawing (P2/Q2 through their nodes)."""
    return np.asarray(mesh.cells)[:, np.array(_TRIS[mesh.element])].reshape(-1, 3)


def segments(mesh, points) -> np.ndarray:
    """Every cell edge as straight segments (a P2/Q2 edge as two, through its midpoint)."""
    local = mesh.fe.edges
    if local.shape[1] == 3:
        local = local[:, [0, 2, 2, 1]].reshape(-1, 2)
    pairs = np.asarray(mesh.cells)[:, local].reshape(-1, 2)
    pairs = np.unique(np.sort(pairs, axis=1), axis=0)
    return points[pairs]  # (n_segments, 2, 2)


