"""The eigenproblem (3.2) of one contact state: its index sets, its reduced operator, its
modes and their check, in 2D and 3D.

A contact state gives each contact node a status and each slipping node a slip sign gamma. In
the contact basis (2D: n, t; 3D: n, s, e with s the slip direction, e = n x s,
:mod:`critfric.fem.contact3d`) the eigenproblem is: find alpha and (Phi, X, Y) with
K Phi = B_n X + B_t Y (3D: + B_e Y_e) and

* stuck nodes: Phi = 0 (every component); free nodes: X = Y = 0 (and Y_e = 0);
* slipping nodes: Phi_n = 0 and Y = alpha gamma X on the t (3D: s) DOF; in 3D, under the
  ``rate`` law (the default) Phi_e = 0 and Y_e is a reaction, under the ``frozen`` law
  Y_e = 0 and Phi_e is free.

So every DOF is either clamped (Phi = 0, a reaction: :attr:`Problem.clamped`), loaded by the
slip law (the t/s DOFs of the slipping nodes), or load-free; both laws are linear in alpha
with p0 = |slipping nodes| eigenvalues, K stays symmetric positive definite on the unclamped
DOFs, and the 2D machinery applies unchanged.

Each eigenpair carries r (0 in 2D): |Y_e| / |(Y_s, Y_e)| under the rate law, |Phi_e| /
|(Phi_s, Phi_e)| under the frozen law, over the slipping nodes. r = 0 means the pair solves
the other law's problem too: an exact static branch.

Criteria (stated once, used everywhere):

* infinite eigenvalue: |1/alpha| <= INFINITE_TOL. 1/alpha is a dimensionless force ratio of
  order one; an infinite alpha comes out of floating point as |1/alpha| ~ 1e-16, or ~1e-8
  from a defective (Jordan) pair: friction coefficients above 1e6 are not reported.
* real eigenvalue: |Im alpha| <= real_tol * |alpha| (``[solve] real_tol``, default 1e-8).
* eigenvector check: the relative residual of the equilibrium rows (the load-free DOFs, Y_e
  of the frozen law among them), of the slip law Y = alpha gamma X and of the clamped DOFs
  (Phi_n = 0, Phi_e = 0 of the rate law) must be at most RESIDUAL_TOL, or the solve fails
  loudly.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp

from ..errors import CaseError, SolverError
from ..fem.contact import SLIP, STUCK, ContactSystem
from ..fem.contact3d import LAWS
from .backends import factorize
from .ordering import fill_order

INFINITE_TOL = 1e-6
RESIDUAL_TOL = 1e-6


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
    """One real eigenvalue with its eigenfunction: free-DOF vector Phi (contact basis) and the
    nodal contact forces X = F(theta_n), Y = F(theta_t) at all contact nodes (3D: Y along s,
    Ye along e); r as in the module's description (0 in 2D)."""

    alpha: float
    phi: np.ndarray
    X: np.ndarray
    Y: np.ndarray
    residual: float
    r: float = 0.0
    Ye: np.ndarray | None = None


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
    r: np.ndarray | None = None  # r of each eigenpair of `alpha` (zeros in 2D)
    law: str = "rate"  # the 3D slip law solved

    @property
    def complex_count(self) -> int:
        return len(self.alpha) - len(self.positive) - len(self.negative)


def classify(beta: np.ndarray, real_tol: float):
    """Finite eigenvalues alpha = 1/beta, sorted by modulus; real mask; their indices in
    beta; infinite count."""
    finite = np.abs(beta) > INFINITE_TOL
    alpha = 1.0 / beta[finite]
    order = np.argsort(np.abs(alpha), kind="stable")
    alpha = alpha[order]
    real = np.abs(alpha.imag) <= real_tol * np.abs(alpha)
    return alpha, real, np.flatnonzero(finite)[order], int(np.count_nonzero(~finite))


def ratio(s_part: np.ndarray, e_part: np.ndarray) -> np.ndarray:
    """r = |e| / |(s, e)| of each column (or of the vectors) of the s and e parts."""
    e = np.linalg.norm(e_part, axis=0)
    size = np.sqrt(np.linalg.norm(s_part, axis=0) ** 2 + e ** 2)
    return np.where(size > 0, e / np.where(size > 0, size, 1.0), 0.0)


