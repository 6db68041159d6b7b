"""3D elements (tetrahedra, hexahedra) and 3D elasticity: node order against gmsh, shape
functions, quadrature, and the assembled stiffness and mass on small distorted meshes."""

from itertools import permutations
from math import factorial

import gmsh
import numpy as np
import pytest

from critfric.errors import CaseError
from critfric.fem.assembly import (
    assemble_elasticity,
    assemble_mass,
    cell_geometry,
    cell_strain,
    cell_stress,
    von_mises,
)
from critfric.fem.elements import ELEMENTS, ELEMENTS_3D, get_element
from critfric.fem.mesh import Mesh, orient, signed_volumes
from critfric.fem.pattern import BlockPattern
from critfric.fem.solids import face_normals, face_quadrature, face_shape

NAMES = ["P1", "P2", "Q1", "Q2"]
GMSH_TYPES = {"P1": (4, 2), "P2": (11, 9), "Q1": (5, 3), "Q2": (12, 10)}
RNG = np.random.default_rng(3)
# an affine map x -> A x + b applied to the meshes below (det A > 0, not a rotation)
A_MAP = np.array([[1.0, 0.2, 0.1], [0.1, 0.9, -0.15], [0.05, 0.1, 1.1]])
B_MAP = np.array([0.3, -0.2, 0.5])
LAM_G = [(1.0, 1.0), (2.0, 0.7)]


# ---------------------------------------------------------------- in-code meshes
HEX_CORNERS = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0],
                        [0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]])  # gmsh vertex order


def hex_grid(n=2):
    """Points of the n x n x n grid of [0, 1]^3 and its hexahedra (gmsh vertex order)."""
    s = np.linspace(0.0, 1.0, n + 1)
    points = np.stack(np.meshgrid(s, s, s, indexing="ij"), axis=-1).reshape(-1, 3)
    stride = np.array([(n + 1) ** 2, n + 1, 1])
    corner = (np.stack(np.meshgrid(*[np.arange(n)] * 3, indexing="ij"), -1).reshape(-1, 3)
              @ stride)
    return points, corner[:, None] + HEX_CORNERS @ stride


def kuhn_tetrahedra(hexes):
    """Each hexahedron cut into 6 tetrahedra along its diagonal 0-6, in mixed orientations."""
    local = {tuple(c): i for i, c in enumerate(HEX_CORNERS)}
    tets = []
    for perm in permutations(range(3)):
        path = [np.zeros(3, dtype=int)]
        for axis in perm:
            path.append(path[-1] + np.eye(3, dtype=int)[axis])
        tets.append([local[tuple(p)] for p in path])
    return hexes[:, tets].reshape(-1, 4)


def lift(points, cells, name):
    """The mesh of element ``name`` on the vertex cells: every node placed by the cell's
    affine or trilinear map; nodes shared by cells (same supporting vertices) merged."""
    fe = get_element(name, 3)
    linear = get_element("P1" if fe.reference == "tetrahedron" else "Q1", 3)
    N, _ = linear.shape(fe.doflocs)  # (n_vertices, n_local)
    X = np.einsum("cvi,va->cai", points[cells], N).reshape(-1, 3)
    support = np.abs(N.T) > 1e-12  # (n_local, n_vertices): the vertices a node depends on
    keys = np.where(support[None], cells[:, None, :], -1).reshape(-1, cells.shape[1])
    keys = np.sort(keys, axis=1)
    _, first, inverse = np.unique(keys, axis=0, return_index=True, return_inverse=True)
    return X[first], inverse.reshape(len(cells), fe.n_local)


def distorted_mesh(name):
    """``name`` on the 2x2x2 grid of the unit cube (tetrahedra: Kuhn-cut) with its centre
    node moved, mapped by A_MAP, B_MAP; and the mask of its interior nodes."""
    points, hexes = hex_grid(2)
    points[13] += [0.07, -0.05, 0.04]  # the centre: cells no longer parallelepipeds
    tet = name.startswith("P")
    cells = kuhn_tetrahedra(hexes) if tet else hexes
    if tet:
        cells, _ = orient(points, cells, "P1")
    points, cells = lift(points, cells, name)
    inner = np.all((points > 1e-9) & (points < 1 - 1e-9), axis=1)
    return Mesh(points @ A_MAP.T + B_MAP, cells, name), inner


