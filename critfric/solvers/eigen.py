"""The eigenproblem (3.2): critical friction coefficients and their eigenfunctions.

Notation of METHOD.md. In the n/t basis of :mod:`critfric.contact`, find alpha and
(Phi, X, Y) with K Phi = B_n X + B_t Y, Phi_n = Phi_t = 0 on stuck nodes, X = Y = 0 on free
nodes, Phi_n = 0 and Y = alpha gamma X on slipping nodes.

Three solvers, which agree to round-off:

* ``arpack`` (shift 0): ARPACK on the reduced operator T: r -> gamma * X (p0 x p0), whose
  eigenvalues are 1/alpha. K_c (K without the stuck DOFs and the slipping normal DOFs) is
  factored once; each application is one solve. 'LM' on T is shift-invert at 0 for free.
  Beyond the lowest real ones, the spectrum of T accumulates near the imaginary axis at
  |1/alpha| ~ (1 - 2 nu) / (2 (1 - nu)); a real alpha hidden behind that cluster (small nu)
  is out of ARPACK's reach at small k. So: k = 2 count, then WIDEN times more, until `count`
  positive AND `count` negative real values are found; else T is formed explicitly (p0
  solves, in blocks) and every eigenvalue is computed. Where p0 is too large for that, the
  result says how far it is complete (``Spectrum.complete``, ``radius``, a warning).
* ``arpack`` (shift sigma != 0): ARPACK on (K_c - sigma M)^-1 M, with the rank-p0 matrix
  M = E_t gamma R_n (slipping tangential rows <- gamma * normal reaction rows). Its
  eigenvalues are theta = 1/(alpha - sigma): the alphas nearest sigma come first.
* ``dense``: the Schur complement S of K onto the 2p contact DOFs, then every eigenvalue
  of the dense pencil B x = (1/alpha) S_uu x, u = slipping tangential + free contact DOFs,
  B = gamma * (slipping normal rows of S) on the slipping tangential rows: S_uu is SPD, so
  this is the p0 x p0 matrix T = gamma S_nu S_uu^-1 E (Cholesky, then dense eig). S comes
  from the factorization itself on both backends (:func:`critfric.solvers.backends.schur`):
  PARDISO's Schur option, or SuperLU with the contact DOFs ordered last. Every eigenvalue at
  about the cost of one factorization.

``backend`` ("auto", "scipy", "pardiso"; :mod:`critfric.solvers.backends`) picks the sparse
solver. Method "auto": dense whenever p <= SCHUR_MAX_CONTACT (and no shift), on every
install, so that both give the same complete spectrum; ARPACK beyond that.

Criteria (stated once, used everywhere):

* infinite eigenvalue: |1/alpha| <= INFINITE_TOL. 1/alpha is a dimensionless force ratio of
  order one; an infinite alpha comes out of floating point as |1/alpha| ~ 1e-16, or ~1e-8
  from a defective (Jordan) pair: friction coefficients above 1e6 are not reported.
* real eigenvalue: |Im alpha| <= real_tol * |alpha| (``[solve] real_tol``, default 1e-8).
* eigenvector check: the relative residual of the equilibrium rows and of the slip law
  Y = alpha gamma X must be at most RESIDUAL_TOL, or the solve fails loudly.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.linalg as la
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from threadpoolctl import threadpool_limits

from ..errors import SolverError
from ..fem.contact import FREE, SLIP, STUCK, ContactSystem
from .backends import PardisoPlan, factorize, resolve_backend, schur
from .ordering import fill_order, pieces

INFINITE_TOL = 1e-6
RESIDUAL_TOL = 1e-6
EXPLICIT_T_MAX = 3000  # widest ARPACK fallback: form T explicitly up to this p0
WIDEN = 4  # ARPACK's second try asks for WIDEN times more eigenvalues
SCHUR_MAX_CONTACT = 4000  # dense Schur path: at most this many contact nodes
START_SEED = 20030328  # fixed ARPACK start vector: identical runs give identical results


@dataclass(frozen=True)
class ContactState:
    """Status of each contact node (FREE, STUCK, SLIP) and the slip sign gamma (+1/-1)."""

    status: np.ndarray
    gamma: np.ndarray

    @classmethod
    def all_slipping(cls, p: int, gamma: int = 1) -> ContactState:
        return cls(np.full(p, SLIP, dtype=np.int8), np.full(p, float(gamma)))

    @property
    def n_slip(self) -> int:
        return int(np.count_nonzero(self.status == SLIP))


@dataclass
class Mode:
    """One real eigenvalue with its eigenfunction: free-DOF vector Phi (n/t basis) and the
    nodal contact forces X = F(theta_n), Y = F(theta_t) at all contact nodes."""

    alpha: float
    phi: np.ndarray
    X: np.ndarray
    Y: np.ndarray
    residual: float


@dataclass
class Spectrum:
    alpha: np.ndarray  # finite eigenvalues found, complex, sorted by modulus
    positive: np.ndarray  # real ones > 0, sorted
    negative: np.ndarray  # real ones < 0, sorted by |alpha|
    modes: list[Mode]  # lowest `count` of each family, positive first
    method: str
    n_infinite: int = 0
    applications: int = 0  # ARPACK operator applications (linear solves)
    warnings: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)  # how the search went, for the log
    backend: str = "scipy"  # linear-solver backend used (critfric.solvers.backends)
    complete: bool = True  # every eigenvalue found (else only those within `radius`)
    radius: float = float("inf")

    @property
    def complex_count(self) -> int:
        return len(self.alpha) - len(self.positive) - len(self.negative)


def _classify(beta: np.ndarray, real_tol: float):
    """Finite eigenvalues alpha = 1/beta, sorted by modulus; real mask; infinite count."""
    finite = np.abs(beta) > INFINITE_TOL
    alpha = 1.0 / beta[finite]
    order = np.argsort(np.abs(alpha), kind="stable")
    alpha = alpha[order]
    real = np.abs(alpha.imag) <= real_tol * np.abs(alpha)
    return alpha, real, np.flatnonzero(finite)[order], int(np.count_nonzero(~finite))


class _Problem:
    """K in the n/t basis with the index sets of a contact state."""

    def __init__(self, K: sp.csr_matrix, system: ContactSystem, state: ContactState):
        if len(state.status) != system.n_contact:
            raise SolverError("the contact state does not match the number of contact nodes")
        self.K, self.system, self.state = K, system, state
        self.slip = np.flatnonzero(state.status == SLIP)
        self.gamma = state.gamma[self.slip]
        if len(self.slip) == 0:
            raise SolverError("no slipping contact node: the eigenproblem (3.2) is empty")

    def mode(self, alpha: float, phi: np.ndarray) -> Mode:
        """Normalize Phi, recover the contact forces and check the residual."""
        s = self.system
        F = self.K @ phi
        zero = np.ones(len(phi), dtype=bool)
        zero[s.cn[self.state.status != FREE]] = False
        zero[s.ct[self.state.status != FREE]] = False
        X, Y = F[s.cn], F[s.ct]
        Xc, Yc = X[self.slip], Y[self.slip]
        eq = np.linalg.norm(F[zero]) / max(np.linalg.norm(F), 1e-300)
        law = np.linalg.norm(Yc - alpha * self.gamma * Xc) / max(
            np.linalg.norm(Yc) + abs(alpha) * np.linalg.norm(Xc), 1e-300)
        u = s.to_xy(phi)
        # sign: the largest tangential contact displacement (first along t) is positive
        pt = np.abs(phi[s.ct])
        big = np.flatnonzero(pt >= 0.999 * pt.max()) if pt.max() > 0 else []
        ref = phi[s.ct[big[0]]] if len(big) else phi[np.argmax(np.abs(phi))]
        scale = np.sign(ref) / np.abs(u).max()
        return Mode(float(alpha), phi * scale, X * scale, Y * scale, float(max(eq, law)))


class _Reduced(_Problem):
    """K_c (stuck DOFs and slipping normal DOFs eliminated), factored once."""

    def __init__(self, K, system, state, *, shift=0.0, backend="scipy"):
        super().__init__(K, system, state)
        stuck = state.status == STUCK
        elim = np.concatenate([system.cn[self.slip], system.cn[stuck], system.ct[stuck]])
        keep = np.ones(K.shape[0], dtype=bool)
        keep[elim] = False
        self.kept = np.flatnonzero(keep)
        position = np.cumsum(keep) - 1
        self.tc = position[system.ct[self.slip]]
        self.Kc = K[self.kept][:, self.kept].tocsc()
        self.Rn = K[system.cn[self.slip]][:, self.kept].tocsr()
        if shift == 0.0:
            self.factor = factorize(self.Kc, symmetric=True, backend=backend,
                                    order=self.order(backend))
        else:  # M: slipping tangential rows <- gamma * normal reaction rows (rank p0)
            E = sp.csr_matrix((self.gamma, (self.tc, np.arange(len(self.slip)))),
                              shape=(self.Kc.shape[0], len(self.slip)))
            self.M = (E @ self.Rn).tocsr()
            self.factor = factorize((self.Kc - shift * self.M).tocsc(), symmetric=False,
                                    backend=backend, order=self.order(backend))
        self.applications = 0

    def order(self, backend: str):
        return _fill_order(self.system, self.kept, backend)

    def solve_tangential(self, r: np.ndarray) -> np.ndarray:
        """K_c V = tangential load r on the slipping nodes (r of shape (p0,) or (p0, k))."""
        b = np.zeros((self.Kc.shape[0],) + r.shape[1:])
        b[self.tc] = r
        self.applications += 1 if r.ndim == 1 else r.shape[1]
        return self.factor.solve(b)

    def T(self, r: np.ndarray) -> np.ndarray:
        V = self.solve_tangential(r)
        g = self.gamma if r.ndim == 1 else self.gamma[:, None]
        return g * (self.Rn @ V)

    def shifted(self, v: np.ndarray) -> np.ndarray:
        self.applications += 1
        return self.factor.solve(self.M @ v)

    def explicit_T(self, block: int = 64) -> np.ndarray:
        """T as a dense p0 x p0 matrix, solving `block` right-hand sides at a time."""
        p0 = len(self.slip)
        T = np.empty((p0, p0))
        for j in range(0, p0, block):
            cols = np.arange(j, min(j + block, p0))
            E = np.zeros((p0, len(cols)))
            E[cols, np.arange(len(cols))] = 1.0
            T[:, cols] = self.T(E)
        return T

    def phi(self, V: np.ndarray) -> np.ndarray:
        out = np.zeros(self.K.shape[0])
        out[self.kept] = V
        return out


def _fill_order(system: ContactSystem, dofs: np.ndarray, backend: str):
    """The fill-reducing order SciPy's SuperLU is given (PARDISO orders by itself)."""
    return fill_order(system, dofs) if backend == "scipy" else None


