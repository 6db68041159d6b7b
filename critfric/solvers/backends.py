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
  factorization, with the Schur rows ordered last; from SPLIT_MIN_ROWS rows on, from the two
  halves of a bisection factored one after the other (:class:`SplitSchur`), in about two
  thirds of the memory.
* ``pardiso``: Intel MKL PARDISO, from the ``pypardiso`` wheel (``pip install
  critfric[fast]``, x86-64), called directly through ctypes: METIS ordering, Cholesky-class
  factorization (mtype 2) and the Schur complement computed during the factorization
  itself (iparm[35] = 2), solves without PARDISO's default iterative refinement.
"""

from __future__ import annotations

import ctypes
import functools
import importlib.metadata
import importlib.util
import threading
import weakref

import numpy as np
import scipy.linalg as la
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from ..errors import SolverError
from .superlu import trailing_blocks

BACKENDS = ("scipy", "pardiso")
SPLIT_MIN_ROWS = 400_000  # SciPy's Schur complement by substructuring from here on (memory)
REFINE_STEPS = 3  # ScipySchur.extend: refinement steps on the contact rows (1-2 are used)
PREFERENCE = ("pardiso", "scipy")  # "auto": fastest first

_SINGULAR = ("the stiffness matrix is singular. Check that the Dirichlet edges hold the body "
             "(no rigid motion left).")


def available_backends() -> tuple[str, ...]:
    """Backends that can run here, fastest first."""
    return tuple(b for b in PREFERENCE if b == "scipy" or _pardiso_library() is not None)


def resolve_backend(backend: str = "auto") -> str:
    """The backend name that ``backend`` ("auto" or a name) stands for here."""
    if backend == "auto":
        return available_backends()[0]
    if backend not in BACKENDS:
        raise SolverError(f"unknown linear solver backend {backend!r}; allowed: auto, "
                          + ", ".join(BACKENDS))
    if backend not in available_backends():
        raise SolverError(f"the linear solver backend {backend!r} is not available here; "
                          "install it with `pip install critfric[fast]` (x86-64) or use "
                          "backend = 'auto' or 'scipy'")
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
            return self._lu.solve(b, trans=trans)
        x = np.empty_like(b)
        x[self._order] = self._lu.solve(np.ascontiguousarray(b[self._order]), trans=trans)
        return x


# ------------------------------------------------------------------------------- PARDISO
@functools.cache
def _pardiso_library():
    """MKL's ``pardiso`` entry point (None if absent): mkl_rt from the ``mkl`` wheel's file
    list (fast), else found the way pypardiso finds it (importing it searches directories)."""
    if importlib.util.find_spec("pypardiso") is None:
        return None
    try:
        rt = [f for f in importlib.metadata.files("mkl") or [] if "libmkl_rt" in f.name]
        lib = ctypes.CDLL(str(rt[0].locate()))
    except (importlib.metadata.PackageNotFoundError, IndexError, OSError):
        try:
            import pypardiso
            lib = pypardiso.PyPardisoSolver().libmkl
        except (ImportError, OSError, AttributeError):
            return None
    p, i32 = ctypes.c_void_p, ctypes.POINTER(ctypes.c_int32)
    fn = lib.pardiso
    fn.argtypes = [p, i32, i32, i32, i32, i32, p, i32, i32, i32, i32, i32, i32, p, p, i32]
    fn.restype = None
    init = lib.pardisoinit
    init.argtypes = [p, i32, i32]
    init.restype = None
    return fn, init


_PARDISO_ERRORS = {-1: "input inconsistent", -2: "not enough memory",
                   -3: "reordering problem", -4: "zero pivot: " + _SINGULAR,
                   -7: "diagonal matrix is singular: " + _SINGULAR}


class PardisoFactor:
    """MKL PARDISO: symmetric positive definite (mtype 2) or general (mtype 11) matrices.

    With ``schur_index`` the factorization also returns the dense Schur complement onto
    those rows/columns (``self.S``, in the order given) and keeps the interior factors for
    :meth:`extend`.
    """

    backend = "pardiso"

    def __init__(self, A: sp.spmatrix, *, symmetric: bool, schur_index=None):
        fn, init = _pardiso_library()
        self._fn, n = fn, A.shape[0]
        if symmetric and not np.all(A.diagonal() > 0):
            raise SolverError(f"the matrix has a non-positive diagonal entry: {_SINGULAR}")
        A = upper_triangle(A) if symmetric else sp.csr_matrix(A)
        A.sort_indices()
        if A.nnz >= 2**31:
            raise SolverError(f"{A.nnz} nonzeros is too many for PARDISO's 32-bit interface; "
                              "use backend = 'scipy'")
        self._a = np.ascontiguousarray(A.data, dtype=np.float64)
        self._ia = A.indptr.astype(np.int32)
        self._ja = A.indices.astype(np.int32)
        self.mtype = 2 if symmetric else 11
        self.shape = (n, n)
        self._pt = np.zeros(64, dtype=np.int64)
        self._iparm = np.zeros(64, dtype=np.int32)
        init(self._pt.ctypes.data, _int(self.mtype), self._iparm.ctypes.data_as(_I32))
        self._iparm[0] = 1   # iparm given
        self._iparm[1] = 2   # METIS nested dissection
        self._iparm[7] = 0   # no iterative refinement beyond what perturbed pivots ask for
        self._iparm[34] = 1  # zero-based indices
        self._perm = np.zeros(n, dtype=np.int32)
        weakref.finalize(self, _pardiso_release, fn, self._pt, self.mtype, n)
        if schur_index is None:
            self._call(12, 1, np.zeros(n), np.zeros(n))
            return
        index = np.asarray(schur_index)
        self._perm[index] = 1
        self._iparm[35] = 2  # Schur complement, keep the interior factors for phase 333
        ns = len(index)
        buf = np.zeros(max(ns * ns, n))
        self._call(12, 1, np.zeros(n), buf)
        # PARDISO orders the Schur rows by increasing global index
        pos = np.searchsorted(np.sort(index), index)
        S = buf[:ns * ns].reshape(ns, ns)[np.ix_(pos, pos)]
        self.S = 0.5 * (S + S.T)
        self._index = index

    def _call(self, phase: int, nrhs: int, b: np.ndarray, x: np.ndarray) -> None:
        err = ctypes.c_int32(0)
        with _MKL_LOCK:
            self._fn(self._pt.ctypes.data, _int(1), _int(1), _int(self.mtype), _int(phase),
                     _int(self.shape[0]), self._a.ctypes.data, self._ia.ctypes.data_as(_I32),
                     self._ja.ctypes.data_as(_I32), self._perm.ctypes.data_as(_I32),
                     _int(nrhs), self._iparm.ctypes.data_as(_I32), _int(0), b.ctypes.data,
                     x.ctypes.data, ctypes.byref(err))
        if err.value != 0:
            what = _PARDISO_ERRORS.get(err.value, "see the MKL PARDISO error codes")
            raise SolverError(f"PARDISO phase {phase} failed with error {err.value} ({what}); "
                              "try backend = 'scipy'")

    def solve(self, b: np.ndarray, *, transpose: bool = False) -> np.ndarray:
        """A^-1 b (A^-T b with ``transpose``) for b of shape (n,) or (n, k)."""
        b = np.asarray(b, dtype=np.float64)
        bt = np.ascontiguousarray(b.T)  # column-major right-hand sides
        x = np.zeros_like(bt)
        self._iparm[11] = 2 if transpose and self.mtype != 2 else 0  # A^T x = b
        try:
            self._call(33, 1 if b.ndim == 1 else b.shape[1], bt, x)
        finally:
            self._iparm[11] = 0
        return x.T

    def extend(self, xc: np.ndarray) -> np.ndarray:
        xc = np.asarray(xc, dtype=np.float64)
        b = np.zeros(xc.shape[1:][::-1] + (self.shape[0],))
        b[..., self._index] = xc.T
        x = np.zeros_like(b)
        self._call(333, 1 if xc.ndim == 1 else xc.shape[1], b, x)
        return x.T


_I32 = ctypes.POINTER(ctypes.c_int32)


def upper_triangle(A: sp.spmatrix) -> sp.csr_matrix:
    """The upper triangle (diagonal included) of a square matrix as sorted CSR: one mask over
    the entries (what ``sp.triu`` gives, ~4x faster at 1 M rows)."""
    A = sp.csr_matrix(A)
    if not A.has_sorted_indices:
        A = A.sorted_indices()
    n = A.shape[0]
    row = np.repeat(np.arange(n, dtype=A.indices.dtype), np.diff(A.indptr))
    keep = A.indices >= row
    ptr = np.zeros(n + 1, dtype=A.indptr.dtype)
    np.cumsum(np.bincount(row[keep], minlength=n), out=ptr[1:])
    U = sp.csr_matrix((A.data[keep], A.indices[keep], ptr), shape=A.shape)
    U.has_sorted_indices = True
    return U


def _int(value: int):
    return ctypes.byref(ctypes.c_int32(value))


#: every MKL PARDISO call, the finalizers' releases included, one at a time: a factor freed
#: by the cyclic garbage collector is released in whatever thread the collection ran (pytest
#: workers' I/O threads, a user's threads), possibly during another factor's call; a full
#: suite under pytest -n 2 aborted twice in phase 12 with a corrupted heap
_MKL_LOCK = threading.RLock()


def _pardiso_release(fn, pt, mtype, n) -> None:
    """Phase -1 on ``pt``, with arrays of the sizes PARDISO's interface declares."""
    zero, index = np.zeros(n), np.zeros(n + 1, dtype=np.int32)
    iparm = np.zeros(64, dtype=np.int32)
    with _MKL_LOCK:
        fn(pt.ctypes.data, _int(1), _int(1), _int(mtype), _int(-1), _int(n), zero.ctypes.data,
           index.ctypes.data_as(_I32), index.ctypes.data_as(_I32), index.ctypes.data_as(_I32),
           _int(1), iparm.ctypes.data_as(_I32), _int(0), zero.ctypes.data, zero.ctypes.data,
           ctypes.byref(ctypes.c_int32(0)))


