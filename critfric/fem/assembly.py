"""Vectorized assembly of linear elasticity, plane strain (2D) or 3D: stiffness, mass and
stresses.

DOFs are interleaved: node i has DOFs dim i + k (2D: x 2i, y 2i+1). The stiffness splits as
``K = lam * K_lam + G * K_G`` with ``a(u, v) = int lam div u div v + 2 G eps(u) : eps(v)``.
All element arrays are (n_cells, n_qp, ...) numpy arrays; there are no loops over cells.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from ..errors import CaseError
from .mesh import Mesh
from .pattern import BlockPattern, local_pairs


def lame(E: float, nu: float) -> tuple[float, float]:
    """Lamé constants (lam, G) from Young's modulus ``E`` and Poisson ratio ``nu``."""
    return E * nu / ((1.0 + nu) * (1.0 - 2.0 * nu)), E / (2.0 * (1.0 + nu))


def _index_dtype(n_dofs: int):
    return np.int32 if n_dofs < np.iinfo(np.int32).max else np.int64


def _jacobians(mesh: Mesh, dref: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """J[c, q, i, j] = d x_i / d xi_j (dim x dim) and det J at the points of the reference
    gradients ``dref`` (n_local, n_pts, dim); :class:`CaseError` if any det J is non-positive."""
    element, d = mesh.fe, mesh.dim
    cells = _checked_cells(mesh)
    X = np.asarray(mesh.points, dtype=float)[cells]  # (n_cells, n_local, dim)
    J = np.empty((len(cells), dref.shape[1], d, d))
    for i in range(d):  # dim x dim plain matrix products, not a batch of tiny ones
        for j in range(d):
            J[..., i, j] = X[:, :, i] @ dref[:, :, j]
    if d == 2:
        det = J[..., 0, 0] * J[..., 1, 1] - J[..., 0, 1] * J[..., 1, 0]
        scale = np.square(J).sum(axis=(-2, -1))
    else:
        det = (J[..., 0, 0] * (J[..., 1, 1] * J[..., 2, 2] - J[..., 1, 2] * J[..., 2, 1])
               - J[..., 0, 1] * (J[..., 1, 0] * J[..., 2, 2] - J[..., 1, 2] * J[..., 2, 0])
               + J[..., 0, 2] * (J[..., 1, 0] * J[..., 2, 1] - J[..., 1, 1] * J[..., 2, 0]))
        scale = np.square(J).sum(axis=(-2, -1)) ** 1.5
    # scale-free test: det J / |J|_F^dim <= dim^(-dim/2), and is ~0 for a degenerate cell
    bad = np.any(det <= 1e-12 * scale, axis=1)
    if np.any(bad):
        orientation = "clockwise" if d == 2 else "negative volume"
        raise CaseError(
            f"{int(bad.sum())} of {len(cells)} {element.name} cells have a non-positive Jacobian "
            f"determinant (inverted, {orientation} or degenerate), first cell index "
            f"{int(np.flatnonzero(bad)[0])}"
        )
    return J, det


def _checked_cells(mesh: Mesh) -> np.ndarray:
    """The mesh's cells, (n_cells, n_local) as its element needs them (else CaseError)."""
    element, cells = mesh.fe, np.asarray(mesh.cells)
    if cells.ndim != 2 or cells.shape[1] != element.n_local:
        raise CaseError(
            f"cells have shape {cells.shape}; element {element.name} needs {element.n_local} nodes"
        )
    return cells


def _inverse(J: np.ndarray, det: np.ndarray) -> np.ndarray:
    """inv[..., j, i] = d xi_j / d x_i of the Jacobians ``J`` (..., dim, dim): adjugate / det."""
    inv = np.empty_like(J)
    if J.shape[-1] == 2:
        inv[..., 0, 0], inv[..., 1, 1] = J[..., 1, 1] / det, J[..., 0, 0] / det
        inv[..., 0, 1], inv[..., 1, 0] = -J[..., 0, 1] / det, -J[..., 1, 0] / det
        return inv
    for i in range(3):  # cofactor (i, j) is adjugate entry (j, i)
        a, b = (i + 1) % 3, (i + 2) % 3
        for j in range(3):
            c, e = (j + 1) % 3, (j + 2) % 3
            inv[..., j, i] = (J[..., a, c] * J[..., b, e] - J[..., a, e] * J[..., b, c]) / det
    return inv


def cell_geometry(mesh: Mesh, xi: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Shape values (n_local, n_pts), determinants (n_cells, n_pts) and physical gradients
    (n_cells, n_pts, n_local, dim) at reference points ``xi`` (n_pts, dim).

    Raises :class:`CaseError` if a determinant is non-positive (inverted or degenerate cell).
    """
    values, dref = mesh.fe.shape(xi)  # (n_local, n_pts), (n_local, n_pts, dim)
    J, det = _jacobians(mesh, dref)
    inv = _inverse(J, det)  # inv[c, q, j, i] = d xi_j / d x_i
    d = mesh.dim
    grads = np.empty(det.shape + (dref.shape[0], d))  # sum_j dref[a, q, j] inv[c, q, j, i]
    dj = [dref[:, :, j].T for j in range(d)]  # (n_pts, n_local) each
    for i in range(d):
        grads[..., i] = sum(dj[j] * inv[..., j, i, None] for j in range(d))
    return values, det, grads


def assemble_elasticity(mesh: Mesh, *, on_pattern=None) -> tuple[sp.csr_matrix, sp.csr_matrix]:
    """CSR matrices ``(K_lam, K_G)`` over all dim * n_nodes DOFs with ``K = lam K_lam + G K_G``,
    assembled into the mesh's precomputed pattern (:class:`.pattern.BlockPattern`).
    ``on_pattern(pattern)`` is called with that pattern, made from the cells alone, before
    any geometry (whose check of the cells may still refuse the mesh): work that needs only
    the sparsity starts there, while the values are computed."""
    pattern, B, K_G = _stiffness_blocks(mesh, on_pattern)
    return pattern.csr(B), pattern.csr(K_G)


def assemble_stiffness(mesh: Mesh, lam: float, G: float, *, on_pattern=None) -> sp.csr_matrix:
    """``lam K_lam + G K_G`` of :func:`assemble_elasticity` as one CSR matrix, combined node
    block by node block before the DOF matrix is made (half the work of the parts and their
    sum, for a single Poisson ratio; each entry the same number as the parts' sum)."""
    pattern, B, K_G = _stiffness_blocks(mesh, on_pattern)
    d = mesh.dim
    return pattern.csr([[lam * B[k][m] + G * K_G[k][m] for m in range(d)] for k in range(d)])


def _stiffness_blocks(mesh: Mesh, on_pattern) -> tuple[BlockPattern, list, list]:
    """The pattern and the node-block entries [k][m] of K_lam and K_G."""
    element, d = mesh.fe, mesh.dim
    pattern = BlockPattern(_checked_cells(mesh), mesh.n_nodes, d)
    if on_pattern is not None:
        on_pattern(pattern)
    if element.name != "P1":  # also reject cells inverted at nodes (P1: J is constant)
        _jacobians(mesh, element.shape(element.doflocs)[1])
    xi, w = element.quadrature()
    _, det, grads = cell_geometry(mesh, xi)
    wdet = det * w  # (n_cells, n_qp)
    # node block (a, b) of K_lam: B_km = int d_k N_a d_m N_b, summed over the cells; B_mk is
    # the transpose of B_km, and B_kk symmetric (summed from the local pairs a <= b alone)
    B = [[None] * d for _ in range(d)]
    for k in range(d):
        for m in range(k, d):
            B[k][m], B[m][k] = pattern.sums(*_gradient_products(grads, wdet, k, m))
    del grads
    # K_G[(a,k),(b,m)] = int (delta_km grad N_a . grad N_b + d_m N_a d_k N_b): node block by
    # node block, K_G = B^T + tr(B) I for the dim x dim block B of K_lam (same sparsity)
    K_G = [[B[m][k] if k != m else sum(2 * B[j][j] if j == k else B[j][j] for j in range(d))
            for m in range(d)] for k in range(d)]
    return pattern, B, K_G


def _gradient_products(grads: np.ndarray, wdet: np.ndarray, k: int, m: int) -> list:
    """Sum over quadrature points of w det d_k N_a d_m N_b, (n_cells, ...) arrays for the
    local blocks (a, a), then (a, b) of the local pairs a < b, then (b, a) (k != m only) of
    :meth:`.pattern.BlockPattern.sums`. Several points: one batch of n_local x n_qp by n_qp x
    n_local products (P2, 6 points, 4x faster than a sum of outer products over the points);
    one point: each product alone."""
    n_cells, n_qp, nl, _ = grads.shape
    nodes, (a, b) = np.arange(nl), local_pairs(nl)
    blocks = [(nodes, nodes), (a, b)] + ([(b, a)] if m != k else [])
    if n_qp == 1:
        weighted = grads[:, 0, :, k] * wdet
        return [weighted[:, i] * grads[:, 0, j, m] for i, j in blocks]
    weighted = grads[..., k] * wdet[..., None]  # (n_cells, n_qp, n_local)
    full = np.matmul(weighted.transpose(0, 2, 1), grads[..., m]).reshape(n_cells, nl * nl)
    return [full[:, i * nl + j] for i, j in blocks]


def assemble_mass(mesh: Mesh, density: float = 1.0) -> sp.csr_matrix:
    """Consistent mass matrix ``rho int u . v`` over all dim * n_nodes DOFs (interleaved), by
    one COO scatter of the scalar mass into every component."""
    element, d = mesh.fe, mesh.dim
    xi, w = element.mass_quadrature()
    values, _ = element.shape(xi)  # (n_local, n_qp)
    _, det, _ = cell_geometry(mesh, xi)
    local = density * np.einsum("aq,bq,cq->cab", values, values, det * w, optimize=True)
    nl = local.shape[1]
    itype = _index_dtype(d * mesh.n_nodes)
    cells = np.asarray(mesh.cells, dtype=itype)
    rows = np.repeat(cells, nl, axis=1).ravel()
    cols = np.tile(cells, (1, nl)).ravel()
    data = local.ravel()
    n = d * mesh.n_nodes
    return sp.coo_matrix((np.concatenate([data] * d),
                          (np.concatenate([d * rows + k for k in range(d)]),
                           np.concatenate([d * cols + k for k in range(d)]))),
                         shape=(n, n)).tocsr()


# Voigt order of the strain and stress components in 3D
_VOIGT_3D = [(0, 0), (1, 1), (2, 2), (1, 2), (0, 2), (0, 1)]


def cell_strain(mesh: Mesh, u: np.ndarray, xi: np.ndarray) -> np.ndarray:
    """Strain at reference points ``xi`` of every cell: (exx, eyy, exy) in 2D,
    (n_cells, n_pts, 3); (exx, eyy, ezz, eyz, exz, exy) in 3D, (n_cells, n_pts, 6)."""
    _, _, grads = cell_geometry(mesh, xi)
    d = mesh.dim
    ue = np.asarray(u, dtype=float).reshape(-1, d)[np.asarray(mesh.cells)]  # (n_cells, nl, d)
    du = np.einsum("cak,cqai->cqki", ue, grads)  # du[c, q, k, i] = d u_k / d x_i
    pairs = [(0, 0), (1, 1), (0, 1)] if d == 2 else _VOIGT_3D
    return np.stack([du[..., i, i] if i == j else 0.5 * (du[..., i, j] + du[..., j, i])
                     for i, j in pairs], -1)


def cell_stress(
    mesh: Mesh, u: np.ndarray, lam: float, G: float, at: str = "nodes"
) -> np.ndarray:
    """Stress per cell: plane strain (sxx, syy, sxy, szz), (n_cells, n_pts, 4) in 2D;
    (sxx, syy, szz, syz, sxz, sxy), (n_cells, n_pts, 6) in 3D.

    ``at="nodes"`` evaluates at the cell's nodes (local order, n_pts = n_local, discontinuous
    between cells); ``at="centroid"`` at the reference centroid (n_pts = 1).
    """
    element, d = mesh.fe, mesh.dim
    if at == "nodes":
        xi = element.doflocs
    elif at == "centroid":
        simplex = element.reference in ("triangle", "tetrahedron")
        xi = np.full((1, d), 1.0 / (d + 1)) if simplex else np.zeros((1, d))
    else:
        raise CaseError(f"unknown stress location {at!r}; allowed: nodes, centroid")
    eps = cell_strain(mesh, u, xi)
    if d == 3:
        tr = eps[..., 0] + eps[..., 1] + eps[..., 2]
        return np.concatenate([lam * tr[..., None] + 2 * G * eps[..., :3], 2 * G * eps[..., 3:]],
                              axis=-1)
    tr = eps[..., 0] + eps[..., 1]
    return np.stack(
        [lam * tr + 2 * G * eps[..., 0], lam * tr + 2 * G * eps[..., 1], 2 * G * eps[..., 2],
         lam * tr], axis=-1
    )


def von_mises(stress: np.ndarray) -> np.ndarray:
    """Von Mises stress from (..., 4) plane-strain components (sxx, syy, sxy, szz), szz
    included, or from (..., 6) 3D components (sxx, syy, szz, syz, sxz, sxy)."""
    stress = np.asarray(stress)
    if stress.shape[-1] == 6:
        sxx, syy, szz, syz, sxz, sxy = np.moveaxis(stress, -1, 0)
        shear = syz**2 + sxz**2 + sxy**2
    else:
        sxx, syy, sxy, szz = np.moveaxis(stress, -1, 0)
        shear = sxy**2
    return np.sqrt(0.5 * ((sxx - syy) ** 2 + (syy - szz) ** 2 + (szz - sxx) ** 2) + 3 * shear)
