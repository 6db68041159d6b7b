"""The 3D eigenproblems (rate and frozen slip laws): closed forms, symmetries, independent
formulations, and the 2D problem as a periodic extrusion."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
import scipy.linalg as la
import scipy.sparse as sp
from fem.test_contact3d import box_mesh, corner_tet, tet_parts
from helpers import four_triangles_alpha
from scipy.spatial.transform import Rotation

from critfric.errors import CaseError
from critfric.fem.assembly import assemble_elasticity, lame
from critfric.fem.contact import FREE, SLIP, STUCK, contact_system
from critfric.fem.contact3d import contact_layout3d, contact_system3d
from critfric.fem.elements import ELEMENTS_3D
from critfric.fem.mesh import Mesh
from critfric.solvers import eigen
from critfric.solvers.backends import available_backends
from critfric.solvers.eigen import ContactState

LAWS = ("rate", "frozen")


def same_spectrum(a, b, rtol):
    """Two lists of (complex) eigenvalues agree as multisets."""
    a, b = np.sort_complex(np.asarray(a)), np.sort_complex(np.asarray(b))
    assert len(a) == len(b), (a, b)
    for x in a:
        assert np.min(np.abs(b - x)) <= rtol * abs(x), (x, b)


# --------------------------------------------------------------- one corner tetrahedron
def corner_system(phi=0.0, *, rotation=None, E=1.0, nu=0.3):
    mesh = corner_tet(rotation)
    Kl, KG = tet_parts(mesh.points, mesh.cells)
    t = np.radians(phi)
    s0 = np.array([np.cos(t), 0.0, np.sin(t)])  # the slip direction before the rotation
    # unrotated: t1 = e_x, t2 = n x t1 = e_z, so the slip angle phi gives s0
    given = {"angle": phi} if rotation is None else {"direction": rotation @ s0}
    system = contact_system3d(mesh, Kl, KG, contact=["contact"], dirichlet=["clamp"], **given)
    return system, system.stiffness(*lame(E, nu))


def solve_corner(phi, law, **kwargs):
    system, K = corner_system(phi, **kwargs)
    return eigen.solve(K, system, law=law)


def corner_closed_forms(phi, nu):
    """alpha and r of both laws (K = V((lam + G) 1 1^T + 3 G I) at the origin; P = s.1,
    Q = e.1 with e = n x s, c0 = 3 G / (lam + G) = 3 (1 - 2 nu), w = -P)."""
    c, s = np.cos(np.radians(phi)), np.sin(np.radians(phi))
    P, Q, c0 = c + s, c - s, 3 * (1 - 2 * nu)
    w = -P
    return {"rate": (w + c0 / w, abs(P * Q) / np.hypot(P * P + c0, P * Q)),
            "frozen": ((2 + c0) / w, abs(P * Q) / np.hypot(Q * Q + c0, P * Q))}


@pytest.mark.parametrize("method", ["dense", "arpack"])
@pytest.mark.parametrize("nu", [0.0, 0.2, 0.3, 0.45, 0.499])
@pytest.mark.parametrize("phi", [100.0, 135.0, 180.0, 200.0, 225.0, 250.0, 300.0, 17.0])
def test_corner_tet_closed_forms(phi, nu, method):
    system, K = corner_system(phi, nu=nu)
    for law in LAWS:
        spec = eigen.solve(K, system, method=method, law=law, backend="scipy")
        assert spec.method == ("dense" if method == "dense" else "arpack+explicit")  # p0 = 1
        alpha, r = corner_closed_forms(phi, nu)[law]
        if phi == 135.0:  # s . 1 = 0: n^T K s = 0, no friction makes the node slip
            assert len(spec.alpha) == 0 and spec.n_infinite == 1
            continue
        assert len(spec.alpha) == 1
        assert spec.alpha[0].real == pytest.approx(alpha, rel=1e-12, abs=1e-12)
        assert spec.r[0] == pytest.approx(r, rel=1e-10, abs=1e-13)
        mode = spec.modes[0]
        assert mode.r == pytest.approx(r, rel=1e-10, abs=1e-13)
        assert mode.residual < 1e-12


@pytest.mark.parametrize("method", ["dense", "arpack"])
def test_corner_tet_paper_values(method):
    def alphas(phi, nu=0.3):
        system, K = corner_system(phi, nu=nu)
        return [eigen.solve(K, system, method=method, law=law) for law in LAWS]

    rate, frozen = alphas(180.0)
    assert rate.positive[0] == pytest.approx(2.2, rel=1e-12)
    assert frozen.positive[0] == pytest.approx(3.2, rel=1e-12)
    assert rate.r[0] > 0.4 and frozen.r[0] > 0.4  # not static branches
    for spec in alphas(225.0):
        assert spec.positive[0] == pytest.approx((5 - 6 * 0.3) / np.sqrt(2), rel=1e-12)
        assert spec.positive[0] == pytest.approx(2.2627417, rel=1e-8)
        assert spec.r[0] < 1e-14  # e carries no force and does not move: both laws agree
    # the lowest rate-law value over the slip angle: 2 sqrt(c0) at cos + sin = -sqrt(c0)
    c0 = 3 * (1 - 2 * 0.3)
    best = 225.0 + np.degrees(np.arccos(np.sqrt(c0 / 2)))
    low = [alphas(best + d)[0].positive[0] for d in (-1.0, 0.0, 1.0)]
    assert low[1] == pytest.approx(2 * np.sqrt(c0), rel=1e-12)
    assert low[1] == pytest.approx(2.1908902, rel=1e-7)
    assert low[0] > low[1] and low[2] > low[1]


def test_one_node_rate_law_is_a_ratio_of_the_node_block():
    """One slipping node: alpha = s^T K s / n^T K s over its 3x3 block (xyz), whatever s."""
    rng = np.random.default_rng(11)
    for _ in range(10):
        pts = np.array([[0.0, 0, 0], [1, 0, 0.2], [0.1, 1, -0.3], [-0.2, 0, 1]])
        pts[[1, 3], ::2] += 0.3 * rng.standard_normal((2, 2))  # keep y = 0: the contact plane
        pts[2] += 0.3 * rng.standard_normal(3)
        mesh = Mesh(pts, np.array([[0, 1, 2, 3]]), "P1",
                    faces={"contact": np.array([[0, 1, 3]]), "clamp": np.array([[1, 2, 3]])})
        Kl, KG = tet_parts(pts, mesh.cells)
        nu = rng.uniform(0.05, 0.45)
        lam, G = lame(1.0, nu)
        B = (lam * Kl + G * KG).toarray()[:3, :3]
        s = np.array([np.cos(a := rng.uniform(0, 2 * np.pi)), 0.0, np.sin(a)])
        n = np.array([0.0, -1.0, 0.0])
        system = contact_system3d(mesh, Kl, KG, contact=["contact"], dirichlet=["clamp"],
                                  direction=s)
        for method in ("dense", "arpack"):
            spec = eigen.solve(system.stiffness(lam, G), system, method=method)
            assert spec.alpha[0].real == pytest.approx(s @ B @ s / (n @ B @ s), rel=1e-12)


def test_reversed_directions_flip_every_alpha_and_E_does_not_matter():
    for phi in (150.0, 200.0, 260.0):
        for law in LAWS:
            ref = solve_corner(phi, law).alpha
            back = solve_corner(phi + 180.0, law).alpha
            stiff = solve_corner(phi, law, E=210e9).alpha
            np.testing.assert_allclose(back, -ref, rtol=1e-12)
            np.testing.assert_allclose(stiff, ref, rtol=1e-12)


def test_rigid_rotation_leaves_the_spectrum_unchanged():
    """The contact plane becomes oblique (t1 changes); the directions turn with the body."""
    for seed in range(4):
        R = Rotation.random(random_state=seed).as_matrix()
        for phi in (190.0, 240.0):
            for law in LAWS:
                ref = solve_corner(phi, law)
                turned = solve_corner(phi, law, rotation=R)
                np.testing.assert_allclose(turned.alpha, ref.alpha, rtol=1e-12)
                np.testing.assert_allclose(turned.r, ref.r, rtol=1e-10, atol=1e-14)


# ------------------------------------------------------------------------------- a box
def box_case(rotation=None, *, law="rate", nu=0.3, mixed=True, parts=tet_parts):
    """The box of :func:`box_mesh` on its bottom face, top clamped, slip directions and a
    contact state given per node (by node index, so they follow the nodes under rotation)."""
    mesh = box_mesh()
    if rotation is not None:
        mesh = replace(mesh, points=mesh.points @ rotation.T)
    rng = np.random.default_rng(5)
    angle_of = rng.uniform(0, 360, mesh.n_nodes)  # per node, before the rotation
    status_of = rng.choice([SLIP, SLIP, SLIP, STUCK, FREE], mesh.n_nodes) if mixed else \
        np.full(mesh.n_nodes, SLIP)
    gamma_of = rng.choice([1.0, -1.0], mesh.n_nodes)
    bc = {"contact": ["bottom"], "dirichlet": ["top"]}
    nodes = contact_layout3d(mesh, **bc).nodes
    t = np.radians(angle_of[nodes])
    d = np.column_stack([np.cos(t), np.sin(t), np.zeros_like(t)])
    d = d if rotation is None else d @ rotation.T
    system = contact_system3d(mesh, *parts(mesh.points, mesh.cells), direction=d, **bc)
    state = ContactState(status_of[nodes].astype(np.int8), gamma_of[nodes])
    return mesh, system, state, system.stiffness(*lame(1.0, nu))


def full_pencil(mesh, system, state, law, nu=0.3):
    """Independent formulation, in xyz: z = (Phi, X, Y_e) over the DOFs neither Dirichlet nor
    at a stuck node, A z = alpha M z with A = [[K, -B_n, -B_e], [-B_n^T, 0, 0], [-B_e^T, 0, 0]]
    (B_e only in the rate law) and M = [[0, B_s Gamma, 0], 0], dense QZ."""
    lam, G = lame(1.0, nu)
    Kl, KG = tet_parts(mesh.points, mesh.cells)
    K = (lam * Kl + G * KG).toarray()
    keep = np.ones(3 * mesh.n_nodes, dtype=bool)
    keep[system.fixed] = False
    stuck = system.nodes[state.status == STUCK]
    keep[(3 * stuck[:, None] + np.arange(3)).ravel()] = False
    slip = np.flatnonzero(state.status == SLIP)
    node, s = system.nodes[slip], system.slip[slip]
    n = np.broadcast_to(system.normal, s.shape)
    e = np.cross(n, s)

    def B(vectors):  # (3 n_nodes, p0): vector i at node i's DOFs
        out = np.zeros((3 * mesh.n_nodes, len(slip)))
        out[(3 * node[:, None] + np.arange(3)), np.arange(len(slip))[:, None]] = vectors
        return out[keep]

    Bn, Bs, Be = B(n), B(s) * state.gamma[slip], B(e)
    cons = np.hstack([Bn, Be]) if law == "rate" else Bn
    m, c = int(keep.sum()), cons.shape[1]
    A = np.block([[K[np.ix_(keep, keep)], -cons], [-cons.T, np.zeros((c, c))]])
    M = np.zeros_like(A)
    M[:m, m:m + len(slip)] = Bs
    w = la.eigvals(A, M)
    return w[np.isfinite(w) & (np.abs(w) < 1e8)]


@pytest.mark.parametrize("backend", available_backends())
@pytest.mark.parametrize("law", LAWS)
def test_box_dense_arpack_and_full_pencil_agree(law, backend):
    mesh, system, state, K = box_case(law=law)
    assert state.n_slip >= 6 and np.any(state.status == STUCK) and np.any(state.status == FREE)
    pencil = full_pencil(mesh, system, state, law)
    dense = eigen.solve(K, system, state, method="dense", law=law, count=3, backend=backend)
    assert dense.backend == backend
    same_spectrum(dense.alpha, pencil, rtol=1e-9)
    assert len(dense.alpha) + dense.n_infinite == state.n_slip  # p0 eigenvalues
    arpack = eigen.solve(K, system, state, method="arpack", law=law, count=1, backend=backend)
    assert arpack.method in ("arpack", "arpack+explicit")
    found = arpack.alpha
    for x in found:
        assert np.min(np.abs(dense.alpha - x)) <= 1e-9 * abs(x)
    idx = [np.argmin(np.abs(dense.alpha - x)) for x in found]
    np.testing.assert_allclose(arpack.r, dense.r[idx], rtol=1e-7, atol=1e-12)
    target = dense.positive[0]
    near = eigen.solve(K, system, state, method="arpack", law=law, shift=target + 0.05,
                       backend=backend)
    assert near.method == "arpack-shift"
    assert near.positive[0] == pytest.approx(target, rel=1e-10)
    for spec in (dense, arpack, near):
        check_modes(spec, system, state, K, law)


def check_modes(spec, system, state, K, law):
    """Each mode solves its law (from its own Phi, independently of the solver's check)."""
    slip = np.flatnonzero(state.status == SLIP)
    stuck = state.status == STUCK
    for mode in spec.modes:
        F = K @ mode.phi
        scale = np.abs(F).max()
        loaded = np.concatenate([system.cn[state.status != FREE], system.ct[state.status != FREE],
                                 system.ce[stuck]] + ([system.ce[slip]] if law == "rate" else []))
        rest = np.setdiff1d(np.arange(len(F)), loaded)
        assert np.abs(F[rest]).max() < 1e-9 * scale  # no load elsewhere (frozen: Y_e = 0)
        assert np.all(mode.phi[system.cn[slip]] == 0)  # Phi_n = 0
        if law == "rate":
            assert np.all(mode.phi[system.ce[slip]] == 0)  # Phi_e = 0
            r = np.linalg.norm(F[system.ce[slip]]) / np.hypot(
                np.linalg.norm(F[system.ce[slip]]), np.linalg.norm(F[system.ct[slip]]))
        else:
            e, t = mode.phi[system.ce[slip]], mode.phi[system.ct[slip]]
            r = np.linalg.norm(e) / np.hypot(np.linalg.norm(e), np.linalg.norm(t))
        assert mode.r == pytest.approx(r, rel=1e-8, abs=1e-12)
        np.testing.assert_allclose(F[system.ct[slip]],
                                   mode.alpha * state.gamma[slip] * F[system.cn[slip]],
                                   rtol=1e-8, atol=1e-10 * scale)
        np.testing.assert_allclose(mode.Ye, F[system.ce], atol=1e-14 * scale)


def test_box_arpack_runs_arpack_itself():
    """p0 >= 4: ARPACK applies (T is not formed) and finds the dense path's lowest values."""
    _, system, state, K = box_case(mixed=False)
    dense = eigen.solve(K, system, state, method="dense", count=2)
    arpack = eigen.solve(K, system, state, method="arpack", count=1)
    assert arpack.method == "arpack" and state.n_slip == 16
    np.testing.assert_allclose(arpack.positive[:1], dense.positive[:1], rtol=1e-10)
    np.testing.assert_allclose(arpack.negative[:1], dense.negative[:1], rtol=1e-10)
    idx = [np.argmin(np.abs(dense.alpha - x)) for x in arpack.alpha]
    np.testing.assert_allclose(arpack.r, dense.r[idx], rtol=1e-7, atol=1e-12)


def test_box_reversed_rotated_and_stiffer():
    for law in LAWS:
        _, system, state, K = box_case(law=law)
        ref = eigen.solve(K, system, state, law=law).alpha
        flipped = ContactState(state.status, -state.gamma)
        same_spectrum(eigen.solve(K, system, flipped, law=law).alpha, -ref, rtol=1e-10)
        reversed_dirs = contact_system3d(
            system.mesh, *tet_parts(system.mesh.points, system.mesh.cells),
            contact=["bottom"], dirichlet=["top"], direction=-system.slip)
        same_spectrum(eigen.solve(reversed_dirs.stiffness(*lame(1.0, 0.3)), reversed_dirs,
                                  state, law=law).alpha, -ref, rtol=1e-10)
        same_spectrum(eigen.solve(K * 3e5, system, state, law=law).alpha, ref, rtol=1e-10)
        R = Rotation.random(random_state=2).as_matrix()
        _, turned, turned_state, Kt = box_case(R, law=law)
        np.testing.assert_array_equal(np.sort(turned.nodes), np.sort(system.nodes))
        same_spectrum(eigen.solve(Kt, turned, turned_state, law=law).alpha, ref, rtol=1e-10)


def test_unknown_law_is_a_case_error():
    system, K = corner_system(200.0)
    with pytest.raises(CaseError, match="unknown slip law 'sticky'.*rate, frozen") as err:
        eigen.solve(K, system, law="sticky")
    assert err.value.key == "contact.law"


def test_two_dimensional_results_carry_r_zero(coarse_square):
    _, prep = coarse_square
    K = prep.system.stiffness(*lame(1.0, 0.3))
    for method in ("dense", "arpack"):
        spec = eigen.solve(K, prep.system, method=method, count=2, law="frozen")
        assert np.all(spec.r == 0) and all(m.r == 0 and m.Ye is None for m in spec.modes)


# ------------------------------------------------------- the 2D problem, extruded in z
FOUR = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0], [0.5, 0.5]])  # A B C D O
FOUR_TRIANGLES = np.array([[0, 1, 4], [1, 2, 4], [2, 3, 4], [3, 0, 4]])


