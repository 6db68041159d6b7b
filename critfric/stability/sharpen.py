"""Sharpening: the reduced model's coalescences made accurate enough for one Newton step.

Each coalescence located on the reduced model (:func:`.locus.locate_flutter`) is found
exactly on the small pencil (:func:`.fold.find_fold`), then the model is enlarged by K_rr^-1
of the full pencil's residuals L v, L^T w of its null vectors and of B v, B^T w (its Jordan
direction), and the coalescence found again, round after round, until it moves by less than
SHARPEN_TOL: a guess whose first Newton correction on the full pencil is already below
Newton's tolerance. Each coalescence has its own added columns T (orthonormal to the
basis V and to each other).

The coalescences (one a sliding direction) go through their rounds in lockstep: a round
solves with K_rr once for all of them (8 columns for two; at 295 k DOFs PARDISO solves 8
columns in 14 ms a column, 4 in 23, SuperLU 8 in 22-25, 4 in 32-35) and reads V, the
largest array of the stage (n x 80), once for all of them in each of its products.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from threadpoolctl import threadpool_limits

from ..errors import SolverError
from . import fold
from .bordered import RANK_TOL, orthonormal, tdot
from .locus import Block, Guess, Reduced, blocks_of
from .pencil import SlidingPencil

SHARPEN_ROUNDS = 8  # at most this many enlargements of the reduced model at a coalescence
SHARPEN_TOL = 1e-7  # ... until its coalescence moves by less than this (relative): each round
# shrinks the move 300-600 times (7.7e-4, 4.4e-6, 1.3e-8, 1.9e-11 at 295 k DOFs), so the
# guess is then within ~1e-10 and the full pencil's Newton stops after one step
WIDE = 4  # columns a round adds to a coalescence's model at most


def sharpen(red: Reduced, pencil: SlidingPencil, factor, guesses: list[Guess]
            ) -> list[Guess]:
    """The sharpened ``guesses`` (module docstring), in their order. ``factor``: a
    factorization of K_rr. At most WIDE SHARPEN_ROUNDS columns are added to each. A model
    on the full space (small problems) is exact: its guesses are returned as they are."""
    if red.V is None or not guesses:
        return list(guesses)
    with threadpool_limits(1, user_api="blas"):
        return _sharpen(red, pencil, factor, guesses)


class _Run:
    """One coalescence's rounds: its reduced matrices, its added columns T[:, :t], and the
    coalescence (f, kappa) with its null vectors' reduced coordinates y, z."""

    def __init__(self, red: Reduced, guess: Guess, yz: np.ndarray):
        self.mats = [red.A0, red.A1, red.B0, red.B1]
        self.T = np.empty((len(red.V), WIDE * SHARPEN_ROUNDS), order="F")  # written by columns
        self.t = 0
        self.f, self.kappa, self.branch = guess.friction, guess.kappa, guess.branch
        self.y, self.z = yz.T
        self.jacobian = None  # the last small Newton's (fold.Fold.jacobian)
        self.active = True

    def find(self, rnd: int) -> None:
        """The coalescence of the current small pencil, from the last one; inactive once it
        moved by less than SHARPEN_TOL, after SHARPEN_ROUNDS or where Newton fails there
        (the full pencil's Newton then starts from the last good point)."""
        d = len(self.mats[0])
        A0, A1, B0, B1 = (sp.csr_matrix(mat) for mat in self.mats)
        small = SlidingPencil(system=None, state=None, kept=np.arange(d), slip=np.arange(d),
                              Krr=A0, Mrr=B0, Knr=A1, Mnr=B1, G=sp.identity(d, format="csr"))
        try:
            found = fold.find_fold(small, self.f, self.kappa, self.y, self.z)
        except SolverError:
            self.active, self.jacobian = False, None
            return
        still = (abs(found.friction - self.f) <= SHARPEN_TOL * abs(found.friction)
                 and abs(found.kappa - self.kappa) <= SHARPEN_TOL * abs(found.kappa))
        self.f, self.kappa, self.y, self.z = (found.friction, found.kappa, found.right,
                                              found.left)
        self.jacobian = found.jacobian
        self.active = not ((rnd and still) or rnd == SHARPEN_ROUNDS)

    def residuals(self, pencil: SlidingPencil, vw: np.ndarray, out: np.ndarray) -> None:
        """L v, L^T w, B v, B^T w (v, w: the null vectors on the kept DOFs) into the WIDE
        columns ``out``."""
        v, w = vw.T
        f, kappa = self.f, self.kappa
        out[:, 2], out[:, 3] = pencil.apply_B(f, v), pencil.apply_B(f, w, transpose=True)
        out[:, 0] = pencil.apply_A(f, v) - kappa * out[:, 2]
        out[:, 1] = pencil.apply_A(f, w, transpose=True) - kappa * out[:, 3]

    def extend(self, new: np.ndarray, edges: list[tuple]) -> None:
        """W' = [W, N] (W = [V, T]): W'^T b W' from W^T b W and the borders W^T b N,
        W^T b^T N, N^T b N of each block b."""
        k = new.shape[1]
        self.mats = [np.block([[mat, right], [below.T, corner]])
                     for mat, (right, below, corner) in zip(self.mats, edges)]
        self.T[:, self.t:self.t + k] = new
        self.t += k
        self.y = np.concatenate([self.y, np.zeros(k)])
        self.z = np.concatenate([self.z, np.zeros(k)])


