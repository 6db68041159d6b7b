"""Fill-reducing orderings for SciPy's SuperLU: geometric nested dissection of the mesh, and
minimum degree on a graph.

SuperLU offers only minimum-degree orderings; nested dissection gives larger supernodes and
a factorization several times faster (measured, 2D: 263 k DOFs, 7.2 s with MMD_AT_PLUS_A,
2.0 s with a METIS ordering; 3D P1: 76 k DOFs, 48 s and 190 M entries in the factors against
14 s and 117 M). This module computes one from the mesh itself: every part is split at the
median of its longest coordinate extent, the nodes of the lower half that share a cell with
the upper half form the separator, and a separator is ordered after the two halves it
separates (recursively; one vectorized pass per level). Any ordering gives the same
solution; a good one only makes the factorization cheaper.

Where: 2D order-1 meshes (P1, Q1) from ND_MIN_DOFS on (on 2D P2/Q2 these separators are two
node layers thick and minimum degree does as well); every 3D mesh from ND_MIN_DOFS_3D on. On
3D order-2 meshes (P2, Q2) the vertices are dissected and every other node joins the part or
separator of the deepest vertex of its edge, face or cell (the one eliminated first): one
node layer per separator, 25-40% fewer entries in the factors than dissecting every node or
minimum degree (measured at 80-100 k DOFs). The DOFs of a node (``dim`` a node) follow it.
"""

from __future__ import annotations

import threading
import weakref

import numpy as np

from ..fem.arrays import distinct
from ..fem.elements import get_element
from ..fem.pattern import distinct_pairs

LEAF = 16  # parts of at most this many nodes are not split further (64: 9% more fill)
MAX_LEVELS = 50  # keeps the integer keys of the dissection tree exact
PIECE_LEVELS = 3  # pieces() of substructuring: the parts after this many splits (8)


