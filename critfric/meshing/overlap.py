"""Do a mesh's cells tile a body, without overlap? Checks of meshes read from files or given
inline, after each cell is oriented (counterclockwise, positive volume).

A cell may be numbered in either orientation (the numbering is not geometry: each is
reoriented), but the cells must not fold over each other or overlap. Refused, with the cell
indices (in the order the cells were given) named:

* two nodes at one point (a mesh cut open there: duplicate nodes never merged);
* a hinge: cells that share a node (3D: or an edge) but are joined along no chain of shared
  edges (3D: faces), a piece that could turn about that node (a singular stiffness);
* repeated cells (the same node set twice);
* a fold: two cells on the same side of their shared edge (2D) or face (3D), which is what
  an inverted cell or an overlapping neighbour gives (both run the shared edge or face in the
  same direction once oriented);
* overlap across the boundary (2D): two boundary edges that cross, or a point just inside a
  boundary edge that the boundary winds around more than once (a second copy of the body on
  top of the first, a mesh inside another's cells, two meshes overlapping). With neither, the
  boundary edges enclose exactly the cells: the sum of the cells' areas is the area the
  boundary encloses;
* overlap across the boundary (3D): a point just inside one face of each connected piece of
  the boundary around which the boundary's solid angle is more than 4 pi (a second copy, a
  body inside another). Surfaces of two bodies that cut through each other are not tested
  face against face.

The tests are vectorized; the 2D boundary ones compare only edges in neighbouring cells of a
grid (crossings) or in neighbouring bands (the winding number's ray, across the body's shorter
extent) as fine as the longest boundary edge; the 3D one costs (pieces of the boundary) x
(boundary faces).
"""

from __future__ import annotations

import numpy as np

from ..errors import CaseError

CHUNK = 1 << 20  # pairs of (point or edge, edge) per numpy pass
INSIDE = 1e-9  # the test points: this fraction of a facet's size inside it
SAME_POINT = 1e-12  # two nodes closer than this times the body's size are one point


def _coincident(points: np.ndarray, key: str) -> None:
    """Two nodes at one point (to 1e-12 of the body's size)."""
    scale = float(np.ptp(points, axis=0).max()) or 1.0
    grid = np.round((points - points.min(axis=0)) / (SAME_POINT * scale)).astype(np.int64)
    order = np.lexsort(grid.T[::-1])
    same = np.flatnonzero(np.all(grid[order[1:]] == grid[order[:-1]], axis=1))
    if len(same):
        i, j = sorted(int(x) for x in order[[same[0], same[0] + 1]])
        raise CaseError(f"{i} and {j} are at the same point {points[i].tolist()}: the "
                        "mesh is cut open there (duplicate nodes not merged); allowed: one node "
                        "per point (merge duplicates, e.g. gmsh's Coherence Mesh)", key=key)


def _hinge(points: np.ndarray, cells: np.ndarray, inverse: np.ndarray, key: str,
           facet: str) -> None:
    """``inverse`` (n_cells * per-cell,): each cell's facets numbered as one set; a hinge
    where the cells around a node belong to pieces joined along no chain of facets."""
    import scipy.sparse as sp
    from scipy.sparse.csgraph import connected_components

    n_cells, n = len(cells), len(points)
    inverse = inverse.ravel()
    owner = np.arange(len(inverse)) // (len(inverse) // n_cells)
    order = np.argsort(inverse, kind="stable")
    pair = np.flatnonzero(inverse[order[1:]] == inverse[order[:-1]])  # an interior facet
    a, b = owner[order[pair]], owner[order[pair + 1]]
    joined = sp.coo_matrix((np.ones(len(a)), (a, b)), shape=(n_cells, n_cells))
    pieces, label = connected_components(joined, directed=False)
    if pieces == 1:
        return
    node, piece = cells.ravel(), np.repeat(label, cells.shape[1])
    low = np.full(n, pieces)
    np.minimum.at(low, node, piece)
    high = np.full(n, -1)
    np.maximum.at(high, node, piece)
    hinged = np.flatnonzero((high >= 0) & (low != high))
    if len(hinged):
        i = int(hinged[0])
        raise CaseError(f"the cells around node {i} at {points[i].tolist()} form pieces joined "
                        f"there only, along no {facet} (a hinge: one piece could turn about "
                        f"it); allowed: cells joined along their {facet}s", key=key)