MESHES = {name: distorted_mesh(name) for name in NAMES}
VOLUME = np.linalg.det(A_MAP)  # the unit cube mapped (the moved centre keeps the volume)


def affine_field(points, A, b):
    return (points @ np.asarray(A).T + b).ravel()


def rigid_modes(points):
    x, y, z = points.T
    one, zero = np.ones_like(x), np.zeros_like(x)
    return [np.column_stack(m).ravel() for m in (
        [one, zero, zero], [zero, one, zero], [zero, zero, one],
        [-y, x, zero], [zero, -z, y], [z, zero, -x])]


def voigt(grads):
    """Strain-displacement matrix (6, 3 n) of gradients (n, 3): (xx, yy, zz, 2yz, 2xz, 2xy)."""
    n = len(grads)
    B = np.zeros((6, 3 * n))
    gx, gy, gz = grads.T
    B[0, 0::3], B[1, 1::3], B[2, 2::3] = gx, gy, gz
    B[3, 1::3], B[3, 2::3] = gz, gy
    B[4, 0::3], B[4, 2::3] = gz, gx
    B[5, 0::3], B[5, 1::3] = gy, gx
    return B


def isotropic(lam, G):
    """The 6 x 6 isotropic elasticity matrix for engineering shear strains."""
    D = np.zeros((6, 6))
    D[:3, :3] = lam
    D[np.arange(3), np.arange(3)] += 2 * G
    D[np.arange(3, 6), np.arange(3, 6)] = G
    return D


def stiffness(mesh, lam, G):
    K_lam, K_G = assemble_elasticity(mesh)
    return (lam * K_lam + G * K_G).toarray()


# ---------------------------------------------------------------- the elements
def test_lookup_and_attributes():
    assert list(ELEMENTS_3D) == NAMES
    for name in NAMES:
        e = get_element(name, 3)
        assert e is ELEMENTS_3D[name] and e is not ELEMENTS[name]
        assert e.dim == 3 and e.name == name and e.doflocs.shape == (e.n_local, 3)
        assert (e.gmsh_cell, e.gmsh_facet) == GMSH_TYPES[name]
        assert e.facet is ELEMENTS[name] and e.facet_nodes == ELEMENTS[name].n_local
        assert e.faces.shape == ({"P": 4, "Q": 6}[name[0]], e.facet_nodes)
        assert e.edges.shape == ({"P": 6, "Q": 12}[name[0]], e.order + 1)
    assert get_element("P2", 3).n_local == 10 and get_element("Q2", 3).n_local == 27
    mesh = MESHES["Q1"][0]
    assert mesh.dim == 3 and mesh.fe is ELEMENTS_3D["Q1"]
    with pytest.raises(CaseError, match="P1, P2, Q1, Q2"):
        get_element("P3", 3)


@pytest.fixture(scope="module")
def gmsh_session():
    gmsh.initialize(readConfigFiles=False)
    gmsh.option.setNumber("General.Terminal", 0)
    try:
        yield gmsh
    finally:
        gmsh.finalize()


@pytest.mark.parametrize("name", NAMES)
def test_doflocs_are_gmsh_reference_nodes(name, gmsh_session):
    e = get_element(name, 3)
    for gmsh_type, ours in [(e.gmsh_cell, e.doflocs), (e.gmsh_facet, e.facet.doflocs)]:
        _, dim, order, n_nodes, local, _ = gmsh.model.mesh.getElementProperties(gmsh_type)
        assert (order, n_nodes) == (e.order, len(ours))
        np.testing.assert_array_equal(ours, np.reshape(local, (n_nodes, dim)))