def _sharpen(red: Reduced, pencil: SlidingPencil, factor, guesses: list[Guess]
             ) -> list[Guess]:
    V, m = red.V, red.V.shape[1]
    blocks = blocks_of(pencil)
    yz = tdot(V, np.column_stack([x for g in guesses for x in (g.right, g.left)]))
    runs = [_Run(red, g, yz[:, 2 * i:2 * i + 2]) for i, g in enumerate(guesses)]
    for rnd in range(SHARPEN_ROUNDS + 1):
        for run in runs:
            if run.active:
                run.find(rnd)
        active = [run for run in runs if run.active]
        if not active:
            break
        vw = _lift(V, m, active)
        R = np.empty((len(V), WIDE * len(active)), order="F")  # column-major, as solves read
        for i, run in enumerate(active):
            run.residuals(pencil, vw[:, 2 * i:2 * i + 2], R[:, WIDE * i:WIDE * (i + 1)])
        X = factor.solve(R)
        news = _outside(V, [run.T[:, :run.t] for run in active], X)
        grown = [(run, new) for run, new in zip(active, news) if new.shape[1]]
        for run, new in zip(active, news):
            run.active = new.shape[1] > 0  # nothing new outside the basis: as good as it gets
        edges = _borders(blocks, V, [run.T[:, :run.t] for run, _ in grown],
                         [new for _, new in grown])
        for (run, new), edge in zip(grown, edges):
            run.extend(new, edge)
    vw = _lift(V, m, runs)
    return [Guess(float(run.f), float(run.kappa), vw[:, 2 * i], vw[:, 2 * i + 1], run.branch,
                  run.jacobian) for i, run in enumerate(runs)]


def _lift(V: np.ndarray, m: int, runs: list[_Run]) -> np.ndarray:
    """The runs' null vectors v, w on the kept DOFs, side by side (V read once)."""
    out = V @ np.column_stack([x[:m] for run in runs for x in (run.y, run.z)])
    for i, run in enumerate(runs):
        if run.t:
            out[:, 2 * i:2 * i + 2] += run.T[:, :run.t] @ np.column_stack([run.y[m:],
                                                                            run.z[m:]])
    return out


def _outside(V: np.ndarray, Ts: list[np.ndarray], X: np.ndarray) -> list[np.ndarray]:
    """For each run i (its WIDE columns X_i of X, its added columns Ts[i]): an orthonormal
    basis of the part of X_i's span outside that of [V, T_i], orthonormal columns. X_i
    projected out, once more if that cancelled more than 99 % of a column of any run
    ("twice is enough"; once, the sharpened coalescence of the unit square at h = 0.05 was
    1.9e-9 from the full pencil's instead of 9e-13, and Newton took two steps); columns
    left with less than RANK_TOL of their norm dropped."""
    parts = [slice(WIDE * i, WIDE * (i + 1)) for i in range(len(Ts))]
    before = np.linalg.norm(X, axis=0)
    for sweep in range(2):
        C = tdot(V, X)
        D = [tdot(T, X[:, part]) for T, part in zip(Ts, parts)]
        X = X - V @ C
        for T, part, Di in zip(Ts, parts, D):
            X[:, part] -= T @ Di
        after = np.linalg.norm(X, axis=0)
        if sweep or not np.any(after < 0.01 * before):
            break
    keep = after > RANK_TOL * np.maximum(before, 1e-300)
    return [orthonormal(X[:, part][:, keep[part]]) if keep[part].any() else X[:, part][:, :0]
            for part in parts]


def _borders(blocks: list[Block], V: np.ndarray, Ts: list[np.ndarray],
             Ns: list[np.ndarray]) -> list[list[tuple]]:
    """For each run i: :meth:`Block.borders` of every block with W = [V, Ts[i]] and its new
    columns Ns[i]; V^T (b N) of the symmetric blocks without few rows (K_rr, M_rr) of every
    run in one product (V read once)."""
    whole = [b for b in blocks if b.sub is None and b.symmetric]
    if not Ns:
        return []
    bN = [[b.b @ N for b in whole] for N in Ns]
    flat = [x for row in bN for x in row]
    right_V = tdot(V, np.hstack(flat)) if flat else None
    out, col = [], 0
    for T, N, row in zip(Ts, Ns, bN):
        done = {}
        for b, bNi in zip(whole, row):
            k = bNi.shape[1]
            right = np.concatenate([right_V[:, col:col + k], tdot(T, bNi)])
            done[id(b)] = (right, right, tdot(N, bNi))
            col += k
        out.append([done[id(b)] if id(b) in done else b.borders([V, T], N) for b in blocks])
    return out