def _duplicates(rows: np.ndarray, key: str, what: str) -> None:
    s = np.sort(rows, axis=1)
    order = np.lexsort(s.T[::-1])
    same = np.flatnonzero(np.all(s[order[1:]] == s[order[:-1]], axis=1))
    if len(same):
        i, j = sorted(int(x) for x in order[[same[0], same[0] + 1]])
        raise CaseError(f"cells {i} and {j} are the same {what} (nodes {rows[j].tolist()}); "
                        "allowed: each cell once", key=key)


def _fold(directed: np.ndarray, width: int, key: str, what: str) -> None:
    """``directed`` (n_cells * per-cell, k): the cells' oriented edges (faces); a fold where
    two occurrences of one edge (face) have the same direction."""
    k = directed.shape[1]
    start = np.argmin(directed, axis=1)  # each row rotated to start at its smallest node
    rot = directed[np.arange(len(directed))[:, None], (start[:, None] + np.arange(k)) % k]
    sense = rot[:, 1] < rot[:, -1] if k > 2 else rot[:, 0] == directed[:, 0]
    key_rows = np.sort(directed, axis=1)
    rows = np.concatenate([key_rows, sense[:, None].astype(key_rows.dtype)], axis=1)
    order = np.lexsort(rows.T[::-1])
    ranked = rows[order]
    same = np.flatnonzero(np.all(ranked[1:] == ranked[:-1], axis=1))
    if len(same):
        i, j = sorted(int(x) // width for x in order[[same[0], same[0] + 1]])
        raise CaseError(f"cells {i} and {j} overlap: they lie on the same side of their shared "
                        f"{what} {key_rows[order[same[0]]].tolist()} (a cell inverted or folded "
                        "over its neighbour); allowed: cells that tile the body", key=key)


def check_tiling_2d(points: np.ndarray, cells: np.ndarray, key: str) -> None:
    """``cells`` (n, 3 or 4) counterclockwise; CaseError naming ``key`` and the cells (or
    the nodes at one point, where the cells tile but are cut open)."""
    inverse = _tiling_2d(points, cells, key)
    _coincident(points, "geometry.nodes")
    _hinge(points, cells, inverse, key, "edge")


def _tiling_2d(points: np.ndarray, cells: np.ndarray, key: str) -> np.ndarray:
    nv = cells.shape[1]
    _duplicates(cells, key, "triangle" if nv == 3 else "quadrangle")
    directed = np.stack([cells, np.roll(cells, -1, axis=1)], axis=-1).reshape(-1, 2)
    _fold(directed, nv, key, "edge")
    lo, hi = directed.min(axis=1), directed.max(axis=1)
    _, inverse, count = np.unique(lo * len(points) + hi, return_inverse=True,
                                  return_counts=True)
    boundary = np.flatnonzero(count[inverse.ravel()] == 1)
    a, b = points[directed[boundary, 0]], points[directed[boundary, 1]]
    owner = boundary // nv
    crossing = _crossing(a, b, directed[boundary])
    if crossing is not None:
        i, j = sorted(int(owner[x]) for x in crossing)
        raise CaseError(f"cells {i} and {j} overlap: their boundary edges cross; allowed: "
                        "cells that tile the body", key=key)
    d = b - a
    inside = 0.5 * (a + b) + INSIDE * np.column_stack([-d[:, 1], d[:, 0]])
    winding = _winding(inside, a, b)
    if np.any(winding != 1):
        e = int(np.argmax(winding != 1))
        over = _containing(points, cells, inside[e])
        shown = sorted(set(over.tolist()) | {int(owner[e])})
        raise CaseError(f"cells {', '.join(map(str, shown[:-1]))} and {shown[-1]} overlap (the "
                        f"point {inside[e].round(12).tolist()} is in {int(winding[e])} cells; "
                        "the cells' areas add up to more than the area their boundary "
                        "encloses); allowed: cells that tile the body" if len(shown) > 1 else
                        f"cell {shown[0]} lies over another part of the body; allowed: cells "
                        "that tile the body", key=key)
    return inverse


def _pairs(n: int, m: int):
    """Chunks of rows of an n x m table, CHUNK pairs each."""
    step = max(1, CHUNK // max(m, 1))
    for start in range(0, n, step):
        yield slice(start, min(start + step, n))


def _near(keys_a: np.ndarray, keys_b: np.ndarray, offsets):
    """Chunks (ia, ib) of every pair with keys_b[ib] == keys_a[ia] + offset for an offset of
    ``offsets`` (integer cell keys: pairs of neighbouring cells)."""
    order = np.argsort(keys_b, kind="stable")
    ranked = keys_b[order]
    for offset in offsets:
        target = keys_a + offset
        lo = np.searchsorted(ranked, target, "left")
        count = np.searchsorted(ranked, target, "right") - lo
        ends = np.cumsum(count)
        first = 0
        while first < len(keys_a):  # about CHUNK pairs at a time
            last = int(np.searchsorted(ends, (ends[first - 1] if first else 0) + CHUNK,
                                       "right"))
            last = max(last, first + 1)
            c = count[first:last]
            ia = np.repeat(np.arange(first, last), c)
            within = np.arange(len(ia)) - np.repeat(np.cumsum(c) - c, c)
            yield ia, order[np.repeat(lo[first:last], c) + within]
            first = last


def _cells(x: np.ndarray, origin: float, step: float) -> np.ndarray:
    return np.floor((x - origin) / step).astype(np.int64)


def _crossing(a: np.ndarray, b: np.ndarray, nodes: np.ndarray):
    """The first pair (i, j) of segments a_i b_i, a_j b_j that cross at a point inside both
    (not at an end), or None. Only segments whose midpoints are in neighbouring cells of a
    grid as fine as the longest segment are compared."""
    if len(a) < 2:
        return None
    both = np.concatenate([a, b])
    low, scale = both.min(axis=0), float(np.ptp(both, axis=0).max())
    tol = 1e-12 * scale * scale
    d = b - a
    step = max(float(np.abs(d).max()), 1e-300)
    cell = _cells(0.5 * (a + b), low, step)
    width = int(cell[:, 1].max()) + 3
    keys = cell[:, 0] * width + cell[:, 1]

    def side(p, dp, r):  # sign of dp x (r - p), zero within the tolerance
        v = dp[:, 0] * (r[:, 1] - p[:, 1]) - dp[:, 1] * (r[:, 0] - p[:, 0])
        return np.where(np.abs(v) <= tol, 0.0, np.sign(v))

    for i, j in _near(keys, keys, [u * width + v for u in (-1, 0, 1) for v in (-1, 0, 1)]):
        keep = (i < j) & ~(nodes[i, :, None] == nodes[j, None, :]).any(axis=(1, 2))
        i, j = i[keep], j[keep]
        hit = (side(a[i], d[i], a[j]) * side(a[i], d[i], b[j]) < 0) & (
            side(a[j], d[j], a[i]) * side(a[j], d[j], b[i]) < 0)
        if hit.any():
            k = int(np.argmax(hit))
            return int(i[k]), int(j[k])
    return None


def _winding(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Winding numbers of the closed directed edges a -> b around the points ``p``: edges
    crossing a ray from each point across the body's shorter extent, found in bands as wide
    as the longest edge."""
    both = np.concatenate([a, b])
    extent = np.ptp(both, axis=0)
    sign = 1
    if extent[0] > extent[1]:  # the ray along y: x and y swapped (a mirror: sign reversed)
        p, a, b, both, sign = p[:, ::-1], a[:, ::-1], b[:, ::-1], both[:, ::-1], -1
    step = max(float(np.abs(b[:, 1] - a[:, 1]).max()), 1e-300)
    low = float(both[:, 1].min())
    band = _cells(0.5 * (a[:, 1] + b[:, 1]), low, step)
    out = np.zeros(len(p), dtype=np.int64)
    for i, j in _near(_cells(p[:, 1], low, step), band, (-1, 0, 1)):
        x, y = p[i, 0], p[i, 1]
        ax, ay, bx, by = a[j, 0], a[j, 1], b[j, 0], b[j, 1]
        cross = (bx - ax) * (y - ay) - (by - ay) * (x - ax)
        turn = ((ay <= y) & (by > y) & (cross > 0)).astype(np.int64) - (
            (by <= y) & (ay > y) & (cross < 0))
        out += np.bincount(i, weights=turn, minlength=len(p)).astype(np.int64)
    return sign * out


def _containing(points: np.ndarray, cells: np.ndarray, p: np.ndarray) -> np.ndarray:
    """Indices of the (counterclockwise, convex) cells that contain the point ``p``, on
    their edges included (within INSIDE of an edge's length)."""
    v = points[cells]
    d = np.roll(v, -1, axis=1) - v
    cross = d[..., 0] * (p[1] - v[..., 1]) - d[..., 1] * (p[0] - v[..., 0])
    return np.flatnonzero(np.all(cross >= -INSIDE * np.sum(d * d, axis=-1), axis=1))


# ------------------------------------------------------------------------------------- 3D
def check_tiling_3d(points: np.ndarray, cells: np.ndarray, faces: np.ndarray,
                    key: str) -> None:
    """``cells`` (n, 4 or 8) of positive volume with their outward ``faces`` (local vertex
    lists, (n_faces, 3 or 4)); CaseError naming ``key`` and the cells (or
    the nodes at one point, where the cells tile but are cut open)."""
    inverse = _tiling_3d(points, cells, faces, key)
    _coincident(points, "geometry.nodes")
    _hinge(points, cells, inverse, key, "face")


def _tiling_3d(points: np.ndarray, cells: np.ndarray, faces: np.ndarray,
               key: str) -> np.ndarray:
    """``cells`` (n, 4 or 8) of positive volume with their outward ``faces`` (local vertex
    lists, (n_faces, 3 or 4)); the checks of :func:`check_tiling_3d` but the last two; the
    faces of the cells numbered as one set (n_cells * n_faces,)."""
    nf = len(faces)
    _duplicates(cells, key, "tetrahedron" if cells.shape[1] == 4 else "hexahedron")
    directed = cells[:, faces].reshape(-1, faces.shape[1])
    _fold(directed, nf, key, "face")
    s = np.sort(directed, axis=1)
    _, inverse, count = np.unique(s, axis=0, return_inverse=True, return_counts=True)
    boundary = np.flatnonzero(count[inverse.ravel()] == 1)
    tri = directed[boundary][:, [0, 1, 2]]
    if directed.shape[1] == 4:
        tri = np.concatenate([tri, directed[boundary][:, [0, 2, 3]]])
    owner = np.concatenate([boundary, boundary])[:len(tri)] // nf
    x = points[tri]
    normal = np.cross(x[:, 1] - x[:, 0], x[:, 2] - x[:, 0])
    size = np.sqrt(np.linalg.norm(normal, axis=1))[:, None]
    inside = x.mean(axis=1) - INSIDE * size * normal / np.maximum(size**2, 1e-300)
    picked = _one_per_piece(tri, len(points))
    turns = _solid_angles(inside[picked], x) / (4 * np.pi)
    bad = np.abs(turns - 1) > 0.5
    if bad.any():
        f = int(picked[int(np.argmax(bad))])
        raise CaseError(f"cell {int(owner[f])} lies inside another part of the body (the point "
                        f"{inside[f].round(12).tolist()} is inside {turns[np.argmax(bad)]:.0f} "
                        "closed boundaries: a second copy of the body, or a body inside "
                        "another); allowed: cells that tile the body", key=key)
    return inverse


def _one_per_piece(tri: np.ndarray, n: int) -> np.ndarray:
    """One boundary triangle of each connected piece of the boundary surface."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    rows = np.repeat(np.arange(len(tri)), 3)
    graph = coo_matrix((np.ones(len(rows)), (rows, tri.ravel())), shape=(len(tri), n)).tocsr()
    _, label = connected_components(graph @ graph.T, directed=False)
    return np.unique(label, return_index=True)[1]


def _solid_angles(p: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Sum over the triangles ``x`` (m, 3, 3) of their signed solid angles seen from each
    point of ``p`` (Van Oosterom and Strackee)."""
    out = np.zeros(len(p))
    for rows in _pairs(len(p), len(x)):
        r = x[None] - p[rows, None, None, :]  # (k, m, 3, 3)
        length = np.linalg.norm(r, axis=-1)
        a, b, c = r[..., 0, :], r[..., 1, :], r[..., 2, :]
        det = np.einsum("kmi,kmi->km", a, np.cross(b, c))
        la, lb, lc = length[..., 0], length[..., 1], length[..., 2]
        den = (la * lb * lc + np.einsum("kmi,kmi->km", a, b) * lc
               + np.einsum("kmi,kmi->km", a, c) * lb + np.einsum("kmi,kmi->km", b, c) * la)
        out[rows] = 2 * np.arctan2(det, den).sum(axis=1)
    return out
