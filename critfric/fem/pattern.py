"""The sparsity pattern of a vector (two DOFs a node) finite-element matrix, built once from
the cells, and CSR assembly into it by index arithmetic (no COO sum of duplicates).

Node level first: row i of the node pattern holds every node sharing a cell with i, columns
sorted (the lower neighbours, i itself, the upper ones). Each entry (i, j) is a 2 x 2 block
of the DOF matrix (interleaved DOFs 2i, 2i + 1): DOF rows 2i and 2i + 1 each hold the two
columns 2j, 2j + 1 of every neighbour j, in the node order. One sort of the distinct node
pairs of the cells (a < b) locates every cell's node pair in that pattern; assembling is then
one ``bincount`` per block component, in cell order.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp


class BlockPattern:
    """The node-block CSR pattern of ``cells`` (n_cells, n_local) over ``n_nodes`` nodes.

    where : (n_cells, n_local, n_local) position, in the node pattern, of the block of
            cell c's local node pair (a, b).
    """

    def __init__(self, cells: np.ndarray, n_nodes: int):
        cells = np.asarray(cells, dtype=np.int64)
        n_cells, nl = cells.shape
        n = int(n_nodes)
        a, b = np.triu_indices(nl, k=1)
        u, v = cells[:, a], cells[:, b]  # (n_cells, n_pairs), u != v
        keys, inverse = np.unique((np.minimum(u, v) * n + np.maximum(u, v)).ravel(),
                                  return_inverse=True)
        lo, hi = keys // n, keys % n  # distinct pairs lo < hi, sorted by (lo, hi)
        n_lower, n_upper = np.bincount(hi, minlength=n), np.bincount(lo, minlength=n)
        degree = n_lower + n_upper + 1
        ptr = np.zeros(n + 1, dtype=np.int64)
        np.cumsum(degree, out=ptr[1:])
        diag = ptr[:-1] + n_lower
        pair = np.arange(len(keys))
        upper = diag[lo] + 1 + pair - (np.cumsum(n_upper) - n_upper)[lo]  # (lo, hi) in row lo
        by_hi = np.argsort(hi, kind="stable")  # row hi: its lower neighbours sorted by lo
        lower = np.empty_like(upper)  # (hi, lo) in row hi
        lower[by_hi] = ptr[hi[by_hi]] + pair - (np.cumsum(n_lower) - n_lower)[hi[by_hi]]
        col = np.empty(ptr[-1], dtype=np.int64)
        col[diag], col[upper], col[lower] = np.arange(n), hi, lo

        where = np.empty((n_cells, nl, nl), dtype=np.intp)
        where[:, np.arange(nl), np.arange(nl)] = diag[cells]
        inverse = inverse.reshape(n_cells, -1)
        in_upper, in_lower = upper[inverse], lower[inverse]
        ab = np.where(u < v, in_upper, in_lower)  # (u, v) is in row u
        where[:, a, b], where[:, b, a] = ab, in_upper + in_lower - ab
        self.where, self.n_nodes, self.nnz = where, n, int(ptr[-1])

        # DOF level: block q of node row i starts at 4 ptr[i] + 2 (q - ptr[i]) in DOF row 2i;
        # DOF row 2i + 1 starts 2 degree[i] entries later
        row = np.repeat(np.arange(n), degree)
        start, row_length = 2 * (np.arange(self.nnz) + ptr[row]), 2 * degree[row]
        del row
        self._at = [[start + k * row_length + m for m in range(2)] for k in range(2)]
        del start, row_length
        itype = np.int32 if 4 * self.nnz < np.iinfo(np.int32).max else np.int64
        indptr = np.empty(2 * n + 1, dtype=itype)
        indptr[0:-1:2], indptr[1::2] = 4 * ptr[:-1], 4 * ptr[:-1] + 2 * degree
        indptr[-1] = 4 * ptr[-1]
        indices = np.empty(4 * self.nnz, dtype=itype)
        for k in range(2):
            for m in range(2):
                indices[self._at[k][m]] = 2 * col + m
        self.indptr, self.indices = indptr, indices

    def block_sums(self, values: np.ndarray) -> np.ndarray:
        """Sum of cell values (n_cells, n_local, n_local) into the node pattern (nnz,)."""
        return np.bincount(self.where.ravel(), weights=values.ravel(), minlength=self.nnz)

    def csr(self, blocks) -> sp.csr_matrix:
        """The DOF matrix (2 n_nodes square, sorted indices) whose 2 x 2 block q has entries
        ``blocks[k][m][q]`` (k: row component, m: column component)."""
        data = np.empty(4 * self.nnz)
        for k in range(2):
            for m in range(2):
                data[self._at[k][m]] = blocks[k][m]
        n = 2 * self.n_nodes
        A = sp.csr_matrix((data, self.indices.copy(), self.indptr.copy()), shape=(n, n))
        A.has_sorted_indices = True
        return A


def upper_pattern(indptr: np.ndarray, indices: np.ndarray, position: np.ndarray | None = None
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The upper triangle (diagonal included) of a sorted CSR pattern: its ``(indptr,
    indices)`` and the mask of the entries kept (for the values: ``data[keep]``). With
    ``position`` (each row's and column's new index, -1 to drop it, increasing where kept),
    restricted to the rows and columns kept and renumbered: e.g. the free-DOF block."""
    n = len(indptr) - 1
    row = np.repeat(np.arange(n, dtype=indices.dtype), np.diff(indptr))
    keep = indices >= row
    if position is None:
        m, new_row, new_col = n, row, indices
    else:
        position = np.asarray(position).astype(indices.dtype)
        new_row, new_col = position[row], position[indices]
        keep &= (new_row >= 0) & (new_col >= 0)
        m = int(np.count_nonzero(position >= 0))
    ptr = np.zeros(m + 1, dtype=indptr.dtype)
    np.cumsum(np.bincount(new_row[keep], minlength=m), out=ptr[1:])
    return ptr, new_col[keep], keep