# ------------------------------------------------------------------------------- interface
def factorize(A: sp.spmatrix, *, symmetric: bool = True, backend: str = "scipy", order=None,
              diagonal: bool = False):
    """Factor a sparse square matrix once; solve many right-hand sides. ``order``: a
    fill-reducing permutation for backends without a good ordering of their own (scipy).
    ``diagonal``: a structurally symmetric, unsymmetric matrix factored with diagonal pivots
    in that order (scipy; ~10x less fill and time than threshold pivoting on the stability
    pencils, measured); the caller checks its solves' residuals (PARDISO's pivoting is its
    own either way)."""
    if A.shape[0] == 0:
        raise SolverError("nothing to factor: the system has no free degree of freedom")
    backend = resolve_backend(backend)
    if backend == "pardiso":
        return PardisoFactor(A, symmetric=symmetric)
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
            blocks = trailing_blocks(lu, k)  # read in place (lu.L, lu.U copy whole factors)
            if blocks is None:
                blocks = (lu.L[n - k:, n - k:].toarray(), lu.U[n - k:, n - k:].toarray())
            S = blocks[0] @ blocks[1]
        else:  # SuperLU reordered the tail after all: S^-1 from k solves
            E = np.zeros((n, k))
            E[tail, np.arange(k)] = 1.0
            S = np.linalg.inv(lu.solve(E)[tail])
        self._lu, self._index, self.shape = lu, np.asarray(index), (n, n)
        self.S = 0.5 * (S + S.T)

    def solve(self, b: np.ndarray) -> np.ndarray:
        """A^-1 b for b of shape (n,) or (n, m)."""
        b = np.asarray(b, dtype=np.float64)
        x = np.empty_like(b)
        x[self._order] = self._lu.solve(np.ascontiguousarray(b[self._order]))
        return x

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