@pytest.mark.parametrize("name", NAMES)
def test_faces_are_gmsh_element_faces(name, gmsh_session):
    """gmsh's own face nodes of a meshed cell, as local indices, are ``faces``."""
    e = get_element(name, 3)
    gmsh.model.add(name)
    try:
        gmsh.model.occ.addBox(0, 0, 0, 1, 1, 1)
        gmsh.model.occ.synchronize()
        gmsh.option.setNumber("Mesh.MeshSizeMin", 2.0)
        gmsh.option.setNumber("Mesh.MeshSizeMax", 2.0)
        if e.reference == "hexahedron":
            gmsh.model.mesh.setTransfiniteAutomatic()
            gmsh.option.setNumber("Mesh.RecombineAll", 1)
        gmsh.model.mesh.generate(3)
        gmsh.model.mesh.setOrder(e.order)
        _, nodes = gmsh.model.mesh.getElementsByType(e.gmsh_cell)
        cell = list(np.reshape(nodes, (-1, e.n_local))[0])
        face_type = 3 if e.facet.reference == "triangle" else 4
        faces = np.reshape(gmsh.model.mesh.getElementFaceNodes(e.gmsh_cell, face_type),
                           (-1, len(e.faces), e.facet_nodes))[0]
        np.testing.assert_array_equal([[cell.index(n) for n in f] for f in faces], e.faces)
    finally:
        gmsh.model.remove()


@pytest.mark.parametrize("name", NAMES)
def test_edges_faces_and_flip_are_consistent(name):
    e = get_element(name, 3)
    X = e.doflocs
    if e.order == 2:  # midpoints sit between their ends; face nodes follow the facet's nodes
        np.testing.assert_allclose(X[e.edges[:, 2]], X[e.edges[:, :2]].mean(axis=1))
    facet = e.facet
    for face in e.faces:
        corners = X[face[:facet.n_vertices]]
        linear = ELEMENTS["P1" if facet.reference == "triangle" else "Q1"]
        N, _ = linear.shape(facet.doflocs)  # the facet's nodes placed by its vertices
        np.testing.assert_allclose(X[face], N.T @ corners, atol=1e-15)
        normal = np.cross(corners[1] - corners[0], corners[-1] - corners[0])
        assert normal @ (corners.mean(axis=0) - X[:e.n_vertices].mean(axis=0)) > 0  # outward
    # flip: the mirror x <-> y of the reference cell, vertex 0 kept
    np.testing.assert_array_equal(X[e.flip], X[:, [1, 0, 2]])
    assert e.flip[0] == 0 and sorted(e.flip) == list(range(e.n_local))


def random_points(e, n=7):
    if e.reference == "tetrahedron":
        p = RNG.random((n, 3))
        return p / np.maximum(1.0, p.sum(axis=1) / RNG.uniform(0.2, 1.0, n))[:, None]
    return RNG.uniform(-1, 1, (n, 3))


def monomials(e):
    p = e.order
    if e.reference == "tetrahedron":
        return [(i, j, k) for i in range(p + 1) for j in range(p + 1) for k in range(p + 1)
                if i + j + k <= p]
    return [(i, j, k) for i in range(p + 1) for j in range(p + 1) for k in range(p + 1)]


@pytest.mark.parametrize("name", NAMES)
def test_shape_functions(name):
    e = get_element(name, 3)
    values, _ = e.shape(e.doflocs)
    np.testing.assert_allclose(values, np.eye(e.n_local), atol=1e-14)  # N_a(x_b) = delta_ab
    xi = random_points(e)
    values, grads = e.shape(xi)
    assert values.shape == (e.n_local, 7) and grads.shape == (e.n_local, 7, 3)
    np.testing.assert_allclose(values.sum(axis=0), 1.0, atol=1e-13)
    np.testing.assert_allclose(grads.sum(axis=0), 0.0, atol=1e-12)
    for i, j, k in monomials(e):  # the element's polynomial space is reproduced
        nodal = np.prod(e.doflocs ** [i, j, k], axis=1)
        np.testing.assert_allclose(nodal @ values, np.prod(xi ** [i, j, k], axis=1), atol=1e-13)
    h = 1e-6
    for k in range(3):
        step = np.zeros(3)
        step[k] = h
        fd = (e.shape(xi + step)[0] - e.shape(xi - step)[0]) / (2 * h)
        np.testing.assert_allclose(grads[:, :, k], fd, atol=1e-8)


