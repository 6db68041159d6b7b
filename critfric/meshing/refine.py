"""Uniform refinement and second-order nodes of a mesh, by index arithmetic.

gmsh meshes a coarse body; the splitting into 4 similar cells per level and the P2/Q2 edge
(and Q2 centre) nodes are done here in numpy: the same cells and node positions as gmsh's
``refine()`` and ``setOrder(2)`` with straight edges, in another node numbering (vertices,
then each level's edge midpoints by edge, then its cell centres), about 10x faster.
:func:`renumber` then puts the nodes of a refined mesh in Z-curve order of their position
(neighbours get near numbers: the sparse matrices and their factorizations touch memory
in order) and the cells by their lowest node.
"""

from __future__ import annotations

import numpy as np

from ..fem.arrays import distinct
from ..fem.elements import get_element
from ..fem.mesh import Mesh


def edge_table(cells: np.ndarray, n_nodes: int, local_edges: np.ndarray):
    """The distinct edges of order-1 ``cells``: (ends, inverse), where ``ends`` (n_edges, 2)
    holds each edge's end nodes, lower first, in increasing (lower, upper) order, and
    ``inverse`` (n_cells, len(local_edges)) the edge of each local edge of each cell."""
    directed = cells[:, local_edges]  # (n_cells, n_edges, 2)
    key = (np.minimum(directed[..., 0], directed[..., 1]) * np.int64(n_nodes)
           + np.maximum(directed[..., 0], directed[..., 1]))
    keys = distinct(key)
    return np.column_stack([keys // n_nodes, keys % n_nodes]), np.searchsorted(keys, key)


def _edge_lookup(ends, n_nodes: int):
    """A function (k, 2) node pairs -> their edge numbers (pairs must be edges)."""
    keys = ends[:, 0] * np.int64(n_nodes) + ends[:, 1]

    def lookup(pairs):
        pairs = np.asarray(pairs, dtype=np.int64)
        return np.searchsorted(keys, np.minimum(pairs[:, 0], pairs[:, 1]) * np.int64(n_nodes)
                               + np.maximum(pairs[:, 0], pairs[:, 1]))
    return lookup


def split(mesh: Mesh) -> Mesh:
    """One uniform refinement of an order-1 mesh (P1 or Q1): every edge halved, every
    triangle into 4, every quad into 4 around its centre (the mean of its corners); boundary
    facets (a, b) become (a, m), (m, b)."""
    spec = mesh.fe
    points, cells = mesh.points, np.asarray(mesh.cells, dtype=np.int64)
    n, nc = len(points), len(cells)
    ends, inverse = edge_table(cells, n, spec.edges)
    mid = n + inverse  # (nc, n_vertices): node of the midpoint of local edge i (i -> i+1)
    new = [points, 0.5 * (points[ends[:, 0]] + points[ends[:, 1]])]
    v = cells
    if spec.n_vertices == 3:
        children = [(v[:, 0], mid[:, 0], mid[:, 2]), (mid[:, 0], v[:, 1], mid[:, 1]),
                    (mid[:, 2], mid[:, 1], v[:, 2]), (mid[:, 0], mid[:, 1], mid[:, 2])]
    else:
        c = n + len(ends) + np.arange(nc)
        new.append(0.25 * (points[v[:, 0]] + points[v[:, 1]] + points[v[:, 2]]
                           + points[v[:, 3]]))
        children = [(v[:, 0], mid[:, 0], c, mid[:, 3]), (mid[:, 0], v[:, 1], mid[:, 1], c),
                    (c, mid[:, 1], v[:, 2], mid[:, 2]), (mid[:, 3], c, mid[:, 2], v[:, 3])]
    fine = np.empty((nc, 4, spec.n_vertices), dtype=np.int64)  # cell k -> cells 4k .. 4k+3
    for k, child in enumerate(children):
        for j, node in enumerate(child):
            fine[:, k, j] = node
    lookup = _edge_lookup(ends, n)
    edges = {}
    for name, facets in mesh.edges.items():
        m = n + lookup(facets[:, :2])
        edges[name] = np.stack([np.column_stack([facets[:, 0], m]),
                                np.column_stack([m, facets[:, 1]])], axis=1).reshape(-1, 2)
    return Mesh(np.concatenate(new), fine.reshape(-1, spec.n_vertices), mesh.element, edges)


def second_order(mesh: Mesh, element: str) -> Mesh:
    """An order-1 mesh (P1 or Q1) with the nodes of ``element`` (P2 or Q2) added: a node at
    the middle of every edge (numbered by edge, after the vertices) and, for Q2, one at
    every cell's centre (the mean of its corners, numbered last)."""
    spec = get_element(element)
    points, cells = mesh.points, np.asarray(mesh.cells, dtype=np.int64)
    n, nv = len(points), spec.n_vertices
    ends, inverse = edge_table(cells, n, spec.edges[:, :2])
    new_points = [points, 0.5 * (points[ends[:, 0]] + points[ends[:, 1]])]
    new_cells = [cells, n + inverse]
    if nv == 4:
        new_points.append(points[cells].mean(axis=1))
        new_cells.append(n + len(ends) + np.arange(len(cells))[:, None])
    lookup = _edge_lookup(ends, n)
    edges = {name: np.column_stack([f[:, :2], n + lookup(f[:, :2])])
             for name, f in mesh.edges.items()}
    return Mesh(np.concatenate(new_points), np.concatenate(new_cells, axis=1), element, edges)


def _spread(x: np.ndarray) -> np.ndarray:
    """The bits of 32-bit ``x`` (uint64) moved to the even bit positions."""
    for shift, mask in ((16, 0x0000FFFF0000FFFF), (8, 0x00FF00FF00FF00FF),
                        (4, 0x0F0F0F0F0F0F0F0F), (2, 0x3333333333333333),
                        (1, 0x5555555555555555)):
        x = (x | (x << np.uint64(shift))) & np.uint64(mask)
    return x


def renumber(mesh: Mesh) -> Mesh:
    """The same mesh with its nodes in Z-curve (Morton) order of their coordinates and its
    cells sorted by their lowest new node number (ties kept in order)."""
    p = mesh.points
    low, extent = p.min(axis=0), float(np.ptp(p, axis=0).max()) or 1.0
    q = np.minimum((p - low) / extent * 2.0**31, 2.0**31 - 1).astype(np.uint64)
    order = np.argsort(_spread(q[:, 0]) | (_spread(q[:, 1]) << np.uint64(1)), kind="stable")
    rank = np.empty(len(order), dtype=np.int64)
    rank[order] = np.arange(len(order))
    cells = rank[mesh.cells]
    cells = cells[np.argsort(cells.min(axis=1), kind="stable")]
    return Mesh(p[order], cells, mesh.element,
                {name: rank[f] for name, f in mesh.edges.items()})
