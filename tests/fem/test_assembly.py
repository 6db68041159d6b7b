"""Elasticity assembly: the paper's matrices, element properties, patch tests, loads, stresses."""

import itertools

import numpy as np
import pytest
import scipy.sparse as sp

from critfric.errors import CaseError
from critfric.fem.assembly import assemble_elasticity, cell_strain, cell_stress, lame, von_mises
from critfric.fem.elements import get_element
from critfric.fem.loads import body_force_load, traction_load
from critfric.fem.mesh import Mesh

NAMES = ["P1", "P2", "Q1", "Q2"]
LAM_G = [(1.0, 1.0), (2.0, 0.7), (1.3e3, 0.37)]

# ---------------------------------------------------------------- in-code meshes (gmsh order)
# Distorted quadrilateral domain cut into 4 triangles around the interior node 4.
P1_MESH = Mesh(
    points=np.array([[0.0, 0.0], [2.0, 0.0], [2.2, 1.5], [-0.1, 1.8], [0.9, 0.7]]),
    cells=np.array([[0, 1, 4], [1, 2, 4], [2, 3, 4], [3, 0, 4]]),
    element="P1",
    edges={"bottom": np.array([[0, 1]]), "right": np.array([[1, 2]])},
)
# Same triangles with the 8 edge midpoints (nodes 5..12) written out.
P2_MESH = Mesh(
    points=np.array(
        [[0.0, 0.0], [2.0, 0.0], [2.2, 1.5], [-0.1, 1.8], [0.9, 0.7],  # vertices
         [1.0, 0.0], [2.1, 0.75], [1.05, 1.65], [-0.05, 0.9],  # boundary midpoints 01 12 23 30
         [0.45, 0.35], [1.45, 0.35], [1.55, 1.1], [0.4, 1.25]]  # interior midpoints 04 14 24 34
    ),
    cells=np.array(
        [[0, 1, 4, 5, 10, 9], [1, 2, 4, 6, 11, 10], [2, 3, 4, 7, 12, 11], [3, 0, 4, 8, 9, 12]]
    ),
    element="P2",
    edges={"bottom": np.array([[0, 1, 5]]), "right": np.array([[1, 2, 6]])},
)
# 2x2 distorted grid: cell 0 is a non-square parallelogram, the others general convex quads.
Q1_MESH = Mesh(
    points=np.array(
        [[0.0, 0.0], [1.0, 0.0], [2.2, 0.1],
         [0.3, 1.0], [1.3, 1.0], [2.0, 1.2],
         [0.1, 2.1], [1.2, 1.9], [2.3, 2.2]]
    ),
    cells=np.array([[0, 1, 4, 3], [1, 2, 5, 4], [3, 4, 7, 6], [4, 5, 8, 7]]),
    element="Q1",
    edges={"bottom": np.array([[0, 1], [1, 2]])},
)
# A parallelogram (0,1,4,3) and a general convex quad (1,2,5,4) with midpoints and centres.
Q2_MESH = Mesh(
    points=np.array(
        [[0.0, 0.0], [2.0, 0.0], [3.2, -0.3], [0.5, 1.0], [2.5, 1.0], [3.0, 1.4],  # vertices
         [1.0, 0.0], [2.25, 0.5], [1.5, 1.0], [0.25, 0.5],  # midpoints 01, 14 (shared), 43, 30
         [1.25, 0.5],  # centre of the parallelogram
         [2.6, -0.15], [3.1, 0.55], [2.75, 1.2],  # midpoints 12, 25, 54
         [2.675, 0.525]]  # centre of the general quad (mean of its vertices)
    ),
    cells=np.array([[0, 1, 4, 3, 6, 7, 8, 9, 10], [1, 2, 5, 4, 11, 12, 13, 7, 14]]),
    element="Q2",
    edges={"bottom": np.array([[0, 1, 6], [1, 2, 11]])},
)
MESHES = {"P1": P1_MESH, "P2": P2_MESH, "Q1": Q1_MESH, "Q2": Q2_MESH}
INTERIOR = {"P1": [4], "P2": [4, 9, 10, 11, 12], "Q1": [4], "Q2": [7, 10, 14]}
CLOCKWISE = {  # local permutations that reverse a cell's orientation
    "P1": [0, 2, 1],
    "P2": [0, 2, 1, 5, 4, 3],
    "Q1": [0, 3, 2, 1],
    "Q2": [0, 3, 2, 1, 7, 6, 5, 4, 8],
}


