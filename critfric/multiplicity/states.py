"""The static problem (2.8) condensed onto Gamma_C, contact state by contact state.

With C = S^-1 the flexibility of Gamma_C (S: the Schur complement of K onto the contact DOFs,
:mod:`critfric.solvers.coulomb`) the contact displacements are u_c = (U_n, U_t) = u0 + C z for
contact forces z = (X, Y), u0 being the contact displacements under the load alone. Each
contact node is free (X = Y = 0), stuck (U_n = 0, U_t = U^r), slipping along +t (slip+:
U_n = 0, Y = friction X) or along -t (slip-: U_n = 0, Y = -friction X): a status per node is a
*state*, and a state is one linear system A z = b (rows scaled to forces by r = mean diag S).
A solution of the state's system solves (2.9)-(2.11) exactly when it satisfies the state's
inequalities (free: U_n <= 0; stuck: X <= 0, |Y| <= -friction X; slipping: X <= 0,
gamma (U_t - U^r) >= 0). A is affine in the friction and b, h are linear in (u0, U^r).

Scales: F (forces: the all-stuck solution and the condensed load) and D (displacements);
inequalities are divided by F or D so that one relative tolerance serves all of them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..fem.static import StaticProblem
from ..solvers.coulomb import condense

FREE, STUCK, SLIP_PLUS, SLIP_MINUS = range(4)
LABELS = ("free", "stuck", "slip+", "slip-")
CONSISTENT_TOL = 1e-9  # a node value within this (relative to F or D) of a boundary is on it


@dataclass
class Condensed:
    """The condensed problem: flexibility C (2p, 2p), u0 (2p,), U^r (p,), the row scale r and
    the scales F, D; ``cond``: the factorization of K it came from (for K^-1 solves), and the
    static problem itself."""

    C: np.ndarray
    u0: np.ndarray
    Ur: np.ndarray
    r: float
    F: float
    D: float
    cond: object = None
    problem: StaticProblem | None = None

    @property
    def p(self) -> int:
        return len(self.Ur)

    @classmethod
    def of(cls, problem: StaticProblem, condensed=None, *, extra=()) -> Condensed:
        """Condense a static problem (``condensed``: (Condensed, u0) of coulomb.condense;
        ``extra``: u0 of other loads, counted in the scales F and D)."""
        cond, u0 = condensed or condense(problem)
        p, Ur = cond.p, problem.reference
        C = np.linalg.inv(cond.S)
        C = 0.5 * (C + C.T)
        r = float(np.mean(np.diag(cond.S)))
        stuck = cond.S @ (np.concatenate([np.zeros(p), Ur]) - u0)
        loads = [u0, *extra]
        F = max(np.abs(stuck).max(), *(np.abs(cond.S @ u).max() for u in loads), 1e-300)
        D = max(*(np.abs(u).max() for u in loads), np.abs(Ur).max(), F / r)
        return cls(C, u0, Ur, r, F, D, cond, problem)

    def contact(self, z: np.ndarray, u0=None, uc=None):
        """(U_n, U_t, X, Y) of contact forces z (..., 2p) (``u0``: another load's u0;
        ``uc``: the displacements C z where already known)."""
        u = (self.u0 if u0 is None else u0) + (z @ self.C.T if uc is None else uc)
        p = self.p
        return u[..., :p], u[..., p:], z[..., :p], z[..., p:]

    def norm(self, z: np.ndarray, u0=None) -> np.ndarray:
        """The point z in scaled coordinates (X, Y)/F, (U_n, U_t)/D: what 'same' compares."""
        Un, Ut, X, Y = self.contact(z, u0)
        return np.concatenate([X / self.F, Y / self.F, Un / self.D, Ut / self.D], axis=-1)

    def systems(self, codes: np.ndarray, friction: float, *, u0=None, Ur=None):
        """Batched A z = b (..., 2p, 2p) of the states ``codes`` (..., p)."""
        p, r = self.p, self.r
        u0 = self.u0 if u0 is None else u0
        Ur = self.Ur if Ur is None else Ur
        I = np.eye(2 * p)
        EX, EY = I[:p], I[p:]
        c = codes[..., None]
        gamma = np.where(codes == SLIP_PLUS, 1.0, -1.0)[..., None]
        first = np.where(c == FREE, EX, r * self.C[:p])
        second = np.where(c == FREE, EY, np.where(c == STUCK, r * self.C[p:],
                                                  EY - gamma * friction * EX))
        return np.concatenate([first, second], axis=-2), self.rhs(codes, u0=u0, Ur=Ur)

    def matrix(self, code: np.ndarray) -> np.ndarray:
        """A of one state at friction 0 (:meth:`systems` for one code, without its batch)."""
        p, r = self.p, self.r
        contact = np.concatenate([code != FREE, code == STUCK])  # rows of C, others unit
        A = np.zeros((2 * p, 2 * p))
        A[contact] = r * self.C[contact]
        unit = np.flatnonzero(~contact)
        A[unit, unit] = 1.0
        return A

    def rhs(self, codes: np.ndarray, *, u0=None, Ur=None) -> np.ndarray:
        """b of :meth:`systems` alone (..., 2p)."""
        p, r = self.p, self.r
        u0 = self.u0 if u0 is None else u0
        Ur = self.Ur if Ur is None else Ur
        b1 = np.where(codes == FREE, 0.0, -r * u0[:p])
        b2 = np.where(codes == STUCK, r * (Ur - u0[p:]), 0.0)
        return np.concatenate([b1, b2], axis=-1)

    def inequalities(self, code: np.ndarray, friction: float, *, u0=None, Ur=None):
        """G z <= h of one state (rows scaled by F or D) and the node of each row."""
        p, F, D = self.p, self.F, self.D
        u0 = self.u0 if u0 is None else u0
        Ur = self.Ur if Ur is None else Ur
        I = np.eye(2 * p)
        nodes = np.arange(p)
        free, stuck = code == FREE, code == STUCK
        slip = (code == SLIP_PLUS) | (code == SLIP_MINUS)
        g = np.where(code == SLIP_PLUS, 1.0, -1.0)
        first = np.where(free[:, None], self.C[:p] / D, I[:p] / F)
        h1 = np.where(free, -u0[:p] / D, 0.0)
        s, k = nodes[stuck], nodes[slip]
        cone = np.concatenate([I[p + s] + friction * I[s], -I[p + s] + friction * I[s]]) / F
        turn = -g[k, None] * self.C[p + k] / D
        G = np.concatenate([first, cone, turn])
        h = np.concatenate([h1, np.zeros(2 * len(s)), g[k] * (u0[p + k] - Ur[k]) / D])
        return G, h, np.concatenate([nodes, s, s, k])

    def slack(self, code: np.ndarray, friction: float, z: np.ndarray, *, u0=None,
              Ur=None, uc=None) -> np.ndarray:
        """G z - h of :meth:`inequalities` (same rows) from node values, for z (..., 2p):
        linear in (z, u0, U^r) together, so u0 = U^r = 0 gives the rows' linear part
        (``uc``: C z where already known)."""
        Un, Ut, X, Y = self.contact(z, u0, uc)
        Ur = self.Ur if Ur is None else Ur
        stuck, slip = code == STUCK, (code == SLIP_PLUS) | (code == SLIP_MINUS)
        g = np.where(code == SLIP_PLUS, 1.0, -1.0)
        F, D = self.F, self.D
        first = np.where(code == FREE, Un / D, X / F)
        Xs, Ys = X[..., stuck], Y[..., stuck]
        turn = -g[slip] * (Ut[..., slip] - Ur[slip]) / D
        return np.concatenate([first, (Ys + friction * Xs) / F, (-Ys + friction * Xs) / F,
                               turn], axis=-1)

    def slack_friction(self, code: np.ndarray, z: np.ndarray) -> np.ndarray:
        """d/d(friction) of :meth:`slack` at fixed z: X / F on both cone rows of each stuck
        node, 0 on the other rows."""
        stuck = np.flatnonzero(code == STUCK)
        Xs = z[stuck] / self.F
        n_slip = np.count_nonzero((code == SLIP_PLUS) | (code == SLIP_MINUS))
        return np.concatenate([np.zeros(self.p), Xs, Xs, np.zeros(n_slip)])

    def labels(self, z: np.ndarray, friction: float, u0=None) -> list[str]:
        """Status words of a solution: free, stuck, slip+, slip- or cone (on the Coulomb cone
        without slipping)."""
        Un, Ut, X, Y = self.contact(z, u0)
        tf, td = CONSISTENT_TOL * self.F, CONSISTENT_TOL * self.D
        w = Ut - self.Ur
        word = np.where(Un < -td, "free", np.where(
            np.abs(Y) < -friction * X - tf, "stuck",
            np.where(w > td, "slip+", np.where(w < -td, "slip-", "cone"))))
        return word.tolist()

    def consistent(self, z: np.ndarray, friction: float, u0=None) -> np.ndarray:
        """(p, 4) bool: which statuses each node's values at z satisfy (equations and
        inequalities, to CONSISTENT_TOL): the states of which z is a solution."""
        Un, Ut, X, Y = self.contact(z, u0)
        tf, td = CONSISTENT_TOL * self.F, CONSISTENT_TOL * self.D
        w = Ut - self.Ur
        touch = (np.abs(Un) <= td) & (X <= tf)
        return np.stack([
            (np.abs(X) <= tf) & (np.abs(Y) <= tf) & (Un <= td),
            touch & (np.abs(w) <= td) & (np.abs(Y) <= -friction * X + tf),
            touch & (np.abs(Y - friction * X) <= tf) & (w >= -td),
            touch & (np.abs(Y + friction * X) <= tf) & (w <= td),
        ], axis=1)
