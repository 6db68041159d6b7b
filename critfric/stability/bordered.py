"""Solvers for the bordered matrices of :mod:`.fold`, A = [[L, b], [c^T, 0]] (L = L(f, kappa)
of the sliding pencil, b and c the null vectors' approximations).

:class:`Deflated` needs no factorization of A: GMRES on A, started from and deflated on a
coarse space Z (the constrained free-vibration modes, b and c; the small dense Galerkin matrix
Z^T A Z) and right-preconditioned by K_rr^-1. L = (K_rr - kappa M_rr) - f G C differs from
K_rr by the modes below and near kappa, which Z holds, and by terms that K_rr^-1 maps close
to the identity, so a few solves with the factorization of K_rr that served the modes reach
rounding (3-4 a system at 95 k and 295 k DOFs from a sharpened coalescence, measured).
Every solve's residual is checked on A itself; :class:`NotConverged` when GMRES stalls, and
:func:`.fold.find_fold` then takes :class:`Bordered`.

:class:`Bordered` factors A (SuperLU or PARDISO) and solves the matrices of further Newton
steps by iterative refinement on that LU, a fresh LU whenever refinement does not reach
rounding.
"""

from __future__ import annotations

import itertools
from concurrent.futures import ThreadPoolExecutor
from typing import NamedTuple

import numpy as np
import scipy.linalg as la
import scipy.sparse as sp
from threadpoolctl import threadpool_limits

from ..guards import freed_memory_kept, usable_cpus
from ..solvers.backends import factorize

REFINE_MAX = 12  # refinement steps on an older LU before a fresh one is taken
REFINE_TOL = 1e-14  # a solve is done: residual below this x |A| |x| (an LU solve's own level)
ROUGH_TOL = 1e-5  # ... for the solves behind Newton's Jacobian only: its relative error e
# leaves e times the step (~1e-15 of a 1e-10 step from a sharpened coalescence; from a cruder
# guess, Newton converges at that rate); sigma and the null vectors are solved to REFINE_TOL
RANK_TOL = 1e-7  # bases: relative singular values below this are dropped (a Gram matrix
# resolves them to ~1e-8)
GMRES_MAX = 20  # GMRES iterations a solve (each: one solve with K_rr) before NotConverged


class NotConverged(Exception):
    """GMRES did not reach the tolerance within GMRES_MAX iterations."""


def bordered(L: sp.spmatrix, b: np.ndarray, c: np.ndarray) -> sp.csc_matrix:
    return sp.bmat([[L, sp.csr_matrix(b[:, None])], [sp.csr_matrix(c[None, :]), None]],
                   format="csc")


def _row_norm(L: sp.spmatrix, b: np.ndarray, c: np.ndarray) -> float:
    """max row sum of |A|."""
    rows = np.asarray(abs(L).sum(axis=1)).ravel() + np.abs(b)
    return float(max(rows.max(), np.abs(c).sum()))


def orthonormal(W: np.ndarray, *, overwrite: bool = False) -> np.ndarray:
    """An orthonormal basis of the span of the columns of W, directions below ``RANK_TOL`` of
    the largest dropped: W R with R from the small Gram matrix G = W^T W, its columns scaled
    to unit norm (D G D, D = diag(G)^-1/2), as (D G D)^-1/2, then the same once more on the
    result (Cholesky QR twice, by eigenvalues: matrix products only, W read four times, at
    295 k x 62 on one thread 0.2 s, against 1.1 s at 295 k x 150 for a blocked QR, 3.7 s
    pivoted). One pass is orthonormal only to ~1e-16 cond(W D)^2 (7e-3 for the stability
    basis at 295 k DOFs, 2.4e-3 at 1 k, whose columns are nearly dependent before the drop):
    the sharpening's projections onto the span's complement then kept parts of the basis,
    and its enlarged models grew ill-conditioned. The second pass starts from columns of
    condition ~1 and ends orthonormal to ~1e-13 (2e-13 measured at 295 k DOFs).
    ``overwrite`` (W contiguous, not needed after): the result, row-major, is written in
    W's memory, already touched (a new n x 80 array's first touch costs about as much as
    the product)."""
    G = W.T @ W
    d = np.sqrt(np.diag(G))
    live = np.flatnonzero(d > 0)
    s = 1.0 / d[live]
    lam, U = la.eigh(G[np.ix_(live, live)] * s[:, None] * s[None, :])
    keep = lam > RANK_TOL ** 2 * lam[-1] if len(lam) else lam > 0
    R = np.zeros((W.shape[1], int(keep.sum())))
    R[live] = s[:, None] * (U[:, keep] / np.sqrt(lam[keep]))
    Q = W @ R
    if Q.shape[1] == 0:
        return Q
    lam, U = la.eigh(Q.T @ Q)
    square = (U / np.sqrt(lam)) @ U.T
    if not (overwrite and (W.flags.c_contiguous or W.flags.f_contiguous)):
        return Q @ square
    out = W.ravel(order="K")[:Q.size].reshape(Q.shape)
    return np.matmul(Q, square, out=out)


