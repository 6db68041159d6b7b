"""Sparse direct solvers behind one small interface, with backends chosen at run time.

* ``factorize(A, symmetric=..., backend=...)``: an object with ``solve(b)`` for b of shape
  (n,) or (n, k) and the ``backend`` name it used.
* ``schur(A, index, backend=...)``: the dense Schur complement ``S`` of A onto the rows and
  columns ``index`` (in that order), and ``extend(x_c)``: the full vector x with
  ``x[index] = x_c`` and the other rows solving ``(A x)_i = 0``.

Backends (``BACKENDS``; ``"auto"`` takes the first available of ``PREFERENCE``):

* ``scipy``, always there: SuperLU with diagonal pivots and a symmetric ordering, never the
  default COLAMD (~16x slower and ~8x larger on these matrices): nested dissection of the mesh
  when the caller gives it (:mod:`critfric.solvers.ordering`, ~3x faster than the
  alternative), else minimum degree on A^T + A. Its Schur complement comes from the same
  factorization, with the Schur rows ordered last; from SPLIT_MIN_ROWS rows (or
  SPLIT_MIN_SCHUR Schur rows) on, from the pieces of a partition factored two at a time in
  threads (:class:`SplitSchur`), in about half the memory (2.1 against 4.2 GB at 1.3 M rows,
  measured) and, with many Schur rows (3D), in less time.
* ``pardiso``: Intel MKL PARDISO, from the ``pypardiso`` wheel (``pip install
  critfric[fast]``, x86-64), called directly through ctypes (:mod:`.pardiso`): METIS
  ordering, Cholesky-class factorization (mtype 2) and the Schur complement computed during
  the factorization itself; its analysis can start from the pattern before the values exist
  (``schur(..., plan=PardisoPlan(...))``).
"""

from __future__ import annotations

import functools
import threading
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import scipy.linalg as la
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from threadpoolctl import ThreadpoolController

from ..errors import CaseError, SolverError
from ..fem.arrays import distinct
from ..guards import SPLIT_MIN_ROWS, usable_cpus
from .pardiso import SINGULAR as _SINGULAR
from .pardiso import PardisoFactor, PardisoPlan, pardiso_library, symmetrize
from .superlu import trailing_blocks

BACKENDS = ("scipy", "pardiso")
#: SciPy substructures from SPLIT_MIN_ROWS rows (guards: the memory model depends on it) or
#: from this many Schur rows on: SuperLU factors the dense trailing block of k rows
#: itself, slowly (3D P1 box, k = 4311 / 5790 / 9051 at 47 k / 76 k / 144 k DOFs: 21.6 / 68 /
#: 361 s and 2.5 / 4.5 / 11.1 GB in one factorization, 17.1 / 52 / 283 s and 2.2 / 3.8 /
#: 8.6 GB substructured; at k = 2367, 20 k DOFs, 3.9 against 7.0 s)
SPLIT_MIN_SCHUR = 4000
SPLIT_WORKERS = 2  # pieces factored at once (threads; at most the CPUs this process may use)
#: a SuperLU solve of many right-hand sides shares them among threads (:func:`_superlu_solve`),
#: SOLVE_PART columns at least each, from SOLVE_SPLIT_ROWS rows on. K_rr of the P1 unit square
#: on 2 cores, ms a column, shared against one call (the best of 5): 295 k rows, 16 columns
#: 16.8 against 23.8, 60 columns 14.5 against 20.7 (8 columns 26.9 against 25.3); 50 k rows,
#: 16 columns 2.6 against 3.5; 24 k rows, 16 columns 1.5 against 1.5
SOLVE_PART, SOLVE_SPLIT_ROWS = 8, 50_000
SYMMETRIZE_ROWS = 256  # _trailing_product mirrors S's lower triangle this many rows at a time
REFINE_STEPS = 3  # ScipySchur.extend: refinement steps on the contact rows (1-2 are used)
PREFERENCE = ("pardiso", "scipy")  # "auto": fastest first


def available_backends() -> tuple[str, ...]:
    """Backends that can run here, fastest first."""
    return tuple(b for b in PREFERENCE if b == "scipy" or pardiso_library() is not None)