# ---------------------------------------------------------------- independent helpers
def vertex_triangles(mesh):
    """Straight triangles (n, 3, 2) covering the mesh (quads split along a diagonal)."""
    X = mesh.points[mesh.cells]
    if get_element(mesh.element).reference == "triangle":
        return X[:, :3]
    return np.concatenate([X[:, [0, 1, 2]], X[:, [0, 2, 3]]])


def exact_integral(mesh, func):
    """Integral of a quadratic ``func(x, y)`` over the mesh (edge-midpoint rule, degree 2)."""
    T = vertex_triangles(mesh)
    e1, e2 = T[:, 1] - T[:, 0], T[:, 2] - T[:, 0]
    area = 0.5 * (e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0])
    mids = [(T[:, a] + T[:, b]) / 2 for a, b in [(0, 1), (1, 2), (2, 0)]]
    return sum(area / 3 * func(m[:, 0], m[:, 1]) for m in mids).sum()


def area(mesh):
    return exact_integral(mesh, lambda x, y: np.ones_like(x))


def linear_field(points, A, b):
    return (points @ np.asarray(A).T + b).ravel()


def quadratic_field(points, C):
    """u_k = sum_m C[k, m] * (1, x, y, x^2, xy, y^2)[m]; returns nodal u and the gradient."""
    def monomials(x, y):
        return np.array([np.ones_like(x), x, y, x * x, x * y, y * y])

    def gradient(x, y):  # (2 components, 2 derivatives, n)
        z, o = np.zeros_like(x), np.ones_like(x)
        dx = np.array([z, o, z, 2 * x, y, z])
        dy = np.array([z, z, o, z, x, 2 * y])
        return np.stack([C @ dx, C @ dy], axis=1)

    u = (C @ monomials(*points.T)).T.ravel()
    return u, gradient


def energy_densities(grad):
    """(div^2, 2 eps:eps) as functions of (x, y) from a displacement gradient function."""
    def div2(x, y):
        g = grad(x, y)
        return (g[0, 0] + g[1, 1]) ** 2

    def two_eps2(x, y):
        g = grad(x, y)
        exy = 0.5 * (g[0, 1] + g[1, 0])
        return 2 * (g[0, 0] ** 2 + g[1, 1] ** 2 + 2 * exy**2)

    return div2, two_eps2


def stiffness(mesh, lam, G):
    K_lam, K_G = assemble_elasticity(mesh)
    return (lam * K_lam + G * K_G).toarray()


def rigid_modes(points):
    x, y = points.T
    one, zero = np.ones_like(x), np.zeros_like(x)
    return [np.column_stack(m).ravel() for m in ([one, zero], [zero, one], [-y, x])]


def test_fixture_meshes_are_straight_sided():
    """Midpoint and centre nodes written above sit where the straight geometry puts them."""
    for mesh, pairs in [(P2_MESH, [(0, 1, 3), (1, 2, 4), (2, 0, 5)]),
                        (Q2_MESH, [(0, 1, 4), (1, 2, 5), (2, 3, 6), (3, 0, 7)])]:
        X = mesh.points[mesh.cells]
        for a, b, m in pairs:
            np.testing.assert_allclose(X[:, m], (X[:, a] + X[:, b]) / 2, atol=1e-15)
    X = Q2_MESH.points[Q2_MESH.cells]
    np.testing.assert_allclose(X[:, 8], X[:, :4].mean(axis=1), atol=1e-15)
    P = Q1_MESH.points[Q1_MESH.cells[0]]
    np.testing.assert_allclose(P[1] - P[0], P[2] - P[3])  # cell 0 is a parallelogram
    assert abs((P[1] - P[0]) @ (P[3] - P[0])) > 0.1  # and not a rectangle


