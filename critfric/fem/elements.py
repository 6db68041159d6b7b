"""Reference finite elements (P1, P2, Q1, Q2) with node order as in gmsh: every fact about an
element lives here, in its class (adding an element is adding a class to ``ELEMENTS``).

Each element gives its reference nodes ``doflocs`` (vertices first, counterclockwise, then edge
midpoints, then interior nodes), its local edges, the permutation that reverses a cell's
orientation, its gmsh cell and facet types, shape functions and gradients on the
reference cell, and a quadrature rule that integrates the stiffness integrand exactly on
straight-sided triangles (P1, P2) and parallelograms (Q1, Q2). Reference cells: the triangle
(0,0), (1,0), (0,1) and the square [-1, 1]^2. Facets (edges) use the interval [-1, 1] with
local nodes ordered end, end, midpoint. The 3D elements (tetrahedra, hexahedra) are in
:mod:`.solids`, which registers them into ``ELEMENTS_3D``.
"""

from __future__ import annotations

import numpy as np

from ..errors import CaseError


def _lagrange_1d(s: np.ndarray, nodes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """1D Lagrange basis on ``nodes`` at points ``s``: values and derivatives (n_nodes, n_s)."""
    s = np.asarray(s, dtype=float)
    n = len(nodes)
    values = np.ones((n, s.size))
    derivs = np.zeros((n, s.size))
    for j in range(n):
        others = [m for m in range(n) if m != j]
        for m in others:
            values[j] *= (s - nodes[m]) / (nodes[j] - nodes[m])
        for m in others:
            term = np.full(s.size, 1.0 / (nodes[j] - nodes[m]))
            for k in others:
                if k != m:
                    term *= (s - nodes[k]) / (nodes[j] - nodes[k])
            derivs[j] += term
    return values, derivs


def gauss_legendre(n: int) -> tuple[np.ndarray, np.ndarray]:
    """``n``-point Gauss-Legendre rule on [-1, 1] (exact for degree 2n - 1)."""
    return np.polynomial.legendre.leggauss(n)


def facet_quadrature(order: int) -> tuple[np.ndarray, np.ndarray]:
    """Rule on [-1, 1] exact for (facet shape) x (facet shape) on straight facets of ``order``."""
    return gauss_legendre(order + 1)


def facet_shape(s: np.ndarray, order: int) -> tuple[np.ndarray, np.ndarray]:
    """Facet shape functions at ``s`` in [-1, 1], nodes (end, end[, mid]): values, d/ds."""
    nodes = np.array([-1.0, 1.0]) if order == 1 else np.array([-1.0, 1.0, 0.0])
    return _lagrange_1d(s, nodes)


class Element:
    """Base class: subclasses set the attributes and implement :meth:`shape`.

    name, order  : "P1" ..., polynomial degree (1 or 2).
    dim          : 2 (triangles, quadrilaterals) or 3 (tetrahedra, hexahedra); a name means
                   one element per dimension (P1: the linear triangle or tetrahedron).
    n_local      : nodes of one cell; n_vertices of them are the corners (in 2D
                   counterclockwise).
    reference    : "triangle" (0,0), (1,0), (0,1) or "quad" [-1, 1]^2; in 3D "tetrahedron"
                   or "hexahedron" (:mod:`.solids`).
    doflocs      : (n_local, dim) reference coordinates of the nodes.
    edges        : (n_edges, 2 or 3) local nodes of each edge: end, end[, midpoint].
    flip         : local permutation reversing a cell's orientation (vertex 0 kept, midpoints
                   follow their edge, face and cell centres their face and cell).
    gmsh_cell    : gmsh element type of a cell; gmsh_facet: of a boundary facet.
    """

    name: str
    dim: int = 2
    n_local: int
    n_vertices: int
    order: int
    reference: str
    doflocs: np.ndarray
    edges: np.ndarray
    flip: list[int]
    gmsh_cell: int
    gmsh_facet: int

    @property
    def facet_nodes(self) -> int:
        """Nodes on one boundary facet: order + 1."""
        return self.order + 1

    def shape(self, xi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Values (n_local, n_qp) and reference gradients (n_local, n_qp, dim) at ``xi``
        (n_qp, dim)."""
        raise NotImplementedError

    def quadrature(self) -> tuple[np.ndarray, np.ndarray]:
        """Points (n_qp, dim) and weights (n_qp,) on the reference cell, exact for the
        stiffness integrand on straight-sided cells (simplices, parallelograms or
        parallelepipeds)."""
        raise NotImplementedError

    def mass_quadrature(self) -> tuple[np.ndarray, np.ndarray]:
        """A rule exact for (shape) x (shape) on straight-sided cells: the mass matrix."""
        raise NotImplementedError

    def __repr__(self) -> str:
        return f"{type(self).__name__}()"


def _symmetric_triangle_rule(orbits) -> tuple[np.ndarray, np.ndarray]:
    """Points and weights on the reference triangle (area 1/2) from (a, weight) orbits
    {(a, a), (1 - 2a, a), (a, 1 - 2a)}, weights normalised to a unit-area triangle."""
    pts = [[a, a] for a, _ in orbits] + [[1 - 2 * a, a] for a, _ in orbits] \
        + [[a, 1 - 2 * a] for a, _ in orbits]
    w = [0.5 * wt for _, wt in orbits] * 3
    return np.array(pts), np.array(w)


_TRIANGLE_DEGREE_2 = _symmetric_triangle_rule([(1 / 6, 1 / 3)])
_TRIANGLE_DEGREE_4 = _symmetric_triangle_rule([  # Dunavant (1985), 6 points, degree 4
    (0.445948490915964886318329253883, 0.223381589678011465944640422276),
    (0.091576213509770743459571463402, 0.109951743655321867389035245202)])


class P1(Element):
    name, n_local, n_vertices, order, reference = "P1", 3, 3, 1, "triangle"
    edges = np.array([[0, 1], [1, 2], [2, 0]])
    flip = [0, 2, 1]
    gmsh_cell, gmsh_facet = 2, 1  # triangle, line
    doflocs = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])

    def shape(self, xi):
        x, y = np.asarray(xi, dtype=float).T
        values = np.array([1.0 - x - y, x, y])
        grads = np.broadcast_to(
            np.array([[-1.0, -1.0], [1.0, 0.0], [0.0, 1.0]])[:, None, :], (3, len(x), 2)
        ).copy()
        return values, grads

    def quadrature(self):
        return np.array([[1.0 / 3.0, 1.0 / 3.0]]), np.array([0.5])

    def mass_quadrature(self):
        return _TRIANGLE_DEGREE_2


class P2(Element):
    name, n_local, n_vertices, order, reference = "P2", 6, 3, 2, "triangle"
    edges = np.array([[0, 1, 3], [1, 2, 4], [2, 0, 5]])
    flip = [0, 2, 1, 5, 4, 3]
    gmsh_cell, gmsh_facet = 9, 8  # triangle6, line3
    doflocs = np.array(
        [[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [0.5, 0.0], [0.5, 0.5], [0.0, 0.5]]
    )

    def shape(self, xi):
        x, y = np.asarray(xi, dtype=float).T
        lam = np.array([1.0 - x - y, x, y])  # barycentric coordinates (3, n_qp)
        dlam = np.array([[-1.0, -1.0], [1.0, 0.0], [0.0, 1.0]])  # (3, 2)
        values = np.empty((6, len(x)))
        grads = np.empty((6, len(x), 2))
        for i in range(3):
            values[i] = lam[i] * (2.0 * lam[i] - 1.0)
            grads[i] = (4.0 * lam[i] - 1.0)[:, None] * dlam[i]
        for k, (i, j) in enumerate([(0, 1), (1, 2), (2, 0)]):
            values[3 + k] = 4.0 * lam[i] * lam[j]
            grads[3 + k] = 4.0 * (lam[i][:, None] * dlam[j] + lam[j][:, None] * dlam[i])
        return values, grads

    def quadrature(self):
        return _TRIANGLE_DEGREE_2

    def mass_quadrature(self):
        return _TRIANGLE_DEGREE_4


class _TensorQuad(Element):
    """Lagrange tensor-product element on [-1, 1]^2 with nodes at ``doflocs``."""

    reference, n_vertices = "quad", 4

    def shape(self, xi):
        xi = np.asarray(xi, dtype=float)
        nodes = np.linspace(-1.0, 1.0, self.order + 1)
        vx, dx = _lagrange_1d(xi[:, 0], nodes)
        vy, dy = _lagrange_1d(xi[:, 1], nodes)
        ix = np.rint((self.doflocs[:, 0] + 1.0) * self.order / 2.0).astype(int)
        iy = np.rint((self.doflocs[:, 1] + 1.0) * self.order / 2.0).astype(int)
        values = vx[ix] * vy[iy]
        grads = np.stack([dx[ix] * vy[iy], vx[ix] * dy[iy]], axis=-1)
        return values, grads

    def quadrature(self):
        s, w = gauss_legendre(self.order + 1)
        sx, sy = np.meshgrid(s, s, indexing="ij")
        return np.column_stack([sx.ravel(), sy.ravel()]), np.outer(w, w).ravel()

    def mass_quadrature(self):  # degree 2 order per direction (parallelograms): same rule
        return self.quadrature()


class Q1(_TensorQuad):
    name, n_local, order = "Q1", 4, 1
    edges = np.array([[0, 1], [1, 2], [2, 3], [3, 0]])
    flip = [0, 3, 2, 1]
    gmsh_cell, gmsh_facet = 3, 1  # quadrangle, line
    doflocs = np.array([[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]])


class Q2(_TensorQuad):
    name, n_local, order = "Q2", 9, 2
    edges = np.array([[0, 1, 4], [1, 2, 5], [2, 3, 6], [3, 0, 7]])
    flip = [0, 3, 2, 1, 7, 6, 5, 4, 8]
    gmsh_cell, gmsh_facet = 10, 8  # quadrangle9, line3
    doflocs = np.array(
        [[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0],
         [0.0, -1.0], [1.0, 0.0], [0.0, 1.0], [-1.0, 0.0], [0.0, 0.0]]
    )


ELEMENTS: dict[str, Element] = {"P1": P1(), "P2": P2(), "Q1": Q1(), "Q2": Q2()}
NAMES = tuple(ELEMENTS)  # what a case's [mesh] element may be


ELEMENTS_3D: dict[str, Element] = {}  # the 3D elements by name, filled by .solids


def get_element(name: str, dim: int = 2) -> Element:
    """The element called ``name`` in dimension ``dim``; :class:`CaseError` listing the
    allowed names otherwise."""
    table = ELEMENTS_3D if dim == 3 else ELEMENTS
    try:
        return table[name]
    except (KeyError, TypeError):
        allowed = ", ".join(table) or "none"
        raise CaseError(f"unknown element {name!r}; allowed: {allowed}",
                        key="mesh.element") from None