def solve_dense(K, system: ContactSystem, state: ContactState, *, count: int,
                real_tol: float, backend: str = "scipy", plan=None) -> Spectrum:
    """Every eigenvalue, from the dense pencil on the Schur complement onto Gamma_C (``plan``:
    :func:`plan_dense`'s analysis of K's pattern, if any)."""
    prob = _Problem(K, system, state)
    p = system.n_contact
    if p > SCHUR_MAX_CONTACT:
        raise SolverError(f"the dense path would form a {2 * p} x {2 * p} Schur complement "
                          f"({p} contact nodes > {SCHUR_MAX_CONTACT}); use method = 'arpack'")
    sc = schur(K, np.concatenate([system.cn, system.ct]), backend=backend,
               order=_fill_order(system, np.arange(K.shape[0]), backend),
               pieces=lambda: pieces(system), plan=plan)
    spec = schur_spectrum(prob, sc.S, sc.extend, count=count, real_tol=real_tol)
    spec.backend = sc.backend
    return spec


def schur_spectrum(prob: _Problem, S: np.ndarray, extend, *, count: int,
                   real_tol: float) -> Spectrum:
    """Every eigenvalue of a contact state from the Schur complement S (2p x 2p, contact
    DOFs in the order cn, ct); ``extend`` maps contact values to the full Phi."""
    p = prob.system.n_contact
    freen = np.flatnonzero(prob.state.status == FREE)
    u = np.concatenate([p + prob.slip, freen, p + freen])
    p0 = len(prob.slip)
    # one BLAS thread for small matrices: on a busy 2-core machine two threads made a
    # 335 x 335 eig 5-30x slower (measured), more so right after PARDISO's threads ran
    with threadpool_limits(1 if len(u) < 1500 else None, user_api="blas"):
        try:  # W = S_uu^-1 E (E: slipping tangential columns, the first p0 of u)
            W = la.cho_solve(la.cho_factor(S[np.ix_(u, u)]), np.eye(len(u), p0))
        except la.LinAlgError:
            raise SolverError("the Schur complement onto the contact DOFs is not positive "
                              "definite: check that the Dirichlet edges hold the body") from None
        T = prob.gamma[:, None] * (S[np.ix_(prob.slip, u)] @ W)
        beta, vecs = la.eig(T)
    alpha, real, index, n_inf = _classify(beta, real_tol)

    def phis_of(js):  # every wanted mode by one (multi-column) extension
        phic = np.zeros((2 * p, len(js)))
        for col, j in enumerate(js):
            phic[u, col] = W @ _real_vector(vecs[:, j])
        return list(extend(phic).T) if js else []

    return _finish(prob, alpha, real, index, phis_of, count, "dense", n_inf, 0)


