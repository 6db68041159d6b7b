"""Flutter onset on the full pencil: the friction at which two real kappa meet.

At a coalescence (f*, kappa*) the matrix L(f, kappa) of :mod:`.pencil` is singular and kappa*
is a double root of det L(f*, .). With the bordered matrix

    [[L, b], [c^T, 0]] [v; sigma] = [0; 1]      (b, c: the null vectors' approximations)

sigma(f, kappa) vanishes exactly where L is singular, and its derivatives come from the same
factorization (Govaerts, Numerical methods for bifurcations of dynamical equilibria, 2000):
sigma_x = -w^T L_x v with w from the transposed system. Newton's method on

    sigma(f, kappa) = 0,   sigma_kappa(f, kappa) = 0

(a double root in kappa) converges quadratically: 3-4 steps from 5e-5, one from the
sharpened guess of :func:`critfric.stability.locus.sharpen` (its first correction is below
FOLD_TOL). The first step factors the bordered matrix; further ones solve with their own
matrix (which moves by the Newton step) by iterative refinement on that LU, a few solves
each (:class:`Bordered`); a fresh LU is taken whenever refinement does not reach rounding.
The other direction's bordered matrix, of the same pattern, is factored on the first one's
PARDISO analysis.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp

from ..errors import SolverError
from ..solvers.backends import factorize
from .pencil import SlidingPencil

FOLD_TOL = 1e-9  # relative Newton step after which the coalescence is converged: the
# convergence is quadratic, and the steps after it stall at the rounding of the bordered
# solves at a double root (1e-11 to 3e-10 relative, measured): the onset to ~1e-10
MAX_STEPS = 25
REFINE_MAX = 12  # refinement steps on an older LU before a fresh one is taken
REFINE_TOL = 1e-14  # refinement done: residual below this x |A| |x| (an LU solve's own level)


@dataclass
class Fold:
    friction: float
    kappa: float
    right: np.ndarray  # the (real) flutter mode at onset, kept DOFs, unit 2-norm
    left: np.ndarray
    steps: int
    residual: float  # ||L v|| / (||L|| ||v||) at the solution
    solver: Bordered | None = field(default=None, repr=False)  # for the next run (renewed)


def _bordered(L: sp.spmatrix, b: np.ndarray, c: np.ndarray) -> sp.csc_matrix:
    return sp.bmat([[L, sp.csr_matrix(b[:, None])], [sp.csr_matrix(c[None, :]), None]],
                   format="csc")


def find_fold(pencil: SlidingPencil, f0: float, kappa0: float, right: np.ndarray,
              left: np.ndarray, *, backend: str = "scipy", order=None,
              solver: Bordered | None = None) -> Fold:
    """Newton's method for the coalescence nearest (f0, kappa0); SolverError if it fails.
    ``solver``: the :class:`Bordered` of an earlier call on the same pencil (the other
    direction), whose analysis PARDISO reuses."""
    n = pencil.size
    f, kappa = float(f0), float(kappa0)
    c, b = _unit(right), _unit(left)
    border_order = None if order is None else np.concatenate([order, [n]])
    e = np.zeros(n + 1)
    e[n] = 1.0
    L_kf = pencil.L_kappa_f()
    F = Bordered(backend, border_order) if solver is None else solver.renewed()
    for step in range(1, MAX_STEPS + 1):
        L = pencil.L(f, kappa)
        F.set(_bordered(L, b, c))
        vs = F.solve(e)
        ws = F.solve(e, transpose=True)
        v, sigma, w = vs[:n], vs[n], ws[:n]
        Lk, Lf = pencil.L_kappa(f), pencil.L_f(kappa)
        Lkv, Lfv = Lk @ v, Lf @ v
        s_k, s_f = -w @ Lkv, -w @ Lfv
        rhs = np.zeros((n + 1, 2))
        rhs[:n, 0], rhs[:n, 1] = -Lkv, -Lfv
        dv = F.solve(rhs)  # v_kappa, v_f
        rhs_t = np.zeros((n + 1, 2))
        rhs_t[:n, 0], rhs_t[:n, 1] = -(Lk.T @ w), -(Lf.T @ w)
        dw = F.solve(rhs_t, transpose=True)  # w_kappa, w_f
        v_k, v_f, w_k, w_f = dv[:n, 0], dv[:n, 1], dw[:n, 0], dw[:n, 1]
        s_kk = -(w_k @ Lkv + w @ (Lk @ v_k))
        s_kf = -(w_f @ Lkv + w @ (L_kf @ v) + w @ (Lk @ v_f))
        J = np.array([[s_f, s_k], [s_kf, s_kk]])
        try:
            df, dk = np.linalg.solve(J, -np.array([sigma, s_k]))
        except np.linalg.LinAlgError:
            raise SolverError("the coalescence is degenerate (singular Newton matrix at "
                              f"friction {f:.6g}); try more --steps") from None
        f, kappa = f + df, kappa + dk
        c, b = _unit(v), _unit(w)  # better borders: the current null vectors
        if abs(df) <= FOLD_TOL * max(abs(f), 1e-300) and abs(dk) <= FOLD_TOL * abs(kappa):
            L = pencil.L(f, kappa)
            res = np.linalg.norm(L @ c) / max(abs(L).max() * np.sqrt(n), 1e-300)
            return Fold(f, kappa, c, b, step, float(res), F)
        if not (np.isfinite(f) and np.isfinite(kappa)):
            break
    raise SolverError(f"Newton's method for the flutter onset did not converge from friction "
                      f"{f0:.6g} (kappa {kappa0:.6g}); try more --steps or a finer mesh")


class Bordered:
    """Solves with the current bordered matrix A by iterative refinement on the LU of an
    earlier (nearby) one, or on its own; a fresh LU when refinement does not converge."""

    def __init__(self, backend: str, order):
        self.backend, self.order = backend, order
        self.lu = self.A = self.AT = None
        self.exact = False  # the LU is of A itself
        self.renew = False  # the LU is of another problem: the next matrix is factored
        self.lus = 0  # factorizations taken

    def renewed(self) -> Bordered:
        """This solver for another Newton run: its first matrix gets its own LU, on this
        one's analysis where the backend can (PARDISO, same pattern: the ordering, ~half
        of a factorization, is not redone)."""
        self.renew = True
        return self

    def set(self, A: sp.csc_matrix) -> None:
        self.A, self.AT, self.exact = A, None, False
        self.norm = float(abs(A).sum(axis=1).max())
        if self.renew and getattr(self.lu, "refactor", None) and self.lu.refactor(A):
            self.exact, self.renew, self.lus = True, False, self.lus + 1
        elif self.lu is None or self.renew:
            self.renew = False
            self._factor(diagonal=True)

    def _factor(self, diagonal: bool) -> None:
        self.lu = factorize(self.A, symmetric=False, backend=self.backend, order=self.order,
                            diagonal=diagonal)
        self.exact, self.diagonal, self.lus = True, diagonal, self.lus + 1

    def solve(self, rhs: np.ndarray, transpose: bool = False) -> np.ndarray:
        """Every solve is refined to ``REFINE_TOL``: on an older LU, or on this matrix's own
        LU with diagonal pivots (whose growth, if any, shows in the residual). When that
        stalls: this matrix's own LU, with threshold pivoting if it had diagonal pivots."""
        x = self._refined(rhs, transpose)
        while x is None:
            if not self.exact:
                self._factor(diagonal=True)
            elif self.diagonal:
                self._factor(diagonal=False)
            else:  # its own LU with threshold pivoting: as good as it gets
                return self.lu.solve(rhs, transpose=transpose)
            x = self._refined(rhs, transpose)
        return x

    def _refined(self, rhs: np.ndarray, transpose: bool) -> np.ndarray | None:
        x = self.lu.solve(rhs, transpose=transpose)
        if transpose and self.AT is None:
            self.AT = self.A.T.tocsr()
        A = self.AT if transpose else self.A
        previous = np.inf
        for _ in range(REFINE_MAX):
            r = rhs - A @ x
            size = np.max(np.abs(r)) / (self.norm * max(np.max(np.abs(x)), 1e-300))
            if size <= REFINE_TOL:
                return x
            if size > 0.5 * previous:  # not converging
                return None
            previous = size
            x = x + self.lu.solve(r, transpose=transpose)
        return None


def _unit(x: np.ndarray) -> np.ndarray:
    x = np.asarray(x).real
    return x / np.linalg.norm(x)
