"""The lowest constrained free vibrations K phi = omega^2 M phi by (block) shift-invert
Lanczos, each mode to its own tolerance.

The operator A = K^-1 M is self-adjoint in the M inner product. Each step applies it to the
newest block, orthogonalizes the result against the two newest blocks (the three-term
recurrence), then once against every block (full reorthogonalization, so no ghost copies of
converged modes), and M-orthonormalizes it (Cholesky of its Gram matrix). The projection
T = Q^T M A Q is block tridiagonal; its eigenpairs (theta, y) give omega^2 = 1 / theta and
the residual ||A Q y - theta Q y||_M = ||R y_last|| (R: the new block's Cholesky factor):
the k largest theta are accepted when the residual of each is at most its tolerance times
|theta| (ARPACK's criterion, which has one tolerance for all). A breakdown (a block that lost
rank) or no convergence within the basis' width returns None: the caller runs ARPACK.

Block sizes (:data:`BLOCK`), measured at 295 k DOFs (P1 unit square, K_rr of the sliding
pencil, 20 modes to 1e-10): SuperLU's solve of one column reads the whole factor for one
vector, 80-85 ms alone, 32 ms a column four at a time, 22-25 ms from eight on (one BLAS
thread): blocks of 4, 26 solves (104 columns) where ARPACK asks for 64 single ones.
PARDISO's parallel solve of one column costs 24 ms, in blocks of 2, 3 and 4 37, 29 and 23 ms
a column: single columns, 62 solves in 2.35 s against ARPACK's 64 in 2.94-3.02 s (its own
work, restarts included, 0.9 s of that; blocks of 2 took 78 columns, 3.5 s). With the 10
further modes of the stability basis to 1e-4 instead of 1e-10: 52 solves on PARDISO, 18
blocks of 4 (72 columns) on SuperLU.
"""

from __future__ import annotations

import numpy as np
import scipy.linalg as la

from ..guards import available_memory
from .bordered import tdot

#: block sizes by linear-solver backend (the factorization's ``backend``); a backend not
#: listed uses ARPACK
BLOCK = {"scipy": 4, "pardiso": 1}
WIDTH, EXTRA = 4, 64  # the basis holds at most WIDTH k + EXTRA columns (k modes): 104 of
# 144 used for k = 20 at 295 k DOFs, 80 of 112 for k = 12 at 2.8 k (measured)
RANK_TOL = 1e-10  # a new block below this times the operator's norm: the basis is invariant
MIN_ROWS = 2000  # below this many DOFs ARPACK (its solves cost next to nothing)
MEMORY_SHARE = 0.25  # the basis' largest share of the memory available


def block_size(backend: str, n: int, k: int) -> int | None:
    """The block size for ``k`` modes of an ``n``-DOF problem on a backend, or None (ARPACK:
    also where the basis, WIDTH k + EXTRA columns against ARPACK's 2 k + 1, would take more
    than MEMORY_SHARE of the memory available)."""
    block = BLOCK.get(backend)
    if block is None or n < max(MIN_ROWS, 2 * (WIDTH * k + EXTRA)):
        return None
    if 8.0 * n * (WIDTH * k + EXTRA) > MEMORY_SHARE * available_memory():
        return None
    return block


def lowest_modes(K, M, solve, k: int, *, block: int, tol, seed: int
                 ) -> tuple[np.ndarray, np.ndarray, int] | None:
    """(omega^2 ascending, M-orthonormal modes (n, k), columns solved) of the ``k`` lowest
    eigenpairs of K phi = omega^2 M phi (K, M symmetric positive definite; ``solve``: K^-1
    on (n, block) arrays), or None if the block Lanczos broke down or did not converge.
    ``tol``: the relative tolerance of every mode, or of each, lowest first (k,)."""
    n = K.shape[0]
    tol = np.broadcast_to(np.asarray(tol, dtype=float), (k,))
    width = min(n - n % block, WIDTH * k + EXTRA - (WIDTH * k + EXTRA) % block)
    Q = np.empty((n, width), order="F")  # M-orthonormal basis (pages touched as used)
    T = np.zeros((width + block, width))
    X = np.random.default_rng(seed).standard_normal((n, block))
    MX = M @ X
    R = _cholesky(X.T @ MX)
    if R is None:
        return None
    Q[:, :block], MQ = _right_divide(X, R), [_right_divide(MX, R)]  # M Q of the newest two
    c = block  # columns of Q in use
    while True:
        j = c - block  # the newest block: Q[:, j:c]
        W = solve(MQ[-1])
        MW = M @ W
        lo = max(0, j - block)
        H = tdot(Q[:, lo:c], MW)  # the recurrence's coefficients
        W -= Q[:, lo:c] @ H
        MW -= np.hstack(MQ) @ H
        C = tdot(Q[:, :c], MW)  # once against every block
        W -= Q[:, :c] @ C
        C[lo:c] += H
        T[:c, j:c] = C
        MW = M @ W
        R = _cholesky(W.T @ MW)
        if R is None:
            return None
        theta, Y = la.eigh(0.5 * (T[:c, :c] + T[:c, :c].T))
        top = np.argsort(-theta, kind="stable")[:k]
        if len(top) == k and theta[top[-1]] > 0:
            residual = np.linalg.norm(R @ Y[j:c, top], axis=0)
            if np.all(residual <= tol * theta[top]):
                return 1.0 / theta[top], Q[:, :c] @ Y[:, top], c
        # a new block much smaller than the operator: the span is (nearly) invariant, and
        # what is left of W is rounding, not new directions
        if c + block > width or np.abs(np.diag(R)).min() <= RANK_TOL * theta[-1]:
            return None
        T[c:c + block, j:c] = R
        Q[:, c:c + block] = _right_divide(W, R)
        MQ = [MQ[-1], _right_divide(MW, R)]
        c += block


def _cholesky(G: np.ndarray) -> np.ndarray | None:
    """The upper Cholesky factor of a Gram matrix, or None (not positive definite: the block
    lost rank)."""
    try:
        R = la.cholesky(0.5 * (G + G.T))
    except la.LinAlgError:
        return None
    return R


def _right_divide(X: np.ndarray, R: np.ndarray) -> np.ndarray:
    """X R^-1 (R upper triangular, block x block): one product with the small inverse (a
    triangular solve on X^T copied X first, measured 5x slower); for one column a scaling,
    the same numbers (a product of one term) without a matrix product's call."""
    if len(R) == 1:
        return X * (1.0 / R[0, 0])
    return X @ la.solve_triangular(R, np.eye(len(R)), check_finite=False)