def reference_integral(reference, i, j, k):
    if reference == "tetrahedron":
        return factorial(i) * factorial(j) * factorial(k) / factorial(i + j + k + 3)
    one_d = lambda m: 0.0 if m % 2 else 2.0 / (m + 1)
    return one_d(i) * one_d(j) * one_d(k)


# (name, rule, claimed degree): total degree on the tetrahedron, per variable on the cube
RULES = [("P1", "quadrature", 1), ("P1", "mass_quadrature", 2), ("P2", "quadrature", 2),
         ("P2", "mass_quadrature", 5), ("Q1", "quadrature", 3), ("Q1", "mass_quadrature", 3),
         ("Q2", "quadrature", 5), ("Q2", "mass_quadrature", 5)]


@pytest.mark.parametrize("name,rule,degree", RULES)
def test_quadrature_exactness(name, rule, degree):
    e = get_element(name, 3)
    points, weights = getattr(e, rule)()
    assert points.shape == (len(weights), 3) and np.all(weights > 0)
    tet = e.reference == "tetrahedron"
    for i, j, k in np.ndindex(degree + 1, degree + 1, degree + 1):
        if tet and i + j + k > degree:
            continue
        approx = weights @ np.prod(points ** [i, j, k], axis=1)
        assert approx == pytest.approx(reference_integral(e.reference, i, j, k), rel=1e-14,
                                       abs=1e-15)
    if tet:  # and not more: the claimed degree is the rule's
        exact = [reference_integral(e.reference, *m) for m in [(degree + 1, 0, 0),
                                                                (degree - 1, 2, 0)]]
        moments = [weights @ points[:, 0] ** (degree + 1),
                   weights @ (points[:, 0] ** (degree - 1) * points[:, 1] ** 2)]
        assert max(abs(a - b) for a, b in zip(moments, exact)) > 1e-6


@pytest.mark.parametrize("name", NAMES)
def test_face_shape_quadrature_and_normals(name):
    """Over the faces of one straight-sided cell: int n dS = 0 and int x . n dS = 3 V."""
    e = get_element(name, 3)
    s, w = face_quadrature(e)
    values, grads = face_shape(e, s)
    np.testing.assert_allclose(values.sum(axis=0), 1.0, atol=1e-14)
    assert grads.shape == (e.facet_nodes, len(w), 2)
    # int N_a over the reference face: the facet element's own rule gives the same
    np.testing.assert_allclose(values @ w, e.facet.shape(e.facet.quadrature()[0])[0]
                               @ e.facet.quadrature()[1], atol=1e-15)
    points = e.doflocs @ A_MAP.T + B_MAP  # one cell, the reference mapped
    n = face_normals(points, e.faces, e, s)  # (n_faces, n_qp, 3)
    volume = np.linalg.det(A_MAP) * (1 / 6 if e.reference == "tetrahedron" else 8)
    np.testing.assert_allclose(np.einsum("fqi,q->i", n, w), 0.0, atol=1e-14)
    x = np.einsum("fai,aq->fqi", points[e.faces], values)
    assert np.einsum("fqi,fqi,q->", x, n, w) == pytest.approx(3 * volume, rel=1e-14)


