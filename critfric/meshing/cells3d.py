"""Tetrahedra and hexahedra in numpy for the mesh builders: corner Jacobians, boundary faces,
second-order nodes and the validation of 3D meshes given by their vertices.

The elements' facts (gmsh node order, edges, outward faces, orientation flip, gmsh types) are
those of :data:`critfric.fem.elements.ELEMENTS_3D` (:mod:`critfric.fem.solids`);
:func:`solid` is meshing's view of them. In short: a tetrahedron has its vertices, then (P2)
the midpoints of the edges 01, 12, 20, 30, 32, 31; a hexahedron its vertices 0-3 on one face,
counterclockwise seen from the opposite face 4-7 (vertex 4 across from 0), then (Q2) the
midpoints of the edges 01, 03, 04, 12, 15, 23, 26, 37, 45, 47, 56, 67, the centres of the
faces 0321, 0154, 0473, 1265, 2376, 4567 and the cell's centre. Cells have a positive Jacobian
determinant. A boundary facet is its cell's face as the element lists it, normal (right-hand
rule) out of the cell, so a mesh's named faces point out of the body: a 3-node triangle (gmsh
type 2), 6-node triangle (9: vertices, midpoints 01, 12, 20), 4-node quadrangle (3) or 9-node
quadrangle (10: vertices, midpoints 01, 12, 23, 30, centre).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import CaseError
from ..fem.arrays import unused_nodes
from ..fem.elements import get_element
from ..fem.mesh import Mesh, orient
from .overlap import check_tiling_3d


@dataclass(frozen=True)
class Solid:
    """What meshing needs of a 3D element.

    name, order   : "P1" ..., 1 or 2; n_vertices: 4 (tetrahedron) or 8 (hexahedron).
    n_local       : nodes of a cell (4, 10, 8, 27).
    gmsh_cell     : gmsh type of a cell (4, 11, 5, 12); gmsh_facet: of a boundary facet
                    (2, 9, 3, 10).
    edges         : (n_edges, 2) local vertices of each edge; edge k's midpoint (order 2) is
                    local node n_vertices + k.
    faces         : (n_faces, 3 or 4) local vertices of each face, outward normal; face k's
                    centre (Q2) is local node n_vertices + n_edges + k.
    facet_local   : (n_faces, facet nodes) local nodes of each face as a boundary facet.
    flip          : local node permutation that reverses a cell's orientation.
    """

    name: str
    order: int
    n_vertices: int
    n_local: int
    gmsh_cell: int
    gmsh_facet: int
    edges: np.ndarray
    faces: np.ndarray
    facet_local: np.ndarray
    flip: np.ndarray

    @property
    def linear(self) -> str:
        """The first-order element of the same cell: "P1" or "Q1"."""
        return "P1" if self.n_vertices == 4 else "Q1"

    @property
    def cell_name(self) -> str:
        return "tetrahedra" if self.n_vertices == 4 else "hexahedra"

    @property
    def facet_vertices(self) -> int:
        return self.faces.shape[1]

    @property
    def facet_nodes(self) -> int:
        return self.facet_local.shape[1]


def solid(name: str) -> Solid:
    """The 3D element ``name`` (:class:`CaseError` naming ``mesh.element`` if unknown)."""
    fe = get_element(name, 3)
    facets = np.asarray(fe.faces, dtype=np.int64)
    return Solid(fe.name, fe.order, fe.n_vertices, fe.n_local, int(fe.gmsh_cell),
                 int(fe.gmsh_facet), np.asarray(fe.edges, dtype=np.int64)[:, :2],
                 facets[:, :fe.facet.n_vertices], facets, np.asarray(fe.flip, dtype=np.int64))


# ------------------------------------------------------------------------------ geometry
def _det(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """det[a, b, c] of rows of 3-vectors: a . (b x c)."""
    return np.einsum("...i,...i->...", a, np.cross(b, c))


def corner_jacobians(points: np.ndarray, cells: np.ndarray, n_vertices: int) -> np.ndarray:
    """(n_cells, 1) tetrahedron Jacobians (6 x volume) or (n_cells, 8) hexahedron Jacobian
    determinants at the corners (times 8: the volume of the corner's parallelepiped)."""
    x = points[cells[:, :n_vertices]]
    if n_vertices == 4:
        return _det(x[:, 1] - x[:, 0], x[:, 2] - x[:, 0], x[:, 3] - x[:, 0])[:, None]
    corners = get_element("Q1", 3).doflocs[:8]  # [-1, 1]^3
    out = np.empty((len(cells), 8))
    for k, corner in enumerate(corners):
        cols = []
        for j in range(3):  # neighbour along reference axis j, as a Jacobian column
            other = corner.copy()
            other[j] = -other[j]
            m = int(np.flatnonzero(np.all(corners == other, axis=1))[0])
            cols.append((x[:, k] - x[:, m]) * corner[j])
        out[:, k] = _det(*cols)
    return out


def longest_edges(points: np.ndarray, cells: np.ndarray, spec: Solid) -> np.ndarray:
    """(n_cells,) length of each cell's longest edge."""
    longest = np.zeros(len(cells))
    for a, b in spec.edges:
        d = points[cells[:, a]] - points[cells[:, b]]
        longest = np.maximum(longest, np.einsum("ci,ci->c", d, d))
    return np.sqrt(longest)


# ------------------------------------------------------------------------------ topology
def row_ids(rows: np.ndarray) -> np.ndarray:
    """(m,) ids of ``rows`` (m, k) up to the order within a row: equal vertex sets, equal
    ids, numbered 0, 1, ... in lexicographic order of the sorted rows."""
    s = np.sort(rows, axis=1)
    if len(s) == 0:
        return np.zeros(0, dtype=np.int64)
    order = np.lexsort(s.T[::-1])
    ranked = s[order]
    new = np.ones(len(s), dtype=bool)
    new[1:] = np.any(ranked[1:] != ranked[:-1], axis=1)
    ids = np.empty(len(s), dtype=np.int64)
    ids[order] = np.cumsum(new) - 1
    return ids


def face_ids(cells: np.ndarray, spec: Solid) -> tuple[np.ndarray, np.ndarray]:
    """(n_cells, n_faces) id of every cell face (shared faces share an id) and the number of
    cells of each id."""
    rows = cells[:, spec.faces].reshape(-1, spec.facet_vertices)
    ids = row_ids(rows)
    return ids.reshape(len(cells), -1), np.bincount(ids)


def second_order(points: np.ndarray, cells: np.ndarray, element: str):
    """Points and cells of ``element`` (P2 or Q2) from first-order ``cells`` (vertices only):
    a node at the middle of every edge (numbered by edge, after the given nodes) and, for Q2,
    one at the centre of every face (the mean of its corners), then of every cell; each at
    the local position the element gives it."""
    from .refine import edge_table

    spec = solid(element)
    n, nv = len(points), spec.n_vertices
    ends, inverse = edge_table(cells, n, spec.edges)
    new_points = [points, 0.5 * (points[ends[:, 0]] + points[ends[:, 1]])]
    out = np.empty((len(cells), spec.n_local), dtype=np.int64)
    out[:, :nv] = cells
    edge_nodes = np.asarray(get_element(element, 3).edges)[:, 2]
    out[:, edge_nodes] = n + inverse
    if nv == 8:
        ids, count = face_ids(cells, spec)
        corners = np.zeros((len(count), 4), dtype=np.int64)
        corners[ids.ravel()] = cells[:, spec.faces].reshape(-1, 4)
        new_points += [points[corners].mean(axis=1), points[cells].mean(axis=1)]
        face_nodes = spec.facet_local[:, -1]
        out[:, face_nodes] = n + len(ends) + ids
        taken = np.concatenate([np.arange(nv), edge_nodes, face_nodes])
        centre = int(np.setdiff1d(np.arange(spec.n_local), taken)[0])
        out[:, centre] = n + len(ends) + len(count) + np.arange(len(cells))
    return np.concatenate(new_points), out


def locate_faces(cells: np.ndarray, spec: Solid, rows: np.ndarray):
    """Where faces given by their vertices ``rows`` (k, 3 or 4) are: (cell, local face)
    of each (-1 where none), and whether each is a boundary face (one cell)."""
    k = spec.facet_vertices
    own = cells[:, spec.faces].reshape(-1, k)
    ids = row_ids(np.concatenate([own, rows]))
    own_ids, wanted = ids[:len(own)], ids[len(own):]
    count = np.bincount(own_ids, minlength=int(ids.max(initial=-1)) + 1)
    where = np.full(len(count), -1, dtype=np.int64)
    distinct, first = np.unique(own_ids, return_index=True)
    where[distinct] = first  # the first cell face of each id
    at = where[wanted]
    n_faces = len(spec.faces)
    cell = np.where(at >= 0, at // n_faces, -1)
    local = np.where(at >= 0, at % n_faces, -1)
    return cell, local, count[wanted] == 1


def facets(cells: np.ndarray, spec: Solid, cell: np.ndarray, local: np.ndarray) -> np.ndarray:
    """(k, facet nodes) boundary facets: face ``local`` of cell ``cell`` (all nodes)."""
    return cells[cell[:, None], spec.facet_local[local]]


# ------------------------------------------------------------------------------ validation
def check_cells(points: np.ndarray, cells: np.ndarray, spec: Solid, key: str, *,
                min_quality: float) -> np.ndarray:
    """First-order ``cells`` reoriented to positive volume; :class:`CaseError` naming ``key``
    for a repeated node, a flat or inverted cell (a hexahedron needs a positive Jacobian at
    every corner), a sliver (volume / longest edge^3 below ``min_quality``), or a face shared
    by more than two cells."""
    sort = np.sort(cells, axis=1)
    if np.any(sort[:, 1:] == sort[:, :-1]):
        raise CaseError(f"cell {int(np.argmax(np.any(sort[:, 1:] == sort[:, :-1], axis=1)))} "
                        "repeats a node", key=key)
    scale = float(np.ptp(points, axis=0).max())
    cells, volume = orient(points, cells, spec.name)
    jac = corner_jacobians(points, cells, spec.n_vertices)
    bad = np.any(jac <= 1e-12 * scale**3, axis=1)
    if bad.any():
        i = int(np.argmax(bad))
        what = "flat" if spec.n_vertices == 4 else "flat, inverted or not convex"
        raise CaseError(f"cell {i} (nodes {cells[i].tolist()}) is {what}; allowed: cells of "
                        "positive volume" + ("" if spec.n_vertices == 4 else " with a positive "
                                             "Jacobian at every corner"), key=key)
    quality = np.abs(volume) / longest_edges(points, cells, spec) ** 3
    if quality.min() < min_quality:
        i = int(np.argmin(quality))
        raise CaseError(f"cell {i} is a sliver (volume / longest edge^3 = {quality[i]:.2g}, "
                        f"nodes {cells[i].tolist()}): its stiffness would be singular to "
                        f"rounding; allowed: cells with volume / longest edge^3 >= "
                        f"{min_quality:g}", key=key)
    check_tiling_3d(points, cells, spec.faces, key)  # repeated, folded or overlapping cells
    _, count = face_ids(cells, spec)
    if np.any(count > 2):
        raise CaseError("a face is shared by more than two cells", key=key)
    return cells


def inline_solid(nodes, cells, faces: dict, element: str, *,
                 min_quality: float = 1e-6) -> Mesh:
    """A 3D mesh given explicitly: vertex ``nodes`` (n, 3), ``cells`` by their vertices only
    (tetrahedra for P1/P2, hexahedra in gmsh vertex order for Q1/Q2; either orientation) and
    named boundary ``faces`` {name: [[a, b, c], ...]} (triangles of tetrahedra, quadrilaterals
    [a, b, c, d] of hexahedra, vertices in any order). P2/Q2 nodes are appended after the
    given nodes (:func:`second_order`). Boundary facets take the orientation of their cell's
    face (normal out of the body)."""
    spec = solid(element)
    nv, fv = spec.n_vertices, spec.facet_vertices
    points = np.asarray(nodes, dtype=np.float64)
    if points.ndim != 2 or points.shape[1] != 3 or len(points) < 4:
        raise CaseError(f"must be at least 4 [x, y, z] triples, got shape {points.shape}",
                        key="geometry.nodes")
    if not np.all(np.isfinite(points)):
        raise CaseError("node coordinates must be finite numbers", key="geometry.nodes")
    n = len(points)
    ckey = f"geometry.{spec.cell_name}"
    cells = index_array(cells, nv, n, ckey)
    if len(cells) == 0:
        raise CaseError("needs at least one cell", key=ckey)
    cells = check_cells(points, cells, solid(spec.linear), ckey, min_quality=min_quality)
    unused = unused_nodes(cells, n)
    if len(unused):
        raise CaseError(f"node {int(unused[0])} belongs to no cell", key="geometry.nodes")
    linear = cells
    if spec.order == 2:
        points, cells = second_order(points, cells, element)
    groups = {}
    for name, rows in faces.items():
        key = f"geometry.faces.{name}"
        rows = index_array(rows, fv, n, key)
        if len(rows) == 0:
            raise CaseError(f"needs at least one face of {fv} node indices", key=key)
        cell, local, boundary = locate_faces(linear, spec, rows)
        if np.any(cell < 0) or not np.all(boundary):
            i = int(np.argmax((cell < 0) | ~boundary))
            what = "is not a face of any cell" if cell[i] < 0 else "is an interior face"
            raise CaseError(f"{rows[i].tolist()} {what}; allowed: boundary faces of the "
                            f"cells ({'triangles' if fv == 3 else 'quadrilaterals'})", key=key)
        groups[str(name)] = facets(cells, spec, cell, local)
    return Mesh(points, cells, element, faces=groups)


def index_array(value, width: int, n: int, key: str) -> np.ndarray:
    """(k, width) int64 node indices in [0, n), else CaseError naming ``key``."""
    try:
        raw = np.asarray(value)
        arr = raw.astype(np.int64)
    except (TypeError, ValueError):
        raise CaseError(f"must be rows of {width} node indices", key=key) from None
    if raw.size == 0:
        return np.zeros((0, width), dtype=np.int64)
    if arr.ndim != 2 or arr.shape[1] != width or np.any(arr != raw):
        raise CaseError(f"must be rows of {width} integer node indices, got shape {raw.shape}",
                        key=key)
    if arr.min() < 0 or arr.max() >= n:
        raise CaseError(f"node indices must be in 0..{n - 1}, got {int(arr.min())}.."
                        f"{int(arr.max())}", key=key)
    return arr