def tdot(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """A^T B for A, B of n rows and few columns (B may be a vector), as (B^T A)^T: the same
    numbers (the same dot products), and OpenBLAS's kernel for that form is faster at this
    shape (295 k rows, one thread: A row-major with 50 columns against B column-major with
    4, 8 and 16 columns 15, 24 and 32 ms against 39, 45 and 49 ms; never slower, measured
    for 1-50 columns either way)."""
    return (B.T @ A).T


def _small(r: np.ndarray, x: np.ndarray, norm: float, tol: float) -> bool:
    return np.max(np.abs(r)) <= tol * norm * max(np.max(np.abs(x)), 1e-300)


class Deflated:
    """Bordered solves by deflated, K_rr^-1-preconditioned GMRES (module docstring)."""

    def __init__(self, factor, modes: np.ndarray):
        self.factor = factor
        self.Q = orthonormal(modes)  # modes: (n, k) kept-DOF columns
        self.lus = 0  # factorizations taken: none
        self._iterations = []  # GMRES iterations of each cycle (appended from any thread)

    @property
    def iterations(self) -> int:
        """GMRES iterations (solves with K_rr) in all."""
        return sum(self._iterations)

    def renewed(self) -> Deflated:
        return self

    def release(self) -> None:
        """Drop the factorization of K_rr (before a bordered LU is made instead)."""
        self.factor = None

    def set(self, L: sp.spmatrix, b: np.ndarray, c: np.ndarray) -> None:
        # both made here: the solves of both run side by side (:func:`drive`)
        self.L, self.b, self.c = sp.csr_matrix(L), b, c
        self.LT = self.L.T.tocsr()
        self.norm = _row_norm(self.L, b, c)
        bc = np.column_stack([b, c])
        for _ in range(2):  # b and c outside the modes' span ("twice is enough")
            bc -= self.Q @ tdot(self.Q, bc)
        self.E = orthonormal(bc)  # Z = [Q, E], kept apart (Q is the larger: not copied)
        m = self.Q.shape[1] + self.E.shape[1]
        coarse = np.zeros((m + 1, m + 1))
        coarse[:m, :m] = np.hstack([self._Zt(self.L @ self.Q), self._Zt(self.L @ self.E)])
        coarse[:m, m] = self._Zt(b)
        coarse[m, :m] = self._Zt(c)
        self.coarse = la.lu_factor(coarse)

    def _Zt(self, u: np.ndarray) -> np.ndarray:
        """Z^T u."""
        return np.concatenate([tdot(self.Q, u), tdot(self.E, u)])

    def _Z(self, y: np.ndarray) -> np.ndarray:
        """Z y."""
        q = self.Q.shape[1]
        return self.Q @ y[:q] + self.E @ y[q:]

    def _apply(self, x: np.ndarray, transpose: bool) -> np.ndarray:
        """A x (A^T x): [L x + b s; c^T x] for x = [x; s]."""
        if transpose:
            L, b, c = self.LT, self.c, self.b
        else:
            L, b, c = self.L, self.b, self.c
        return np.concatenate([L @ x[:-1] + b * x[-1], [c @ x[:-1]]])

    def _coarse(self, u: np.ndarray, transpose: bool) -> np.ndarray:
        """Z (Z^T A Z)^-1 Z^T u (transposed: with (Z^T A Z)^-T)."""
        y = la.lu_solve(self.coarse, np.concatenate([self._Zt(u[:-1]), u[-1:]]),
                        trans=1 if transpose else 0, check_finite=False)
        return np.concatenate([self._Z(y[:-1]), y[-1:]])

    def _precondition(self, u: np.ndarray, transpose: bool):
        """q + [K_rr^-1 (u - A q); 0] with q the coarse solution of u (a generator: it yields
        u - A q for the solve with K_rr and is sent the result)."""
        q = self._coarse(u, transpose)
        r = u - self._apply(q, transpose)
        q[:-1] += yield r[:-1]
        return q

    def solve(self, rhs: np.ndarray, transpose: bool = False,
              rough: bool = False) -> np.ndarray:
        """A^-1 rhs (A^-T rhs), rhs (n + 1,) or (n + 1, k), to REFINE_TOL (ROUGH_TOL with
        ``rough``); NotConverged after GMRES_MAX iterations."""
        cols = rhs[:, None] if rhs.ndim == 1 else rhs
        x = np.column_stack(self.solve_many([(col, transpose) for col in cols.T], rough))
        return x[:, 0] if rhs.ndim == 1 else x

    def solve_many(self, systems: list[tuple[np.ndarray, bool]],
                   rough: bool = False) -> list[np.ndarray]:
        """A^-1 u (A^-T u if ``transpose``) for each (u, transpose), as :meth:`solve`, by
        :func:`solve_jointly`."""
        return solve_jointly([(self, systems, rough)])[0]

    def sibling(self) -> Deflated:
        """Another solver on the same factorization and modes, for another bordered matrix
        whose solves run beside this one's (:func:`solve_jointly`)."""
        twin = Deflated.__new__(Deflated)
        twin.factor, twin.Q, twin.lus, twin._iterations = self.factor, self.Q, 0, []
        return twin

    def _solve(self, rhs: np.ndarray, transpose: bool, rough: bool):
        tol = ROUGH_TOL if rough else REFINE_TOL
        x = self._coarse(rhs, transpose)
        left = GMRES_MAX
        while True:
            r = rhs - self._apply(x, transpose)
            if _small(r, x, self.norm, tol):
                return x
            if left == 0:
                raise NotConverged
            x, used = yield from self._gmres(r, x, transpose, tol, left)
            left -= used

    def _gmres(self, r: np.ndarray, x: np.ndarray, transpose: bool, tol: float, most: int):
        """One cycle of right-preconditioned GMRES from x (residual r), at most ``most``
        iterations; stops when its residual estimate is below the target. Returns (x, the
        iterations used)."""
        beta = np.linalg.norm(r)
        V, Z = [r / beta], []  # the Krylov basis and its preconditioned images, as used
        H = np.zeros((most + 1, most))
        target = tol * self.norm * max(np.max(np.abs(x)), 1e-300)
        while True:
            j = len(Z)
            Z.append((yield from self._precondition(V[j], transpose)))
            w = self._apply(Z[j], transpose)
            for _ in range(2):  # classical Gram-Schmidt, twice
                h = np.array([v @ w for v in V])
                for hi, v in zip(h, V):
                    w -= hi * v
                H[:j + 1, j] += h
            H[j + 1, j] = np.linalg.norm(w)
            e = np.zeros(j + 2)
            e[0] = beta
            y, *_ = np.linalg.lstsq(H[:j + 2, :j + 1], e, rcond=None)
            estimate = np.linalg.norm(e - H[:j + 2, :j + 1] @ y)
            if estimate <= 0.5 * target or H[j + 1, j] == 0 or j + 1 == most:
                self._iterations.append(j + 1)
                return x + sum(yi * z for yi, z in zip(y, Z)), j + 1
            V.append(w / H[j + 1, j])


def solve_jointly(groups: list[tuple[Deflated, list[tuple[np.ndarray, bool]], bool]]
                  ) -> list[list[np.ndarray]]:
    """For each group (a :class:`Deflated` set on its bordered matrix A, its systems
    (u, transpose), rough): A^-1 u (A^-T u if transpose), as :meth:`Deflated.solve`. One
    GMRES a system, all in lockstep, their solves with K_rr (the groups share one
    factorization) in one call of several columns an iteration (SuperLU: 2 columns cost 1.2
    times one, 4 columns 1.7 times, measured at 295 k); NotConverged if any stalls."""
    factor = groups[0][0].factor
    with threadpool_limits(1, user_api="blas"):  # see locus.Reduced.blas
        runs = [F._solve(u, transpose, rough) for F, systems, rough in groups
                for u, transpose in systems]
        out = drive(runs, lambda us: list(factor.solve(np.column_stack(us)).T))
    ends = np.cumsum([0] + [len(systems) for _, systems, _ in groups])
    return [out[a:b] for a, b in itertools.pairwise(ends)]


def drive(runs: list, answer) -> list:
    """Generator runs taken to their ends in lockstep, their return values in order: each
    round, ``answer`` takes the pending runs' requests (a list) and gives their replies (a
    list, in the same order), each sent to its run (an exception: thrown into it). Several
    runs are resumed two at a time in two threads, for the call only, where there are two
    CPUs and the process's malloc has one arena (:func:`critfric.guards.keep_freed_memory`,
    which ``critfric stability`` asks for: with glibc's default arenas each thread's kept
    what it freed, the peak at 295 k DOFs 1.68-1.71 GB against 1.43 GB one run after the
    other); ``answer`` is called in this thread. Between their requests the runs do sparse
    products with L and dense products over the modes, which release the GIL: the two
    sliding directions' Newton step at 295 k DOFs (PARDISO) took 1.49-1.57 s against
    1.74-1.96 s one run after the other. A run's numbers do not depend on it (one thread resumes it at a
    time; BLAS on one thread in each)."""
    if len(runs) < 2 or usable_cpus() < 2 or not freed_memory_kept():
        return _drive(runs, answer, lambda items: [resume(*item) for item in items])
    with ThreadPoolExecutor(2, thread_name_prefix="critfric-drive") as pool:
        return _drive(runs, answer, lambda items: list(pool.map(lambda i: resume(*i), items)))


def _drive(runs: list, answer, resume_all) -> list:
    out: list = [None] * len(runs)
    pending = list(enumerate(resume_all([(run, None) for run in runs])))
    while True:
        for i, got in pending:
            if isinstance(got, Done):
                out[i] = got.value
        pending = [(i, got) for i, got in pending if not isinstance(got, Done)]
        if not pending:
            return out
        replies = answer([got for _, got in pending])
        resumed = resume_all([(runs[i], reply) for (i, _), reply in zip(pending, replies)])
        pending = [(i, got) for (i, _), got in zip(pending, resumed)]


class Done(NamedTuple):
    """What a generator run returned (:func:`resume`)."""

    value: object


def resume(run, value=None):
    """A generator run's next request: started (``value`` None), sent ``value``, or thrown
    it (an exception); Done(what it returned) once it returns."""
    try:
        if value is None:
            return next(run)
        return run.throw(value) if isinstance(value, BaseException) else run.send(value)
    except StopIteration as done:
        return Done(done.value)


class Bordered:
    """Solves with the current bordered matrix A by iterative refinement on the LU of an
    earlier (nearby) one, or on its own; a fresh LU when refinement does not converge."""

    def __init__(self, backend: str, order):
        self.backend = backend
        self.order = None if order is None else np.concatenate([order, [len(order)]])
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

    def release(self) -> None:
        pass

    def set(self, L: sp.spmatrix, b: np.ndarray, c: np.ndarray) -> None:
        A = bordered(L, b, c)
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

    def solve(self, rhs: np.ndarray, transpose: bool = False,
              rough: bool = False) -> np.ndarray:
        """Every solve is refined to ``REFINE_TOL`` (``rough`` or not): on an older LU, or on
        this matrix's own LU with diagonal pivots (whose growth, if any, shows in the
        residual). When that stalls: this matrix's own LU, with threshold pivoting if it had
        diagonal pivots."""
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

    def solve_many(self, systems: list[tuple[np.ndarray, bool]],
                   rough: bool = False) -> list[np.ndarray]:
        """:meth:`solve` of each (u, transpose), one after the other."""
        return [self.solve(u, transpose, rough) for u, transpose in systems]

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
