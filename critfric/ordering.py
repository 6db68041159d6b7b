"""Geometric nested dissection: a fill-reducing ordering of mesh nodes for SciPy's SuperLU.

SuperLU offers only minimum-degree orderings; on 2D meshes nested dissection gives larger
supernodes and a factorization several times faster (measured: 263 k DOFs, 7.2 s with
MMD_AT_PLUS_A, 2.0 s with a METIS ordering). This module computes one from the mesh itself:
every part is split at the median of its longer coordinate extent, the nodes of the lower half
that share a cell with the upper half form the separator, and a separator is ordered after
the two halves it separates (recursively; one vectorized pass per level). Any ordering gives
the same solution; a good one only makes the factorization cheaper.
"""

from __future__ import annotations

import numpy as np

LEAF = 64  # parts of at most this many nodes are not split further
MAX_LEVELS = 50  # keeps the integer keys of the dissection tree exact


def node_edges(cells: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Directed pairs (u, v) of nodes sharing a cell (both directions, duplicates kept)."""
    cells = np.asarray(cells)
    a, b = np.triu_indices(cells.shape[1], k=1)
    u, v = cells[:, a].ravel(), cells[:, b].ravel()
    return np.concatenate([u, v]), np.concatenate([v, u])


def nested_dissection(points: np.ndarray, cells: np.ndarray, *, leaf: int = LEAF) -> np.ndarray:
    """The elimination rank of every node (a permutation of range(n_nodes))."""
    points = np.asarray(points, dtype=float)
    n = len(points)
    u, v = node_edges(cells)
    code = np.zeros(n, dtype=np.int64)  # bits of the dissection path (one per level)
    stop = np.full(n, -1)  # level at which the node left the dissection
    sep = np.zeros(n, dtype=bool)  # left as a separator node (else as a leaf node)
    active = np.arange(n)
    level = 0
    while len(active):
        order = active[np.argsort(code[active], kind="stable")]
        c = code[order]
        starts = np.r_[0, np.flatnonzero(np.diff(c)) + 1]
        size = np.diff(np.r_[starts, len(order)])
        group = np.repeat(np.arange(len(starts)), size)
        ext = (np.maximum.reduceat(points[order], starts, axis=0)
               - np.minimum.reduceat(points[order], starts, axis=0))
        coord = points[order, np.argmax(ext, axis=1)[group]]
        ranked = np.lexsort((coord, group))
        rank = np.empty(len(order), dtype=np.int64)
        rank[ranked] = np.arange(len(order)) - starts[group[ranked]]
        upper = np.zeros(n, dtype=bool)
        upper[order] = rank >= size[group] // 2
        leafy = np.zeros(n, dtype=bool)
        leafy[order] = (size[group] <= leaf) | (level >= MAX_LEVELS)
        live = np.zeros(n, dtype=bool)
        live[order] = True
        # separator: lower-half nodes sharing a cell with the upper half of the same part
        cut = live[u] & live[v] & (code[u] == code[v]) & ~upper[u] & upper[v] & ~leafy[u]
        new_sep = np.zeros(n, dtype=bool)
        new_sep[u[cut]] = True
        leaving = order[leafy[order] | new_sep[order]]
        stop[leaving], sep[leaving] = level, new_sep[leaving]
        active = order[~leafy[order] & ~new_sep[order]]
        code[active] = 2 * code[active] + upper[active]
        still = np.zeros(n, dtype=bool)
        still[active] = True
        keep = still[u] & still[v]
        u, v = u[keep], v[keep]
        keep = code[u] == code[v]
        u, v = u[keep], v[keep]
        level += 1
    depth = level
    span = np.left_shift(np.int64(1), depth - stop)  # width of the node's subtree interval
    key = np.where(sep, (code + 1) * span - 1, code * span)
    return np.argsort(np.lexsort((np.arange(n), -stop, sep, key)))


def dof_order(nodes: np.ndarray, rank: np.ndarray) -> np.ndarray:
    """A permutation of DOFs (``nodes[i]``: the node of DOF i) that follows the node ranks."""
    return np.lexsort((np.arange(len(nodes)), rank[nodes]))
