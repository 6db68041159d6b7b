"""The root locus: the lowest eigenvalues kappa of the sliding pencil followed along friction.

A reduced model locates the thresholds, enlarged at each one until its coalescence stops
moving (:mod:`.sharpen`); :mod:`.fold` then confirms them on the full pencil.
The reduced basis holds the constrained free-vibration modes (the exact friction-0 modes, so
the friction-0 frequencies are exact) and the static responses of the kept DOFs to
tangential contact loads and to the normal reaction rows (the right and left null vectors of
L at kappa = 0 lie in their span, so divergence is exact too). A problem with at most
FULL_MAX kept DOFs is followed on the full pencil, densely.

Following: the ``modes`` lowest kappa at f = 0 are matched, step after step along a friction
grid, to the nearest eigenvalues of the reduced pencil (extrapolated linearly from the two
previous steps). A branch flutters when its kappa leaves the real axis (|Im kappa| >
COMPLEX_TOL |kappa|); a real kappa passing through 0 is divergence, never flutter.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg as la
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from threadpoolctl import ThreadpoolController, threadpool_limits

from ..errors import SolverError
from ..solvers.backends import PardisoPlan, factorize
from ..solvers.pardiso import upper_triangle
from . import lanczos
from .bordered import orthonormal, tdot
from .pencil import SlidingPencil

FULL_MAX = 80  # kept DOFs up to which the full pencil is followed densely (QZ per step)
EXTRA_MODES = 10  # reduced basis: modes + EXTRA_MODES free-vibration modes
CORRECTED_EXTRA = 5  # "modal" basis: first-order corrections of the modes + 5 lowest only
# (those of higher modes left the reduced model's onset unchanged, measured at 295 k DOFs)
#: largest 2 x steps x d^3 (d: reduced size) of the dense eigenproblems along the grid
#: (a bound of ~40 minutes; a larger request is refused up front rather than left running)
WORK_MAX = 5e11
SECONDS_PER_D3 = 4.5e-9  # one dense eigenproblem of size d, measured on 2 cores (d 300-1200)
COMPLEX_TOL = 1e-9  # |Im kappa| <= COMPLEX_TOL |kappa|: real
INFINITE = 1e-12  # |beta| <= INFINITE |alpha| in the QZ output: an infinite kappa
BISECT = 20  # bisections of a flutter bracket on the reduced model
SEED = 20030328  # the free vibrations' start vector(s): identical runs, identical results
MODES_TOL = 1e-10  # relative tolerance on the followed free vibrations: ARPACK took 64 solves
# for 20 modes instead of 76 at machine precision, the frequencies equal to 5e-15 (second order)
BASIS_TOL = 1e-4  # ... on the further modes of the basis (Lanczos; ARPACK has one tolerance
# for all), which enter the reduced model's span, not the results: 52 solves for 10 + 10
# modes instead of 62 at 295 k DOFs (56 at 1e-6); on the inclined body (P2, 78 k DOFs) the
# branches moved by at most 8.8e-5 up to 4 times the onsets (1.1e-5 at 1e-6), by up to 0.11
# beyond, where the model's own errors reach 0.7 (P1, 78 k DOFs); the onsets by 7e-14


def blas_threads(count: int):
    """numpy's and SciPy's OpenBLAS on ``count`` threads, MKL's (PARDISO's) left alone: its
    factors keep the thread count they were made with. One thread for the stability
    stages' vector work: idle OpenBLAS threads spin beside PARDISO's on the same cores
    (stability at 295 k DOFs, 2 cores: 10.0-10.4 s against 11.0 s, measured)."""
    return ThreadpoolController().select(internal_api="openblas").limit(limits=count)


def openblas_threads() -> int:
    """The OpenBLAS thread count in effect (the largest of numpy's and SciPy's; 1 if none)."""
    info = ThreadpoolController().select(internal_api="openblas").info()
    return max([lib["num_threads"] for lib in info], default=1)


@dataclass
class Reduced:
    """L(f, kappa) projected on a basis V: (A0 - f A1) - kappa (B0 - f B1)."""

    V: np.ndarray | None  # None: the full space (identity)
    A0: np.ndarray
    A1: np.ndarray
    B0: np.ndarray
    B1: np.ndarray
    omega2: np.ndarray  # constrained free-vibration eigenvalues, ascending (exact)
    modes0: np.ndarray  # their modes (kept DOFs), columns
    threads: int = 1  # OpenBLAS threads for its dense eigenproblems from size 400 on

    def blas(self):
        """The BLAS threads for this model's dense eigenproblems: one below size 400 (two on a
        busy 2-core machine made a 335 x 335 eig 5-30x slower, measured), ``threads`` from
        there on. Entered once around a loop: entering costs ~2 ms, more than one
        eigenproblem of size 80."""
        return blas_threads(1 if len(self.A0) < 400 else self.threads)

    def eigenvalues(self, f: float, vectors: bool = False):
        """Finite kappa at friction f (and left, right vectors if asked), by modulus; each
        complex pair exactly conjugate, the one with Im > 0 first."""
        a, b = self.A0 - f * self.A1, self.B0 - f * self.B1
        out = la.eig(a, b, homogeneous_eigvals=True, left=vectors, right=vectors)
        ab = out[0] if vectors else out
        alpha, beta = ab[0], ab[1]
        finite = np.abs(beta) > INFINITE * np.abs(alpha)
        kappa = _conjugate_pairs(alpha, beta, finite)[finite]
        order = np.argsort(np.abs(kappa), kind="stable")
        if not vectors:
            return kappa[order]
        idx = np.flatnonzero(finite)[order]
        return kappa[order], out[1][:, idx], out[2][:, idx]

    def lift(self, y: np.ndarray) -> np.ndarray:
        return y if self.V is None else self.V @ y


def _conjugate_pairs(alpha: np.ndarray, beta: np.ndarray, finite: np.ndarray) -> np.ndarray:
    """alpha / beta with each complex pair of a real pencil made exactly conjugate. QZ gives
    a pair as consecutive (alpha, beta), Im alpha > 0 first, with different scalings: the
    quotients are conjugate only to rounding, so their moduli and their distances to a real
    prediction differ by it, and which branch took which half of a pair changed from run to
    run (PARDISO's parallel solves do not round the same way twice). The mean of the two
    halves, exactly conjugated, leaves that choice to :func:`_match`'s rule alone."""
    kappa = np.full(len(alpha), np.nan + 0j)
    kappa[finite] = alpha[finite] / beta[finite]
    first = np.flatnonzero(alpha.imag[:-1] > 0)
    first = first[(alpha.imag[first + 1] < 0) & finite[first] & finite[first + 1]]
    mean = 0.5 * (kappa[first] + np.conj(kappa[first + 1]))
    kappa[first], kappa[first + 1] = mean, np.conj(mean)
    return kappa


def plan_of(Krr: sp.csr_matrix, backend: str) -> PardisoPlan | None:
    """K_rr's PARDISO analysis, started in the background where :func:`reduce` will factor
    K_rr on PARDISO (else None): pass it to :func:`factor_of`."""
    if backend != "pardiso" or Krr.shape[0] <= FULL_MAX:
        return None
    U = upper_triangle(Krr)
    return PardisoPlan(U.indptr, U.indices)


def factor_of(pencil: SlidingPencil, backend: str, order, plan: PardisoPlan | None = None):
    """A factorization of K_rr (``plan``: :func:`plan_of` K_rr, if started)."""
    return factorize(pencil.Krr, symmetric=True, backend=backend, order=order, plan=plan)


class Block:
    """A sparse block b of the pencil and the projections X^T b Y: through b's few nonzero
    rows and columns where it has them (the friction blocks G K_nr, G M_nr: the slipping
    nodes' tangential rows, the columns next to them), else by one product over all rows."""

    def __init__(self, b: sp.csr_matrix, symmetric: bool):
        self.b, self.symmetric = b, symmetric
        self.rows = self.cols = self.sub = None
        rows = np.flatnonzero(np.diff(b.indptr))
        if len(rows) < b.shape[0] // 4:
            cols = np.unique(b.indices)
            if len(cols) < b.shape[0] // 4:
                self.rows, self.cols, self.sub = rows, cols, b[rows][:, cols].tocsr()

    def product(self, X: np.ndarray, out: np.ndarray, transpose: bool = False) -> None:
        """b X (b^T X with ``transpose``) written into ``out``."""
        if self.sub is None:
            out[:] = (self.b.T if transpose else self.b) @ X
            return
        rows, cols = (self.cols, self.rows) if transpose else (self.rows, self.cols)
        out[:] = 0.0
        out[rows] = (self.sub.T if transpose else self.sub) @ X[cols]

    def form(self, X: np.ndarray, Y: np.ndarray) -> np.ndarray:
        """X^T b Y."""
        if self.sub is None:
            return tdot(X, self.b @ Y)
        return tdot(X[self.rows], self.sub @ Y[self.cols])

    def borders(self, Ws: list[np.ndarray], N: np.ndarray) -> tuple:
        """W^T b N, W^T b^T N (W: the column blocks Ws side by side) and N^T b N."""
        if self.sub is None:
            bN = self.b @ N
            right = np.concatenate([tdot(W, bN) for W in Ws])
            below = right if self.symmetric else np.concatenate([tdot(W, self.b.T @ N)
                                                                 for W in Ws])
            return right, below, tdot(N, bN)
        bN, bTN = self.sub @ N[self.cols], self.sub.T @ N[self.rows]
        return (np.concatenate([tdot(W[self.rows], bN) for W in Ws]),
                np.concatenate([tdot(W[self.cols], bTN) for W in Ws]), tdot(N[self.rows], bN))


def _matrices(pencil: SlidingPencil) -> tuple:
    """The sparse blocks of the pencil, L = (A0 - f A1) - kappa (B0 - f B1): A0, A1, B0, B1."""
    return pencil.Krr, pencil.GKnr, pencil.Mrr, pencil.GMnr


def blocks_of(pencil: SlidingPencil) -> list[Block]:
    """:func:`_matrices` with their projections (A0 and B0 symmetric)."""
    return [Block(b, symmetric) for b, symmetric in zip(_matrices(pencil),
                                                         (True, False, True, False))]


def reduced_size(n: int, p: int, modes: int) -> int:
    """The largest size of the reduced model :func:`reduce` builds ("auto" basis) for a
    pencil with ``n`` kept DOFs and ``p`` contact nodes."""
    if n <= FULL_MAX:
        return n
    k = min(modes + EXTRA_MODES, n - 2)
    corrected = min(k, modes + CORRECTED_EXTRA)
    return min(n, k + (3 * p if _contact_basis(p, corrected) else 2 * corrected))


def _contact_basis(p: int, corrected: int) -> bool:
    """The "auto" basis: the contact one (3 p columns, divergence exact in the model) while
    it has at most twice the modal one's 2 ``corrected`` columns."""
    return 3 * p <= 4 * corrected


def reduce(pencil: SlidingPencil, modes: int, *, backend: str = "scipy", order=None,
           basis: str = "auto", factor=None, threads: int | None = None) -> Reduced:
    """The reduced model of a pencil, with its ``modes`` (at least) lowest free vibrations.

    The basis holds the ``modes`` + ``EXTRA_MODES`` lowest free-vibration modes Phi and:
    basis "contact": the static responses to every contact load (3 p columns: divergence
    exact in the model); "modal": the first-order corrections K^-1 G C_i phi_i and
    K^-1 C_i^T G^T phi_i (C_i = K_nr - omega_i^2 M_nr: the friction derivative of L at mode
    i's own kappa) of the ``modes`` + ``CORRECTED_EXTRA`` lowest (2 columns a mode,
    independent of p); "auto": "contact" while 3 p is at most twice the modal columns. ``factor``:
    a factorization of K_rr to use (the one that also serves the sharpening and
    Newton's bordered solves), else one is made. ``threads``: the model's ``threads``
    (default: the OpenBLAS thread count in effect).

    Dense products run on one BLAS thread: after PARDISO's threads, two threads on a busy
    2-core machine made them up to 30x slower (ARPACK's own work among them)."""
    if pencil.size <= FULL_MAX:
        A0, A1, B0, B1 = (b.toarray() for b in _matrices(pencil))
        w, vecs = la.eigh(A0, B0)
        red = Reduced(None, A0, A1, B0, B1, w, vecs)
    else:
        factor = factor or factor_of(pencil, backend, order)
        with threadpool_limits(1, user_api="blas"):
            red = _reduce(pencil, modes, factor, basis)
    red.threads = openblas_threads() if threads is None else threads
    return red


def _reduce(pencil: SlidingPencil, modes: int, factor, basis: str) -> Reduced:
    n = pencil.size
    k = min(modes + EXTRA_MODES, n - 2)
    w, vecs = _free_vibrations(pencil, k, factor, exact=min(modes, k))
    p0 = pencil.G.shape[1]
    corrected = min(k, modes + CORRECTED_EXTRA)
    if basis == "auto":
        basis = "contact" if _contact_basis(p0, corrected) else "modal"
    blocks = blocks_of(pencil)
    # column-major right-hand sides and basis, written in place: the solves read and write
    # columns, and a row-major n x 60 array costs a transposed copy each way
    if basis == "contact":  # right null space at kappa = 0 (tangential loads), left (reactions)
        loads = np.empty((n, 3 * p0), order="F")
        for j, b in enumerate((pencil.G, pencil.Knr.T, pencil.Mnr.T)):
            b.toarray(out=loads[:, j * p0:(j + 1) * p0])
    else:  # how each mode's contact forces load the body at its own kappa, right and left:
        # G C_i phi_i, C_i^T G^T phi_i with C_i = K_nr - omega_i^2 M_nr
        low, mass = vecs[:, :corrected], np.empty((n, corrected), order="F")
        loads = np.empty((n, 2 * corrected), order="F")
        for j, transpose in enumerate((False, True)):
            part = loads[:, j * corrected:(j + 1) * corrected]
            blocks[1].product(low, part, transpose)
            blocks[3].product(low, mass, transpose)
            part -= mass * w[:corrected]
        del mass
    W = np.empty((n, k + loads.shape[1]), order="F")
    W[:, :k] = vecs
    W[:, k:] = factor.solve(loads)
    del loads
    V = orthonormal(W, overwrite=True)
    A0, A1, B0, B1 = (b.form(V, V) for b in blocks)
    return Reduced(V, A0, A1, B0, B1, w, vecs)


def _free_vibrations(pencil: SlidingPencil, k: int, factor, exact: int | None = None
                     ) -> tuple[np.ndarray, np.ndarray]:
    """The k lowest (omega^2, mode) of (K_rr, M_rr), ascending: by the (block) Lanczos of
    :mod:`.lanczos` on the backends it knows, the ``exact`` lowest (default all) to the
    relative tolerance MODES_TOL, the others to BASIS_TOL; else (or if it breaks down) by
    ARPACK, all to MODES_TOL."""
    n = pencil.size
    block = lanczos.block_size(factor.backend, n, k)
    if block is not None:
        tol = np.full(k, BASIS_TOL)
        tol[:k if exact is None else exact] = MODES_TOL
        found = lanczos.lowest_modes(pencil.Krr, pencil.Mrr, factor.solve, k, block=block,
                                     tol=tol, seed=SEED)
        if found is not None:
            return found[0], found[1]
    op = spla.LinearOperator((n, n), matvec=factor.solve, dtype=np.float64)
    v0 = np.random.default_rng(SEED).standard_normal(n)
    try:
        w, vecs = spla.eigsh(pencil.Krr, k=k, M=pencil.Mrr, sigma=0.0, which="LM",
                             OPinv=op, v0=v0, tol=MODES_TOL)
    except spla.ArpackNoConvergence:
        raise SolverError("ARPACK did not converge on the free vibrations (K, M); try fewer "
                          "modes or a coarser mesh") from None
    order_w = np.argsort(w)
    return w[order_w], vecs[:, order_w]


@dataclass
class Branches:
    """kappa of the followed branches (n_f, modes) along the signed friction grid (n_f,)."""

    friction: np.ndarray
    kappa: np.ndarray


def follow(red: Reduced, modes: int, grid: np.ndarray) -> Branches:
    """Follow the ``modes`` lowest branches along ``grid`` (starting at 0, monotone)."""
    kappa = np.empty((len(grid), modes), dtype=complex)
    kappa[0] = red.omega2[:modes]
    with red.blas():
        for j in range(1, len(grid)):
            ev = red.eigenvalues(grid[j])
            guess = kappa[j - 1] if j == 1 else 2 * kappa[j - 1] - kappa[j - 2]
            kappa[j] = _match(guess, ev, kappa[j - 1])
    return Branches(np.asarray(grid, float), kappa)


def _match(guess: np.ndarray, ev: np.ndarray, previous: np.ndarray) -> np.ndarray:
    """Each branch takes the nearest eigenvalue not taken, closest pairs first; a tie (a
    real prediction, the two halves of a conjugate pair) goes to the earlier eigenvalue of
    ``ev`` (Im > 0 first: the branch nearer a pair where it is born takes Im > 0)."""
    if len(ev) == 0:
        return np.full(len(guess), np.nan + 0j)
    scale = np.maximum(np.abs(previous), 1e-300)[:, None]
    dist = np.abs(guess[:, None] - ev[None, :]) / scale
    out = np.full(len(guess), np.nan + 0j)
    taken_b, taken_e = set(), set()
    for flat in np.argsort(dist, axis=None, kind="stable"):
        b, e = divmod(int(flat), len(ev))
        if b in taken_b or e in taken_e:
            continue
        out[b] = ev[e]
        taken_b.add(b)
        taken_e.add(e)
        if len(taken_b) == len(guess):
            break
    return out


def is_complex(kappa) -> np.ndarray:
    kappa = np.asarray(kappa)
    return np.abs(kappa.imag) > COMPLEX_TOL * np.abs(kappa)


@dataclass
class Guess:
    """A located coalescence: friction, kappa, and null vectors of the reduced L there."""

    friction: float
    kappa: float
    right: np.ndarray  # kept DOFs
    left: np.ndarray
    branch: int  # index of a branch that flutters
    jacobian: np.ndarray | None = None  # a sharpened guess: its model's Newton Jacobian


def locate_flutter(red: Reduced, branches: Branches) -> Guess | None:
    """The first coalescence along the branches, bracketed on the grid, bisected on the
    reduced model and modelled as a square-root fold."""
    flutter = is_complex(branches.kappa)
    hit = np.flatnonzero(flutter.any(axis=1))
    if len(hit) == 0:
        return None
    j = int(hit[0])
    branch = int(np.flatnonzero(flutter[j])[0])
    fa, fb = branches.friction[j - 1], branches.friction[j]
    centre = branches.kappa[j, branch]

    def pair(f):
        """(real pair or None, complex kappa or None) nearest the coalescence centre."""
        ev = red.eigenvalues(f)
        near = ev[np.argsort(np.abs(ev - centre.real))][:4]
        cplx = near[is_complex(near)]
        return near, (cplx[0] if len(cplx) else None)

    with red.blas():
        for _ in range(BISECT):
            fm = 0.5 * (fa + fb)
            near, c = pair(fm)
            if c is None:
                fa = fm
            else:
                fb, centre = fm, c
        near, _ = pair(fa)
    real = np.sort(near[~is_complex(near)].real)
    real = real[np.argsort(np.abs(real - centre.real))][:2]
    gap2 = ((real[1] - real[0]) / 2) ** 2 if len(real) == 2 else 0.0
    d2 = -(centre.imag ** 2)
    t = gap2 / (gap2 - d2) if gap2 - d2 > 0 else 0.5
    f0 = fa + t * (fb - fa)
    k0 = (real.mean() if len(real) == 2 else centre.real) * (1 - t) + centre.real * t
    # null vectors of the reduced L(f0, k0): its smallest singular vectors
    a = (red.A0 - f0 * red.A1) - k0 * (red.B0 - f0 * red.B1)
    U, _, Vt = la.svd(a)
    return Guess(float(f0), float(k0), red.lift(Vt[-1]), red.lift(U[:, -1]), branch)
