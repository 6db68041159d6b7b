"""The block Lanczos of the free vibrations against dense eigensolvers and ARPACK: values,
modes, double eigenvalues, and the hand-over to ARPACK where a block loses rank."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg as la
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from helpers import case_pencil

from critfric.case.schema import load_case
from critfric.solvers.backends import factorize
from critfric.stability import lanczos, locus


@pytest.fixture(scope="module")
def pencil():
    """The all-slipping pencil of the unit square, P1, h = 0.03 (above lanczos.MIN_ROWS)."""
    pen = case_pencil(load_case("unit-square", overrides={"mesh.size": 0.03}))
    assert pen.size >= lanczos.MIN_ROWS
    return pen


@pytest.fixture(scope="module")
def exact(pencil):
    """The 12 lowest eigenvalues of the pencil's (K_rr, M_rr), by a dense solver."""
    return la.eigh(pencil.Krr.toarray(), pencil.Mrr.toarray(), eigvals_only=True,
                   subset_by_index=[0, 11])


def test_lowest_modes_equal_a_dense_solve(pencil, exact):
    K, M = pencil.Krr, pencil.Mrr
    factor = factorize(K, symmetric=True, backend="scipy")
    w, V, columns = lanczos.lowest_modes(K, M, factor.solve, 12, block=4, tol=1e-10, seed=1)
    np.testing.assert_allclose(w, exact, rtol=1e-10)  # the dense solver's own rounding
    assert np.all(np.diff(w) > 0)
    np.testing.assert_allclose(V.T @ (M @ V), np.eye(12), atol=1e-10)
    residual = np.linalg.norm(K @ V - (M @ V) * w, axis=0) / np.linalg.norm(K @ V, axis=0)
    assert residual.max() < 1e-7
    assert columns % 4 == 0 and columns <= lanczos.WIDTH * 12 + lanczos.EXTRA


def test_each_mode_to_its_own_tolerance(pencil, exact):
    """The 6 lowest of 12 to 1e-10, the others to 1e-4: the first equal the dense solve's,
    the others' residuals meet their tolerance, in fewer columns than all to 1e-10."""
    K, M = pencil.Krr, pencil.Mrr
    factor = factorize(K, symmetric=True, backend="scipy")
    tol = np.repeat([1e-10, 1e-4], 6)
    w, V, columns = lanczos.lowest_modes(K, M, factor.solve, 12, block=1, tol=tol, seed=1)
    np.testing.assert_allclose(w[:6], exact[:6], rtol=1e-10)
    np.testing.assert_allclose(w[6:], exact[6:], rtol=1e-6)  # second order in the residual
    assert np.all(np.diff(w) > 0)
    np.testing.assert_allclose(V.T @ (M @ V), np.eye(12), atol=1e-10)
    # ARPACK's criterion: ||K^-1 M v - theta v||_M <= tol theta, theta = 1 / w, |v|_M = 1
    R = factor.solve(M @ V) - V / w
    residual = np.sqrt(np.einsum("ij,ij->j", R, M @ R)) * w
    assert np.all(residual <= 1.01 * tol) and residual[6:].max() > 1e3 * residual[:6].max()
    _, _, all_tight = lanczos.lowest_modes(K, M, factor.solve, 12, block=1, tol=1e-10, seed=1)
    assert columns < all_tight


@pytest.mark.parametrize("block", [1, 4])
def test_double_eigenvalues_are_found_twice(block):
    """K = T (x) I_2 (T: the 1D Laplacian of m points), M = I: every eigenvalue
    2 - 2 cos(j pi / (m + 1)) twice; a block of 4 holds both copies, a single vector's
    Krylov space gets the second from rounding (as ARPACK's does)."""
    m = 1500
    T = sp.diags([-np.ones(m - 1), 2 * np.ones(m), -np.ones(m - 1)], [-1, 0, 1])
    K = sp.kron(T, sp.identity(2)).tocsc()
    M = sp.identity(2 * m, format="csr")
    lu = spla.splu(K)
    w, V, _ = lanczos.lowest_modes(K, M, lu.solve, 10, block=block, tol=1e-10, seed=3)
    exact = np.repeat(2 - 2 * np.cos(np.arange(1, 6) * np.pi / (m + 1)), 2)
    np.testing.assert_allclose(w, exact, rtol=1e-10)
    np.testing.assert_allclose(V.T @ V, np.eye(10), atol=1e-10)


def test_a_block_that_loses_rank_hands_over():
    """K with two eigenvalues, 1500 times each, M = I: from a block of 4 the Krylov space is
    invariant after 8 columns, which hold 4 copies of the lowest eigenvalue at most; 10
    were asked for: None (the caller runs ARPACK), not vectors made of rounding."""
    K = sp.diags(np.repeat([1.0, 2.0], 1500)).tocsr()
    eye = sp.identity(3000, format="csr")
    assert lanczos.lowest_modes(K, eye, lambda b: b / K.diagonal()[:, None], 10, block=4,
                                tol=1e-10, seed=1) is None


def test_block_lanczos_and_arpack_give_the_same_modes(pencil, monkeypatch):
    factor = factorize(pencil.Krr, symmetric=True, backend="scipy")
    assert lanczos.block_size(factor.backend, pencil.size, 12) == 4
    w_block, V_block = locus._free_vibrations(pencil, 12, factor)
    monkeypatch.setattr(lanczos, "BLOCK", {})  # every backend on ARPACK
    w_arpack, V_arpack = locus._free_vibrations(pencil, 12, factor)
    np.testing.assert_allclose(w_block, w_arpack, rtol=1e-12)
    # the same modes up to sign: the cosines of the angles between the spans are 1
    cosines = la.svdvals(V_block.T @ (pencil.Mrr @ V_arpack))
    np.testing.assert_allclose(cosines, 1.0, atol=1e-9)


def test_block_sizes_and_the_hand_over_to_arpack(monkeypatch):
    monkeypatch.setattr(lanczos, "available_memory", lambda: 64e9)
    assert lanczos.block_size("pardiso", 10**6, 20) == lanczos.BLOCK["pardiso"] == 1
    assert lanczos.block_size("another", 10**6, 20) is None
    assert lanczos.block_size("scipy", lanczos.MIN_ROWS - 1, 20) is None
    assert lanczos.block_size("scipy", 10**6, 20) == lanczos.BLOCK["scipy"]
    # 10^6 DOFs x 144 columns: 1.15 GB, more than a quarter of 4 GB
    monkeypatch.setattr(lanczos, "available_memory", lambda: 4e9)
    assert lanczos.block_size("scipy", 10**6, 20) is None