class Problem:
    """K in the contact basis with the index sets of a contact state and a slip law.

    slip, gamma : the slipping nodes and their slip signs.
    clamped     : the DOFs with Phi = 0 (normal DOFs of stuck and slipping nodes, the other
                  DOFs of stuck nodes, 3D rate law: the e DOFs of slipping nodes).
    e_slip      : 3D: the e DOFs of the slipping nodes (else empty).
    """

    def __init__(self, K: sp.csr_matrix, system: ContactSystem, state: ContactState,
                 law: str = "rate"):
        if len(state.status) != system.n_contact:
            raise SolverError("the contact state does not match the number of contact nodes")
        if law not in LAWS:
            raise CaseError(f"unknown slip law {law!r}; allowed: " + ", ".join(LAWS),
                            key="contact.law")
        self.K, self.system, self.state, self.law = K, system, state, law
        self.slip = np.flatnonzero(state.status == SLIP)
        self.gamma = state.gamma[self.slip]
        if len(self.slip) == 0:
            raise SolverError("no slipping contact node: the eigenproblem (3.2) is empty")
        stuck = state.status == STUCK
        s = system
        self.three = s.ce is not None  # 3D: an e DOF at each contact node
        self.e_slip = s.ce[self.slip] if self.three else s.cn[:0]
        clamped = [s.cn[self.slip], s.cn[stuck], s.ct[stuck]]
        if self.three:
            clamped += [s.ce[stuck]] + ([self.e_slip] if law == "rate" else [])
        self.clamped = np.concatenate(clamped)

    @property
    def contact_dofs(self) -> np.ndarray:
        """The contact DOFs: cn, ct (3D: then ce), the order of the Schur complement."""
        return self.system.contact_dofs

    def mode(self, alpha: float, phi: np.ndarray) -> Mode:
        """Normalize Phi, recover the contact forces and check the residual."""
        s = self.system
        F = self.K @ phi
        zero = np.ones(len(phi), dtype=bool)
        zero[self.clamped] = False
        zero[s.ct[self.slip]] = False
        X, Y = F[s.cn], F[s.ct]
        Xc, Yc = X[self.slip], Y[self.slip]
        eq = np.linalg.norm(F[zero]) / max(np.linalg.norm(F), 1e-300)
        law = np.linalg.norm(Yc - alpha * self.gamma * Xc) / max(
            np.linalg.norm(Yc) + abs(alpha) * np.linalg.norm(Xc), 1e-300)
        clamp = np.linalg.norm(phi[self.clamped]) / max(np.linalg.norm(phi), 1e-300)
        u = s.to_xy(phi)
        # sign: the largest tangential contact displacement (first along t) is positive
        pt = np.abs(phi[s.ct])
        big = np.flatnonzero(pt >= 0.999 * pt.max()) if pt.max() > 0 else []
        ref = phi[s.ct[big[0]]] if len(big) else phi[np.argmax(np.abs(phi))]
        scale = np.sign(ref) / np.abs(u).max()
        r, Ye = 0.0, None
        if self.three:
            ts = s.ct[self.slip]
            pair = (F[ts], F[self.e_slip]) if self.law == "rate" else (phi[ts], phi[self.e_slip])
            r, Ye = float(ratio(*pair)), F[s.ce] * scale
        return Mode(float(alpha), phi * scale, X * scale, Y * scale,
                    float(max(eq, law, clamp)), r, Ye)


