"""A contact state of a load path on its displacement unknowns.

On a load path the friction is fixed, so a state's system can be written on the contact
displacements it leaves free: the tangential one of each slipping node and both of each free
node, n_u = p0 + 2 p_free unknowns instead of the 2p contact forces of :class:`.arcs.State`.
With S the Schur complement onto (U_n, U_t) and z = S (u_c - u0):

* free node: X = Y = 0, rows n and t of S (u_c - u0) = 0;
* slipping node: Y = gamma f X, row t minus gamma f row n of S (u_c - u0) = 0;
* stuck and slipping nodes: their U_n = 0 and the stuck U_t = U^r are known.

That is R (u_c - u0) = 0 with R the n_u rows above: M u_u = R u0 - R_k u_k, M = R_u, one LU of
size n_u. The critical values of the state are 1/beta for the real eigenvalues beta of the
eigen stage's reduced operator T = gamma S_nu S_uu^-1 E (:func:`critfric.solvers.eigen.
schur_spectrum`), S_uu symmetric positive definite. A press-then-shear path mostly has few
slipping nodes, so both cost a fraction of the 2p systems.
"""

from __future__ import annotations

import numpy as np
import scipy.linalg as la

from ..solvers.eigen import INFINITE_TOL
from .arcs import REAL_TOL, State, Track
from .states import FREE, SLIP_MINUS, SLIP_PLUS, STUCK


class Singular(Exception):
    """The fixed friction is a critical value of the state: its system is singular."""


class LoadState(State):
    """:class:`.arcs.State` of a load path, solved on its displacement unknowns; its
    critical values (only its margins need them) are computed when first asked for."""

    def __init__(self, track: Track, code: np.ndarray):
        self.track, self.cz, self.code = track, track.cz, np.asarray(code, dtype=np.int8)
        cz, p = self.cz, self.cz.p
        S = cz.cond.S
        self.slip = np.flatnonzero((self.code == SLIP_PLUS) | (self.code == SLIP_MINUS))
        self.gamma = np.where(self.code[self.slip] == SLIP_PLUS, 1.0, -1.0)
        free, stuck = np.flatnonzero(self.code == FREE), np.flatnonzero(self.code == STUCK)
        self.u = np.concatenate([p + self.slip, free, p + free])
        self.known = np.concatenate([stuck, p + stuck, self.slip])
        self.uk = np.concatenate([np.zeros(len(stuck)), cz.Ur[stuck], np.zeros(len(self.slip))])
        p0, f = len(self.slip), float(track.fixed)
        self._gf = self.gamma * f
        Suu = S[np.ix_(self.u, self.u)]  # R[:, u], R the rows of the state (module notes)
        self.lu = None
        if len(self.u):
            M = Suu.copy()
            M[:p0] -= self._gf[:, None] * S[np.ix_(self.slip, self.u)]
            self.lu = la.lu_factor(M, check_finite=False)
            pivots = np.abs(np.diag(self.lu[0]))
            if not pivots.min() > 1e-13 * pivots.max():
                raise Singular
        self._critical = None
        self.ref, self.schur, self.Z1, self.H, self._rows = f, None, None, None, None
        self._affine = self._direction = None

    @property
    def critical(self) -> np.ndarray:
        """The state's critical values, sorted."""
        if self._critical is None:
            self._critical = (_critical(self.cz.cond.S, self.u, self.slip, self.gamma)
                              if len(self.slip) else np.zeros(0))
        return self._critical

    def singular_at(self, f: float) -> None:
        """None: a state whose system is singular at the fixed friction is no LoadState."""

    def _rows_times(self, v: np.ndarray) -> np.ndarray:
        """R v for a vector v of all 2p contact displacements: rows of S v."""
        Sv = self.cz.cond.S @ v
        out = Sv[self.u]
        out[:len(self.slip)] -= self._gf * Sv[self.slip]
        return out

    def _forces(self, du: np.ndarray, dk: np.ndarray, u0: np.ndarray) -> np.ndarray:
        """z = S (u_c - u0) for the unknown and known contact displacements du, dk."""
        uc = np.zeros(2 * self.cz.p)
        uc[self.u], uc[self.known] = du, dk
        return self.cz.cond.S @ (uc - u0)

    def solve(self, t: float) -> np.ndarray:
        """z(t) = z(0) + t dz/dt: affine in the load factor (both made once)."""
        if self._affine is None:
            u0 = self.track.cz.u0
            uk = np.zeros(2 * self.cz.p)
            uk[self.known] = self.uk
            rhs = self._rows_times(u0 - uk)
            du = la.lu_solve(self.lu, rhs) if self.lu is not None else np.zeros(0)
            self._affine = (self._forces(du, self.uk, u0), self.solve_direction())
        return self._affine[0] + t * self._affine[1]

    def solve_direction(self) -> np.ndarray:
        """dz/dt: u0 moves along u0 of L1, the known displacements stay."""
        if self._direction is None:
            u0b = self.track.u0b
            du = la.lu_solve(self.lu, self._rows_times(u0b)) if self.lu is not None \
                else np.zeros(0)
            self._direction = self._forces(du, np.zeros(len(self.known)), u0b)
        return self._direction


def _critical(S: np.ndarray, u: np.ndarray, slip: np.ndarray, gamma: np.ndarray) -> np.ndarray:
    """1/beta, sorted, for the real finite eigenvalues beta of T = gamma S_nu S_uu^-1 E
    (u: the unknowns, the p0 slipping tangential ones first; E picks those)."""
    W = la.cho_solve(la.cho_factor(S[np.ix_(u, u)], check_finite=False),
                     np.eye(len(u), len(slip)), check_finite=False)
    beta = la.eigvals(gamma[:, None] * (S[np.ix_(slip, u)] @ W), check_finite=False)
    finite = np.abs(beta) > INFINITE_TOL
    real = finite & (np.abs(beta.imag) <= REAL_TOL * np.abs(beta))
    return np.sort(1.0 / beta[real].real)