# ---------------------------------------------------------------- the paper's matrices
@pytest.mark.parametrize("lam,G", LAM_G)
def test_paper_one_triangle(lam, G):
    # A=(0,0), B=(-1,0), C=(0,1); counterclockwise order is A, C, B.
    mesh = Mesh(np.array([[0.0, 0.0], [-1.0, 0.0], [0.0, 1.0]]), np.array([[0, 2, 1]]), "P1")
    K = stiffness(mesh, lam, G)
    expected = 0.5 * np.array([[lam + 3 * G, -(lam + G)], [-(lam + G), lam + 3 * G]])
    np.testing.assert_allclose(K[:2, :2], expected, rtol=0, atol=1e-14 * np.abs(expected).max())
    clockwise = Mesh(mesh.points, np.array([[0, 1, 2]]), "P1")
    with pytest.raises(CaseError, match="1 of 1"):
        assemble_elasticity(clockwise)


def paper_square_matrix(l, G):
    return 0.5 * np.array([
        [l + 3 * G, (l + G) / 2, -(l + G), l + G, (-l + G) / 2, -(l + 3 * G)],
        [(l + G) / 2, l + 3 * G, l + G, (l - G) / 2, -(l + G), -(l + 3 * G)],
        [-(l + G), l + G, 4 * l + 12 * G, -(l + 3 * G), -(l + 3 * G), 0],
        [l + G, (l - G) / 2, -(l + 3 * G), l + 3 * G, -(l + G) / 2, -(l + G)],
        [(-l + G) / 2, -(l + G), -(l + 3 * G), -(l + G) / 2, l + 3 * G, l + G],
        [-(l + 3 * G), -(l + 3 * G), 0, -(l + G), l + G, 4 * l + 12 * G],
    ])


@pytest.mark.parametrize("lam,G", LAM_G)
def test_paper_four_triangle_square(lam, G):
    A, B, C, D, O = range(5)
    points = np.array([[0, 0], [1, 0], [1, 1], [0, 1], [0.5, 0.5]], dtype=float)
    mesh = Mesh(points, np.array([[A, B, O], [B, C, O], [C, D, O], [D, A, O]]), "P1")
    K = stiffness(mesh, lam, G)
    dofs = [2 * A + 1, 2 * B + 1, 2 * O, 2 * A, 2 * B, 2 * O + 1]  # A_y, B_y, O_x, A_x, B_x, O_y
    ours = K[np.ix_(dofs, dofs)]
    paper = paper_square_matrix(lam, G)
    tol = 1e-13 * np.abs(paper).max()
    signs = [
        s for s in itertools.product([1.0, -1.0], repeat=6)
        if np.abs(np.outer(s, s) * ours - paper).max() <= tol
    ]
    assert signs, f"no sign matrix D with D K D = paper; max diff {np.abs(ours - paper).max()}"
    # Found: D = identity (up to the irrelevant global sign -I): no row/column flip is needed.
    assert sorted(signs) == [(-1.0,) * 6, (1.0,) * 6]


# ---------------------------------------------------------------- element properties
@pytest.mark.parametrize("name", NAMES)
def test_matrix_format(name):
    mesh = MESHES[name]
    for M in assemble_elasticity(mesh):
        assert isinstance(M, sp.csr_matrix) or M.format == "csr"
        assert M.shape == (2 * mesh.n_nodes, 2 * mesh.n_nodes)
        assert M.dtype == np.float64


def reference_stiffness(mesh, lam, G):
    """Per-cell Voigt-notation assembly (loops; for testing only): B^T C B."""
    element = get_element(mesh.element)
    xi, w = element.quadrature()
    _, dref = element.shape(xi)
    C = np.array([[lam + 2 * G, lam, 0], [lam, lam + 2 * G, 0], [0, 0, G]])
    K = np.zeros((2 * mesh.n_nodes,) * 2)
    for cell in mesh.cells:
        X = mesh.points[cell]
        dofs = np.ravel([[2 * n, 2 * n + 1] for n in cell])
        for q in range(len(w)):
            J = X.T @ dref[:, q, :]
            g = dref[:, q, :] @ np.linalg.inv(J)
            Bm = np.zeros((3, 2 * len(cell)))
            Bm[0, 0::2], Bm[1, 1::2] = g[:, 0], g[:, 1]
            Bm[2, 0::2], Bm[2, 1::2] = g[:, 1], g[:, 0]
            K[np.ix_(dofs, dofs)] += w[q] * np.linalg.det(J) * Bm.T @ C @ Bm
    return K


@pytest.mark.parametrize("name", NAMES)
def test_matches_per_cell_voigt_assembly(name):
    mesh = MESHES[name]
    for lam, G in LAM_G:
        K = stiffness(mesh, lam, G)
        np.testing.assert_allclose(K, reference_stiffness(mesh, lam, G),
                                   atol=1e-13 * np.abs(K).max(), rtol=0)


