"""The trailing diagonal blocks of SciPy's SuperLU factors, read in place.

``SuperLU.L`` and ``.U`` copy both whole factors into new CSC matrices (3.5 GB and 7 s at
1.2 M DOFs) when a Schur complement needs only their last k rows and columns. This module
reads those blocks from the factorization's own arrays (SuperLU's supernodal L, which holds
the diagonal blocks of U too, and its column-compressed U), through the layout of SciPy's
``SuperLU`` object (``scipy/sparse/linalg/_dsolve/_superluobject.h``, unchanged since SciPy
1.0: the Python header, m and n, the L and U ``SuperMatrix`` structs). The layout is checked
before anything is read (object size, shape, storage types, nonzero count): if any check
fails, :func:`trailing_blocks` returns None and the caller copies the factors as before.
"""

from __future__ import annotations

import ctypes

import numpy as np

from ..fem.arrays import ranges

_OBJECT_SIZE = 144  # sizeof(SuperLUObject) on 64-bit CPython
_HEAD = 16  # PyObject_HEAD
SLU_NC, SLU_SC, SLU_D, SLU_TRLU, SLU_TRU = 0, 3, 1, 1, 4  # SuperLU's enum values


class _SuperMatrix(ctypes.Structure):
    _fields_ = [("Stype", ctypes.c_int), ("Dtype", ctypes.c_int), ("Mtype", ctypes.c_int),
                ("nrow", ctypes.c_int), ("ncol", ctypes.c_int), ("Store", ctypes.c_void_p)]


class _Object(ctypes.Structure):  # after PyObject_HEAD
    _fields_ = [("m", ctypes.c_ssize_t), ("n", ctypes.c_ssize_t), ("L", _SuperMatrix),
                ("U", _SuperMatrix)]


_I = ctypes.POINTER(ctypes.c_int)
_D = ctypes.POINTER(ctypes.c_double)


class _SCformat(ctypes.Structure):  # supernodal L
    _fields_ = [("nnz", ctypes.c_int), ("nsuper", ctypes.c_int), ("nzval", _D),
                ("nzval_colptr", _I), ("rowind", _I), ("rowind_colptr", _I),
                ("col_to_sup", _I), ("sup_to_col", _I)]


class _NCformat(ctypes.Structure):  # U outside the supernodes' diagonal blocks
    _fields_ = [("nnz", ctypes.c_int), ("nzval", _D), ("rowind", _I), ("colptr", _I)]


def _array(pointer, length: int) -> np.ndarray:
    return np.ctypeslib.as_array(pointer, shape=(int(length),))


def _stores(lu):
    """SuperLU's (SCformat L, NCformat U) of a real ``lu``, or None if the layout differs."""
    if type(lu).__name__ != "SuperLU" or type(lu).__basicsize__ != _OBJECT_SIZE:
        return None
    obj = _Object.from_address(id(lu) + _HEAD)
    L, U = obj.L, obj.U
    n = lu.shape[0]
    if ((obj.m, obj.n) != lu.shape or (L.Stype, L.Dtype, L.Mtype) != (SLU_SC, SLU_D, SLU_TRLU)
            or (U.Stype, U.Dtype, U.Mtype) != (SLU_NC, SLU_D, SLU_TRU)
            or (L.nrow, L.ncol, U.nrow, U.ncol) != (n, n, n, n) or not (L.Store and U.Store)):
        return None
    Ls, Us = _SCformat.from_address(L.Store), _NCformat.from_address(U.Store)
    if Ls.nnz + Us.nnz != lu.nnz:
        return None
    return Ls, Us


def trailing_blocks(lu, k: int) -> tuple[np.ndarray, np.ndarray] | None:
    """Dense (L_cc, U_cc): rows and columns n-k..n-1 of ``lu``'s L (unit diagonal) and U, as
    ``lu.L`` and ``lu.U`` give them, without copying the factors; None if unreadable."""
    stores = _stores(lu)
    if stores is None:
        return None
    Ls, Us = stores
    n = lu.shape[0]
    t0 = n - k
    cols = np.arange(t0, n)
    # Fortran order, as ``.toarray()`` of the CSC factors gives: the product L_cc U_cc (BLAS)
    # then rounds exactly as before
    Lcc, Ucc = np.zeros((k, k), order="F"), np.zeros((k, k), order="F")
    # L store: column j lists the rows of its supernode (first its diagonal block, whose
    # rows <= j are U's) with the values of column j alongside
    first = _array(Ls.sup_to_col, Ls.nsuper + 2)[_array(Ls.col_to_sup, n)[cols]]
    row_ptr = _array(Ls.rowind_colptr, n + 1)
    start, length = row_ptr[first], row_ptr[first + 1] - row_ptr[first]
    val_ptr = _array(Ls.nzval_colptr, n + 1)
    if np.any(val_ptr[cols + 1] - val_ptr[cols] != length):
        return None
    rows = _array(Ls.rowind, row_ptr[n])[ranges(start, length)]
    vals = _array(Ls.nzval, val_ptr[n])[ranges(val_ptr[cols], length)]
    col = np.repeat(cols, length)
    tail = rows >= t0
    lower, upper = tail & (rows > col), tail & (rows <= col)
    Lcc[rows[lower] - t0, col[lower] - t0] = vals[lower]
    Ucc[rows[upper] - t0, col[upper] - t0] = vals[upper]
    Lcc[np.arange(k), np.arange(k)] = 1.0
    # U store: the rest of U's column j (rows above its supernode)
    ptr = _array(Us.colptr, n + 1)
    where = ranges(ptr[cols], ptr[cols + 1] - ptr[cols])
    rows, vals = _array(Us.rowind, ptr[n])[where], _array(Us.nzval, ptr[n])[where]
    col = np.repeat(cols, ptr[cols + 1] - ptr[cols])
    tail = rows >= t0
    Ucc[rows[tail] - t0, col[tail] - t0] = vals[tail]
    return Lcc, Ucc

