"""The eigenproblem (3.2): critical friction coefficients and their eigenfunctions.

Notation of METHOD.md. In the contact basis of :mod:`critfric.fem.contact` (3D: the n/s/e
basis of :mod:`critfric.fem.contact3d`), find alpha and (Phi, X, Y) with K Phi = B_n X + B_t Y,
Phi_n = Phi_t = 0 on stuck nodes, X = Y = 0 on free nodes, Phi_n = 0 and Y = alpha gamma X on
slipping nodes; in 3D the e DOF of each contact node is clamped or load-free according to its
status and the slip law ``law`` ("rate" or "frozen"; :mod:`.eigenproblem`, which also holds
the index sets, the modes' check and the criteria). One code path serves 2D and 3D: the
clamped DOFs are eliminated, the slipping t (3D: s) DOFs carry the slip law.

Three solvers, which agree to round-off:

* ``arpack`` (shift 0): ARPACK on the reduced operator T: r -> gamma * X (p0 x p0), whose
  eigenvalues are 1/alpha. K_c (K without the clamped DOFs) is factored once; each
  application is one solve. 'LM' on T is shift-invert at 0 for free.
  Beyond the lowest real ones, the spectrum of T accumulates near the imaginary axis at
  |1/alpha| ~ (1 - 2 nu) / (2 (1 - nu)); a real alpha hidden behind that cluster (small nu)
  is out of ARPACK's reach at small k. So: k = 2 count, then WIDEN times more, until `count`
  positive AND `count` negative real values are found; else T is formed explicitly (p0
  solves, in blocks) and every eigenvalue is computed. Where p0 is too large for that, the
  result says how far it is complete (``Spectrum.complete``, ``radius``, a warning). Below
  p0 = 4 ARPACK does not apply: T is formed explicitly.
* ``arpack`` (shift sigma != 0): ARPACK on (K_c - sigma M)^-1 M, with the rank-p0 matrix
  M = E_t gamma R_n (slipping tangential rows <- gamma * normal reaction rows). Its
  eigenvalues are theta = 1/(alpha - sigma): the alphas nearest sigma come first.
* ``dense``: the Schur complement S of K onto the contact DOFs (2p; 3D: 3p), then every
  eigenvalue of the dense pencil B x = (1/alpha) S_uu x, u = the slipping tangential and the
  other unclamped contact DOFs, B = gamma * (slipping normal rows of S) on the slipping
  tangential rows: S_uu is SPD, so this is the p0 x p0 matrix T = gamma S_nu S_uu^-1 E
  (Cholesky, then dense eig). S comes from the factorization itself on both backends
  (:func:`critfric.solvers.backends.schur`): PARDISO's Schur option, or SuperLU with the
  contact DOFs ordered last. Every eigenvalue at about the cost of one factorization.

``backend`` ("auto", "scipy", "pardiso"; :mod:`critfric.solvers.backends`) picks the sparse
solver. Method "auto": dense whenever the Schur complement has at most 2 SCHUR_MAX_CONTACT
rows (2D: p <= SCHUR_MAX_CONTACT) and no shift, on every install, so that both give the same
complete spectrum; ARPACK beyond that. In 3D the Schur complement onto 3p rows costs far more
than ARPACK's solves (boxes, PARDISO: 0.57 / 2.5 / 6.5 / 15.9 s dense against 0.17 / 1.1 / 1.4
/ 4.7 s ARPACK at p = 529 / 1145 / 1437 / 1969): dense only up to AUTO_DENSE_ROWS_3D rows.
"""

from __future__ import annotations

import numpy as np
import scipy.linalg as la
import scipy.sparse.linalg as spla
from threadpoolctl import threadpool_limits

from ..errors import SolverError
from ..fem.contact import FREE, ContactSystem
from .backends import PardisoPlan, factorize, resolve_backend, schur
from .eigenproblem import (
    INFINITE_TOL,
    LAWS,
    RESIDUAL_TOL,
    ContactState,
    Mode,
    Problem,
    Reduced,
    Spectrum,
    classify,
    complete_pairs,
    finish,
    ratio,
    real_vector,
)
from .ordering import fill_order, pieces
from .pardiso import upper_triangle

__all__ = ["INFINITE_TOL", "LAWS", "RESIDUAL_TOL", "ContactState", "Mode", "Spectrum",
           "plan_dense", "schur_spectrum", "solve", "solve_arpack", "solve_dense", "uses_dense"]

