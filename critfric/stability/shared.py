"""One SuperLU factorization for both stages of ``critfric stability`` on SciPy: K_rr (the
sliding pencil's kept block) with its boundary rows J last.

The static stage needs the Schur complement S of K (free DOFs) onto the contact DOFs c; the
pencil needs solves with K_rr, K without its eliminated rows e (the slipping nodes' normal
DOFs, the stuck nodes' DOFs: contact DOFs all). J holds the kept contact DOFs and every kept
row that K couples to e, so that no other row r' sees e. Factored with J last, K_rr gives
S_J = K_JJ - K_Jr' K_r'r'^-1 K_r'J from its trailing blocks (:class:`ScipySchur`); then

    A = [[S_J, K_Je], [K_eJ, K_ee]]

is the Schur complement of K onto J + e, and S follows from A by eliminating densely the
rows of J that are not contact DOFs (m): S = A_cc - A_cm A_mm^-1 A_mc. A contact vector x_c
extends to the free DOFs by x_m = -A_mm^-1 A_mc x_c, then from x_J into the rest of the kept
rows by K_rr's factorization (:meth:`ScipySchur.extend`). One factorization instead of two
(K, then K_rr): SuperLU's solves with K_rr serve the free vibrations, the reduced basis,
the sharpening and Newton's bordered solves. PARDISO factors twice: its Schur
factorization solves K_rr only by phases 331 and 333, each as slow as a whole solve
(measured 45 ms against 24 ms a column at 295 k DOFs).
"""

from __future__ import annotations

import numpy as np
import scipy.linalg as la
import scipy.sparse as sp

from ..errors import SolverError
from ..fem.contact import ContactSystem
from ..solvers import eigen
from ..solvers.backends import ScipySchur
from ..solvers.eigen import ContactState
from ..solvers.eigenproblem import Problem

DENSE_MAX = 8000  # rows of A (J + e) up to which the static stage is taken from K_rr's factor


def boundary_rows(K: sp.csr_matrix, kept: np.ndarray, contact: np.ndarray) -> np.ndarray:
    """Positions (in ``kept``) of the kept contact DOFs and of the kept rows K couples to the
    eliminated ones (all free DOFs not in ``kept``), sorted."""
    n = K.shape[0]
    position = np.full(n, -1)
    position[kept] = np.arange(len(kept))
    eliminated = np.flatnonzero(position < 0)
    coupled = np.unique(K[eliminated].indices)
    J = np.union1d(position[contact], position[coupled])
    return J[J >= 0]


def applies(system: ContactSystem, state: ContactState, method: str, backend: str) -> bool:
    """Whether the stability command may take its static stage from K_rr's factorization:
    SciPy, and the static stage's dense path (:meth:`SharedFactor.of` checks A's size)."""
    return backend == "scipy" and eigen.uses_dense(method, system, state)


class SharedFactor:
    """K_rr's SuperLU factorization with J last, its :meth:`solve`, and the static stage's
    Schur complement ``S`` onto the contact DOFs (the order of :class:`Problem`)."""

    backend = "scipy"

    @classmethod
    def of(cls, K: sp.csr_matrix, Krr: sp.csr_matrix, problem: Problem, kept: np.ndarray,
           order: np.ndarray) -> SharedFactor | None:
        """The shared factorization, or None where A would exceed DENSE_MAX rows (the caller
        factors K and K_rr apart)."""
        K = sp.csr_matrix(K)
        J = boundary_rows(K, kept, problem.contact_dofs)
        if len(J) + K.shape[0] - len(kept) > DENSE_MAX:
            return None
        return cls(K, Krr, problem, kept, order, J)

    def __init__(self, K: sp.csr_matrix, Krr: sp.csr_matrix, problem: Problem,
                 kept: np.ndarray, order: np.ndarray, J: np.ndarray):
        n = K.shape[0]
        contact = problem.contact_dofs
        eliminated = np.setdiff1d(np.arange(n), kept)
        self._factor = ScipySchur(Krr, J, order=order)
        self._kept, self._eliminated, self._J = kept, eliminated, J
        # A's rows: J (kept-DOF positions), then e; the contact DOFs' rows in A, in order
        in_J = np.full(n, -1)
        in_J[kept[J]] = np.arange(len(J))
        in_e = np.full(n, -1)
        in_e[eliminated] = len(J) + np.arange(len(eliminated))
        c = np.where(in_J[contact] >= 0, in_J[contact], in_e[contact])
        if np.any(c < 0):
            raise SolverError("internal: a contact DOF is neither kept in J nor eliminated")
        is_c = np.zeros(len(J) + len(eliminated), dtype=bool)
        is_c[c] = True
        m = np.flatnonzero(~is_c)  # rows of J that are not contact DOFs
        A = np.empty((len(J) + len(eliminated),) * 2)
        A[:len(J), :len(J)] = self._factor.S
        K_Je = K[kept[J]][:, eliminated].toarray()
        A[:len(J), len(J):], A[len(J):, :len(J)] = K_Je, K_Je.T
        A[len(J):, len(J):] = K[eliminated][:, eliminated].toarray()
        try:
            cho = la.cho_factor(A[np.ix_(m, m)])
        except la.LinAlgError:
            raise SolverError("the Schur complement onto the boundary rows is not positive "
                              "definite: check that the Dirichlet edges hold the body") from None
        self._X = la.cho_solve(cho, A[np.ix_(m, c)])  # A_mm^-1 A_mc
        S = A[np.ix_(c, c)] - A[np.ix_(c, m)] @ self._X
        self.S = 0.5 * (S + S.T)
        self._c, self._m, self._nJ = c, m, len(J)
        self.shape = Krr.shape

    def solve(self, b: np.ndarray) -> np.ndarray:
        """K_rr^-1 b for b of shape (n_kept,) or (n_kept, k)."""
        return self._factor.solve(b)

    def extend(self, xc: np.ndarray) -> np.ndarray:
        """The free-DOF vector(s) with contact values ``xc`` (Problem order) and K x = 0 on
        every other row."""
        xc = np.asarray(xc, dtype=np.float64)
        tail = xc.shape[1:]
        a = np.zeros((self._nJ + len(self._eliminated),) + tail)
        a[self._c] = xc
        a[self._m] = -(self._X @ xc)
        x = np.zeros((len(self._kept) + len(self._eliminated),) + tail)
        x[self._kept] = self._factor.extend(a[:self._nJ])
        x[self._eliminated] = a[self._nJ:]
        return x