def resolve_backend(backend: str = "auto") -> str:
    """The backend name that ``backend`` ("auto" or a name) stands for here."""
    if backend == "auto":
        return available_backends()[0]
    if backend not in BACKENDS:
        raise CaseError(f"got {backend!r}; allowed: auto, " + ", ".join(BACKENDS),
                        key="solve.backend")
    if backend not in available_backends():
        raise CaseError(f"got {backend!r}, which is not installed here; allowed: "
                        + ", ".join(("auto",) + available_backends())
                        + " (`pip install critfric[fast]` adds PARDISO on x86-64)",
                        key="solve.backend")
    return backend


class ScipyFactor:
    """SuperLU with a symmetric ordering: ``order`` (a fill-reducing permutation, e.g.
    :func:`critfric.ordering.nested_dissection`) if given, else minimum degree on A^T + A."""

    backend = "scipy"

    def __init__(self, A: sp.spmatrix, *, symmetric: bool, order=None):
        self._order = None if order is None else np.asarray(order)
        if self._order is not None:
            A = sp.csr_matrix(A)[self._order][:, self._order]
        A = sp.csc_matrix(A)
        options = {"SymmetricMode": True} if symmetric else {}
        try:
            self._lu = spla.splu(A, permc_spec="MMD_AT_PLUS_A" if order is None else "NATURAL",
                                 diag_pivot_thresh=0.0 if symmetric else 0.1, options=options)
        except RuntimeError as exc:  # "Factor is exactly singular"
            raise SolverError(f"the sparse factorization failed ({exc}): {_SINGULAR}") from None
        self.shape = A.shape

    def solve(self, b: np.ndarray, *, transpose: bool = False) -> np.ndarray:
        """A^-1 b (A^-T b with ``transpose``) for b of shape (n,) or (n, k)."""
        b = np.asarray(b, dtype=np.float64)
        trans = "T" if transpose else "N"
        if self._order is None:
            return _superlu_solve(self._lu, b, trans)
        return _permuted_solve(self._lu, b, self._order, trans)


def _permuted_solve(lu, b: np.ndarray, order: np.ndarray, trans: str = "N") -> np.ndarray:
    """x with x[order] = lu.solve(b[order]): the rows gathered by ``np.take`` into the
    column-major array SuperLU reads (b[order] and a copy for SuperLU took 32 ms at 295 k
    rows and 4 columns, np.take 14 ms); a column-major b gathered column by column (60
    columns: 74 ms against 221 ms through a row-major copy)."""
    if b.ndim == 2 and b.flags.f_contiguous:
        gathered = np.take(b.T, order, axis=1).T
    else:
        gathered = np.asfortranarray(np.take(b, order, axis=0))
    y = _superlu_solve(lu, gathered, trans)
    x = np.empty_like(y)
    x[order] = y
    return x