@pytest.mark.parametrize("name", NAMES)
def test_symmetric_rigid_modes_and_kernel(name):
    mesh = MESHES[name]
    K_lam, K_G = assemble_elasticity(mesh)
    for M in (K_lam, K_G):
        assert abs(M - M.T).max() <= 1e-14 * abs(M).max()
    for lam, G in LAM_G:
        K = stiffness(mesh, lam, G)
        norm = np.linalg.norm(K, 2)
        for mode in rigid_modes(mesh.points):
            assert np.linalg.norm(K @ mode) <= 1e-12 * norm * np.linalg.norm(mode)
        eig = np.linalg.eigvalsh(K)
        assert eig.min() >= -1e-12 * eig.max()
        assert np.sum(np.abs(eig) <= 1e-10 * eig.max()) == 3
        assert eig[3] > 1e-6 * eig.max()


@pytest.mark.parametrize("name", NAMES)
def test_energy_of_linear_field(name):
    mesh = MESHES[name]
    A, b = np.array([[0.3, -0.7], [1.1, 0.2]]), np.array([0.5, -2.0])
    u = linear_field(mesh.points, A, b)
    eps = 0.5 * (A + A.T)
    K_lam, K_G = assemble_elasticity(mesh)
    assert u @ K_lam @ u == pytest.approx(area(mesh) * np.trace(eps) ** 2, rel=1e-13)
    assert u @ K_G @ u == pytest.approx(area(mesh) * 2 * np.sum(eps * eps), rel=1e-13)
    lam, G = 2.0, 0.7
    assert u @ stiffness(mesh, lam, G) @ u == pytest.approx(
        area(mesh) * (lam * np.trace(eps) ** 2 + 2 * G * np.sum(eps * eps)), rel=1e-13
    )


@pytest.mark.parametrize("name", ["P2", "Q2"])
def test_energy_of_quadratic_field(name):
    mesh = MESHES[name]
    C = np.array([[0.1, 0.4, -0.3, 0.7, -1.2, 0.5], [-0.2, 0.9, 0.6, -0.8, 0.3, 1.1]])
    u, grad = quadratic_field(mesh.points, C)
    div2, two_eps2 = energy_densities(grad)
    K_lam, K_G = assemble_elasticity(mesh)
    assert u @ K_lam @ u == pytest.approx(exact_integral(mesh, div2), rel=1e-13)
    assert u @ K_G @ u == pytest.approx(exact_integral(mesh, two_eps2), rel=1e-13)


@pytest.mark.parametrize("name", ["P1", "Q1"])
def test_linear_elements_do_not_reproduce_quadratic_energy(name):
    """Sanity check that the quadratic-energy test can fail."""
    mesh = MESHES[name]
    C = np.array([[0.0, 0.0, 0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 0.0, 0.0, 0.0, 1.0]])
    u, grad = quadratic_field(mesh.points, C)
    _, K_G = assemble_elasticity(mesh)
    assert abs(u @ K_G @ u - exact_integral(mesh, energy_densities(grad)[1])) > 1e-3


@pytest.mark.parametrize("name", NAMES)
def test_displacement_patch_test(name):
    mesh = MESHES[name]
    inner = np.ravel([[2 * n, 2 * n + 1] for n in INTERIOR[name]])
    outer = np.setdiff1d(np.arange(2 * mesh.n_nodes), inner)
    u_exact = linear_field(mesh.points, [[0.3, -0.7], [1.1, 0.2]], [0.5, -2.0])
    K = stiffness(mesh, 2.0, 0.7)
    u_inner = np.linalg.solve(K[np.ix_(inner, inner)], -K[np.ix_(inner, outer)] @ u_exact[outer])
    np.testing.assert_allclose(u_inner, u_exact[inner], atol=1e-12)


