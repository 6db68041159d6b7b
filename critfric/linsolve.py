"""Sparse direct solvers behind one small interface.

``factorize(A, symmetric=...)`` returns an object with ``solve(b)`` for b of shape (n,) or
(n, k) and a ``backend`` name. The SciPy backend never uses SuperLU's default COLAMD
ordering on these matrices: for an SPD stiffness matrix it orders A^T + A by minimum degree
and pivots on the diagonal (symmetric mode), which is several times faster and leaner.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from .errors import SolverError

BACKENDS = ("scipy",)


class ScipyFactor:
    """SuperLU with a symmetric ordering (minimum degree on A^T + A)."""

    backend = "scipy"

    def __init__(self, A: sp.spmatrix, *, symmetric: bool):
        A = sp.csc_matrix(A)
        options = {"SymmetricMode": True} if symmetric else {}
        try:
            self._lu = spla.splu(
                A,
                permc_spec="MMD_AT_PLUS_A",
                diag_pivot_thresh=0.0 if symmetric else 0.1,
                options=options,
            )
        except RuntimeError as exc:  # "Factor is exactly singular"
            raise SolverError(
                f"the sparse factorization failed ({exc}): the stiffness matrix is singular. "
                "Check that the Dirichlet edges hold the body (no rigid motion left)."
            ) from None
        self.shape = A.shape

    def solve(self, b: np.ndarray) -> np.ndarray:
        return self._lu.solve(np.asarray(b, dtype=np.float64))


def factorize(A: sp.spmatrix, *, symmetric: bool = True, backend: str = "scipy"):
    """Factor a sparse square matrix once; solve many right-hand sides."""
    if A.shape[0] == 0:
        raise SolverError("nothing to factor: the system has no free degree of freedom")
    if backend not in BACKENDS:
        raise SolverError(f"unknown linear solver backend {backend!r}; available: "
                          + ", ".join(BACKENDS))
    return ScipyFactor(A, symmetric=symmetric)