EXPLICIT_T_MAX = 3000  # widest ARPACK fallback: form T explicitly up to this p0
WIDEN = 4  # ARPACK's second try asks for WIDEN times more eigenvalues
SCHUR_MAX_CONTACT = 4000  # dense Schur path: at most this many contact nodes (2D)
AUTO_DENSE_ROWS_3D = 1800  # 3D, method "auto": dense up to this many Schur rows (under ~1 s)
START_SEED = 20030328  # fixed ARPACK start vector: identical runs give identical results


def _schur_rows(system: ContactSystem) -> int:
    """Rows of the Schur complement onto the contact DOFs: dim * p."""
    return system.dim * system.n_contact


def solve_dense(K, system: ContactSystem, state: ContactState, *, count: int,
                real_tol: float, backend: str = "scipy", plan=None, law: str = "rate",
                made=None) -> Spectrum:
    """Every eigenvalue, from the dense pencil on the Schur complement onto Gamma_C (``plan``:
    :func:`plan_dense`'s analysis of K's pattern, if any; ``made``: that Schur complement
    already made, an object with ``S``, ``extend`` and ``backend`` as :func:`schur` gives)."""
    prob = Problem(K, system, state, law)
    p, rows = system.n_contact, _schur_rows(system)
    if rows > 2 * SCHUR_MAX_CONTACT:
        raise SolverError(f"the dense path would form a {rows} x {rows} Schur complement "
                          f"({p} contact nodes > {2 * SCHUR_MAX_CONTACT // system.dim}); use "
                          "method = 'arpack'")
    sc = made or schur(K, prob.contact_dofs, backend=backend,
                       order=fill_order(system) if backend == "scipy" else None,
                       pieces=lambda: pieces(system), plan=plan)
    spec = schur_spectrum(prob, sc.S, sc.extend, count=count, real_tol=real_tol)
    spec.backend = sc.backend
    return spec


def schur_spectrum(prob: Problem, S: np.ndarray, extend, *, count: int,
                   real_tol: float) -> Spectrum:
    """Every eigenvalue of a contact state from the Schur complement S onto the contact DOFs
    in the order of ``prob.contact_dofs`` (cn, ct; 3D: then ce); ``extend`` maps contact
    values to the full Phi."""
    p = prob.system.n_contact
    freen = np.flatnonzero(prob.state.status == FREE)
    e_free = [2 * p + freen] if prob.three else []
    e_slip = 2 * p + prob.slip if prob.three else prob.slip[:0]
    frozen = prob.three and prob.law == "frozen"
    u = np.concatenate([p + prob.slip, freen, p + freen, *e_free] + ([e_slip] if frozen else []))
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
        ratios = None
        if prob.three:  # the s and e parts of r, linear in the eigenvector (Y_s = v)
            Ps, Pe = ((np.eye(p0), S[np.ix_(e_slip, u)] @ W) if not frozen
                      else (W[:p0], W[len(u) - p0:]))
            ratios = ratio(Ps @ vecs, Pe @ vecs)
    alpha, real, index, n_inf = classify(beta, real_tol)

    def phis_of(js):  # every wanted mode by one (multi-column) extension
        phic = np.zeros((S.shape[0], len(js)))
        for col, j in enumerate(js):
            phic[u, col] = W @ real_vector(vecs[:, j])
        return list(extend(phic).T) if js else []

    return finish(prob, alpha, real, index, phis_of, count, "dense", n_inf, 0, ratios)


def solve_arpack(K, system: ContactSystem, state: ContactState, *, count: int, shift: float,
                 tol: float, maxiter: int | None, real_tol: float,
                 backend: str = "scipy", law: str = "rate") -> Spectrum:
    """ARPACK on T (shift 0) or on the shifted pencil, widening until `count` positives."""
    red = Reduced(K, system, state, law=law, shift=shift, backend=backend)
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
            alpha, real, _, _ = classify(beta, real_tol)
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
    P = None  # 3D, explicit T: the matrices of r's parts
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
        T, P = red.explicit_T()
        beta, vecs = la.eig(T)
        if n >= 4:
            notes.append(f"T formed explicitly ({p0} solves) to find every eigenvalue")
        method = "arpack+explicit"
    else:
        method = "arpack" if shift == 0.0 else "arpack-shift"
    beta, vecs = complete_pairs(beta, vecs)
    alpha, real, index, n_inf = classify(beta, real_tol)
    ratios = None
    if red.three:  # r of every eigenvector found
        if P is not None:
            ratios = ratio(P[0] @ vecs, P[1] @ vecs)
        else:
            V = vecs if method == "arpack-shift" else red.solve_tangential(vecs)
            ratios = ratio(*red.parts(V))

    def phis_of(js):
        out = []
        for j in js:
            v = real_vector(vecs[:, j])
            if method != "arpack-shift":  # v is r, the tangential load on I_c
                v = red.solve_tangential(v)
            out.append(red.phi(v))
        return out

    spec = finish(red, alpha, real, index, phis_of, count, method, n_inf, red.applications,
                  ratios)
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