def solve_arpack(K, system: ContactSystem, state: ContactState, *, count: int, shift: float,
                 tol: float, maxiter: int | None, real_tol: float,
                 backend: str = "scipy") -> Spectrum:
    """ARPACK on T (shift 0) or on the shifted pencil, widening until `count` positives."""
    red = _Reduced(K, system, state, shift=shift, backend=backend)
    p0 = len(red.slip)
    notes: list[str] = []
    if shift == 0.0:
        n, apply = p0, red.T
    else:
        n, apply = red.Kc.shape[0], red.shifted
    k0 = max(2, 2 * count)
    vecs = beta = None
    radius = np.inf  # every eigenvalue with |alpha - shift| < radius is found
    kept = None  # the widest converged ARPACK result, used if T is too large to form
    if n >= 4:
        op = spla.LinearOperator((n, n), matvec=apply, dtype=np.float64)
        v0 = np.random.default_rng(START_SEED).standard_normal(n)
        for k in sorted({min(k0, n - 2), min(WIDEN * k0, n - 2, p0)}):
            try:
                theta, vecs = spla.eigs(op, k=k, which="LM", v0=v0, tol=tol, maxiter=maxiter,
                                        ncv=min(n, max(2 * k + 1, 20)))
                converged = True
            except spla.ArpackNoConvergence as exc:
                theta, vecs, converged = exc.eigenvalues, exc.eigenvectors, False
            beta = theta if shift == 0.0 else theta / (1.0 + shift * theta)
            alpha, real, _, _ = _classify(beta, real_tol)
            pos = np.count_nonzero(real & (alpha.real > 0))
            neg = np.count_nonzero(real & (alpha.real < 0))
            if converged:
                kept = (beta, vecs, 1.0 / np.min(np.abs(theta)))
            if converged and pos >= count and neg >= count:
                break  # both families complete up to the count asked
            what = "did not converge" if not converged else (
                f"found {pos} positive and {neg} negative real eigenvalue(s), {count} of each "
                "wanted,")
            notes.append(f"ARPACK {what} among the {k} eigenvalues nearest the shift")
            beta = None
    if beta is None and p0 > EXPLICIT_T_MAX:  # T too large: keep what ARPACK proved
        if kept is None:
            raise SolverError(f"ARPACK did not converge and p0 = {p0} is too many to form T; "
                              "try a larger [solve] tol, method = 'dense' or a shift near the "
                              "value sought")
        beta, vecs, radius = kept
        method = "arpack" if shift == 0.0 else "arpack-shift"
    elif beta is None:  # widest search: every eigenvalue of T, formed explicitly
        if shift != 0.0:
            red.factor = factorize(red.Kc, symmetric=True, backend=backend,
                                   order=red.order(backend))
        beta, vecs = la.eig(red.explicit_T())
        if n >= 4:
            notes.append(f"T formed explicitly ({p0} solves) to find every eigenvalue")
        method = "arpack+explicit"
    else:
        method = "arpack" if shift == 0.0 else "arpack-shift"
    beta, vecs = _complete_pairs(beta, vecs)
    alpha, real, index, n_inf = _classify(beta, real_tol)

    def phis_of(js):
        out = []
        for j in js:
            v = _real_vector(vecs[:, j])
            if method != "arpack-shift":  # v is r, the tangential load on I_c
                v = red.solve_tangential(v)
            out.append(red.phi(v))
        return out

    spec = _finish(red, alpha, real, index, phis_of, count, method, n_inf, red.applications)
    spec.notes[:0] = notes
    spec.backend = red.factor.backend
    if np.isfinite(radius):
        where = f"|alpha - {shift:g}|" if shift else "|alpha|"
        spec.complete, spec.radius = False, float(radius)
        spec.warnings.append(
            f"ARPACK's search is complete only for {where} < {radius:.6g}: a family with "
            f"fewer than {count} coefficient(s) listed may have more beyond; use method = "
            "'dense' to get every eigenvalue")
    return spec