def extruded(points2d, triangles, depth=0.37):
    """One layer of prisms, each cut into 3 tetrahedra by the lower-global-index rule (every
    quadrilateral face is cut from its lowest-index vertex), top node k + n = bottom node k
    moved by depth e_z; faces y = 0 "bottom" and y = 1 "top" (two triangles each)."""
    n = len(points2d)
    pts = np.vstack([np.column_stack([points2d, np.zeros(n)]),
                     np.column_stack([points2d, np.full(n, depth)])])
    v = np.sort(triangles, axis=1)
    a, b, c = v.T
    tets = np.concatenate([np.column_stack(t) for t in (
        (a, b, c, c + n), (a, b, b + n, c + n), (a, a + n, b + n, c + n))])
    X = pts[tets]
    neg = np.einsum("ci,ci->c", X[:, 1] - X[:, 0],
                    np.cross(X[:, 2] - X[:, 0], X[:, 3] - X[:, 0])) < 0
    tets[neg] = tets[neg][:, [0, 2, 1, 3]]

    def side(i, j):  # the quadrilateral (i, j, j', i'), i < j, cut from i to j'
        return np.array([[i, j, j + n], [i, j + n, i + n]])

    return Mesh(pts, tets, "P1", faces={"bottom": side(0, 1), "top": side(2, 3)})