class Reduced(Problem):
    """K_c (the clamped DOFs eliminated), factored once: the reduced operator T."""

    def __init__(self, K, system, state, *, law="rate", shift=0.0, backend="scipy"):
        super().__init__(K, system, state, law)
        keep = np.ones(K.shape[0], dtype=bool)
        keep[self.clamped] = False
        self.kept = np.flatnonzero(keep)
        position = np.cumsum(keep) - 1
        self.tc = position[system.ct[self.slip]]
        self.Kc = K[self.kept][:, self.kept].tocsc()
        self.Rn = K[system.cn[self.slip]][:, self.kept].tocsr()
        if self.three and law == "rate":  # the e reactions of the slipping nodes
            self.Re = K[self.e_slip][:, self.kept].tocsr()
            self.Ks = K[system.ct[self.slip]][:, self.kept].tocsr()
        elif self.three:
            self.ec = position[self.e_slip]
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
        return fill_order_for(self.system, self.kept, backend)

    def solve_tangential(self, r: np.ndarray) -> np.ndarray:
        """K_c V = tangential load r on the slipping nodes (r of shape (p0,) or (p0, k);
        complex r: real and imaginary parts solved together)."""
        if np.iscomplexobj(r):
            k = r.shape[1] if r.ndim > 1 else None
            V = self.solve_tangential(np.column_stack([r.real, r.imag]))
            return V[:, 0] + 1j * V[:, 1] if k is None else V[:, :k] + 1j * V[:, k:]
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

    def parts(self, V: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """3D: the s and e parts that r compares, of kept-DOF vectors V (n_kept, k): the
        slipping nodes' forces (rate law) or displacements (frozen law)."""
        if self.law == "rate":
            return self.Ks @ V, self.Re @ V
        return V[self.tc], V[self.ec]

    def explicit_T(self, block: int = 64):
        """T as a dense p0 x p0 matrix, solving `block` right-hand sides at a time; in 3D
        also the matrices Ps, Pe of :meth:`parts` of the same solves (else None)."""
        p0 = len(self.slip)
        T = np.empty((p0, p0))
        P = (np.empty((p0, p0)), np.empty((p0, p0))) if self.three else None
        for j in range(0, p0, block):
            cols = np.arange(j, min(j + block, p0))
            E = np.zeros((p0, len(cols)))
            E[cols, np.arange(len(cols))] = 1.0
            V = self.solve_tangential(E)
            T[:, cols] = self.gamma[:, None] * (self.Rn @ V)
            if P is not None:
                P[0][:, cols], P[1][:, cols] = self.parts(V)
        return T, P

    def phi(self, V: np.ndarray) -> np.ndarray:
        out = np.zeros(self.K.shape[0])
        out[self.kept] = V
        return out


def fill_order_for(system: ContactSystem, dofs: np.ndarray, backend: str):
    """The fill-reducing order SciPy's SuperLU is given (PARDISO orders by itself)."""
    return fill_order(system, dofs) if backend == "scipy" else None


def complete_pairs(beta: np.ndarray, vecs: np.ndarray):
    """Add the missing conjugate of a complex eigenvalue ARPACK returned alone."""
    lone = [j for j, b in enumerate(beta)
            if b.imag != 0 and np.min(np.abs(beta - np.conj(b))) > 1e-10 * abs(b)]
    if not lone:
        return beta, vecs
    return (np.concatenate([beta, np.conj(beta[lone])]),
            np.concatenate([vecs, np.conj(vecs[:, lone])], axis=1))


def real_vector(v: np.ndarray) -> np.ndarray:
    """The real eigenvector of a real eigenvalue: remove the arbitrary complex phase."""
    j = np.argmax(np.abs(v))
    return (v * (np.abs(v[j]) / v[j])).real


def finish(prob: Problem, alpha, real, index, phis_of, count, method, n_inf, applications,
           ratios: np.ndarray | None = None) -> Spectrum:
    """The spectrum with the modes of the lowest ``count`` of each family; ``phis_of`` maps
    a list of eigenvector indices to their Phi; ``ratios``: r of every eigenvector (3D)."""
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
                "ill-conditioned (nu very near 0.5, or cells of very different sizes: "
                "edges far shorter than the mesh size?): try "
                + ("method = 'arpack', " if method == "dense" else "method = 'dense', ")
                + "P2/Q2 elements or a tighter [solve] tol")
        modes.append(mode)
    alpha = np.where(real, alpha.real + 0j, alpha)
    r = np.zeros(len(alpha)) if ratios is None else np.asarray(ratios)[index]
    spec = Spectrum(alpha=alpha, positive=alpha[pos].real, negative=alpha[neg].real,
                    modes=modes, method=method, n_infinite=n_inf, applications=applications,
                    r=r, law=prob.law)
    if len(pos) < count:
        spec.warnings.append(f"only {len(pos)} real positive eigenvalue(s) found, {count} asked")
    return spec