def _complete_pairs(beta: np.ndarray, vecs: np.ndarray):
    """Add the missing conjugate of a complex eigenvalue ARPACK returned alone."""
    lone = [j for j, b in enumerate(beta)
            if b.imag != 0 and np.min(np.abs(beta - np.conj(b))) > 1e-10 * abs(b)]
    if not lone:
        return beta, vecs
    return (np.concatenate([beta, np.conj(beta[lone])]),
            np.concatenate([vecs, np.conj(vecs[:, lone])], axis=1))


def _real_vector(v: np.ndarray) -> np.ndarray:
    """The real eigenvector of a real eigenvalue: remove the arbitrary complex phase."""
    j = np.argmax(np.abs(v))
    return (v * (np.abs(v[j]) / v[j])).real


def _finish(prob, alpha, real, index, phis_of, count, method, n_inf, applications) -> Spectrum:
    """The spectrum with the modes of the lowest ``count`` of each family; ``phis_of`` maps
    a list of eigenvector indices to their Phi."""
    pos = np.flatnonzero(real & (alpha.real > 0))
    neg = np.flatnonzero(real & (alpha.real < 0))
    modes = []
    wanted = list(pos[:count]) + list(neg[:count])
    for j, phi in zip(wanted, phis_of([index[j] for j in wanted])):
        mode = prob.mode(alpha[j].real, phi)
        if not mode.residual <= RESIDUAL_TOL:
            raise SolverError(
                f"the eigenvector of alpha = {alpha[j].real:.10g} has relative residual "
                f"{mode.residual:.2e} > {RESIDUAL_TOL:g} ({method} path); the system is too "
                "ill-conditioned (nu very near 0.5?): try "
                + ("method = 'arpack', " if method == "dense" else "method = 'dense', ")
                + "P2/Q2 elements or a tighter [solve] tol")
        modes.append(mode)
    alpha = np.where(real, alpha.real + 0j, alpha)
    spec = Spectrum(alpha=alpha, positive=alpha[pos].real, negative=alpha[neg].real,
                    modes=modes, method=method, n_infinite=n_inf, applications=applications)
    if len(pos) < count:
        spec.warnings.append(f"only {len(pos)} real positive eigenvalue(s) found, {count} asked")
    return spec