# ---------------------------------------------------------------- mesh geometry
def test_signed_volumes_orient_and_diameter():
    points, hexes = hex_grid(1)
    assert signed_volumes(points, hexes, "Q1") == pytest.approx([1.0], rel=1e-15)
    assert signed_volumes(points, hexes[:, ELEMENTS_3D["Q1"].flip], "Q1") == pytest.approx(
        [-1.0], rel=1e-15)
    tets = kuhn_tetrahedra(hexes)
    vol = signed_volumes(points, tets, "P1")
    np.testing.assert_allclose(np.abs(vol), 1 / 6, rtol=1e-15)
    assert 0 < np.sum(vol > 0) < 6  # the fixture mixes orientations
    fixed, before = orient(points, tets, "P1")
    np.testing.assert_array_equal(before, vol)
    np.testing.assert_allclose(signed_volumes(points, fixed, "P1"), 1 / 6, rtol=1e-15)
    np.testing.assert_array_equal(fixed[vol > 0], tets[vol > 0])
    assert Mesh(points, hexes, "Q1").diameter == pytest.approx(np.sqrt(3), rel=1e-15)
    assert Mesh(points, fixed, "P1").diameter == pytest.approx(np.sqrt(3), rel=1e-15)
    mesh = MESHES["Q2"][0]
    assert signed_volumes(mesh.points, mesh.cells, "Q2").sum() == pytest.approx(VOLUME, 1e-14)


def test_cell_geometry_gradients():
    mesh = MESHES["Q1"][0]
    e = mesh.fe
    xi = random_points(e, 4)
    _, det, grads = cell_geometry(mesh, xi)
    _, dref = e.shape(xi)
    X = mesh.points[mesh.cells]
    J = np.einsum("cai,aqj->cqij", X, dref)
    np.testing.assert_allclose(det, np.linalg.det(J), rtol=1e-13)
    expected = np.einsum("aqj,cqji->cqai", dref, np.linalg.inv(J))
    np.testing.assert_allclose(grads, expected, atol=1e-13)


# ---------------------------------------------------------------- stiffness and mass
@pytest.mark.parametrize("lam,G", LAM_G)
def test_one_tetrahedron_closed_form(lam, G):
    X = np.array([[0.1, 0.0, 0.2], [1.3, 0.1, -0.1], [0.2, 0.9, 0.3], [0.3, 0.2, 1.4]])
    coefficients = np.linalg.inv(np.column_stack([np.ones(4), X]))  # N_a = c0a + c_a . x
    volume = np.linalg.det(np.column_stack([np.ones(4), X])) / 6
    assert volume > 0
    B = voigt(coefficients[1:].T)
    expected = volume * B.T @ isotropic(lam, G) @ B
    K = stiffness(Mesh(X, np.array([[0, 1, 2, 3]]), "P1"), lam, G)
    np.testing.assert_allclose(K, expected, rtol=0, atol=1e-14 * np.abs(expected).max())


def reference_stiffness(mesh, lam, G):
    """Per-cell Voigt assembly (loops; for testing only): sum_q w det J B^T D B."""
    e = mesh.fe
    xi, w = e.quadrature()
    _, dref = e.shape(xi)
    D = isotropic(lam, G)
    K = np.zeros((3 * mesh.n_nodes,) * 2)
    for cell in mesh.cells:
        dofs = (3 * cell[:, None] + np.arange(3)).ravel()
        for q in range(len(w)):
            J = mesh.points[cell].T @ dref[:, q, :]
            B = voigt(dref[:, q, :] @ np.linalg.inv(J))
            K[np.ix_(dofs, dofs)] += w[q] * np.linalg.det(J) * B.T @ D @ B
    return K


@pytest.mark.parametrize("name", NAMES)
def test_matches_per_cell_voigt_assembly(name):
    mesh, _ = MESHES[name]
    for lam, G in LAM_G:
        K = stiffness(mesh, lam, G)
        assert K.shape == (3 * mesh.n_nodes,) * 2
        np.testing.assert_allclose(K, reference_stiffness(mesh, lam, G),
                                   rtol=0, atol=1e-13 * np.abs(K).max())


