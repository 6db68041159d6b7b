"""The static Coulomb problem (2.8)-(2.11) in nodal form: a semi-smooth Newton solver.

Condensation. K is factored once with the 2p contact DOFs ordered last (the rest in a
minimum-degree order); the trailing block of the factors is then the Schur complement S of K
onto the contact DOFs, the stiffness of the body seen from Gamma_C. With u0 the contact
displacements under the load alone (X = Y = 0), contact displacements u_c = (U_n, U_t) come
with the contact forces z = (X, Y) = S (u_c - u0); K U = rhs + B_n X + B_t Y then holds exactly
when U is recovered with one more solve. Cost: about two sparse factorizations, no 2p solves.

Complementarity (Alart-Curnier), with P = -X the contact pressure, w = U_t - U^r the slip,
N = P + r U_n the augmented pressure, xi = Y - r w and the cone radius b = friction max(N, 0):
    F_n = P - max(0, N),    F_t = Y - clip(xi, -b, b).
F = 0 exactly when (2.9)-(2.11) hold. F is piecewise linear in u_c: Newton on its generalized
Jacobian (branch by branch: free N <= 0, stuck |xi| < b, slipping otherwise with sign -sign xi)
ends in one step once the active set is right. r = mean of diag(S) balances forces and
displacements.

Convergence criterion: |F|_inf <= tol * scale, with the load scale
scale = max(|z|_inf, |S u0|_inf, r |U^r|_inf), and the active set unchanged by the last step
(or the tolerance met at SETTLE iterates in a row: a node exactly at a kink may flip status on
round-off); a starting point that already meets the tolerance is accepted as it is. Steps are
halved (at most 8 times) while they do not decrease |F|; at most ``maxiter`` iterations.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp

from ..errors import CaseError, SolverError
from ..fem.contact import FREE, SLIP, STUCK, ContactSystem
from ..fem.static import StaticProblem
from .backends import schur
from .eigen import ContactState
from .ordering import fill_order

TOL = 1e-10
MAXITER = 50
HALVINGS = 8
SETTLE = 3


class Condensed:
    """K factored once with its Schur complement onto the contact DOFs
    (:func:`critfric.solvers.backends.schur`: PARDISO's Schur option, or SuperLU with the
    contact DOFs last); ``S`` (2p, 2p): the Schur complement onto (U_n, U_t); ``solve``: K^-1."""

    def __init__(self, K: sp.spmatrix, system: ContactSystem, backend: str = "auto"):
        self.cdofs = np.concatenate([system.cn, system.ct])
        self.p = system.n_contact
        self._schur = schur(K, self.cdofs, backend=backend, order=fill_order(system))
        self.S = self._schur.S

    def solve(self, b: np.ndarray) -> np.ndarray:
        """K^-1 b for b of shape (m,) or (m, k)."""
        return self._schur.solve(b)


class Complementarity:
    """The Alart-Curnier function F(u_c) of a condensed problem at one friction value."""

    def __init__(self, S: np.ndarray, u0: np.ndarray, reference: np.ndarray, friction: float):
        self.S, self.u0, self.Ur, self.friction = S, u0, reference, float(friction)
        self.p = len(reference)
        self.r = float(np.mean(np.diag(S)))
        self.load_scale = max(np.abs(S @ u0).max(), self.r * np.abs(reference).max())

    def forces(self, uc: np.ndarray) -> np.ndarray:
        return self.S @ (uc - self.u0)

    def evaluate(self, uc: np.ndarray, jacobian: bool = True):
        """F (2p,), its generalized Jacobian (2p, 2p) or None, and the active set codes."""
        p, r, f = self.p, self.r, self.friction
        z = self.forces(uc)
        X, Y, Un, w = z[:p], z[p:], uc[:p], uc[p:] - self.Ur
        N = -X + r * Un
        xi = Y - r * w
        contact = N > 0
        stick = contact & (np.abs(xi) < f * N)
        s = np.sign(xi)
        F = np.concatenate([np.where(contact, -r * Un, -X),
                            np.where(~contact, Y, np.where(stick, r * w, Y - s * f * N))])
        active = np.where(~contact, 0, np.where(stick, 1, 2 + (s > 0)))
        if not jacobian:
            return F, None, active
        I = np.eye(2 * p)
        dX, dY, dUn, dw = self.S[:p], self.S[p:], I[:p], I[p:]
        Jn = np.where(contact[:, None], -r * dUn, -dX)
        Jslip = dY - (s * f)[:, None] * (-dX + r * dUn)
        Jt = np.where(~contact[:, None], dY, np.where(stick[:, None], r * dw, Jslip))
        return F, np.vstack([Jn, Jt]), active

    def residual(self, uc: np.ndarray) -> float:
        """|F(u_c)|_inf relative to the load scale (the Newton convergence measure)."""
        F, _, _ = self.evaluate(uc, jacobian=False)
        scale = max(self.load_scale, np.abs(self.forces(uc)).max(), 1e-300)
        return float(np.abs(F).max() / scale)


@dataclass
class CoulombSolution:
    """A solution of (2.8): U on the free DOFs (n/t), u (n_nodes, 2) with the Dirichlet data,
    contact values along Gamma_C (sorted along t) and the contact state (3.2) it defines."""

    U: np.ndarray
    u: np.ndarray
    Un: np.ndarray
    Ut: np.ndarray
    X: np.ndarray
    Y: np.ndarray
    state: ContactState
    friction: float
    iterations: int
    residual: float
    history: list[float] = field(default_factory=list)

    @property
    def labels(self) -> list[str]:
        names = {FREE: "free", STUCK: "stuck"}
        return [names.get(int(s), "slip+" if g > 0 else "slip-")
                for s, g in zip(self.state.status, self.state.gamma)]


def condense(problem: StaticProblem) -> tuple[Condensed, np.ndarray]:
    """The condensed problem: the factored K and u0, the contact displacements under the load."""
    cond = Condensed(problem.K, problem.system)
    return cond, cond.solve(problem.rhs)[cond.cdofs]


def solve(problem: StaticProblem, friction: float | None = None, *, condensed=None,
          start: np.ndarray | None = None, tol: float = TOL,
          maxiter: int = MAXITER) -> CoulombSolution:
    """Solve (2.8)-(2.11) by semi-smooth Newton on the Alart-Curnier functions.

    Parameters
    ----------
    friction
        The friction coefficient (default: the problem's ``[load] friction``).
    condensed
        (Condensed, u0) from :func:`condense`, to reuse one factorization.
    start
        Contact displacements (U_n, U_t) (2p,) to start from (default: all stuck, U_n = 0,
        U_t = U^r).
    """
    friction = problem.friction if friction is None else friction
    if friction is None or not friction >= 0:
        raise CaseError(f"got friction {friction!r}; allowed: a number >= 0 ([load] friction)",
                        key="load.friction")
    cond, u0 = condensed or condense(problem)
    p = cond.p
    comp = Complementarity(cond.S, u0, problem.reference, friction)
    uc = (np.concatenate([np.zeros(p), problem.reference]) if start is None
          else np.asarray(start, dtype=float).copy())
    F, J, active = comp.evaluate(uc)
    history = [comp.residual(uc)]
    previous = None if start is None or history[0] > tol else active
    iterations = 0
    while not _converged(history, active, previous, tol):
        if iterations == maxiter:
            raise SolverError(
                f"the semi-smooth Newton method did not converge in {maxiter} iterations "
                f"(relative residual {history[-1]:.2e} > {tol:g}); try another friction value, "
                "a start closer to the solution, or a larger maxiter")
        try:
            step = np.linalg.solve(J, -F)
        except np.linalg.LinAlgError:
            step = np.linalg.lstsq(J, -F, rcond=None)[0]
        norm, t = np.abs(F).max(), 1.0
        for _ in range(HALVINGS):
            if np.abs(comp.evaluate(uc + t * step, jacobian=False)[0]).max() < norm:
                break
            t *= 0.5
        else:
            t = 1.0  # no decrease along the step: take it whole (leaves a kink)
        uc = uc + t * step
        previous = active
        F, J, active = comp.evaluate(uc)
        history.append(comp.residual(uc))
        iterations += 1
    return _solution(problem, cond, comp, uc, friction, iterations, history)


def _converged(history, active, previous, tol) -> bool:
    """Residual <= tol and the status unchanged by the last step, or the residual <= tol at
    SETTLE iterates in a row (a node exactly at a kink, such as a grazing node with
    X = U_n = 0, may flip status on round-off at every step)."""
    if history[-1] > tol:
        return False
    if previous is not None and np.array_equal(active, previous):
        return True
    return len(history) >= SETTLE and max(history[-SETTLE:]) <= tol


def _solution(problem, cond, comp, uc, friction, iterations, history) -> CoulombSolution:
    p, s = cond.p, problem.system
    z = comp.forces(uc)
    b = problem.rhs.copy()
    b[s.cn] += z[:p]
    b[s.ct] += z[p:]
    U = cond.solve(b)
    _, _, active = comp.evaluate(uc, jacobian=False)
    status = np.choose(np.minimum(active, 2), [FREE, STUCK, SLIP]).astype(np.int8)
    gamma = np.where(active == 3, -1.0, 1.0)  # xi > 0: slip towards -t
    return CoulombSolution(U=U, u=problem.displacement(U), Un=U[s.cn], Ut=U[s.ct], X=z[:p],
                           Y=z[p:], state=ContactState(status, gamma), friction=float(friction),
                           iterations=iterations, residual=history[-1], history=history)


def violations(Un, Ut, X, Y, reference, friction, *, force_scale, disp_scale) -> dict:
    """Largest violation of each condition of (2.9)-(2.11) (arrays over leading axes).

    Forces are divided by ``force_scale``, displacements by ``disp_scale``. "stick" measures
    (2.11): at each node the smaller of the distance to the cone and the slip.
    """
    F, D = force_scale, disp_scale
    w = Ut - reference
    gap = -friction * X - np.abs(Y)
    return {
        "X<=0": np.maximum(X, 0).max(-1) / F,
        "Un<=0": np.maximum(Un, 0).max(-1) / D,
        "X.Un=0": (np.abs(X) / F * np.abs(Un) / D).max(-1),  # no F * D: it may underflow
        "|Y|<=-fX": np.maximum(-gap, 0).max(-1) / F,
        "Y.w<=0": np.maximum(Y / F * (w / D), 0).max(-1),
        "stick": np.minimum(np.maximum(gap, 0) / F, np.abs(w) / D).max(-1),
    }