def plan_dense(indptr: np.ndarray, indices: np.ndarray, contact_dofs: np.ndarray, *,
               method="auto", shift=0.0, backend="auto") -> PardisoPlan | None:
    """Start PARDISO's analysis of K from its upper-triangle pattern (sorted CSR ``indptr``,
    ``indices``) and ``contact_dofs`` (``cn`` then ``ct``), in the background, where
    :func:`solve` with these arguments takes the dense path on PARDISO (else None): pass it
    to :func:`solve` as ``plan`` with K of that pattern."""
    try:
        backend = resolve_backend(backend)
    except SolverError:  # solve() reports it
        return None
    p = len(contact_dofs) // 2  # the slipping nodes are not known yet: as if all slipped
    if (backend != "pardiso" or _method(method, p, shift, p) != "dense"
            or p > SCHUR_MAX_CONTACT or len(contact_dofs) >= len(indptr) - 1):
        return None
    return PardisoPlan(indptr, indices, contact_dofs)


def _method(method: str, n_contact: int, shift: float, n_slip: int) -> str:
    """The method "auto" stands for: every eigenvalue whenever the Schur complement fits."""
    if method != "auto":
        return method
    dense = n_contact <= SCHUR_MAX_CONTACT and shift == 0.0
    return "dense" if dense or n_slip < 4 else "arpack"


def solve(K, system: ContactSystem, state: ContactState | None = None, *, method="auto",
          count=1, shift=0.0, tol=0.0, maxiter=None, real_tol=1e-8, gamma=1,
          backend="auto", plan=None) -> Spectrum:
    """Critical friction coefficients of a contact state (default: all nodes slipping).
    ``plan``: :func:`plan_dense` of K's pattern (used if the dense path runs on PARDISO)."""
    state = state or ContactState.all_slipping(system.n_contact, gamma)
    backend = resolve_backend(backend)
    method = _method(method, system.n_contact, shift, state.n_slip)
    if method == "dense":
        return solve_dense(K, system, state, count=count, real_tol=real_tol, backend=backend,
                           plan=plan)
    if method == "arpack":
        return solve_arpack(K, system, state, count=count, shift=shift, tol=tol,
                            maxiter=maxiter, real_tol=real_tol, backend=backend)
    raise SolverError(f"unknown eigen method {method!r}; allowed: auto, arpack, dense")
