"""Reference 3D finite elements (P1, P2 tetrahedra; Q1, Q2 hexahedra) with node order as in
gmsh, registered into :data:`.elements.ELEMENTS_3D` (the names are the 2D ones; a mesh's
dimension picks the table).

Reference cells: the tetrahedron (0,0,0), (1,0,0), (0,1,0), (0,0,1) and the cube [-1, 1]^3.
Nodes are numbered as gmsh numbers them: vertices, then edge midpoints in gmsh's edge order
(tetrahedron: 01, 12, 20, 30, 32, 31; hexahedron: 01, 03, 04, 12, 15, 23, 26, 37, 45, 47, 56,
67), then face centres (hexahedron: faces z=-1, y=-1, x=-1, x=1, y=1, z=1) and the cell
centre. ``faces`` lists each boundary face's local nodes in the order of the facet element
(triangle 3 / 6 nodes, quadrangle 4 / 9 nodes, as gmsh's ``getElementFaceNodes``), ordered so
that the right-hand-rule normal points out of the cell. ``facet`` is that facet element: the
2D element of the same name, whose shape functions and rules (on the reference triangle or
square) integrate over faces (:func:`face_shape`, :func:`face_quadrature`,
:func:`face_normals`).
"""

from __future__ import annotations

from itertools import permutations

import numpy as np

from .elements import ELEMENTS, ELEMENTS_3D, Element, _lagrange_1d, gauss_legendre


def _tetrahedron_orbits(orbits) -> tuple[np.ndarray, np.ndarray]:
    """Points (n, 3) and weights (n,) on the reference tetrahedron (volume 1/6) from
    (barycentric 4-tuple, weight) orbits: every distinct permutation of the tuple, the weights
    given for a unit-volume tetrahedron."""
    points, weights = [], []
    for bary, weight in orbits:
        for p in sorted(set(permutations(bary))):
            points.append(p[1:])  # x, y, z are the barycentric coordinates 1, 2, 3
            weights.append(weight / 6.0)
    return np.array(points), np.array(weights)


_A2 = (5.0 - np.sqrt(5.0)) / 20.0
_TETRAHEDRON_DEGREE_2 = _tetrahedron_orbits([((1 - 3 * _A2, _A2, _A2, _A2), 0.25)])
_TETRAHEDRON_DEGREE_5 = _tetrahedron_orbits([  # Walkington (2000), 14 points, degree 5
    ((1 - 3 * 0.0927352503108912264,) + (0.0927352503108912264,) * 3,
     0.0734930431163619495),
    ((1 - 3 * 0.3108859192633006097,) + (0.3108859192633006097,) * 3,
     0.1126879257180158507),
    ((0.0455037041256496494,) * 2 + (0.4544962958743503506,) * 2, 0.0425460207770814664)])


class SolidElement(Element):
    """Base class of the 3D elements: adds ``faces`` (n_faces, facet nodes), outward by the
    right-hand rule, and ``facet``, the 2D element of the boundary faces."""

    dim = 3
    faces: np.ndarray
    facet: Element

    @property
    def facet_nodes(self) -> int:
        """Nodes on one boundary face: 3 or 6 (triangle), 4 or 9 (quadrangle)."""
        return self.facet.n_local


_TET_EDGES = np.array([[0, 1, 4], [1, 2, 5], [2, 0, 6], [3, 0, 7], [3, 2, 8], [3, 1, 9]])
_TET_FACES = np.array([[0, 2, 1, 6, 5, 4], [0, 1, 3, 4, 9, 7], [0, 3, 2, 7, 8, 6],
                       [3, 1, 2, 9, 5, 8]])
