"""The 3D contact plane: normal, in-plane axes, slip directions and the n/s/e basis."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
from scipy.spatial.transform import Rotation

from critfric.errors import CaseError
from critfric.fem.assembly import lame
from critfric.fem.contact3d import contact_layout3d, contact_system3d, plane_axes
from critfric.fem.mesh import Mesh


def tet_parts(points: np.ndarray, tets: np.ndarray) -> list[sp.csr_matrix]:
    """K_lam, K_G of P1 tetrahedra, written out: K = V B^T D B with constant gradients g_a,
    K_lam[3a+i, 3b+j] = V g_ai g_bj, K_G[3a+i, 3b+j] = V (delta_ij g_a.g_b + g_aj g_bi)."""
    X = points[tets]
    J = np.stack([X[:, 1] - X[:, 0], X[:, 2] - X[:, 0], X[:, 3] - X[:, 0]], axis=2)
    vol = np.abs(np.linalg.det(J)) / 6.0
    g = np.einsum("aj,cjx->cax", np.array([[-1.0, -1, -1], [1, 0, 0], [0, 1, 0], [0, 0, 1]]),
                  np.linalg.inv(J))
    Kl = np.einsum("c,cai,cbj->caibj", vol, g, g)
    KG = np.einsum("c,cab,ij->caibj", vol, np.einsum("cak,cbk->cab", g, g), np.eye(3)) \
        + np.einsum("c,caj,cbi->caibj", vol, g, g)
    dofs = (3 * tets[:, :, None] + np.arange(3)).reshape(len(tets), 12)
    rows, cols = np.repeat(dofs, 12, axis=1).ravel(), np.tile(dofs, (1, 12)).ravel()
    n = 3 * len(points)
    return [sp.csr_matrix((M.reshape(-1), (rows, cols)), shape=(n, n)) for M in (Kl, KG)]


def corner_tet(rotation: np.ndarray | None = None) -> Mesh:
    """Vertices 0, e_x, e_y, e_z (optionally rotated); face (0, e_x, e_z) in contact, face
    (e_x, e_y, e_z) clamped: the origin is the one contact node."""
    pts = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]])
    if rotation is not None:
        pts = pts @ rotation.T
    return Mesh(pts, np.array([[0, 1, 2, 3]]), "P1",
                faces={"contact": np.array([[0, 1, 3]]), "clamp": np.array([[1, 2, 3]])})


def box_mesh(nx: int = 3, ny: int = 3, nz: int = 2, size=(1.0, 1.0, 1.0)) -> Mesh:
    """A box of nx ny nz cubes, each cut into 6 tetrahedra around its main diagonal
    (positive volumes), with the boundary triangles of its faces z = 0 "bottom", z = top
    "top", x = 0 "left"."""
    axes = [np.linspace(0.0, s, k + 1) for s, k in zip(size, (nx, ny, nz))]
    pts = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    idx = np.arange(len(pts)).reshape(nx + 1, ny + 1, nz + 1)
    corner = np.stack([idx[i:i + nx, j:j + ny, k:k + nz].ravel() for i, j, k in
                       np.ndindex(2, 2, 2)], axis=1)  # bit order (x, y, z) -> 4x + 2y + z
    paths = [(0, 4, 6, 7), (0, 4, 5, 7), (0, 2, 6, 7), (0, 2, 3, 7), (0, 1, 5, 7),
             (0, 1, 3, 7)]
    tets = np.concatenate([corner[:, list(p)] for p in paths])
    X = pts[tets]
    neg = np.einsum("ci,ci->c", X[:, 1] - X[:, 0],
                    np.cross(X[:, 2] - X[:, 0], X[:, 3] - X[:, 0])) < 0
    tets[neg] = tets[neg][:, [0, 2, 1, 3]]

    def squares(a, b, c, d):
        return np.concatenate([np.column_stack([a, b, d]), np.column_stack([a, c, d])])

    bottom = squares(*(idx[i:i + nx, j:j + ny, 0].ravel() for i, j in np.ndindex(2, 2)))
    top = squares(*(idx[i:i + nx, j:j + ny, nz].ravel() for i, j in np.ndindex(2, 2)))
    left = squares(*(idx[0, j:j + ny, k:k + nz].ravel() for j, k in np.ndindex(2, 2)))
    return Mesh(pts, tets, "P1", faces={"bottom": bottom, "top": top, "left": left})


def test_corner_tet_plane_and_basis():
    mesh = corner_tet()
    Kl, KG = tet_parts(mesh.points, mesh.cells)
    s = contact_system3d(mesh, Kl, KG, contact=["contact"], dirichlet=["clamp"], angle=30.0)
    np.testing.assert_array_equal(s.nodes, [0])
    assert np.array_equal(s.normal, [0.0, -1.0, 0.0])  # outward: the body is at y > 0
    assert np.array_equal(s.tangent, [1.0, 0.0, 0.0])  # t1 = e_x; t2 = n x t1 = e_z
    np.testing.assert_allclose(s.slip, [[np.cos(np.pi / 6), 0.0, np.sin(np.pi / 6)]],
                               atol=1e-16)
    np.testing.assert_array_equal(s.free, [0, 1, 2])
    np.testing.assert_array_equal(s.fixed, np.arange(3, 12))
    assert (s.cn[0], s.ct[0], s.ce[0]) == (0, 1, 2)
    F = s.frames[0]  # rows n, s, e: orthonormal, right-handed
    np.testing.assert_allclose(F @ F.T, np.eye(3), atol=1e-15)
    assert np.linalg.det(F) == pytest.approx(1.0)
    # the node's 3x3 block in the (n, s, e) basis
    K = s.stiffness(*lame(1.0, 0.3))
    Kxyz = (lame(1.0, 0.3)[0] * Kl + lame(1.0, 0.3)[1] * KG).toarray()[:3, :3]
    np.testing.assert_allclose(K.toarray(), F @ Kxyz @ F.T, rtol=1e-14, atol=1e-15)


@pytest.mark.parametrize("normal, t1", [
    ([0, -1, 0], [1, 0, 0]), ([0, 0, -1], [1, 0, 0]), ([1, 0, 0], [0, 1, 0]),
    ([-1, 0, 0], [0, 1, 0]), ([0.6, 0.8, 0], [0.8, -0.6, 0]), ([0.6, -0.8, 0], [0.8, 0.6, 0])])
def test_plane_axes(normal, t1):
    a1, a2 = plane_axes(np.array(normal, dtype=float))
    np.testing.assert_allclose(a1, t1, atol=1e-15)
    np.testing.assert_allclose(a2, np.cross(normal, t1), atol=1e-15)


def test_t1_against_the_2d_tangent_of_an_extruded_body():
    """2D: t = (-n2, n1) = e_z x n. t1 equals it for n2 < 0 (a contact face below the body)
    and for n = +e_x, and is its opposite for n2 > 0 and n = -e_x."""
    for a in np.linspace(0.0, 2 * np.pi, 37):
        n = np.array([np.cos(a), np.sin(a), 0.0])
        t2d = np.array([-n[1], n[0], 0.0])
        t1, _ = plane_axes(n)
        sign = -np.sign(n[1]) if abs(n[1]) > 1e-9 else np.sign(n[0])
        np.testing.assert_allclose(t1, sign * t2d, atol=1e-12)


def test_random_plane_axes_are_the_projection_of_e_x():
    rng = np.random.default_rng(3)
    for n in rng.standard_normal((20, 3)):
        n /= np.linalg.norm(n)
        t1, t2 = plane_axes(n)
        proj = np.array([1.0, 0, 0]) - n[0] * n
        np.testing.assert_allclose(t1, proj / np.linalg.norm(proj), atol=1e-14)
        np.testing.assert_allclose(np.linalg.det(np.stack([n, t1, t2])), 1.0)


def test_box_bottom_normal_axes_and_dirichlet_dofs():
    mesh = box_mesh()
    layout = contact_layout3d(mesh, contact=["bottom"], dirichlet=["left"], angle=90.0)
    assert np.array_equal(layout.normal, [0.0, 0.0, -1.0])
    assert np.array_equal(layout.tangent, [1.0, 0.0, 0.0])
    np.testing.assert_array_equal(layout.slip, np.tile([0.0, -1.0, 0.0], (12, 1)))  # t2 = -e_y
    left = np.unique(mesh.faces["left"])
    on_bottom = np.unique(mesh.faces["bottom"])
    np.testing.assert_array_equal(np.sort(layout.nodes), np.setdiff1d(on_bottom, left))
    x = mesh.points[layout.nodes]  # sorted along t1 = x, then t2 = -y
    assert np.all(np.diff(x[:, 0]) >= 0)
    assert np.all(np.diff(-x[:, 1])[np.diff(x[:, 0]) == 0] > 0)
    fixed = np.zeros(3 * mesh.n_nodes, dtype=bool)
    fixed[(3 * left[:, None] + np.arange(3)).ravel()] = True
    np.testing.assert_array_equal(layout.fixed, fixed)


def test_slip_given_by_direction_vectors():
    mesh = box_mesh()
    d = np.array([1.0, 1.0, 5.0])  # projected on z = 0, normalised
    lay = contact_layout3d(mesh, contact=["bottom"], dirichlet=["top"], direction=d)
    np.testing.assert_allclose(lay.slip, np.tile([2 ** -0.5, 2 ** -0.5, 0.0], (16, 1)))
    per_node = np.random.default_rng(0).standard_normal((16, 3))
    lay = contact_layout3d(mesh, contact=["bottom"], dirichlet=["top"], direction=per_node)
    expect = per_node * [1, 1, 0] / np.linalg.norm(per_node[:, :2], axis=1)[:, None]
    np.testing.assert_allclose(lay.slip, expect, atol=1e-15)
    angles = np.linspace(0, 350, 16)
    lay = contact_layout3d(mesh, contact=["bottom"], dirichlet=["top"], angle=angles)
    t = np.radians(angles)
    np.testing.assert_allclose(lay.slip, np.column_stack([np.cos(t), -np.sin(t), 0 * t]),
                               atol=1e-15)


@pytest.mark.parametrize("kwargs, key", [
    ({"contact": ["bottom", "left"]}, "boundary.contact"),  # two planes
    ({"contact": ["nope"]}, "boundary.contact"),
    ({"dirichlet": ["nope"]}, "boundary.dirichlet"),
    ({"direction": [0.0, 0.0, 1.0]}, "contact.direction"),  # normal to the plane
    ({"direction": np.ones((3, 3))}, "contact.direction"),
    ({"angle": [0.0, 90.0]}, "contact.angle"),
    ({"angle": float("nan")}, "contact.angle"),
])
def test_bad_contact_input_is_a_case_error(kwargs, key):
    args = {"contact": ["bottom"], "dirichlet": ["top"], **kwargs}
    with pytest.raises(CaseError) as err:
        contact_layout3d(box_mesh(), **args)
    assert err.value.key == key


def test_contact_face_inside_the_body_is_refused():
    mesh = box_mesh(nz=2)
    inner = mesh.faces["bottom"] + 1  # node (i, j, k) + 1 is (i, j, k + 1): the plane z = 1/2
    assert np.all(mesh.points[inner, 2] == 0.5)
    mesh = Mesh(mesh.points, mesh.cells, "P1", faces={**mesh.faces, "inner": inner})
    with pytest.raises(CaseError, match="cells on both sides") as err:
        contact_layout3d(mesh, contact=["inner"], dirichlet=["top"])
    assert err.value.key == "boundary.contact"


def test_in_place_rotation_equals_the_sparse_product():
    """Full 3x3 blocks are rotated in place; without them (zeros dropped) by Q^T K Q: the
    same matrices, and the same as restrict()."""
    mesh = box_mesh()
    Kl, KG = tet_parts(mesh.points, mesh.cells)
    bc = {"contact": ["bottom"], "dirichlet": ["top"], "angle": np.linspace(10, 300, 16)}
    full = contact_system3d(mesh, Kl, KG, **bc)
    dropped = [sp.csr_matrix(A.toarray()) for A in (Kl, KG)]
    assert dropped[0].nnz < Kl.nnz
    products = contact_system3d(mesh, *dropped, **bc)
    for a, b, A in ((full.K_lam, products.K_lam, Kl), (full.K_G, products.K_G, KG)):
        np.testing.assert_allclose(a.toarray(), b.toarray(), atol=1e-14)
        np.testing.assert_allclose(full.restrict(A).toarray(), a.toarray(), atol=1e-14)
    np.testing.assert_allclose(full.D_lam.toarray(), products.D_lam.toarray(), atol=1e-14)


def test_to_and_from_xyz_are_inverse_and_keep_the_energy():
    mesh = box_mesh()
    Kl, KG = tet_parts(mesh.points, mesh.cells)
    s = contact_system3d(mesh, Kl, KG, contact=["bottom"], dirichlet=["top"], angle=47.0)
    rng = np.random.default_rng(1)
    u = rng.standard_normal((2, mesh.n_nodes, 3))
    u[:, np.unique(mesh.faces["top"])] = 0.0
    v = s.from_xy(u.reshape(2, -1))
    np.testing.assert_allclose(s.to_xy(v), u, atol=1e-14)
    lam, G = lame(1.0, 0.3)
    K3 = (lam * Kl + G * KG)
    np.testing.assert_allclose(np.einsum("ki,ki->k", v, (s.stiffness(lam, G) @ v.T).T),
                               np.einsum("ki,ki->k", u.reshape(2, -1), (K3 @ u.reshape(2, -1).T).T))
    only = np.zeros(s.n_dofs)
    only[s.ct] = 1.0  # unit displacement along s at every contact node
    np.testing.assert_allclose(s.to_xy(only)[s.nodes], s.slip, atol=1e-15)


def test_rotated_body_keeps_its_contact_geometry():
    R = Rotation.random(random_state=7).as_matrix()
    mesh = corner_tet(R)
    lay = contact_layout3d(mesh, contact=["contact"], dirichlet=["clamp"], direction=R[:, 0])
    np.testing.assert_allclose(lay.normal, -R[:, 1], atol=1e-15)
    np.testing.assert_allclose(lay.slip[0], R[:, 0], atol=1e-15)
