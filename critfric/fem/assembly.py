"""Vectorized assembly of plane-strain elasticity: stiffness, loads and stresses.

DOFs are interleaved: node i has x DOF 2i and y DOF 2i+1. The stiffness splits as
``K = lam * K_lam + G * K_G`` with ``a(u, v) = int lam div u div v + 2 G eps(u) : eps(v)``.
All element arrays are (n_cells, n_qp, ...) numpy arrays; there are no loops over cells.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from ..errors import CaseError
from .elements import get_element
from .mesh import Mesh
from .pattern import BlockPattern


def lame(E: float, nu: float) -> tuple[float, float]:
    """Lamé constants (lam, G) from Young's modulus ``E`` and Poisson ratio ``nu``."""
    return E * nu / ((1.0 + nu) * (1.0 - 2.0 * nu)), E / (2.0 * (1.0 + nu))


def _index_dtype(n_dofs: int):
    return np.int32 if n_dofs < np.iinfo(np.int32).max else np.int64


def _jacobians(mesh: Mesh, dref: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """J[c, q, i, j] = d x_i / d xi_j and det J at the points of the reference gradients
    ``dref`` (n_local, n_pts, 2); :class:`CaseError` if any det J is non-positive."""
    element = get_element(mesh.element)
    cells = np.asarray(mesh.cells)
    if cells.ndim != 2 or cells.shape[1] != element.n_local:
        raise CaseError(
            f"cells have shape {cells.shape}; element {element.name} needs {element.n_local} nodes"
        )
    X = np.asarray(mesh.points, dtype=float)[cells]  # (n_cells, n_local, 2)
    J = np.empty((len(cells), dref.shape[1], 2, 2))
    for i in range(2):  # 2 x 2 plain matrix products, not a batch of tiny ones
        for j in range(2):
            J[..., i, j] = X[:, :, i] @ dref[:, :, j]
    det = J[..., 0, 0] * J[..., 1, 1] - J[..., 0, 1] * J[..., 1, 0]
    # scale-free test: det J / |J|_F^2 <= 1/2, and is ~0 for a degenerate cell
    bad = np.any(det <= 1e-12 * np.square(J).sum(axis=(-2, -1)), axis=1)
    if np.any(bad):
        raise CaseError(
            f"{int(bad.sum())} of {len(cells)} {element.name} cells have a non-positive Jacobian "
            f"determinant (inverted, clockwise or degenerate), first cell index "
            f"{int(np.flatnonzero(bad)[0])}"
        )
    return J, det


def cell_geometry(mesh: Mesh, xi: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Shape values (n_local, n_pts), determinants (n_cells, n_pts) and physical gradients
    (n_cells, n_pts, n_local, 2) at reference points ``xi`` (n_pts, 2).

    Raises :class:`CaseError` if a determinant is non-positive (inverted or degenerate cell).
    """
    values, dref = get_element(mesh.element).shape(xi)  # (n_local, n_pts), (n_local, n_pts, 2)
    J, det = _jacobians(mesh, dref)
    inv = np.empty_like(J)  # inv[c, q, j, i] = d xi_j / d x_i
    inv[..., 0, 0], inv[..., 1, 1] = J[..., 1, 1] / det, J[..., 0, 0] / det
    inv[..., 0, 1], inv[..., 1, 0] = -J[..., 0, 1] / det, -J[..., 1, 0] / det
    grads = np.empty(det.shape + (dref.shape[0], 2))  # sum_j dref[a, q, j] inv[c, q, j, i]
    d0, d1 = dref[:, :, 0].T, dref[:, :, 1].T  # (n_pts, n_local)
    for i in range(2):
        grads[..., i] = d0 * inv[..., 0, i, None] + d1 * inv[..., 1, i, None]
    return values, det, grads


def assemble_elasticity(mesh: Mesh, *, on_pattern=None) -> tuple[sp.csr_matrix, sp.csr_matrix]:
    """CSR matrices ``(K_lam, K_G)`` over all 2 * n_nodes DOFs with ``K = lam K_lam + G K_G``,
    assembled into the mesh's precomputed pattern (:class:`.pattern.BlockPattern`).
    ``on_pattern(pattern)`` is called with that pattern (the cells checked) before the values
    are summed: work that needs only the sparsity can start there."""
    element = get_element(mesh.element)
    if element.name != "P1":  # also reject cells inverted at nodes (P1: J is constant)
        _jacobians(mesh, element.shape(element.doflocs)[1])
    xi, w = element.quadrature()
    _, det, grads = cell_geometry(mesh, xi)  # every cell checked before its pattern is used
    wdet = det * w  # (n_cells, n_qp)
    pattern = BlockPattern(mesh.cells, mesh.n_nodes)
    if on_pattern is not None:
        on_pattern(pattern)
    # node block (a, b) of K_lam: B_km = int d_k N_a d_m N_b, summed over the cells
    B = [[pattern.block_sums(_gradient_products(grads, wdet, k, m)) for m in range(2)]
         for k in range(2)]
    del grads
    # K_G[(a,k),(b,m)] = int (delta_km grad N_a . grad N_b + d_m N_a d_k N_b): node block by
    # node block, K_G = B^T + tr(B) I for the 2 x 2 block B of K_lam (same sparsity)
    (b00, b01), (b10, b11) = B
    return pattern.csr(B), pattern.csr([[2 * b00 + b11, b10], [b01, b00 + 2 * b11]])


def _gradient_products(grads: np.ndarray, wdet: np.ndarray, k: int, m: int) -> np.ndarray:
    """(n_cells, n_local, n_local): sum over quadrature points of w det d_k N_a d_m N_b."""
    out = 0.0
    for q in range(wdet.shape[1]):
        out = out + (grads[:, q, :, k] * wdet[:, q, None])[:, :, None] * grads[:, q, None, :, m]
    return out


def assemble_mass(mesh: Mesh, density: float = 1.0) -> sp.csr_matrix:
    """Consistent mass matrix ``rho int u . v`` over all 2 * n_nodes DOFs (interleaved), by
    one COO scatter of the scalar mass into both components."""
    element = get_element(mesh.element)
    xi, w = element.mass_quadrature()
    values, _ = element.shape(xi)  # (n_local, n_qp)
    _, det, _ = cell_geometry(mesh, xi)
    local = density * np.einsum("aq,bq,cq->cab", values, values, det * w, optimize=True)
    nl = local.shape[1]
    itype = _index_dtype(2 * mesh.n_nodes)
    cells = np.asarray(mesh.cells, dtype=itype)
    rows = np.repeat(cells, nl, axis=1).ravel()
    cols = np.tile(cells, (1, nl)).ravel()
    data = local.ravel()
    n = 2 * mesh.n_nodes
    return sp.coo_matrix((np.concatenate([data, data]),
                          (np.concatenate([2 * rows, 2 * rows + 1]),
                           np.concatenate([2 * cols, 2 * cols + 1]))), shape=(n, n)).tocsr()


def cell_strain(mesh: Mesh, u: np.ndarray, xi: np.ndarray) -> np.ndarray:
    """Strain (exx, eyy, exy) at reference points ``xi`` of every cell: (n_cells, n_pts, 3)."""
    _, _, grads = cell_geometry(mesh, xi)
    ue = np.asarray(u, dtype=float).reshape(-1, 2)[np.asarray(mesh.cells)]  # (n_cells, nl, 2)
    du = np.einsum("cak,cqai->cqki", ue, grads)  # du[c, q, k, i] = d u_k / d x_i
    return np.stack([du[..., 0, 0], du[..., 1, 1], 0.5 * (du[..., 0, 1] + du[..., 1, 0])], -1)


def cell_stress(
    mesh: Mesh, u: np.ndarray, lam: float, G: float, at: str = "nodes"
) -> np.ndarray:
    """Plane-strain stress (sxx, syy, sxy, szz) per cell, (n_cells, n_pts, 4).

    ``at="nodes"`` evaluates at the cell's nodes (local order, n_pts = n_local, discontinuous
    between cells); ``at="centroid"`` at the reference centroid (n_pts = 1).
    """
    element = get_element(mesh.element)
    if at == "nodes":
        xi = element.doflocs
    elif at == "centroid":
        xi = np.array([[1 / 3, 1 / 3]]) if element.reference == "triangle" else np.zeros((1, 2))
    else:
        raise CaseError(f"unknown stress location {at!r}; allowed: nodes, centroid")
    eps = cell_strain(mesh, u, xi)
    tr = eps[..., 0] + eps[..., 1]
    return np.stack(
        [lam * tr + 2 * G * eps[..., 0], lam * tr + 2 * G * eps[..., 1], 2 * G * eps[..., 2],
         lam * tr], axis=-1
    )


def von_mises(stress: np.ndarray) -> np.ndarray:
    """Von Mises stress from (..., 4) components (sxx, syy, sxy, szz), szz included."""
    sxx, syy, sxy, szz = np.moveaxis(np.asarray(stress), -1, 0)
    return np.sqrt(0.5 * ((sxx - syy) ** 2 + (syy - szz) ** 2 + (szz - sxx) ** 2) + 3 * sxy**2)