class SplitSchur:
    """Schur complement by substructuring: SuperLU factors the two halves of a bisection one
    at a time, each with its interface last, so that only one half's factors (about half of
    the whole matrix's) are ever in memory.

    ``halves``: 0 or 1 for the two halves' rows, 2 for a separator such that no entry of A
    joins the halves. The interface is I = [index, separator rows not in index]; half h
    touches only the part I_h of I not in the other half, and gives, as :class:`ScipySchur`
    with I_h last, S_h = A_(I_h I_h) - A_(I_h h) A_hh^-1 A_(h I_h). The Schur complement onto
    I is A_II plus each S_h - A_(I_h I_h) in its rows and columns; onto ``index``, that with
    the separator rows eliminated densely. :meth:`extend` sets the separator rows from the
    contact values, then extends into each half: the half whose factors are still there
    first, then the other's interior, factored again without its interface (two half
    factorizations and one of a half's interior in all)."""

    backend = "scipy"

    def __init__(self, A: sp.spmatrix, index: np.ndarray, halves: np.ndarray, order=None):
        A = sp.csr_matrix(A)
        n, k = A.shape[0], len(index)
        halves = np.asarray(halves)
        in_index = np.zeros(n, dtype=bool)
        in_index[index] = True
        label = np.where(in_index, 2, halves)  # the rows of ``index`` join the interface
        order = np.arange(n) if order is None else np.asarray(order)
        side = label[order]
        self._rows = [order[side == h] for h in (0, 1)]
        sep = order[(side == 2) & ~in_index[order]]
        # an entry of A in a row of one half and a column of the other: no bisection
        row_label = np.repeat(label, np.diff(A.indptr))
        if not (len(self._rows[0]) and len(self._rows[1]) and len(sep)) or np.any(
                row_label + label[A.indices] == 1):
            raise _NoSplit
        interface = np.concatenate([index, sep]).astype(np.int64)
        self._touch = [np.flatnonzero(halves[interface] != 1 - h) for h in (0, 1)]
        self._A, self._interface = A, interface
        self.shape, self._half = (n, n), None
        A_II = A[interface][:, interface].toarray()
        S_I = A_II.copy()
        for h in (0, 1):  # the second half's factors stay for extend
            t = np.ix_(self._touch[h], self._touch[h])
            S_I[t] += self._factor(h).S - A_II[t]
        S_I = 0.5 * (S_I + S_I.T)
        try:
            self._sep = la.cho_factor(S_I[k:, k:])
        except la.LinAlgError:
            raise SolverError("the Schur complement onto the separator is not positive "
                              f"definite: {_SINGULAR}") from None
        self._S_sc = S_I[k:, :k]
        S = S_I[:k, :k] - self._S_sc.T @ la.cho_solve(self._sep, self._S_sc)
        self.S = 0.5 * (S + S.T)

    def _factor(self, h: int) -> ScipySchur:
        """Half h's factorization with its interface last; the other's is dropped first."""
        self._half = None  # one half's factors are freed before the other's are made
        rows = np.concatenate([self._rows[h], self._interface[self._touch[h]]])
        tail = np.arange(len(self._rows[h]), len(rows))
        self._half = (h, ScipySchur(self._A[rows][:, rows], tail, order=np.arange(len(rows))))
        return self._half[1]

    def extend(self, xc: np.ndarray) -> np.ndarray:
        """x with x[index] = xc and (A x)_i = 0 on the other rows."""
        xc = np.asarray(xc, dtype=np.float64)
        x_I = np.concatenate([xc, -la.cho_solve(self._sep, self._S_sc @ xc)])
        x = np.zeros((self.shape[0],) + xc.shape[1:])
        kept = self._half[0] if self._half else None
        for h in sorted((0, 1), key=lambda h: h != kept):
            rows, touch = self._rows[h], self._interface[self._touch[h]]
            if h == kept:
                x[rows] = self._half[1].extend(x_I[self._touch[h]])[:len(rows)]
                continue
            # the other half's interior alone (no dense interface block: ~2x cheaper), its
            # rows solving A_hh x_h = -A_hI x_I; the kept half's factors are freed first
            self._half = None
            interior = ScipyFactor(self._A[rows][:, rows], symmetric=True,
                                   order=np.arange(len(rows)))
            x[rows] = -interior.solve(self._A[rows][:, touch] @ x_I[self._touch[h]])
        x[self._interface] = x_I
        return x


class _NoSplit(Exception):
    """The halves given to :class:`SplitSchur` are empty or not separated."""


def schur(A: sp.spmatrix, index: np.ndarray, *, backend: str = "scipy", order=None,
          halves=None):
    """Dense Schur complement of a symmetric positive definite A onto ``index`` (object with
    ``S``, ``extend(x_c)`` and ``backend``); ``order`` as for :func:`factorize`. ``halves``: a
    bisection of A's rows as :class:`SplitSchur` takes it, or a function that makes one; SciPy
    substructures on it from SPLIT_MIN_ROWS rows on (peak memory 4.0 -> 2.7 GB at 1.3 M
    rows, measured)."""
    index = np.asarray(index, dtype=np.int64)
    backend = resolve_backend(backend)
    if backend == "pardiso" and len(index) < A.shape[0]:
        return PardisoFactor(A, symmetric=True, schur_index=index)
    if halves is not None and A.shape[0] >= SPLIT_MIN_ROWS:
        try:
            return SplitSchur(A, index, halves() if callable(halves) else halves, order=order)
        except _NoSplit:  # no bisection of A's graph: one factorization of the whole
            pass
    return ScipySchur(A, index, order=order)
