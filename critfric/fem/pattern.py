"""The sparsity pattern of a vector (dim DOFs a node, dim = 2 or 3) finite-element matrix,
built once from the cells, and CSR assembly into it by index arithmetic (no COO sum of
duplicates).

Node level first: row i of the node pattern holds every node sharing a cell with i, columns
sorted (the lower neighbours, i itself, the upper ones). Each entry (i, j) is a dim x dim
block of the DOF matrix (interleaved DOFs dim i + k, k < dim): each DOF row dim i + k holds
the dim columns dim j + m of every neighbour j, in the node order. One sort of the distinct node
pairs of the cells (a < b) locates every cell's node pair in that pattern; assembling is then
one ``bincount`` per block component, in cell order.
"""

from __future__ import annotations

from functools import cached_property

import numpy as np
import scipy.sparse as sp


class BlockPattern:
    """The node-block CSR pattern of ``cells`` (n_cells, n_local) over ``n_nodes`` nodes,
    ``dim`` x ``dim`` blocks (node i has DOFs dim i + k).

    where : (n_cells, n_local, n_local) position, in the node pattern, of the block of
            cell c's local node pair (a, b) (made on first use: the node pattern, and with it
            :meth:`upper`, is ready before).
    """

    def __init__(self, cells: np.ndarray, n_nodes: int, dim: int = 2):
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
        self.n_nodes, self.nnz, self.dim = n, int(ptr[-1]), int(dim)
        self._ptr, self._col = ptr, col  # the node pattern
        self._itype = np.int32 if dim * dim * self.nnz < np.iinfo(np.int32).max else np.int64
        # what ``where`` is made from, on first use: the node pattern is ready before it
        self._made_from = (cells, inverse.reshape(n_cells, -1), diag, upper, lower)

    @cached_property
    def where(self) -> np.ndarray:
        cells, inverse, diag, upper, lower = self._made_from
        del self._made_from
        n_cells, nl = cells.shape
        a, b = np.triu_indices(nl, k=1)
        where = np.empty((n_cells, nl, nl), dtype=np.intp)
        where[:, np.arange(nl), np.arange(nl)] = diag[cells]
        in_upper, in_lower = upper[inverse], lower[inverse]
        ab = np.where(cells[:, a] < cells[:, b], in_upper, in_lower)  # (u, v) is in row u
        where[:, a, b], where[:, b, a] = ab, in_upper + in_lower - ab
        return where

    @cached_property
    def _at(self) -> list:
        """_at[k][m][q]: the DOF-level entry of component (k, m) of node block q. Block q of
        node row i starts at d^2 ptr[i] + d (q - ptr[i]) in DOF row d i; DOF row d i + k
        starts k d degree[i] entries later (d = dim)."""
        return _block_entries(self._ptr, self.dim)

    @cached_property
    def indptr(self) -> np.ndarray:
        """The DOF matrix's CSR row pointers (built on first use)."""
        d, ptr = self.dim, self._ptr
        degree = np.diff(ptr)
        indptr = np.empty(d * self.n_nodes + 1, dtype=self._itype)
        for k in range(d):
            indptr[k:-1:d] = d * d * ptr[:-1] + k * d * degree
        indptr[-1] = d * d * ptr[-1]
        return indptr

    @cached_property
    def indices(self) -> np.ndarray:
        """The DOF matrix's CSR column indices, sorted in each row (built on first use)."""
        d = self.dim
        indices = np.empty(d * d * self.nnz, dtype=self._itype)
        for k in range(d):
            for m in range(d):
                indices[self._at[k][m]] = d * self._col + m
        return indices

    def upper(self, position: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``upper_pattern(self.indptr, self.indices, position)[:2]``, the upper triangle of
        the DOF pattern restricted to the rows and columns kept by ``position``, made from the
        node pattern's upper half alone (a quarter of the DOF pattern's entries, and the DOF
        pattern is not built): what a factorization's analysis needs first."""
        d, n, ptr, col = self.dim, self.n_nodes, self._ptr, self._col
        itype = self._itype
        node_row = np.repeat(np.arange(n, dtype=itype), np.diff(ptr))
        up = np.flatnonzero(col >= node_row)  # node entries (i, j >= i), in CSR order
        i, j = node_row[up], col[up].astype(itype)
        del node_row
        uptr = np.zeros(n + 1, dtype=np.int64)
        np.cumsum(np.bincount(i, minlength=n), out=uptr[1:])
        at = _block_entries(uptr, d)  # the DOF order of the upper node blocks' entries
        dof_row = np.empty(d * d * len(up), dtype=itype)
        dof_col = np.empty_like(dof_row)
        for k in range(d):
            for m in range(d):
                dof_row[at[k][m]], dof_col[at[k][m]] = d * i + k, d * j + m
        del at, i, j
        position = np.asarray(position).astype(itype)
        new_row, new_col = position[dof_row], position[dof_col]
        keep = (dof_col >= dof_row) & (new_row >= 0) & (new_col >= 0)
        m_kept = int(np.count_nonzero(position >= 0))
        out = np.zeros(m_kept + 1, dtype=itype)
        np.cumsum(np.bincount(new_row[keep], minlength=m_kept), out=out[1:])
        return out, new_col[keep]

    def block_sums(self, values: np.ndarray) -> np.ndarray:
        """Sum of cell values (n_cells, n_local, n_local) into the node pattern (nnz,)."""
        return np.bincount(self.where.ravel(), weights=values.ravel(), minlength=self.nnz)

    def csr(self, blocks) -> sp.csr_matrix:
        """The DOF matrix (dim n_nodes square, sorted indices) whose dim x dim block q has
        entries ``blocks[k][m][q]`` (k: row component, m: column component)."""
        d = self.dim
        data = np.empty(d * d * self.nnz)
        for k in range(d):
            for m in range(d):
                data[self._at[k][m]] = blocks[k][m]
        n = d * self.n_nodes
        A = sp.csr_matrix((data, self.indices.copy(), self.indptr.copy()), shape=(n, n))
        A.has_sorted_indices = True
        return A


def _block_entries(ptr: np.ndarray, d: int) -> list:
    """[k][m]: the DOF-level CSR position of component (k, m) of each block of a node-block
    pattern with row pointers ``ptr`` (blocks in CSR order, d x d each, rows interleaved)."""
    degree = np.diff(ptr)
    row = np.repeat(np.arange(len(degree)), degree)
    start, row_length = d * (np.arange(ptr[-1]) + (d - 1) * ptr[row]), d * degree[row]
    del row
    return [[start + k * row_length + m for m in range(d)] for k in range(d)]


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