def periodic(system, n):
    """The extruded system with each top node k + n merged into bottom node k: the free DOFs
    of a pair summed, K_periodic = P^T K P."""
    node = system.free // 3
    comp = system.free % 3
    rep = node < n
    merged = np.full(3 * n, -1)
    merged[system.free[rep]] = np.arange(rep.sum())
    col = merged[3 * (node % n) + comp]
    P = sp.csr_matrix((np.ones(len(col)), (np.arange(len(col)), col)),
                      shape=(len(col), rep.sum()))
    keep = system.nodes < n
    cn, ct, ce = (col[pos[keep]] for pos in (system.cn, system.ct, system.ce))
    return replace(system, free=system.free[rep], nodes=system.nodes[keep], cn=cn, ct=ct, ce=ce,
                   slip=system.slip[keep], K_lam=(P.T @ system.K_lam @ P).tocsr(),
                   K_G=(P.T @ system.K_G @ P).tocsr(), D_lam=None, D_G=None)


def two_d_spectra(points2d, triangles, nu):
    mesh = Mesh(points2d, triangles, "P1",
                edges={"bottom": np.array([[0, 1]]), "top": np.array([[2, 3]])})
    s = contact_system(mesh, *assemble_elasticity(mesh), contact=["bottom"], dirichlet=["top"])
    assert np.array_equal(s.tangent, [1.0, 0.0])  # t = (-n2, n1) with n = -e_y
    K = s.stiffness(*lame(1.0, nu))
    return {g: eigen.solve(K, s, gamma=g, method="dense").alpha for g in (1, -1)}