def node_edges(cells: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Directed pairs (u, v) of distinct nodes sharing a cell, each pair once per direction."""
    key = distinct_pairs(cells, n)
    itype = np.int32 if n < 2**31 else np.int64
    u, v = (key // n).astype(itype), (key % n).astype(itype)
    return np.concatenate([u, v]), np.concatenate([v, u])


def nested_dissection(points: np.ndarray, cells: np.ndarray, *, leaf: int = LEAF) -> np.ndarray:
    """The elimination rank of every node (a permutation of range(n_nodes))."""
    return _dissect(points, cells, leaf)[0]


def _dissect(points: np.ndarray, cells: np.ndarray, leaf: int = LEAF, levels: int = MAX_LEVELS):
    """(rank, piece): the elimination rank of every node and its piece of the first
    PIECE_LEVELS splits (0 ... 2**PIECE_LEVELS - 1; -1 for the separators of those splits:
    no cell joins two pieces); ``levels`` of splits."""
    points = np.asarray(points, dtype=float)
    n = len(points)
    u, v = node_edges(cells, n)
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
        leafy[order] = (size[group] <= leaf) | (level >= levels)
        # (u, v) now join active nodes of one part; the separator: lower-half nodes sharing
        # a cell with the upper half
        up_u, up_v = upper[u], upper[v]
        cut = ~up_u & up_v & ~leafy[u]
        new_sep = np.zeros(n, dtype=bool)
        new_sep[u[cut]] = True
        leaving = order[leafy[order] | new_sep[order]]
        stop[leaving], sep[leaving] = level, new_sep[leaving]
        active = order[~leafy[order] & ~new_sep[order]]
        code[active] = 2 * code[active] + upper[active]
        still = np.zeros(n, dtype=bool)
        still[active] = True
        keep = still[u] & still[v] & (up_u == up_v)
        u, v = u[keep], v[keep]
        level += 1
    depth = level
    span = np.left_shift(np.int64(1), depth - stop)  # width of the node's subtree interval
    key = np.where(sep, (code + 1) * span - 1, code * span)
    # a node that left at level s carries s bits of path: its top PIECE_LEVELS bits, or, for
    # a part that stopped splitting earlier, the first piece of the range it would cover
    top = np.minimum(stop, PIECE_LEVELS)
    piece = np.left_shift(np.right_shift(code, stop - top), PIECE_LEVELS - top)
    piece[sep & (stop < PIECE_LEVELS)] = -1
    return np.argsort(np.lexsort((np.arange(n), -stop, sep, key))), piece


def dof_order(nodes: np.ndarray, rank: np.ndarray) -> np.ndarray:
    """A permutation of DOFs (``nodes[i]``: the node of DOF i) that follows the node ranks."""
    return np.lexsort((np.arange(len(nodes)), rank[nodes]))


_RANKS: dict[tuple[int, int], tuple[weakref.ref, tuple[np.ndarray, np.ndarray]]] = {}
_COMPUTING: dict[tuple[int, int], threading.Lock] = {}  # held while a dissection is made


def _mesh_dissection(mesh, levels: int = MAX_LEVELS) -> tuple[np.ndarray, np.ndarray]:
    """:func:`_dissect` of a mesh (of its vertices, for 3D order-2 meshes:
    :func:`_vertex_dissection`), computed once per mesh object and ``levels`` (a sweep over
    nu reuses it); a computation under way in another thread (:func:`dissect_beside`) is
    waited for, not repeated."""
    key = (id(mesh), levels)
    with _COMPUTING.setdefault(key, threading.Lock()):  # setdefault: atomic (GIL)
        entry = _RANKS.get(key)
        if entry is not None and entry[0]() is mesh:
            return entry[1]
        if mesh.dim == 3 and mesh.fe.order > 1:
            found = _vertex_dissection(mesh, levels)
        else:
            found = _dissect(mesh.points, mesh.cells, levels=levels)
        _RANKS[key] = (weakref.ref(mesh, lambda _: _forget(key)), found)
        return found


def _forget(key: tuple[int, int]) -> None:
    """A mesh's dissection dropped with the mesh (no lock taken: a weakref callback runs
    wherever the collector does)."""
    _RANKS.pop(key, None)
    _COMPUTING.pop(key, None)


def dissects(mesh) -> bool:
    """Whether :func:`fill_order` orders this mesh's free DOFs by its nested dissection (as
    far as the mesh tells: the free DOFs are a few fewer than its DOFs)."""
    dofs = mesh.dim * mesh.n_nodes
    if mesh.dim == 3:
        return dofs >= ND_MIN_DOFS_3D
    return dofs >= ND_MIN_DOFS and mesh.element in ("P1", "Q1")


def dissect_beside(mesh) -> threading.Thread:
    """Start the mesh's nested dissection (what :func:`fill_order` and :func:`pieces` read)
    in a thread, beside the assembly that the caller runs meanwhile: both are numpy work
    that leaves the GIL in its large array operations (P1 unit square, 1.29 M DOFs: the
    dissection 1.57 s and the assembly 1.62 s alone, both done in 1.99 s side by side,
    measured). The caller joins the thread; an error is raised where the order is used."""

    def run() -> None:
        try:
            _mesh_dissection(mesh)
        except BaseException:  # noqa: BLE001, S110 - computed again, and raised, where used
            pass

    thread = threading.Thread(target=run, name="critfric-dissection", daemon=True)
    thread.start()
    return thread


def _vertex_dissection(mesh, levels: int) -> tuple[np.ndarray, np.ndarray]:
    """(rank, piece) of every node: :func:`_dissect` of the mesh's vertices (the order-1 mesh
    of its cells' corners), each other node placed with the deepest vertex of its entity (the
    vertices whose linear shape function is nonzero at it: its edge, face or cell).

    The nodes of one cell lie on one path of the dissection tree (no cell joins two parts),
    so every neighbour of a node is in its part's subtree or on the way to the root: the
    order keeps the dissection's structure, with separators one node layer thick."""
    fe, cells = mesh.fe, np.asarray(mesh.cells, dtype=np.int64)
    nv = fe.n_vertices
    corners = distinct(cells[:, :nv])
    where = np.full(mesh.n_nodes, -1, dtype=np.int64)
    where[corners] = np.arange(len(corners))
    local = where[cells[:, :nv]]
    vrank, vpiece = _dissect(np.asarray(mesh.points)[corners], local, levels=levels)
    linear = get_element(fe.name[0] + "1", mesh.dim)  # P1 or Q1: the vertices' functions
    support = np.abs(linear.shape(fe.doflocs)[0]) > 1e-9  # (nv, n_local)
    home = where.copy()  # the vertex each node is placed with
    crank = vrank[local]
    for j in range(nv, fe.n_local):
        ends = np.flatnonzero(support[:, j])
        first = ends[np.argmin(crank[:, ends], axis=1)]
        home[cells[:, j]] = local[np.arange(len(cells)), first]
    rank = np.empty(mesh.n_nodes, dtype=np.int64)
    rank[np.lexsort((np.arange(mesh.n_nodes), vrank[home]))] = np.arange(mesh.n_nodes)
    return rank, vpiece[home]