_TET_GRADIENTS = np.array([[-1.0, -1.0, -1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])


def _barycentric(xi) -> np.ndarray:
    """Barycentric coordinates (4, n_pts) of points ``xi`` (n_pts, 3) of the tetrahedron."""
    x, y, z = np.asarray(xi, dtype=float).T
    return np.array([1.0 - x - y - z, x, y, z])


class P1Tetrahedron(SolidElement):
    name, n_local, n_vertices, order, reference = "P1", 4, 4, 1, "tetrahedron"
    edges, faces = _TET_EDGES[:, :2], _TET_FACES[:, :3]
    flip = [0, 2, 1, 3]
    gmsh_cell, gmsh_facet = 4, 2  # tetrahedron, triangle
    facet = ELEMENTS["P1"]
    doflocs = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])

    def shape(self, xi):
        values = _barycentric(xi)
        grads = np.broadcast_to(_TET_GRADIENTS[:, None, :], (4, values.shape[1], 3)).copy()
        return values, grads

    def quadrature(self):
        return np.array([[0.25, 0.25, 0.25]]), np.array([1.0 / 6.0])

    def mass_quadrature(self):
        return _TETRAHEDRON_DEGREE_2


class P2Tetrahedron(SolidElement):
    name, n_local, n_vertices, order, reference = "P2", 10, 4, 2, "tetrahedron"
    edges, faces = _TET_EDGES, _TET_FACES
    flip = [0, 2, 1, 3, 6, 5, 4, 7, 9, 8]
    gmsh_cell, gmsh_facet = 11, 9  # tetrahedron10, triangle6
    facet = ELEMENTS["P2"]
    doflocs = np.array(
        [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0],
         [0.5, 0.0, 0.0], [0.5, 0.5, 0.0], [0.0, 0.5, 0.0],  # edges 01, 12, 20
         [0.0, 0.0, 0.5], [0.0, 0.5, 0.5], [0.5, 0.0, 0.5]]  # edges 30, 32, 31
    )

    def shape(self, xi):
        lam = _barycentric(xi)  # (4, n_pts)
        values = np.empty((10, lam.shape[1]))
        grads = np.empty((10, lam.shape[1], 3))
        for i in range(4):
            values[i] = lam[i] * (2.0 * lam[i] - 1.0)
            grads[i] = (4.0 * lam[i] - 1.0)[:, None] * _TET_GRADIENTS[i]
        for k, (i, j) in enumerate(_TET_EDGES[:, :2]):
            values[4 + k] = 4.0 * lam[i] * lam[j]
            grads[4 + k] = 4.0 * (lam[i][:, None] * _TET_GRADIENTS[j]
                                  + lam[j][:, None] * _TET_GRADIENTS[i])
        return values, grads

    def quadrature(self):
        return _TETRAHEDRON_DEGREE_2

    def mass_quadrature(self):
        return _TETRAHEDRON_DEGREE_5


_HEX_EDGES = np.array([[0, 1, 8], [0, 3, 9], [0, 4, 10], [1, 2, 11], [1, 5, 12], [2, 3, 13],
                       [2, 6, 14], [3, 7, 15], [4, 5, 16], [4, 7, 17], [5, 6, 18], [6, 7, 19]])
_HEX_FACES = np.array([[0, 3, 2, 1, 9, 13, 11, 8, 20], [0, 1, 5, 4, 8, 12, 16, 10, 21],
                       [0, 4, 7, 3, 10, 17, 15, 9, 22], [1, 2, 6, 5, 11, 14, 18, 12, 23],
                       [2, 3, 7, 6, 13, 15, 19, 14, 24], [4, 5, 6, 7, 16, 18, 19, 17, 25]])
_HEX_NODES = np.array(
    [[-1, -1, -1], [1, -1, -1], [1, 1, -1], [-1, 1, -1],
     [-1, -1, 1], [1, -1, 1], [1, 1, 1], [-1, 1, 1],
     [0, -1, -1], [-1, 0, -1], [-1, -1, 0], [1, 0, -1], [1, -1, 0], [0, 1, -1],  # edges
     [1, 1, 0], [-1, 1, 0], [0, -1, 1], [-1, 0, 1], [1, 0, 1], [0, 1, 1],
     [0, 0, -1], [0, -1, 0], [-1, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1],  # faces
     [0, 0, 0]], dtype=float)  # centre