@pytest.mark.parametrize("name", NAMES)
def test_k_lam_annihilates_divergence_free_fields(name):
    mesh = MESHES[name]
    K_lam, K_G = assemble_elasticity(mesh)
    fields = [linear_field(mesh.points, [[1.0, 2.0], [-0.5, -1.0]], [0.3, 0.1])]
    if get_element(name).order == 2:  # u = (x^2 + y^2, -2xy): div u = 0
        C = np.array([[0, 0, 0, 1.0, 0, 1.0], [0, 0, 0, 0, -2.0, 0]])
        fields.append(quadratic_field(mesh.points, C)[0])
    for u in fields:
        assert np.abs(K_lam @ u).max() <= 1e-13 * abs(K_lam).max() * np.abs(u).max()
        assert u @ K_G @ u > 1e-3  # not a rigid mode


@pytest.mark.parametrize("name", NAMES)
def test_clockwise_or_degenerate_cell_raises(name):
    mesh = MESHES[name]
    cells = mesh.cells.copy()
    cells[-1] = cells[-1][CLOCKWISE[name]]
    with pytest.raises(CaseError, match=f"1 of {len(cells)} {name} cells"):
        assemble_elasticity(Mesh(mesh.points, cells, name))
    flipped = mesh.cells[:, CLOCKWISE[name]]
    with pytest.raises(CaseError, match=f"{len(cells)} of {len(cells)}"):
        assemble_elasticity(Mesh(mesh.points, flipped, name))
    points = mesh.points.copy()
    points[mesh.cells[0, 1]] = points[mesh.cells[0, 0]]  # collapse an edge of cell 0
    with pytest.raises(CaseError, match="non-positive Jacobian"):
        assemble_elasticity(Mesh(points, mesh.cells, name))


def test_wrong_cell_width_raises():
    seen = []
    with pytest.raises(CaseError, match="needs 6 nodes"):
        assemble_elasticity(Mesh(P1_MESH.points, P1_MESH.cells, "P2"), on_pattern=seen.append)
    assert seen == []  # no pattern from cells of the wrong width