@pytest.mark.parametrize("name", NAMES)
def test_symmetric_with_six_rigid_modes(name):
    mesh, _ = MESHES[name]
    K_lam, K_G = assemble_elasticity(mesh)
    for M in (K_lam, K_G):
        assert abs(M - M.T).max() <= 1e-14 * abs(M).max()
    # K_G = B^T + tr(B) I node block by node block, B the block of K_lam
    Kl, Kg = K_lam.toarray(), K_G.toarray()
    a, b = 4, mesh.cells[0, 1]
    block = Kl[3 * a:3 * a + 3, 3 * b:3 * b + 3]
    np.testing.assert_allclose(Kg[3 * a:3 * a + 3, 3 * b:3 * b + 3],
                               block.T + np.trace(block) * np.eye(3), atol=1e-14)
    K = stiffness(mesh, 2.0, 0.7)
    norm = np.linalg.norm(K, 2)
    for mode in rigid_modes(mesh.points):
        assert np.linalg.norm(K @ mode) <= 1e-12 * norm * np.linalg.norm(mode)
    eig = np.linalg.eigvalsh(K)
    assert eig.min() >= -1e-12 * eig.max()
    assert np.sum(np.abs(eig) <= 1e-10 * eig.max()) == 6
    assert eig[6] > 1e-6 * eig.max()


@pytest.mark.parametrize("name", NAMES)
def test_patch_test_and_energy_of_affine_field(name):
    mesh, inner = MESHES[name]
    assert inner.sum() >= 1
    A, b = np.array([[0.3, -0.7, 0.2], [1.1, 0.2, -0.4], [0.5, 0.6, -0.9]]), [0.5, -2.0, 1.0]
    u = affine_field(mesh.points, A, b)
    K = stiffness(mesh, 2.0, 0.7)
    residual = (K @ u).reshape(-1, 3)
    assert np.abs(residual[inner]).max() <= 1e-13 * np.abs(K).max() * np.abs(u).max()
    assert np.abs(residual[~inner]).max() > 1e-3  # boundary tractions: the test can fail
    eps = 0.5 * (A + A.T)
    K_lam, K_G = assemble_elasticity(mesh)
    assert u @ K_lam @ u == pytest.approx(VOLUME * np.trace(eps) ** 2, rel=1e-12)
    assert u @ K_G @ u == pytest.approx(VOLUME * 2 * np.sum(eps * eps), rel=1e-12)


@pytest.mark.parametrize("name", NAMES)
def test_mass_matrix(name):
    mesh, _ = MESHES[name]
    M = assemble_mass(mesh, density=2.5)
    assert M.shape == (3 * mesh.n_nodes,) * 2 and abs(M - M.T).max() <= 1e-15
    ones = np.ones(3 * mesh.n_nodes)
    assert ones @ M @ ones == pytest.approx(3 * 2.5 * VOLUME, rel=1e-13)
    x = np.zeros((mesh.n_nodes, 3))
    x[:, 1] = mesh.points[:, 0]  # u = (0, x, 0): int x^2 over the body, components apart
    Mx = M @ x.ravel()
    assert np.abs(Mx.reshape(-1, 3)[:, [0, 2]]).max() == 0.0
    one_y = np.tile([0.0, 1.0, 0.0], mesh.n_nodes)
    centroid_x = (one_y @ Mx) / (2.5 * VOLUME)
    assert centroid_x == pytest.approx((A_MAP @ [0.5, 0.5, 0.5] + B_MAP)[0], rel=1e-13)


def test_one_tetrahedron_mass_closed_form():
    X = np.array([[0.1, 0.0, 0.2], [1.3, 0.1, -0.1], [0.2, 0.9, 0.3], [0.3, 0.2, 1.4]])
    volume = np.linalg.det(np.column_stack([np.ones(4), X])) / 6
    M = assemble_mass(Mesh(X, np.array([[0, 1, 2, 3]]), "P1"), density=2.0).toarray()
    scalar = 2.0 * volume / 20 * (np.ones((4, 4)) + np.eye(4))
    np.testing.assert_allclose(M[1::3, 1::3], scalar, rtol=1e-14)


@pytest.mark.parametrize("name", NAMES)
def test_inverted_cell_raises(name):
    mesh, _ = MESHES[name]
    cells = mesh.cells.copy()
    cells[-1] = cells[-1][mesh.fe.flip]
    with pytest.raises(CaseError, match=f"1 of {len(cells)} {name} cells have a non-positive"):
        assemble_elasticity(Mesh(mesh.points, cells, name))