ASSEMBLIES = [pytest.param(tet_parts, id="written-out"),
              pytest.param(lambda pts, cells: assemble_elasticity(
                  Mesh(pts, cells, "P1")), id="critfric", marks=pytest.mark.skipif(
                      not ELEMENTS_3D, reason="no 3D elements yet (critfric.fem.elements)"))]


@pytest.mark.parametrize("parts", ASSEMBLIES)
@pytest.mark.parametrize("centre", [(0.5, 0.5), (0.35, 0.6)], ids=["symmetric", "skew"])
@pytest.mark.parametrize("nu", [0.3, 0.1])
def test_periodic_extrusion_is_the_2d_problem(parts, centre, nu):
    """Slip angle 0 is 2D's gamma = +1 and 180 is gamma = -1 (n = -e_y: t1 = e_x = 2D's t);
    both laws give the 2D spectrum with r = 0 (the z DOFs decouple exactly)."""
    pts2 = FOUR.copy()
    pts2[4] = centre
    two_d = two_d_spectra(pts2, FOUR_TRIANGLES, nu)
    if centre == (0.5, 0.5):
        assert two_d[1].real.max() == pytest.approx(four_triangles_alpha(nu), rel=1e-12)
        if nu == 0.3:
            assert two_d[1].real.max() == pytest.approx(1.8358568491, rel=1e-10)
    else:  # a spectrum not symmetric about 0: the test tells gamma = +1 from gamma = -1
        a = np.sort(two_d[1].real)
        assert np.min(np.abs(a + a[::-1])) > 0.05
    mesh = extruded(pts2, FOUR_TRIANGLES)
    for angle, gamma in ((0.0, 1), (180.0, -1)):
        s3 = contact_system3d(mesh, *parts(mesh.points, mesh.cells), contact=["bottom"],
                              dirichlet=["top"], angle=angle)
        assert np.array_equal(s3.tangent, [1.0, 0.0, 0.0])
        per = periodic(s3, len(pts2))
        K = per.stiffness(*lame(1.0, nu))
        for law in LAWS:
            for method in ("dense", "arpack"):
                spec = eigen.solve(K, per, method=method, law=law)
                np.testing.assert_allclose(np.sort(spec.alpha.real), np.sort(two_d[gamma].real),
                                           rtol=1e-12)
                assert np.all(spec.alpha.imag == 0) and np.all(spec.r < 1e-12)
