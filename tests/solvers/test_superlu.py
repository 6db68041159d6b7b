"""The trailing blocks of SuperLU's factors, read in place, equal those of ``lu.L``/``lu.U``."""

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from critfric.solvers.superlu import trailing_blocks


def _factor(n: int, density: float, seed: int):
    A = sp.random(n, n, density, random_state=seed, format="csr")
    A = A + A.T + sp.eye(n) * (abs(A).sum(axis=1).max() + 1.0)
    return spla.splu(A.tocsc(), permc_spec="NATURAL", diag_pivot_thresh=0.0,
                     options={"SymmetricMode": True})


def test_trailing_blocks_equal_the_copied_factors():
    for n, k, density in [(40, 6, 0.1), (600, 50, 0.01), (300, 300, 0.02), (200, 1, 0.05)]:
        lu = _factor(n, density, seed=n)
        blocks = trailing_blocks(lu, k)
        assert blocks is not None
        L, U = lu.L, lu.U
        assert np.array_equal(blocks[0], L[n - k:, n - k:].toarray())
        assert np.array_equal(blocks[1], U[n - k:, n - k:].toarray())
        copied = L[n - k:, n - k:].toarray() @ U[n - k:, n - k:].toarray()
        assert np.array_equal(blocks[0] @ blocks[1], copied)  # same layout, same rounding


def test_other_objects_are_refused():
    assert trailing_blocks(object(), 3) is None
    complex_lu = spla.splu((sp.eye(5) * (1 + 1j)).tocsc())  # another storage type
    assert trailing_blocks(complex_lu, 2) is None