def mesh_rank(mesh) -> np.ndarray:
    """The nested-dissection rank of every node of a mesh (:func:`nested_dissection`; 3D
    order-2 meshes: of their vertices, see :func:`_vertex_dissection`), computed once per
    mesh object."""
    return _mesh_dissection(mesh)[0]


def minimum_degree(A) -> np.ndarray:
    """A minimum-degree permutation of A's rows (its graph, via SuperLU's MMD on A^T + A).

    SuperLU computes the order while it factors; it factors here a surrogate with A's pattern,
    (degree + 1) I - adjacency, which is diagonally dominant (no pivoting) and cheap."""
    import scipy.sparse as sp
    import scipy.sparse.linalg as spla

    graph = sp.csr_matrix(A, copy=True)
    graph.data[:] = 1.0
    graph.setdiag(0.0)
    graph.eliminate_zeros()
    graph = (sp.diags(np.asarray(graph.sum(axis=1)).ravel() + 1.0) - graph).tocsc()
    perm = spla.splu(graph, permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                     options={"SymmetricMode": True}).perm_c  # perm[i]: position of row i
    return np.argsort(perm, kind="stable")


ND_MIN_DOFS = 20000  # 2D: nested dissection from this many DOFs on (order-1 meshes)
ND_MIN_DOFS_3D = 5000  # 3D: from this many DOFs on (every element; 3x less time at 20 k)


def fill_order(system, dofs: np.ndarray | None = None) -> np.ndarray:
    """A fill-reducing order of the free DOFs ``dofs`` (default: all) of a contact system, for
    SuperLU: nested dissection of the mesh for large meshes (2D: order 1 only), else minimum
    degree on the node graph (``dim`` DOFs a node: a quarter, 3D a ninth, of K's entries)."""
    import scipy.sparse as sp

    dofs = np.arange(len(system.free)) if dofs is None else np.asarray(dofs)
    nodes = system.free[dofs] // system.dim
    if _dissected(system, dofs):
        return dof_order(nodes, mesh_rank(system.mesh))
    used, local = np.unique(nodes, return_inverse=True)
    cells = np.asarray(system.mesh.cells)
    where = np.full(system.mesh.n_nodes, -1)
    where[used] = np.arange(len(used))
    c = where[cells]
    rows = np.repeat(c, c.shape[1], axis=1).ravel()
    cols = np.tile(c, (1, c.shape[1])).ravel()
    keep = (rows >= 0) & (cols >= 0)
    graph = sp.coo_matrix((np.ones(keep.sum()), (rows[keep], cols[keep])),
                          shape=(len(used), len(used))).tocsr()
    rank = np.empty(len(used), dtype=np.int64)
    rank[minimum_degree(graph)] = np.arange(len(used))
    return dof_order(local, rank)


def _dissected(system, dofs: np.ndarray) -> bool:
    if system.dim == 3:
        return len(dofs) >= ND_MIN_DOFS_3D
    return len(dofs) >= ND_MIN_DOFS and system.mesh.element in ("P1", "Q1")


def pieces(system, dofs: np.ndarray | None = None) -> np.ndarray:
    """The piece of each free DOF ``dofs`` (default: all) after the first PIECE_LEVELS
    nested-dissection splits: 0 ... 2**PIECE_LEVELS - 1, and -1 for the separators of those
    splits (no entry of K joins two pieces). Where :func:`fill_order` dissects the mesh these
    are its order's pieces; else the same first splits alone."""
    dofs = np.arange(len(system.free)) if dofs is None else np.asarray(dofs)
    levels = MAX_LEVELS if _dissected(system, dofs) else PIECE_LEVELS
    return _mesh_dissection(system.mesh, levels)[1][system.free[dofs] // system.dim]
