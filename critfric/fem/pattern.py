"""The sparsity pattern of a vector (dim DOFs a node, dim = 2 or 3) finite-element matrix,
built once from the cells, and CSR assembly into it by index arithmetic (no COO sum of
duplicates).

Node level first: row i of the node pattern holds every node sharing a cell with i, columns
sorted (the lower neighbours, i itself, the upper ones). Each entry (i, j) is a dim x dim
block of the DOF matrix (interleaved DOFs dim i + k, k < dim): each DOF row dim i + k holds
the dim columns dim j + m of every neighbour j, in the node order. One sort gives the distinct
node pairs of the cells (a < b), and a search in them locates every cell's node pairs in that
pattern; assembling a block component is then a ``bincount`` over the cells' diagonal blocks
and one or two over their node pairs, in cell order: a symmetric component is summed from the
cells' local blocks a <= b alone and is exactly symmetric, and a component (k, m) gives its
transpose (m, k) with it.
"""

from __future__ import annotations

from functools import cached_property

import numpy as np
import scipy.sparse as sp

from .arrays import distinct, ranges


class BlockPattern:
    """The node-block CSR pattern of ``cells`` (n_cells, n_local) over ``n_nodes`` nodes,
    ``dim`` x ``dim`` blocks (node i has DOFs dim i + k).

    The distinct node pairs of the cells are found first; :meth:`upper` needs nothing more.
    The node pattern (rows of every neighbour) and each cell's pairs among the distinct ones
    follow on first use (:meth:`sums`, :meth:`csr`).
    """

    def __init__(self, cells: np.ndarray, n_nodes: int, dim: int = 2):
        cells = np.asarray(cells, dtype=np.int64)
        n = int(n_nodes)
        keys = distinct_pairs(cells, n)  # each cell's pairs found in them by ``_local``
        self.n_nodes, self.dim = n, int(dim)
        self.nnz = n + 2 * len(keys)  # node blocks: the diagonal and each pair both ways
        self._itype = np.int32 if dim * dim * self.nnz < np.iinfo(np.int32).max else np.int64
        # the distinct pairs lo < hi, sorted by (lo, hi)
        self._lo, self._hi = (keys // n).astype(self._itype), (keys % n).astype(self._itype)
        self._cells = cells

    @cached_property
    def _node(self) -> tuple:
        """The node pattern (ptr, col) and the positions in it of the diagonal blocks and of
        each pair's blocks (lo, hi) and (hi, lo)."""
        n, lo, hi = self.n_nodes, self._lo, self._hi
        n_lower, n_upper = np.bincount(hi, minlength=n), np.bincount(lo, minlength=n)
        ptr = np.zeros(n + 1, dtype=np.int64)
        np.cumsum(n_lower + n_upper + 1, out=ptr[1:])
        diag = ptr[:-1] + n_lower
        pair = np.arange(len(lo))
        upper = diag[lo] + 1 + pair - (np.cumsum(n_upper) - n_upper)[lo]  # (lo, hi) in row lo
        by_hi = np.argsort(hi, kind="stable")  # row hi: its lower neighbours by lo
        lower = np.empty_like(upper)  # (hi, lo) in row hi
        lower[by_hi] = ptr[hi[by_hi]] + pair - (np.cumsum(n_lower) - n_lower)[hi[by_hi]]
        col = np.empty(ptr[-1], dtype=np.int64)
        col[diag], col[upper], col[lower] = np.arange(n), hi, lo
        return ptr, col, diag, upper, lower

    @property
    def _ptr(self) -> np.ndarray:
        return self._node[0]

    @property
    def _col(self) -> np.ndarray:
        return self._node[1]

    @cached_property
    def _local(self) -> tuple:
        """Each cell's node pairs among the distinct ones, (n_cells, n_pairs) for the local
        pairs a < b in ``np.triu_indices`` order: the pair's index p, and the position of
        block (a, b) and of block (b, a) among the pairs' blocks [(lo, hi) blocks; (hi, lo)
        blocks] (p, or p + the number of pairs); with the cells, the diagonal blocks' index."""
        cells, n = self._cells, self.n_nodes
        del self._cells  # needed for nothing else
        n_cells, nl = cells.shape
        # searched here, after upper() has let the analysis start (1.29 M cells: the distinct
        # pairs alone take 0.13-0.15 s, with np.unique's inverse 0.40 s)
        inverse = np.searchsorted(self._lo.astype(np.int64) * n + self._hi,
                                  pair_keys(cells, n)).reshape(n_cells, -1)
        a, b = local_pairs(nl)
        flip = len(self._lo) * (cells[:, a] > cells[:, b])  # (a, b) is the pair's (hi, lo)
        across = len(self._lo) - flip
        return cells, inverse, inverse + flip, inverse + across

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
        the DOF pattern restricted to the rows and columns kept by ``position`` (increasing
        where kept), made from the distinct node pairs alone (neither the node pattern nor
        the DOF pattern is built): what a factorization's analysis needs first."""
        d, n, itype = self.dim, self.n_nodes, self._itype
        lo, hi = self._lo, self._hi
        # node row i of the upper half: i, then its upper neighbours in order
        uptr = np.zeros(n + 1, dtype=np.int64)
        np.cumsum(np.bincount(lo, minlength=n) + 1, out=uptr[1:])
        ucol = np.empty(uptr[-1], dtype=itype)
        ucol[uptr[:-1]] = np.arange(n, dtype=itype)
        ucol[lo + np.arange(1, len(lo) + 1)] = hi  # pair p of row lo: lo + 1 + p
        # node row i's DOF columns d j + m (j in row i, m < d), renumbered (-1: dropped);
        # DOF row d i + k takes them from the k-th on (the diagonal block's upper triangle)
        position = np.asarray(position).astype(itype)
        new = position[(d * ucol[:, None] + np.arange(d, dtype=itype)).ravel()]
        del ucol
        start = (d * uptr[:-1, None] + np.arange(d)).ravel()  # DOF row d i + k
        stop = np.repeat(d * uptr[1:], d)
        kept = position >= 0
        start, length = start[kept], stop[kept] - start[kept]
        cols = new[ranges(start, length)]
        del new
        keep = cols >= 0
        out = np.zeros(len(length) + 1, dtype=itype)  # every row has its diagonal entry
        out[1:] = np.cumsum(keep, dtype=itype)[np.cumsum(length) - 1]
        return out, cols[keep]

    def sums(self, diagonal: np.ndarray, up: np.ndarray, down: np.ndarray | None = None
             ) -> tuple[np.ndarray, np.ndarray]:
        """One block component (k, m) summed over the cells into the node pattern (nnz,), and
        its transpose, component (m, k): ``diagonal`` (n_cells, n_local) the cells' values at
        their local blocks (a, a), ``up`` (n_cells, n_pairs) at (a, b) and ``down`` at (b, a)
        for the local pairs a < b (:func:`local_pairs`). Without ``down`` the component is
        symmetric: ``up`` serves both, and the transpose is the same array."""
        cells, inverse, ab, ba = self._local
        _, _, diag, upper, lower = self._node
        n_pairs = len(self._lo)
        on_diagonal = np.bincount(cells.ravel(), weights=diagonal.ravel(),
                                  minlength=self.n_nodes)
        out = np.empty(self.nnz)
        out[diag] = on_diagonal
        if down is None:
            out[upper] = out[lower] = np.bincount(inverse.ravel(), weights=up.ravel(),
                                                  minlength=n_pairs)
            return out, out
        both = np.bincount(ab.ravel(), weights=up.ravel(), minlength=2 * n_pairs)
        both += np.bincount(ba.ravel(), weights=down.ravel(), minlength=2 * n_pairs)
        out[upper], out[lower] = both[:n_pairs], both[n_pairs:]
        transposed = np.empty(self.nnz)
        transposed[diag] = on_diagonal
        transposed[upper], transposed[lower] = both[n_pairs:], both[:n_pairs]
        return out, transposed

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


def local_pairs(n_local: int) -> tuple[np.ndarray, np.ndarray]:
    """A cell's local node pairs (a, b), a < b, in the order of every per-pair array here."""
    return np.triu_indices(n_local, k=1)


def pair_keys(cells: np.ndarray, n: int) -> np.ndarray:
    """lo * n + hi (int64) of every cell's local node pairs (a < b), cell after cell: the
    node pair lo < hi of ``n`` nodes as one sortable key."""
    cells = np.asarray(cells, dtype=np.int64)
    a, b = local_pairs(cells.shape[1])
    u, v = cells[:, a], cells[:, b]
    return (np.minimum(u, v) * n + np.maximum(u, v)).ravel()


def distinct_pairs(cells: np.ndarray, n: int) -> np.ndarray:
    """The distinct :func:`pair_keys` of the cells, increasing (pairs by lo, then hi)."""
    return distinct(pair_keys(cells, n))