@pytest.mark.parametrize("name", NAMES)
@pytest.mark.parametrize("dim", [2, 3])
def test_upper_pattern_from_the_node_pattern(name, dim):
    """BlockPattern.upper (from the node pattern) is upper_pattern of the DOF pattern,
    restricted and renumbered, for any DOFs dropped (whole nodes or single components)."""
    from critfric.fem.pattern import BlockPattern, upper_pattern

    mesh = MESHES[name]
    pattern = BlockPattern(mesh.cells, mesh.n_nodes, dim)
    n = dim * mesh.n_nodes
    for drop in (np.zeros(n, bool), np.arange(n) % 5 == 1, np.arange(n) // dim == 2):
        position = np.where(drop, -1, np.cumsum(~drop) - 1)
        ptr, col = pattern.upper(position)
        want_ptr, want_col, _ = upper_pattern(pattern.indptr, pattern.indices, position)
        np.testing.assert_array_equal(ptr, want_ptr)
        np.testing.assert_array_equal(col, want_col)
        assert len(ptr) == np.count_nonzero(~drop) + 1 and len(col) > 0


@pytest.mark.parametrize("name", NAMES)
@pytest.mark.parametrize("symmetric", [False, True])
def test_sums_equal_a_coo_sum_for_cells_in_any_order(name, symmetric):
    """Each cell's node pairs are located among the distinct pairs by a search: the sums of
    a component and of its transpose equal scipy's COO sums of duplicates for the cells
    shuffled and each cell's nodes rolled (the pairs then come as (hi, lo) as well as (lo,
    hi)); a symmetric component is read from the local blocks a <= b alone."""
    from critfric.fem.pattern import BlockPattern, local_pairs

    mesh = MESHES[name]
    rng = np.random.default_rng(7)
    cells = np.roll(mesh.cells[rng.permutation(len(mesh.cells))], 1, axis=1)
    pattern = BlockPattern(cells, mesh.n_nodes)
    nl = cells.shape[1]
    values = rng.standard_normal((len(cells), nl, nl))
    if symmetric:
        values += values.transpose(0, 2, 1)
    a, b = local_pairs(nl)
    parts = [values[:, np.arange(nl), np.arange(nl)], values[:, a, b]]
    got = pattern.sums(*parts, None if symmetric else values[:, b, a])
    rows = np.broadcast_to(cells[:, :, None], values.shape).ravel()
    cols = np.broadcast_to(cells[:, None, :], values.shape).ravel()
    for entries, local in zip(got, (values, values.transpose(0, 2, 1))):
        have = sp.csr_matrix((entries, pattern._col, pattern._ptr),
                             shape=(mesh.n_nodes, mesh.n_nodes))
        want = sp.coo_matrix((local.ravel(), (rows, cols)), shape=have.shape).tocsr()
        assert abs(have - want).max() < 1e-12 * abs(want).max()
        assert have.nnz == want.nnz
    assert (got[0] is got[1]) == symmetric


def test_pattern_handed_over_before_the_geometry():
    """on_pattern gets the pattern from the cells alone (a solve starts its factorization's
    analysis there), before the geometry checks the cells: a mesh refused for a clockwise
    cell has had its pattern handed over."""
    mesh = MESHES["P1"]
    cells = mesh.cells.copy()
    cells[-1] = cells[-1][CLOCKWISE["P1"]]
    seen = []
    with pytest.raises(CaseError, match="non-positive Jacobian"):
        assemble_elasticity(Mesh(mesh.points, cells, "P1"), on_pattern=seen.append)
    K_lam, _ = assemble_elasticity(mesh)
    assert len(seen) == 1
    np.testing.assert_array_equal(seen[0].indptr, K_lam.indptr)
    np.testing.assert_array_equal(seen[0].indices, K_lam.indices)


# ---------------------------------------------------------------- loads
@pytest.mark.parametrize("name", NAMES)
def test_traction_load_sums_to_force(name):
    mesh = MESHES[name]
    t = np.array([0.3, -1.7])
    f = traction_load(mesh, "bottom", t)
    ends = mesh.points[mesh.edges["bottom"][:, :2]]
    length = np.linalg.norm(ends[:, 1] - ends[:, 0], axis=1).sum()
    np.testing.assert_allclose(f.reshape(-1, 2).sum(axis=0), t * length, rtol=1e-14)
    touched = np.unique(mesh.edges["bottom"])
    assert np.all(f.reshape(-1, 2)[np.setdiff1d(np.arange(mesh.n_nodes), touched)] == 0)


def test_traction_load_distribution():
    f1 = traction_load(P1_MESH, "right", [1.0, 2.0]).reshape(-1, 2)
    L = np.hypot(0.2, 1.5)
    np.testing.assert_allclose(f1[[1, 2]], [[L / 2, L], [L / 2, L]], rtol=1e-14)
    f2 = traction_load(P2_MESH, "right", [1.0, 0.0]).reshape(-1, 2)[:, 0]
    np.testing.assert_allclose(f2[[1, 2, 6]], [L / 6, L / 6, 2 * L / 3], rtol=1e-14)
    with pytest.raises(CaseError, match="bottom, right"):
        traction_load(P1_MESH, "top", [1.0, 0.0])


@pytest.mark.parametrize("name", NAMES)
def test_body_force_load(name):
    mesh = MESHES[name]
    fb = np.array([-0.4, 2.5])
    f = body_force_load(mesh, fb)
    np.testing.assert_allclose(f.reshape(-1, 2).sum(axis=0), fb * area(mesh), rtol=1e-13)
    # work on a field of the element's degree equals the exact integral of fb . u
    C = np.array([[0.1, 0.4, -0.3, 0.7, -1.2, 0.5], [-0.2, 0.9, 0.6, -0.8, 0.3, 1.1]])
    if get_element(name).order == 1:
        C[:, 3:] = 0.0
    u, _ = quadratic_field(mesh.points, C)

    def work(x, y):
        m = np.array([np.ones_like(x), x, y, x * x, x * y, y * y])
        return fb @ (C @ m)

    assert f @ u == pytest.approx(exact_integral(mesh, work), rel=1e-13)


def test_body_force_distribution_p1_p2():
    one = Mesh(P1_MESH.points, P1_MESH.cells[:1], "P1")
    a = area(one)
    np.testing.assert_allclose(body_force_load(one, [3.0, 0.0])[0::2][[0, 1, 4]], a, rtol=1e-14)
    two = Mesh(P2_MESH.points, P2_MESH.cells[:1], "P2")
    fx = body_force_load(two, [3.0, 0.0])[0::2]
    np.testing.assert_allclose(fx[[0, 1, 4]], 0.0, atol=1e-15)
    np.testing.assert_allclose(fx[[5, 10, 9]], a, rtol=1e-14)


# ---------------------------------------------------------------- stresses
def test_lame():
    assert lame(1.0, 0.25) == pytest.approx((0.4, 0.4), rel=1e-15)
    lam, G = lame(210e9, 0.3)
    assert lam == pytest.approx(210e9 * 0.3 / (1.3 * 0.4)) and G == pytest.approx(210e9 / 2.6)


@pytest.mark.parametrize("name", NAMES)
def test_stress_of_linear_field(name):
    mesh = MESHES[name]
    A = np.array([[0.3, -0.7], [1.1, 0.2]])
    u = linear_field(mesh.points, A, [0.5, -2.0])
    lam, G = 2.0, 0.7
    eps = 0.5 * (A + A.T)
    tr = np.trace(eps)
    expected = [lam * tr + 2 * G * eps[0, 0], lam * tr + 2 * G * eps[1, 1], 2 * G * eps[0, 1],
                lam * tr]
    n_local = get_element(name).n_local
    nodes = cell_stress(mesh, u, lam, G)
    assert nodes.shape == (mesh.n_cells, n_local, 4)
    np.testing.assert_allclose(nodes, np.broadcast_to(expected, nodes.shape), atol=1e-13)
    centre = cell_stress(mesh, u, lam, G, at="centroid")
    assert centre.shape == (mesh.n_cells, 1, 4)
    np.testing.assert_allclose(centre[:, 0], np.broadcast_to(expected, (mesh.n_cells, 4)),
                               atol=1e-13)
    strain = cell_strain(mesh, u, get_element(name).doflocs)
    np.testing.assert_allclose(strain[..., 2], eps[0, 1], atol=1e-14)
    with pytest.raises(CaseError, match="nodes, centroid"):
        cell_stress(mesh, u, lam, G, at="gauss")


def test_stress_of_quadratic_field_at_nodes():
    C = np.array([[0, 0, 0, 1.0, 0, 0], [0, 0, 0, 0, 0, 0]])  # u = (x^2, 0): exx = 2x
    u, _ = quadratic_field(P2_MESH.points, C)
    s = cell_stress(P2_MESH, u, 0.0, 0.5)  # sxx = 2 G exx = exx
    np.testing.assert_allclose(s[..., 0], 2 * P2_MESH.points[P2_MESH.cells, 0], atol=1e-13)


def test_von_mises():
    tau, p = 2.0, 3.0
    np.testing.assert_allclose(von_mises([0, 0, tau, 0]), np.sqrt(3) * tau, rtol=1e-15)
    np.testing.assert_allclose(von_mises([p, p, 0, p]), 0.0, atol=1e-15)
    np.testing.assert_allclose(von_mises([[p, 0, 0, 0]] * 2), [p, p], rtol=1e-15)
    # plane strain: szz enters; uniaxial strain exx with lam = G = 1 gives (3, 1, 0, 1) * exx
    np.testing.assert_allclose(von_mises([3.0, 1.0, 0.0, 1.0]), 2.0, rtol=1e-15)


@pytest.mark.parametrize("element", ["P1", "Q2"])
def test_contact_system_stiffness_is_the_sum_of_its_parts(element):
    """lam K_lam + G K_G entry by entry on the shared sparsity = the sparse sum, bit for bit
    and with its sparsity (no zero entries: they change SuperLU's rounding); a part with
    another sparsity still combines by the sparse sum."""
    import critfric
    from critfric.fem.contact import ContactSystem

    prep = critfric.prepare(critfric.load_case("unit-square", overrides={
        "mesh.size": 0.2, "mesh.element": element}))
    s = prep.system
    K = s.stiffness(2.5, 0.75)
    ref = (2.5 * s.K_lam + 0.75 * s.K_G).tocsr()
    ref.sort_indices()
    assert K.has_sorted_indices and K.nnz == ref.nnz and not np.any(K.data == 0)
    np.testing.assert_array_equal(K.indptr, ref.indptr)
    np.testing.assert_array_equal(K.indices, ref.indices)
    np.testing.assert_array_equal(K.data, ref.data)
    other = s.K_G.copy()
    other.data[0] = 0.0
    other.eliminate_zeros()  # one entry fewer: another sparsity
    mixed = ContactSystem(**{**s.__dict__, "K_G": other})
    np.testing.assert_allclose(mixed.stiffness(2.5, 0.75).toarray(),
                               (2.5 * s.K_lam + 0.75 * other).toarray())