def plan_dense(indptr: np.ndarray, indices: np.ndarray, contact_dofs: np.ndarray, *,
               method="auto", shift=0.0, backend="auto", dim: int = 2) -> PardisoPlan | None:
    """Start PARDISO's analysis of K from its upper-triangle pattern (sorted CSR ``indptr``,
    ``indices``) and ``contact_dofs`` (``cn`` then ``ct``; 3D, ``dim`` 3: then ``ce``), in
    the background, where :func:`solve` with these arguments takes the dense path on PARDISO
    (else None): pass it to :func:`solve` as ``plan`` with K of that pattern."""
    try:
        backend = resolve_backend(backend)
    except SolverError:  # solve() reports it
        return None
    rows = len(contact_dofs)  # the slipping nodes are not known yet: as if all slipped
    if (backend != "pardiso" or _method(method, rows, shift, rows // dim, dim) != "dense"
            or rows > 2 * SCHUR_MAX_CONTACT or rows >= len(indptr) - 1):
        return None
    return PardisoPlan(indptr, indices, contact_dofs)


def plan_for(K, system: ContactSystem, *, method="auto", shift=0.0, backend="auto"
             ) -> PardisoPlan | None:
    """:func:`plan_dense` of an assembled K (its upper triangle's pattern; zeros kept, so
    that every Poisson ratio's K has it) and ``system``'s contact DOFs."""
    try:
        if resolve_backend(backend) != "pardiso":
            return None
    except SolverError:  # solve() reports it
        return None
    U = upper_triangle(K)
    return plan_dense(U.indptr, U.indices, system.contact_dofs, method=method, shift=shift,
                      backend=backend, dim=system.dim)


def _method(method: str, rows: int, shift: float, n_slip: int, dim: int) -> str:
    """The method "auto" stands for: every eigenvalue whenever the Schur complement (``rows``
    contact DOFs) fits (3D: is cheap, AUTO_DENSE_ROWS_3D)."""
    if method != "auto":
        return method
    dense = rows <= (2 * SCHUR_MAX_CONTACT if dim == 2 else AUTO_DENSE_ROWS_3D) and shift == 0.0
    return "dense" if dense or n_slip < 4 else "arpack"


def uses_dense(method: str, system: ContactSystem, state: ContactState) -> bool:
    """Whether :func:`solve` (no shift) takes the dense path, on the Schur complement."""
    rows = _schur_rows(system)
    return (_method(method, rows, 0.0, state.n_slip, system.dim) == "dense"
            and rows <= 2 * SCHUR_MAX_CONTACT)


def solve(K, system: ContactSystem, state: ContactState | None = None, *, method="auto",
          count=1, shift=0.0, tol=0.0, maxiter=None, real_tol=1e-8, gamma=1,
          backend="auto", plan=None, law="rate", made=None) -> Spectrum:
    """Critical friction coefficients of a contact state (default: all nodes slipping).
    ``plan``: :func:`plan_dense` of K's pattern (used if the dense path runs on PARDISO).
    ``law``: the 3D slip law of the e DOF, "rate" or "frozen" (no effect in 2D).
    ``made``: the Schur complement onto the contact DOFs, already made (the dense path's)."""
    state = state or ContactState.all_slipping(system.n_contact, gamma)
    backend = resolve_backend(backend)
    method = _method(method, _schur_rows(system), shift, state.n_slip, system.dim)
    if method == "dense":
        return solve_dense(K, system, state, count=count, real_tol=real_tol, backend=backend,
                           plan=plan, law=law, made=made)
    if method == "arpack":
        return solve_arpack(K, system, state, count=count, shift=shift, tol=tol,
                            maxiter=maxiter, real_tol=real_tol, backend=backend, law=law)
    raise SolverError(f"unknown eigen method {method!r}; allowed: auto, arpack, dense")
