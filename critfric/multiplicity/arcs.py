"""One piece of a solution curve: a contact state followed along the parameter, exactly.

The parameter t is the friction (load fixed) or the load factor of L0 + t L1 (friction fixed).
In a state (:mod:`.states`) the solution is z(t) = A(t)^-1 b(t):

* load: A is fixed and b affine in t, so z is affine and every inequality g_j(t) is affine:
  the piece ends at the first root of the g_j (a ratio test, as in a pivoting method);
* friction: A(f) = A0 + f E F^T (the slip rows), b fixed. With z0 = A0^-1 b, Z1 = A0^-1 E,
  H = F^T Z1 and q = F^T z0 (Woodbury): z(f) = z0 - f Z1 y(f), (I + f H) y = q. z is rational
  in f with poles at -1/lambda, lambda the eigenvalues of H: the real ones are the critical
  coefficients of the state (eigenproblem (3.2)). An inequality is
  g_j(f) = a_j + f b_j - f (P_j + f Q_j)^T y(f), and its roots are the finite eigenvalues of
  a linear pencil of size 2 p0 + 1 (y, w = f y, 1): exact, for states with at most
  EXACT_SLIP slipping nodes; above that the roots are bracketed on a grid (GRID points, and
  points that close in geometrically on both ends of the interval and on every pole near it)
  and found by Brent's method to ROOT_TOL.

A continuum (a *null* arc) is z + c n at fixed t, n a null vector of a singular A: its
inequalities are affine in c.

Criteria (stated once): a piece shorter than MIN_STEP (relative to the range) is empty; a point
is feasible when every scaled inequality is <= FEASIBLE_TOL; a root within MIN_STEP of the
start of a piece is the start itself (a piece that leaves through it at once is empty, which
the midpoint check finds); the friction is on a critical value when within SINGULAR_TOL
(relative) of it; a pole is removable (the curve goes through it) when its residue is at most
SINGULAR_TOL F.
"""

from __future__ import annotations

import numpy as np
import scipy.linalg as la
from scipy.optimize import brentq

from ..solvers.eigen import INFINITE_TOL
from .states import FREE, SLIP_MINUS, SLIP_PLUS, STUCK, Condensed

EXACT_SLIP = 16
GRID = 64
CHUNK = 16  # grid values evaluated at a time
ROOT_TOL = 1e-13
MIN_STEP = 1e-13
FEASIBLE_TOL = 1e-9
SINGULAR_TOL = 1e-9
REAL_TOL = 1e-8
NOISE = 1e-12  # scaled inequality values within this of 0 are 0 (bracketing grid)


class Track:
    """The parameter of a path: friction(t) and u0(t) (contact displacements under the load)."""

    def __init__(self, cz: Condensed, parameter: str, friction: float | None,
                 u0_load: np.ndarray | None, span: tuple[float, float]):
        self.cz, self.parameter, self.fixed = cz, parameter, friction
        self.u0b = np.zeros_like(cz.u0) if u0_load is None else u0_load
        self.span = span
        self.length = max(span[1] - span[0], 1e-300)

    def friction(self, t: float) -> float:
        return float(t) if self.parameter == "friction" else float(self.fixed)

    def u0(self, t: float) -> np.ndarray:
        return self.cz.u0 if self.parameter == "friction" else self.cz.u0 + t * self.u0b