class _TensorHexahedron(SolidElement):
    """Lagrange tensor-product element on [-1, 1]^3 with nodes at ``doflocs``."""

    reference, n_vertices = "hexahedron", 8

    def shape(self, xi):
        xi = np.asarray(xi, dtype=float)
        nodes = np.linspace(-1.0, 1.0, self.order + 1)
        index = np.rint((self.doflocs + 1.0) * self.order / 2.0).astype(int)  # (n_local, 3)
        v, d = zip(*(_lagrange_1d(xi[:, k], nodes) for k in range(3)))
        v = [v[k][index[:, k]] for k in range(3)]  # (n_local, n_pts) per direction
        d = [d[k][index[:, k]] for k in range(3)]
        values = v[0] * v[1] * v[2]
        grads = np.stack([d[0] * v[1] * v[2], v[0] * d[1] * v[2], v[0] * v[1] * d[2]], axis=-1)
        return values, grads

    def quadrature(self):
        s, w = gauss_legendre(self.order + 1)
        sx, sy, sz = np.meshgrid(s, s, s, indexing="ij")
        points = np.column_stack([sx.ravel(), sy.ravel(), sz.ravel()])
        return points, np.einsum("i,j,k->ijk", w, w, w).ravel()

    def mass_quadrature(self):  # degree 2 order per direction (parallelepipeds): same rule
        return self.quadrature()


class Q1Hexahedron(_TensorHexahedron):
    name, n_local, order = "Q1", 8, 1
    edges, faces = _HEX_EDGES[:, :2], _HEX_FACES[:, :4]
    flip = [0, 3, 2, 1, 4, 7, 6, 5]
    gmsh_cell, gmsh_facet = 5, 3  # hexahedron, quadrangle
    facet = ELEMENTS["Q1"]
    doflocs = _HEX_NODES[:8]


class Q2Hexahedron(_TensorHexahedron):
    name, n_local, order = "Q2", 27, 2
    edges, faces = _HEX_EDGES, _HEX_FACES
    flip = [0, 3, 2, 1, 4, 7, 6, 5, 9, 8, 10, 13, 15, 11, 14, 12, 17, 16, 19, 18,
            20, 22, 21, 24, 23, 25, 26]
    gmsh_cell, gmsh_facet = 12, 10  # hexahedron27, quadrangle9
    facet = ELEMENTS["Q2"]
    doflocs = _HEX_NODES


ELEMENTS_3D.update({"P1": P1Tetrahedron(), "P2": P2Tetrahedron(), "Q1": Q1Hexahedron(),
                    "Q2": Q2Hexahedron()})


def face_shape(element: SolidElement, xi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Shape values (facet nodes, n_pts) and reference gradients (facet nodes, n_pts, 2) of
    the faces of a 3D ``element`` at points ``xi`` (n_pts, 2) of the reference triangle
    (0,0), (1,0), (0,1) or square [-1, 1]^2, nodes in the order of ``element.faces``."""
    return element.facet.shape(xi)


def face_quadrature(element: SolidElement) -> tuple[np.ndarray, np.ndarray]:
    """Points (n_qp, 2) and weights (n_qp,) on the reference face of a 3D ``element``, exact
    for (face shape) x (face shape) on flat straight-sided faces: a surface load times a test
    function, or a face mass."""
    return element.facet.mass_quadrature()


def face_normals(points: np.ndarray, faces: np.ndarray, element: SolidElement,
                 xi: np.ndarray) -> np.ndarray:
    """Area-scaled normals dx/ds x dx/dt (n_faces, n_pts, 3) of ``faces`` (n_faces, facet
    nodes) at reference face points ``xi`` (n_pts, 2): their length is the surface Jacobian
    (so ``sum_q w_q |n_q| f(x_q)`` integrates f over a face) and their direction the
    right-hand-rule normal of the face's node order (out of the cell for ``element.faces``).
    A surface load t gives node a of a face ``sum_q w_q N_a(xi_q) |n_q| t``."""
    _, dref = face_shape(element, xi)  # (facet nodes, n_pts, 2)
    X = np.asarray(points, dtype=float)[np.asarray(faces)]  # (n_faces, facet nodes, 3)
    ds = np.einsum("fai,aq->fqi", X, dref[:, :, 0])
    dt = np.einsum("fai,aq->fqi", X, dref[:, :, 1])
    return np.cross(ds, dt)