def test_block_pattern_3d():
    mesh, _ = MESHES["P1"]
    pattern = BlockPattern(mesh.cells, mesh.n_nodes, dim=3)
    q = np.arange(pattern.nnz)
    A = pattern.csr([[9.0 * q + 3 * k + m + 1 for m in range(3)] for k in range(3)])
    assert A.shape == (3 * mesh.n_nodes,) * 2 and A.nnz == 9 * pattern.nnz
    assert A.has_sorted_indices
    dense = A.toarray()
    adjacency = np.zeros((mesh.n_nodes,) * 2, dtype=bool)
    adjacency[mesh.cells[:, :, None], mesh.cells[:, None, :]] = True
    # block q of node pair (i, j): entry (3i + k, 3j + m) holds 9 q + 3k + m + 1
    for k in range(3):
        for m in range(3):
            part = dense[k::3, m::3]
            np.testing.assert_array_equal(part > 0, adjacency)
            np.testing.assert_array_equal((part[adjacency] - 1 - 3 * k - m) % 9, 0)
            np.testing.assert_array_equal(part[adjacency], dense[0::3, 0::3][adjacency]
                                          + 3 * k + m)
    assert len(np.unique(dense[0::3, 0::3][adjacency])) == pattern.nnz


# ---------------------------------------------------------------- strains and stresses
@pytest.mark.parametrize("name", NAMES)
def test_stress_of_affine_field(name):
    mesh, _ = MESHES[name]
    A = np.array([[0.3, -0.7, 0.2], [1.1, 0.2, -0.4], [0.5, 0.6, -0.9]])
    u = affine_field(mesh.points, A, [0.5, -2.0, 1.0])
    eps = 0.5 * (A + A.T)
    lam, G = 2.0, 0.7
    sigma = lam * np.trace(eps) * np.eye(3) + 2 * G * eps
    order = [(0, 0), (1, 1), (2, 2), (1, 2), (0, 2), (0, 1)]
    strain = cell_strain(mesh, u, mesh.fe.doflocs)
    assert strain.shape == (mesh.n_cells, mesh.fe.n_local, 6)
    np.testing.assert_allclose(strain, np.broadcast_to([eps[i, j] for i, j in order],
                                                       strain.shape), atol=1e-13)
    for at in ("nodes", "centroid"):
        s = cell_stress(mesh, u, lam, G, at=at)
        assert s.shape == (mesh.n_cells, mesh.fe.n_local if at == "nodes" else 1, 6)
        np.testing.assert_allclose(s, np.broadcast_to([sigma[i, j] for i, j in order], s.shape),
                                   atol=1e-13)


def test_von_mises_3d():
    tau, p = 2.0, 3.0
    for k in (3, 4, 5):  # each shear component
        s = np.zeros(6)
        s[k] = tau
        assert von_mises(s) == pytest.approx(np.sqrt(3) * tau, rel=1e-15)
    assert von_mises([p, p, p, 0, 0, 0]) == pytest.approx(0.0, abs=1e-15)
    np.testing.assert_allclose(von_mises([[p, 0, 0, 0, 0, 0]] * 2), [p, p], rtol=1e-15)
    # the plane-strain 4-component form is the 3D one with syz = sxz = 0
    s4 = np.array([3.0, 1.0, 0.5, -0.7])  # sxx, syy, sxy, szz
    s6 = np.array([3.0, 1.0, -0.7, 0.0, 0.0, 0.5])
    assert von_mises(s6) == pytest.approx(von_mises(s4), rel=1e-15)
    # a general stress: sqrt(3/2 s_dev : s_dev)
    S = np.array([[1.0, 0.4, -0.3], [0.4, -2.0, 0.8], [-0.3, 0.8, 0.5]])
    dev = S - np.trace(S) / 3 * np.eye(3)
    s6 = [S[0, 0], S[1, 1], S[2, 2], S[1, 2], S[0, 2], S[0, 1]]
    assert von_mises(s6) == pytest.approx(np.sqrt(1.5 * np.sum(dev * dev)), rel=1e-14)