class State:
    """A contact state along the parameter: its critical values and its pieces."""

    def __init__(self, track: Track, code: np.ndarray):
        self.track, self.cz, self.code = track, track.cz, np.asarray(code, dtype=np.int8)
        p = self.cz.p
        self.slip = np.flatnonzero((self.code == SLIP_PLUS) | (self.code == SLIP_MINUS))
        # A(f) = A0 + f E F^T: E puts y on the slip Y rows, F^T z = -gamma X_slip
        self.gamma = np.where(self.code[self.slip] == SLIP_PLUS, 1.0, -1.0)
        self._U1 = None  # contact displacements of the columns of Z1, where known
        if track.parameter == "friction":
            ref, Z1 = 0.0, self._displacement_form()
        else:
            # one factorization: of A(fixed friction) on a load path (of A0 if that is
            # singular: the fixed friction is a critical value of the state); A(f) = A(ref) +
            # (f - ref) E F^T, singular where 1 + (f - ref) lambda = 0
            E = np.zeros((2 * p, len(self.slip)))
            E[p + self.slip, np.arange(len(self.slip))] = 1.0
            ref = float(track.fixed)
            self.lu = la.lu_factor(self.A(ref), check_finite=False)
            pivots = np.abs(np.diag(self.lu[0]))
            if ref and not pivots.min() > 1e-13 * pivots.max():
                ref, self.lu = 0.0, la.lu_factor(self.A(0.0), check_finite=False)
            Z1 = la.lu_solve(self.lu, E)
        self.ref, self._rows = ref, None
        self.H = self.Ft(Z1)
        self.Z1 = Z1 if track.parameter == "friction" else None  # Woodbury along the friction
        self.schur = None  # H = Z T Z^*: O(p0^2) solves at every friction of the grid
        if track.parameter == "friction" and len(self.slip) > EXACT_SLIP:
            self.schur = la.schur(self.H, output="complex")
            lam = np.diag(self.schur[0])
        else:
            lam = la.eigvals(self.H) if len(self.slip) else np.zeros(0)
        real = (np.abs(lam.imag) <= REAL_TOL * np.abs(lam)) & (np.abs(lam) > INFINITE_TOL)
        self.critical = np.sort(ref - 1.0 / lam[real].real)
        self.poles = ref - 1.0 / lam[np.abs(lam) > INFINITE_TOL]  # complex too: for the grid

    # ------------------------------------------------------------------ the linear system
    def _displacement_form(self) -> np.ndarray:
        """A0 = A(0) of a friction path, solved on the contact displacements it leaves free
        (the tangential one of each slipping node, both of each free node): at friction 0 the
        rows of S on them, S_uu, symmetric positive definite (one Cholesky of size p0 +
        2 p_free instead of an LU of size 2p). Returns Z1 = A0^-1 E, the forces of the
        displacements M0^-1 E (E: the slipping tangential unknowns, first)."""
        p, S = self.cz.p, self.cz.cond.S
        free = np.flatnonzero(self.code == FREE)
        stuck = np.flatnonzero(self.code == STUCK)
        self.lu = None
        self._u = np.concatenate([p + self.slip, free, p + free])
        self._known = np.zeros(2 * p)  # U_n = 0 touching, U_t = U^r stuck, 0 elsewhere
        self._known[p + stuck] = self.cz.Ur[stuck]
        self._chol = (la.cho_factor(S[np.ix_(self._u, self._u)], check_finite=False)
                      if len(self._u) else None)
        p0 = len(self.slip)
        if not p0:
            return np.zeros((2 * p, 0))
        E = np.eye(len(self._u), p0)
        Z = la.cho_solve(self._chol, E, check_finite=False)
        self._U1 = np.zeros((2 * p, p0))  # C Z1 = the displacements themselves
        self._U1[self._u] = Z
        Z1 = np.empty((2 * p, p0))  # S Z on the rows u is S_uu Z = E: only the others
        known = np.setdiff1d(np.arange(2 * p), self._u)
        Z1[self._u], Z1[known] = E, S[np.ix_(known, self._u)] @ Z
        return Z1

    def _base(self, t: float) -> np.ndarray:
        """A(ref)^-1 b(t): the state's solution at the reference friction."""
        if self.lu is not None:
            return la.lu_solve(self.lu, self.b(t))
        S, u0 = self.cz.cond.S, self.track.u0(t)
        uc = self._known.copy()
        if self._chol is not None:
            uc[self._u] = la.cho_solve(self._chol, (S @ (u0 - uc))[self._u], check_finite=False)
        return S @ (uc - u0)

    def A(self, f: float) -> np.ndarray:
        A = self.cz.matrix(self.code)
        A[self.cz.p + self.slip, self.slip] = -self.gamma * f
        return A

    def Ft(self, z: np.ndarray) -> np.ndarray:
        """F^T z = -gamma X on the slipping nodes (z of shape (2p,) or (2p, k))."""
        g = self.gamma if z.ndim == 1 else self.gamma[:, None]
        return -g * z[self.slip]

    def b(self, t: float) -> np.ndarray:
        return self.cz.rhs(self.code, u0=self.track.u0(t))

    def singular_at(self, f: float) -> float | None:
        """The critical value of the state that f is on, or None."""
        near = np.abs(self.critical - f) <= SINGULAR_TOL * np.maximum(np.abs(self.critical), 1)
        return float(self.critical[near][0]) if near.any() else None

    def margins(self) -> tuple[float | None, float | None]:
        """The lowest positive and the negative of least modulus critical value."""
        pos, neg = self.critical[self.critical > 0], self.critical[self.critical < 0]
        return (float(pos[0]) if len(pos) else None, float(neg[-1]) if len(neg) else None)

    def solve(self, t: float) -> np.ndarray:
        """z(t) of a regular state."""
        f, z0 = self.track.friction(t), self._base(t)
        if self.track.parameter == "load":
            return z0
        y = la.solve(np.eye(len(self.slip)) + f * self.H, self.Ft(z0), check_finite=False)
        return z0 - f * self.Z1 @ y

    def slack(self, t: float, z: np.ndarray) -> np.ndarray:
        return self.cz.slack(self.code, self.track.friction(t), z, u0=self.track.u0(t))

    def null(self, f: float) -> np.ndarray:
        """Unit null vectors (2p, k) of the singular A(f) (scaled coordinates' norm)."""
        _, sv, Vt = la.svd(self.A(f))
        N = Vt[sv <= np.sqrt(SINGULAR_TOL) * sv[0]].T
        if N.shape[1] == 0:
            N = Vt[-1:].T
        scale = np.abs(self.cz.norm(N.T, u0=np.zeros_like(self.cz.u0))).max(axis=1)
        return N / scale

    # ------------------------------------------------------------------ pieces
    def exit(self, t0: float, z0: np.ndarray, d: int):
        """The end of the piece from (t0, z0) in direction d (+1/-1): (t_end, z_end, why),
        why in {"row", "end", "pole"}; None if the piece is empty (infeasible at once)."""
        lim = self.track.span[1] if d > 0 else self.track.span[0]
        if d * (lim - t0) <= MIN_STEP * self.track.length:
            return None
        if self.track.parameter == "load":
            s_end, why = self._load_exit(t0, z0, d, lim)
        elif self._leaves_at_once(t0, z0, d):
            return None
        else:
            s_end, why = self._friction_exit(t0, d, lim)
        if s_end <= MIN_STEP * self.track.length:
            return None
        mid = t0 + d * 0.5 * s_end
        if self.slack(mid, self.solve(mid)).max(initial=-np.inf) > FEASIBLE_TOL:
            return None
        t1 = lim if why == "end" else t0 + d * s_end
        return t1, (self.solve(t1) if why != "pole" else self.limit(t1)), why

    def _load_exit(self, t0, z0, d, lim):
        zb = self.solve_direction()
        g0 = self.slack(t0, z0)
        slope = d * self.cz.slack(self.code, self.track.fixed, zb, u0=self.track.u0b,
                                  Ur=np.zeros(self.cz.p))
        end = abs(lim - t0)
        first = first_root(g0, slope, self.track.length)
        return (first, "row") if first < end else (end, "end")

    def solve_direction(self) -> np.ndarray:
        """dz/dt of a load path: A z' = b(u0 of L1, U^r = 0)."""
        b1 = self.cz.rhs(self.code, u0=self.track.u0b, Ur=np.zeros(self.cz.p))
        return la.lu_solve(self.lu, b1)

    def _leaves_at_once(self, t0: float, z0: np.ndarray, d: int) -> bool:
        """Whether a row active at (t0, z0) rises at once along the friction in direction d
        (the rule of :func:`first_root` on the rows' derivatives): the piece is then empty,
        with no search for its end. A state singular at t0 is left to the search."""
        if self.singular_at(t0) is not None:
            return False
        cz, p0 = self.cz, len(self.slip)
        dz = np.zeros_like(z0)
        if p0:  # A(f) z' = -E F^T z, A(f)^-1 E = Z1 (I + f H)^-1
            dz = -self.Z1 @ la.solve(np.eye(p0) + t0 * self.H, self.Ft(z0), check_finite=False)
        zero = np.zeros_like(z0)
        slope = d * (cz.slack_friction(self.code, z0)
                     + cz.slack(self.code, t0, dz, u0=zero, Ur=np.zeros(cz.p)))
        active = self.slack(t0, z0) >= -2 * NOISE
        return bool(np.any(active & (slope * self.track.length > NOISE)))

    def _friction_exit(self, t0, d, lim):
        end = abs(lim - t0)
        real = self.critical[(d * (self.critical - t0) > MIN_STEP * self.track.length)]
        poles = np.abs(real - t0)
        pole = poles.min(initial=np.inf)
        upto = min(end, pole)
        roots = self._roots(t0, d, upto)
        if roots < upto:
            return roots, "row"
        if pole <= end:
            return pole, "pole"
        return end, "end"

    def _parts(self, t0: float):
        """The rows as g(f) = a + f b - f (P + f Q) y(f), (I + f H) y = q: the same at every
        t0 of a friction path (the load is fixed), so made once per state."""
        if self._rows is None:
            z0 = self._base(t0)
            cz, u0 = self.cz, self.track.u0(t0)
            a = cz.slack(self.code, 0.0, z0, u0=u0)
            U1 = None if self._U1 is None else self._U1.T
            linear = lambda f: cz.slack(self.code, f, self.Z1.T, u0=np.zeros_like(z0),
                                        Ur=np.zeros(cz.p), uc=U1).T
            P = linear(0.0)  # y in units of F: the pencils' entries are then all O(1)
            self._rows = (a, cz.slack(self.code, 1.0, z0, u0=u0) - a, cz.F * P,
                          cz.F * (linear(1.0) - P), self.Ft(z0) / cz.F)
        return self._rows

    def _g(self, f, parts):
        """The rows at friction f: (m,) for a number, (n, m) for n values at once."""
        a, b, P, Q, q = parts
        F = np.atleast_1d(np.asarray(f, dtype=float))
        if self.schur is None:
            y = np.linalg.solve(np.eye(len(q)) + F[:, None, None] * self.H,
                                np.broadcast_to(q, (len(F), len(q)))[..., None])[..., 0]
        else:  # (I + f T) w = Z^* q, y = Z w: a triangular solve per friction value
            T, Zs = self.schur
            r, I = Zs.conj().T @ q, np.eye(len(q))
            w = np.stack([la.solve_triangular(I + fi * T, r, check_finite=False) for fi in F])
            y = (w @ Zs.T).real
        g = a + F[:, None] * b - F[:, None] * (y @ P.T + F[:, None] * (y @ Q.T))
        return g if np.ndim(f) else g[0]

    def _g_row(self, f: float, parts, j: int) -> float:
        """Row j alone at friction f (what Brent's method evaluates)."""
        a, b, P, Q, q = parts
        if self.schur is None:
            y = la.solve(np.eye(len(q)) + f * self.H, q, check_finite=False)
        else:
            T, Zs = self.schur
            y = (Zs @ la.solve_triangular(np.eye(len(q)) + f * T, Zs.conj().T @ q,
                                          check_finite=False)).real
        return float(a[j] + f * b[j] - f * (P[j] @ y + f * (Q[j] @ y)))

    def _roots(self, t0: float, d: int, upto: float) -> float:
        """The first s in (MIN_STEP, upto) with a row g_j(t0 + d s) = 0 (inf if none)."""
        parts = self._parts(t0)
        p0, L = len(self.slip), self.track.length
        if p0 == 0:  # nothing depends on the friction but the stuck cones: affine rows
            a, b = parts[0], parts[1]
            return first_root(a + t0 * b, d * b, L)
        probes = t0 + d * upto * np.array([0.2113, 0.5, 0.7887])
        scale = np.abs(self._g(probes, parts)).max(axis=0)
        live = np.flatnonzero(scale > FEASIBLE_TOL)  # rows not identically zero
        if p0 <= EXACT_SLIP:
            found = self._pencil_roots(parts, live, t0, d, upto)
        else:
            found = self._grid_roots(parts, live, t0, d, upto)
        return min(found, default=np.inf)

    def _pencil_roots(self, parts, live, t0, d, upto) -> list[float]:
        a, b, P, Q, q = parts
        p0, L = len(q), self.track.length
        I = np.eye(p0)
        n = 2 * p0 + 1  # the pencil in (y, f y, 1); in (y, 1) where no f^2 term
        big0, big1 = np.zeros((n, n)), np.zeros((n, n))
        big0[:2 * p0, :2 * p0] = np.eye(2 * p0)
        big0[:p0, -1] = -q
        big1[:p0, :p0], big1[p0:2 * p0, :p0] = self.H, -I
        small0, small1 = np.zeros((p0 + 1, p0 + 1)), np.zeros((p0 + 1, p0 + 1))
        small0[:p0, :p0], small0[:p0, -1], small1[:p0, :p0] = I, -q, self.H
        rows, cands = [], []
        for j in live:  # loop over the rows of one state, each a pencil of size 2 p0 + 1
            if Q[j].any() or b[j]:
                M0, M1 = big0, big1
                M0[-1, p0:2 * p0], M0[-1, -1] = -P[j], a[j]
                M1[-1, p0:2 * p0], M1[-1, -1] = -Q[j], b[j]
            else:
                M0, M1 = small0, small1
                M0[-1, -1], M1[-1, :p0] = a[j], -P[j]
            with np.errstate(all="ignore"):
                f = la.eigvals(M0, -M1, check_finite=False)
            f = f[np.isfinite(f) & (np.abs(f.imag) <= REAL_TOL * np.maximum(np.abs(f), 1))].real
            s = d * (f - t0)
            s = s[(s > MIN_STEP * L) & (s < upto)]
            rows += [j] * len(s)
            cands += s.tolist()
        if not cands:
            return []
        rows, cands = np.array(rows), np.array(cands)
        at = self._g(t0 + d * cands, parts)[np.arange(len(rows)), rows]
        half = self._g(t0 + d * cands / 2, parts)[np.arange(len(rows)), rows]
        regular = np.array([self.singular_at(t0 + d * c) is None for c in cands])
        ok = regular & (np.abs(at) <= 1e-6) & (half < -NOISE)  # a root, below 0 before it
        out: list[float] = []
        for i in np.argsort(cands):  # only the first crossing (and its near ties) matter
            if out and cands[i] > min(out) + 1e-6 * max(min(out), L):
                break
            root = self._polish(parts, rows[i], t0, d, cands[i]) if ok[i] else None
            if root is not None:
                out.append(root)
        return out

    def _polish(self, parts, j, t0, d, s) -> float | None:
        """An eigenvalue root of row j made exact to ROOT_TOL by Brent's method on the row;
        None unless the row crosses from below there (within 1e-8 relative): a touch, or the
        round-off copy of a root at the start, is no end of the piece."""
        fn = lambda x: self._g_row(t0 + d * x, parts, j)
        w = 1e-8 * max(s, self.track.length)
        lo, hi = max(s - w, 0.5 * s), s + w
        if fn(lo) < 0 < fn(hi):
            return brentq(fn, lo, hi, xtol=ROOT_TOL * self.track.length, rtol=1e-15)
        return None

    def _grid_roots(self, parts, live, t0, d, upto) -> list[float]:
        ends = np.geomspace(1e-13, 1e-2, 12)  # close in on both ends of the interval
        s = np.concatenate([np.linspace(0.0, upto, GRID + 1)[1:-1], upto * ends,
                            upto * (1 - ends), upto * np.geomspace(1e-6, 1e-2, 17)])
        c = d * (self.poles.real - t0)
        w = np.maximum(np.abs(self.poles.imag), 1e-12 * self.track.length)
        near = (c > -w) & (c < upto + w) & (w < upto)  # the poles that shape the rows here
        for ci, wi in zip(c[near], w[near]):  # close in on each of them
            s = np.concatenate([s, ci + np.outer([-1, 1], wi * np.geomspace(1e3, 1, 10)).ravel()])
        s = np.unique(s[(s > MIN_STEP * self.track.length) & (s < upto)])
        # a crossing: above NOISE after having been below -NOISE (a row active at t0 starts
        # at 0 within round-off: its root there is the start, not an end); evaluated in
        # chunks from t0 on, up to the first chunk with one (pieces are mostly short)
        g = np.zeros((0, len(live)))
        for start in range(0, len(s), CHUNK):
            g = np.vstack([g, self._g(t0 + d * s[start:start + CHUNK], parts)[:, live]])
            below = np.maximum.accumulate(g < -NOISE, axis=0)
            bad = (g > NOISE) & np.vstack([np.zeros((1, len(live)), bool), below[:-1]])
            if bad.any():
                break
        else:
            return []
        k = int(np.argmax(bad.any(axis=1)))
        out = []
        for j in np.flatnonzero(bad[k]):
            lo = s[k - 1]
            if g[k - 1, j] >= 0:  # within round-off of 0 already: the root is there
                out.append(lo)
                continue
            fn = lambda x, j=live[j]: self._g_row(t0 + d * x, parts, j)
            out.append(brentq(fn, lo, s[k], xtol=ROOT_TOL * self.track.length, rtol=1e-15))
        return out

    def limit(self, f: float) -> np.ndarray | None:
        """The limit of z at the critical value f where the pole is removable, else None."""
        lam, V = la.eig(self.H)
        z0 = self._base(f)
        w = la.solve(V, self.Ft(z0))
        at = np.abs(1.0 + f * lam) <= SINGULAR_TOL * np.maximum(np.abs(f * lam), 1.0)
        residue = np.abs(self.Z1 @ (V[:, at] * w[at])).max(initial=0.0) * abs(f)
        if residue > SINGULAR_TOL * self.cz.F * max(abs(f), 1.0):
            return None
        y = V[:, ~at] @ (w[~at] / (1.0 + f * lam[~at]))
        return (z0 - f * self.Z1 @ y).real

    def null_exit(self, t: float, z0: np.ndarray, n: np.ndarray):
        """The end of the continuum z0 + c n, c >= 0: (c_end or inf, z_end or None), or None
        if it is empty."""
        g0 = self.slack(t, z0)
        slope = self.cz.slack(self.code, self.track.friction(t), n, u0=np.zeros_like(z0),
                              Ur=np.zeros(self.cz.p))
        end = first_root(g0, slope, 1.0)
        probe = 0.5 * end if np.isfinite(end) else 1.0
        if end <= MIN_STEP or self.slack(t, z0 + probe * n).max() > FEASIBLE_TOL:
            return None
        return end, (z0 + end * n if np.isfinite(end) else None)


def first_root(g0: np.ndarray, slope: np.ndarray, length: float) -> float:
    """The first s > 0 at which an affine row g0 + slope s rises through 0 (inf: none); 0 if
    a row active at s = 0 (within NOISE) rises at once (the piece is empty)."""
    active = g0 >= -2 * NOISE
    if np.any(active & (slope * length > NOISE)):
        return 0.0
    with np.errstate(divide="ignore", invalid="ignore"):
        s = np.where(~active & (slope > 0), -g0 / slope, np.inf)
    return float(s.min(initial=np.inf))