def _superlu_solve(lu, b: np.ndarray, trans: str = "N") -> np.ndarray:
    """lu.solve(b); from the main thread, the columns of a large b shared among the usable
    CPUs, SOLVE_PART at least each, OpenBLAS on one thread meanwhile: SuperLU's solve is
    sequential, lets other threads run and solves each column on its own (to rounding: its
    kernels differ with the number of columns); two OpenBLAS threads in each solve made it
    1.5-2x slower."""
    k = b.shape[1] if b.ndim == 2 else 1
    parts = min(usable_cpus(), k // SOLVE_PART)
    if (parts < 2 or b.shape[0] < SOLVE_SPLIT_ROWS
            or threading.current_thread() is not threading.main_thread()):
        return lu.solve(b, trans=trans)
    ends = np.linspace(0, k, parts + 1).astype(int)
    x = np.empty(b.shape, order="F")

    def part(i: int) -> None:
        x[:, ends[i]:ends[i + 1]] = lu.solve(b[:, ends[i]:ends[i + 1]], trans=trans)

    with _openblas().limit(limits=1):
        _in_threads(part, range(parts), parts)
    return x


def _in_threads(fn, items, workers: int) -> list:
    """fn over items, ``workers`` threads at a time, the results in order."""
    items = list(items)
    if workers == 1 or len(items) < 2:
        return [fn(h) for h in items]
    pool = ThreadPoolExecutor(min(workers, len(items)))
    try:
        return list(pool.map(fn, items))
    finally:  # on an error or Ctrl-C, no item not yet started is begun
        pool.shutdown(wait=True, cancel_futures=True)


@functools.cache
def _openblas() -> ThreadpoolController:
    """numpy's and SciPy's OpenBLAS (loaded by then: SuperLU's solve calls SciPy's)."""
    return ThreadpoolController().select(internal_api="openblas")


# ------------------------------------------------------------------------------- interface
def factorize(A: sp.spmatrix, *, symmetric: bool = True, backend: str = "scipy", order=None,
              diagonal: bool = False, plan: PardisoPlan | None = None):
    """Factor a sparse square matrix once; solve many right-hand sides. ``order``: a
    fill-reducing permutation for backends without a good ordering of their own (scipy).
    ``diagonal``: a structurally symmetric, unsymmetric matrix factored with diagonal pivots
    in that order (scipy; ~10x less fill and time than threshold pivoting on the stability
    pencils, measured); the caller checks its solves' residuals (PARDISO's pivoting is its
    own either way). ``plan``: a :class:`PardisoPlan` (no Schur rows) of symmetric A's
    pattern, used if it matches."""
    if A.shape[0] == 0:
        raise SolverError("nothing to factor: the system has no free degree of freedom")
    backend = resolve_backend(backend)
    if backend == "pardiso":
        factor = plan.factor(A) if plan is not None and symmetric else None
        return factor or PardisoFactor(A, symmetric=symmetric)
    return ScipyFactor(A, symmetric=symmetric or diagonal, order=order)


class ScipySchur:
    """Schur complement by one SuperLU factorization of A with the ``index`` rows ordered
    last (after ``order``, a fill-reducing order of all rows; minimum degree if None).

    Without pivoting, A = L U and the trailing blocks give S = L_cc U_cc exactly: no solve
    per contact DOF, and the blocks are read inside the factors (:mod:`.superlu`). The
    factorization is kept: :meth:`solve` serves the whole matrix and :meth:`extend` costs
    one solve."""

    backend = "scipy"

    def __init__(self, A: sp.spmatrix, index: np.ndarray, order=None):
        A = sp.csr_matrix(A)
        n, k = A.shape[0], len(index)
        if order is None:
            from .ordering import minimum_degree

            order = minimum_degree(A)
        last = np.zeros(n, dtype=bool)
        last[index] = True
        order = np.asarray(order)
        self._order = np.concatenate([order[~last[order]], index])
        try:
            lu = spla.splu(A[self._order][:, self._order].tocsc(), permc_spec="NATURAL",
                           diag_pivot_thresh=0.0, options={"SymmetricMode": True})
        except RuntimeError as exc:  # "Factor is exactly singular"
            raise SolverError(f"the sparse factorization failed ({exc}): {_SINGULAR}") from None
        tail = np.arange(n - k, n)
        if np.array_equal(lu.perm_c[tail], tail) and np.array_equal(lu.perm_r[tail], tail):
            # read in place (lu.L, lu.U copy whole factors); two k x k arrays at most
            S = _trailing_product(list(trailing_blocks(lu, k) or (
                lu.L[n - k:, n - k:].toarray(), lu.U[n - k:, n - k:].toarray())))
        else:  # SuperLU reordered the tail after all: S^-1 from k solves
            E = np.zeros((n, k))
            E[tail, np.arange(k)] = 1.0
            S = np.linalg.inv(_superlu_solve(lu, E)[tail])
        self._lu, self._index, self.shape = lu, np.asarray(index), (n, n)
        self.S = symmetrize(S)

    def solve(self, b: np.ndarray) -> np.ndarray:
        """A^-1 b for b of shape (n,) or (n, m)."""
        return _permuted_solve(self._lu, np.asarray(b, dtype=np.float64), self._order)

    def extend(self, xc: np.ndarray) -> np.ndarray:
        """x with x[index] = xc and (A x)_i = 0 on the other rows.

        x = A^-1 [0; f] has zero interior rows for any f; f = S xc, refined on the contact
        rows (x_c = S^-1 f carries the conditioning of S), then x[index] = xc exactly."""
        xc = np.asarray(xc, dtype=np.float64)
        b = np.zeros((self.shape[0],) + xc.shape[1:])
        x = np.zeros_like(b)
        error = xc
        for _ in range(REFINE_STEPS):
            b[self._index] = self.S @ error
            x += self.solve(b)
            error = xc - x[self._index]
            if np.abs(error).max() <= 1e-15 * np.abs(xc).max():
                break
        x[self._index] = xc
        return x


def _trailing_product(blocks: list) -> np.ndarray:
    """S = L U for the trailing blocks ``blocks`` = [L, U] of a symmetric positive definite
    matrix's factors without pivoting (L unit lower, U = D L^T upper): L D L^T, by LAPACK's
    lauum on the scaled factor reversed (J M J upper, M = L D^1/2: (J M J)(J M J)^T = J S J),
    a third of a matrix product's operations (2478 rows: 0.12 s against 0.54 s, one thread);
    the product itself where a pivot is not positive. ``blocks`` is emptied: each block is
    freed once read (two k x k arrays at most, where the product holds three)."""
    L, U = blocks
    blocks.clear()
    d = np.diag(U).copy()
    if not np.all(d > 0):
        return L @ U
    del U
    k = len(d)
    R = np.empty((k, k), order="F")
    np.multiply(L[::-1, ::-1], np.sqrt(d)[::-1], out=R)  # J M J: upper (L: zeros above)
    del L
    out, _ = la.lapack.dlauum(R, lower=0, overwrite_c=True)  # fails on bad arguments alone
    S = out[::-1, ::-1]  # S's lower triangle, zeros above: the upper one mirrored in place
    for i in range(0, k, SYMMETRIZE_ROWS):
        j = min(i + SYMMETRIZE_ROWS, k)
        diagonal = S[i:j, i:j]
        diagonal += np.tril(diagonal, -1).T
        S[i:j, j:] = S[j:, i:j].T
    return S


class SplitSchur:
    """Schur complement by substructuring: SuperLU factors the pieces of a partition one per
    worker thread at a time (SuperLU is sequential and releases the GIL), each with its
    interface last, so that at most ``workers`` pieces' factors are ever in memory.

    ``pieces``: a piece number (>= 0) for each row, -1 for separator rows, such that no
    entry of A joins two pieces. The interface is I = [index, separator rows not in index];
    piece h, adjacent to the part I_h of I, gives as :class:`ScipySchur` with I_h last
    S_h = A_(I_h I_h) - A_(I_h h) A_hh^-1 A_(h I_h). The Schur complement onto I is A_II plus
    each S_h - A_(I_h I_h) in its rows and columns; onto ``index``, that with the separator
    rows eliminated densely. :meth:`extend` sets the separator rows from the contact values,
    then extends into each piece by its interior alone, factored again (~2x cheaper than with
    its interface: no dense block; keeping pieces' factors instead would hold ``workers`` of
    them through the dense stage: peak 2.80 against 2.2 GB at 1.3 M rows, measured)."""

    backend = "scipy"

    def __init__(self, A: sp.spmatrix, index: np.ndarray, pieces: np.ndarray, order=None,
                 workers: int = 1):
        A = sp.csr_matrix(A)
        n, k = A.shape[0], len(index)
        in_index = np.zeros(n, dtype=bool)
        in_index[index] = True
        label = np.where(in_index, -1, np.asarray(pieces))  # index rows join the interface
        ids, label[label >= 0] = np.unique(label[label >= 0], return_inverse=True)
        order = np.arange(n) if order is None else np.asarray(order)
        side = label[order]
        self._rows = [order[side == h] for h in range(len(ids))]
        sep = order[(side < 0) & ~in_index[order]]
        row_label, col_label = np.repeat(label, np.diff(A.indptr)), label[A.indices]
        joined = (row_label >= 0) & (col_label >= 0) & (row_label != col_label)
        if len(ids) < 2 or not len(sep) or np.any(joined):  # no partition
            raise _NoSplit
        interface = np.concatenate([index, sep]).astype(np.int64)
        position = np.full(n, -1)
        position[interface] = np.arange(len(interface))
        at = (row_label >= 0) & (col_label < 0)  # piece rows, interface columns
        pairs = distinct(row_label[at] * len(interface) + position[A.indices[at]])
        self._touch = np.split(pairs % len(interface),
                               np.searchsorted(pairs // len(interface), np.arange(1, len(ids))))
        self._A, self._interface, self._workers = A, interface, max(1, workers)
        self.shape = (n, n)
        A_II = A[interface][:, interface]  # sparse: the dense S_I is the one large copy
        S_I = A_II.toarray()
        S_pieces = _in_threads(lambda h: self._factor(h).S, range(len(ids)), self._workers)
        for h, S_h in enumerate(S_pieces):
            touch = self._touch[h]
            S_I[np.ix_(touch, touch)] += S_h - A_II[touch][:, touch].toarray()
        self._S_sc = S_I[k:, :k].copy()
        try:  # reads one triangle of the separator block
            self._sep = la.cho_factor(S_I[k:, k:], overwrite_a=True)
        except la.LinAlgError:
            raise SolverError("the Schur complement onto the separator is not positive "
                              f"definite: {_SINGULAR}") from None
        # S_sc^T C^-1 S_sc = Y^T Y, Y = U^-T S_sc (C = U^T U): one triangular solve, not two
        factor, lower = self._sep
        Y = la.solve_triangular(factor, self._S_sc, trans="N" if lower else "T", lower=lower,
                                check_finite=False)
        S = S_I[:k, :k] - Y.T @ Y
        del Y
        self.S = symmetrize(S)

    def _factor(self, h: int) -> ScipySchur:
        """Piece h's factorization with its interface last."""
        rows = np.concatenate([self._rows[h], self._interface[self._touch[h]]])
        tail = np.arange(len(self._rows[h]), len(rows))
        return ScipySchur(self._A[rows][:, rows], tail, order=np.arange(len(rows)))

    def extend(self, xc: np.ndarray) -> np.ndarray:
        """x with x[index] = xc and (A x)_i = 0 on the other rows."""
        xc = np.asarray(xc, dtype=np.float64)
        x_I = np.concatenate([xc, -la.cho_solve(self._sep, self._S_sc @ xc)])
        x = np.zeros((self.shape[0],) + xc.shape[1:])

        def interior(h: int) -> np.ndarray:  # rows solving A_hh x_h = -A_hI x_I
            rows, touch = self._rows[h], self._interface[self._touch[h]]
            f = ScipyFactor(self._A[rows][:, rows], symmetric=True, order=np.arange(len(rows)))
            return -f.solve(self._A[rows][:, touch] @ x_I[self._touch[h]])

        for h, x_h in enumerate(_in_threads(interior, range(len(self._rows)), self._workers)):
            x[self._rows[h]] = x_h
        x[self._interface] = x_I
        return x


class _NoSplit(Exception):
    """The pieces given to :class:`SplitSchur` are fewer than two or not separated."""


def schur(A: sp.spmatrix, index: np.ndarray, *, backend: str = "scipy", order=None,
          pieces=None, plan: PardisoPlan | None = None):
    """Dense Schur complement of a symmetric positive definite A onto ``index`` (object with
    ``S``, ``extend(x_c)`` and ``backend``); ``order`` as for :func:`factorize`. ``pieces``: a
    partition of A's rows as :class:`SplitSchur` takes it, or a function that makes one; SciPy
    substructures on it from SPLIT_MIN_ROWS rows or SPLIT_MIN_SCHUR Schur rows on,
    SPLIT_WORKERS pieces at a time.
    ``plan``: a :class:`PardisoPlan` of A's pattern, used if it matches."""
    index = np.asarray(index, dtype=np.int64)
    backend = resolve_backend(backend)
    if backend == "pardiso" and len(index) < A.shape[0]:
        factor = plan.schur(A, index) if plan is not None else None
        return factor or PardisoFactor(A, symmetric=True, schur_index=index)
    if pieces is not None and (A.shape[0] >= SPLIT_MIN_ROWS or len(index) >= SPLIT_MIN_SCHUR):
        try:
            return SplitSchur(A, index, pieces() if callable(pieces) else pieces, order=order,
                              workers=min(SPLIT_WORKERS, usable_cpus()))
        except _NoSplit:  # no partition of A's graph: one factorization of the whole
            pass
    return ScipySchur(A, index, order=order)
