"""The mesh container: points, cells and named boundary edges, with what every stage asks of it."""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from . import solids  # noqa: F401  (registers the 3D elements that Mesh.fe looks up)
from .elements import get_element

MAX_GROUP_NAME = 200  # characters of a boundary group's name


def group_name_ok(name) -> bool:
    """Whether ``name`` can name a boundary group: 1 to MAX_GROUP_NAME printable characters
    (names reach messages, terminals and result files)."""
    return isinstance(name, str) and 0 < len(name) <= MAX_GROUP_NAME and name.isprintable()


@dataclass(frozen=True)
class Mesh:
    """A 2D or 3D finite-element mesh; its dimension is the points' second axis.

    points : (n_nodes, dim) float64 node coordinates, dim 2 or 3.
    cells  : (n_cells, n_local) int64 node indices, local order as in gmsh
             (P1: 3 vertices counterclockwise; P2: 3 vertices then edge midpoints 01, 12, 20;
              Q1: 4 vertices counterclockwise; Q2: 4 vertices, midpoints 01, 12, 23, 30, centre;
              3D: tetrahedra and hexahedra of positive volume, see :mod:`.solids`).
    element: "P1" | "P2" | "Q1" | "Q2".
    edges  : boundary group name -> (n_facets, 2) int64 (order 1) or (n_facets, 3) (order 2:
             end, end, midpoint) node indices of the boundary facets in that group (2D).
    faces  : boundary group name -> (n_facets, facet nodes) int64 node indices of the boundary
             faces in that group (3D: triangles or quadrilaterals, gmsh local order).
    """

    points: np.ndarray
    cells: np.ndarray
    element: str
    edges: dict[str, np.ndarray] = field(default_factory=dict)
    faces: dict[str, np.ndarray] = field(default_factory=dict)

    @property
    def dim(self) -> int:
        """2 or 3: the number of coordinates of a point."""
        return int(np.shape(self.points)[1])

    @property
    def fe(self):
        """The element object of this mesh (its name and dimension)."""
        return get_element(self.element, self.dim)

    @property
    def facets(self) -> dict[str, np.ndarray]:
        """The named boundary groups: ``edges`` in 2D, ``faces`` in 3D."""
        return self.faces if self.dim == 3 else self.edges

    @property
    def n_nodes(self) -> int:
        return len(self.points)

    @property
    def n_cells(self) -> int:
        return len(self.cells)

    def __repr__(self) -> str:
        kind = "faces" if self.dim == 3 else "edges"
        return (f"Mesh({self.element}, {self.dim}D, {self.n_nodes} nodes, {self.n_cells} cells, "
                f"{kind} {sorted(self.facets)})")

    @cached_property
    def diameter(self) -> float:
        """h: the largest cell diameter (longest distance between two vertices of a cell),
        made on first use and kept (the mesh is not changed in place)."""
        nv = self.fe.n_vertices
        coords = [np.ascontiguousarray(self.points[:, k]) for k in range(self.dim)]
        largest = 0.0  # each vertex pair once, one coordinate at a time (no (n, nv, dim) copy)
        for a, b in zip(*np.triu_indices(nv, k=1)):
            i, j = self.cells[:, a], self.cells[:, b]
            squared = 0.0
            for x in coords:
                d = x[i] - x[j]
                squared = squared + d * d
            largest = max(largest, float(squared.max()))
        return float(np.sqrt(largest))

    def edge_nodes(self, names) -> np.ndarray:
        """Sorted unique node indices on the boundary groups ``names``."""
        parts = [self.edges[name].ravel() for name in names]
        return np.unique(np.concatenate(parts)) if parts else np.zeros(0, dtype=np.int64)


def shoelace(vertices: np.ndarray) -> np.ndarray:
    """Signed area of polygons (..., n, 2) -> (...), positive when counterclockwise."""
    v = np.asarray(vertices, dtype=np.float64)
    w = np.roll(v, -1, axis=-2)
    with np.errstate(over="ignore", invalid="ignore"):
        return 0.5 * np.sum(v[..., 0] * w[..., 1] - v[..., 1] * w[..., 0], axis=-1)


def signed_volumes(points: np.ndarray, cells: np.ndarray, element: str) -> np.ndarray:
    """Signed volume (n_cells,) of each 3D cell's vertex tetrahedron or trilinear hexahedron
    (``points`` (n, 3)): positive when the vertices are ordered like the reference cell's."""
    spec = get_element(element, 3)
    linear = get_element("P1" if spec.reference == "tetrahedron" else "Q1", 3)
    xi, w = linear.quadrature()  # exact for det J of the affine or trilinear map
    _, dref = linear.shape(xi)  # (n_vertices, n_qp, 3)
    X = np.asarray(points, dtype=np.float64)[np.asarray(cells)[:, :spec.n_vertices]]
    columns = [np.einsum("cvi,vq->cqi", X, dref[:, :, j]) for j in range(3)]  # d x / d xi_j
    det = np.einsum("cqi,cqi->cq", columns[0], np.cross(columns[1], columns[2]))
    return det @ w


def signed_areas(points: np.ndarray, cells: np.ndarray, element: str) -> np.ndarray:
    """Signed measure (n_cells,) of each cell: in 2D the shoelace area of its vertex polygon
    (positive when counterclockwise), in 3D (``points`` (n, 3)) its :func:`signed_volumes`."""
    if np.shape(points)[1] == 3:
        return signed_volumes(points, cells, element)
    return shoelace(points[cells[:, :get_element(element).n_vertices]])


def orient(points, cells, element):
    """Cells reordered to positive orientation (counterclockwise in 2D, positive volume in
    3D) by the element's ``flip``, and their (signed-before-flip) areas or volumes."""
    area = signed_areas(points, cells, element)
    cells = cells.copy()
    negative = area < 0
    cells[negative] = cells[negative][:, get_element(element, np.shape(points)[1]).flip]
    return cells, area
