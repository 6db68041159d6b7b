"""Every solution of the static problem (2.8) of a small case, by enumerating contact states.

Each contact node is free (X = Y = 0), stuck (U_n = 0, U_t = U^r), slipping along +t or -t
(U_n = 0, Y = gamma friction X): 4^p linear systems in the contact forces z = (X, Y), with the
contact displacements u_c = u0 + C z (C = S^-1, the flexibility of Gamma_C; see
:mod:`critfric.coulomb`). Every solution of (2.9)-(2.11) solves one of them and satisfies that
state's inequalities (free: U_n <= 0; stuck: X <= 0, |Y| <= -friction X; slipping: X <= 0,
gamma (U_t - U^r) >= 0), and conversely. All 4^p systems are solved at once (batched LU).

Criteria (stated once, used everywhere), with rows scaled to order one and the problem's scales
F (forces: the all-stuck solution and the condensed load) and D (displacements):

* singular system: the friction is within SINGULAR_TOL (relative) of a real critical value of
  that combination (an eigenvalue of (3.2) for its state, found once per enumerator), and its
  rank is then the number of singular values > RANK_TOL * the largest;
* a solution satisfies every inequality to within FEASIBLE_TOL (relative to F and D);
* a singular system with a solution gives a continuum (a *branch*) when its feasible part has
  extent > SAME_TOL * F along a null direction; otherwise one point;
* two solutions are the same when (X, Y)/F and (U_n, U_t)/D differ by <= SAME_TOL.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import linprog

from ..case.numbers import plain_integer, plain_number, shown
from ..errors import CaseError, SolverError
from ..fem.static import StaticProblem
from ..solvers.coulomb import violations
from ..solvers.eigen import INFINITE_TOL
from .problems import static_problem
from .states import LABELS, Condensed

MAX_NODES = 8
MAX_VALUES = 10_001  # friction values of one table of solutions
ENUMERATED = 3 * 10**7  # friction values x 4^p contact states: about 4 minutes (8.4 us each)
SINGULAR_TOL = 1e-9
RANK_TOL = 1e-8
REAL_TOL = 1e-8
FEASIBLE_TOL = 1e-9
SAME_TOL = 1e-7
CHUNK = 4096  # status combinations per batched SVD


@dataclass
class Solution:
    """Contact values of one solution, sorted along t, and the status of each node
    (free, stuck, slip+, slip-, or 'cone': on the Coulomb cone without slipping)."""

    Un: np.ndarray
    Ut: np.ndarray
    X: np.ndarray
    Y: np.ndarray
    status: list[str]

    def to_json(self, kind: str = "isolated") -> dict:
        return {"kind": kind, "status": self.status, "Un": self.Un.tolist(),
                "Ut": self.Ut.tolist(), "X": self.X.tolist(), "Y": self.Y.tolist()}


@dataclass
class Continuum:
    """A continuum of solutions: ``point`` + span of ``directions`` within the inequalities.
    For one direction, ``ends`` are its two end points (None where unbounded)."""

    status: list[str]
    point: Solution
    directions: list[Solution]
    ends: list[Solution | None] | None
    code: np.ndarray = field(default=None, repr=False)
    friction: float = 0.0

    def to_json(self) -> dict:
        out = self.point.to_json("branch")
        out["status"] = self.status
        out["dimension"] = len(self.directions)
        out["directions"] = [{k: v for k, v in d.to_json().items() if k in ("Un", "Ut", "X", "Y")}
                             for d in self.directions]
        out["ends"] = None if self.ends is None else [
            None if e is None else {k: v for k, v in e.to_json().items() if k != "kind"}
            for e in self.ends]
        return out


@dataclass
class Enumeration:
    """All solutions at one friction value: isolated points and branches (continua)."""

    friction: float
    solutions: list[Solution]
    branches: list[Continuum]

    @property
    def count(self) -> int:
        return len(self.solutions)

    @property
    def branch(self) -> bool:
        return bool(self.branches)

    def to_json(self) -> dict:
        return {"friction": self.friction, "count": self.count, "branch": self.branch,
                "solutions": [s.to_json() for s in self.solutions]
                + [b.to_json() for b in self.branches]}


class Enumerator:
    """The condensed problem of a small case, ready to enumerate at any friction value
    (``condensed``: its :class:`critfric.multiplicity.states.Condensed`, if already made)."""

    def __init__(self, problem: StaticProblem | None, condensed: Condensed | None = None):
        cz = condensed or Condensed.of(problem)
        p = cz.p
        if p > MAX_NODES:
            raise SolverError(f"exact enumeration needs 4^p linear systems: p = {p} contact "
                              f"nodes is above {MAX_NODES}; use the Newton solver "
                              "(critfric.coulomb.solve) or a coarser mesh")
        self.cz, self.p, self.Ur, self.u0 = cz, p, cz.Ur, cz.u0
        self.F, self.D = cz.F, cz.D
        self.codes = np.array(list(itertools.product(range(4), repeat=p)), dtype=np.int8)
        self._critical = None

    def contact(self, z: np.ndarray):
        """(U_n, U_t, X, Y) of contact forces z (..., 2p)."""
        return self.cz.contact(z)

    def point(self, z: np.ndarray, friction: float) -> Solution:
        Un, Ut, X, Y = self.contact(z)
        return Solution(Un, Ut, X, Y, self.cz.labels(z, friction))

    def systems(self, codes: np.ndarray, friction: float):
        """Batched A z = b (n, 2p, 2p) of the status combinations ``codes`` (n, p)."""
        return self.cz.systems(codes, friction)

    def inequalities(self, code: np.ndarray, friction: float):
        """G z <= h of one status combination, rows scaled by F or D."""
        return self.cz.inequalities(code, friction)[:2]

    def critical_values(self, codes: np.ndarray) -> np.ndarray:
        """(n, 2p) real critical values of each status combination (NaN: none): A(friction) =
        A0 + friction A1 is singular exactly at the real eigenvalues of (3.2) for that state,
        -1/lambda for the eigenvalues lambda of A0^-1 A1 (A0, frictionless, is regular)."""
        A0, _ = self.systems(codes, 0.0)
        A1 = self.systems(codes, 1.0)[0] - A0
        lam = np.linalg.eigvals(np.linalg.solve(A0, A1))
        real = (np.abs(lam.imag) <= REAL_TOL * np.abs(lam)) & (np.abs(lam) > INFINITE_TOL)
        return np.where(real, -1.0 / np.where(real, lam.real, 1.0), np.nan)

    def __call__(self, friction: float) -> Enumeration:
        if self._critical is None:  # once per enumerator: every friction value reuses it
            self._critical = [self.critical_values(self.codes[i:i + CHUNK])
                              for i in range(0, len(self.codes), CHUNK)]
        isolated, branches = [], []
        for chunk, start in enumerate(range(0, len(self.codes), CHUNK)):
            codes = self.codes[start:start + CHUNK]
            A, b = self.systems(codes, friction)
            alpha = self._critical[chunk]
            near = np.any(np.abs(alpha - friction) <= SINGULAR_TOL * np.abs(alpha), axis=1)
            z = np.zeros(b.shape)
            try:
                z[~near] = np.linalg.solve(A[~near], b[~near][..., None])[..., 0]
            except np.linalg.LinAlgError:  # exactly singular in floating point: rank by SVD
                near[:] = True
            regular = ~near
            nullspaces = {}
            if near.any():  # rank-revealing SVD, for the few combinations near a critical value
                U, sv, Vt = np.linalg.svd(A[near])
                rank = np.sum(sv > RANK_TOL * sv[:, :1], axis=1)
                kept = np.arange(2 * self.p) < rank[:, None]
                inv = np.divide(1.0, sv, out=np.zeros_like(sv), where=kept)
                c = inv * np.matmul(U.transpose(0, 2, 1), b[near][..., None])[..., 0]
                z[near] = np.matmul(Vt.transpose(0, 2, 1), c[..., None])[..., 0]
                for k, i in enumerate(np.flatnonzero(near)):
                    if rank[k] == 2 * self.p:
                        regular[i] = True
                    else:
                        nullspaces[i] = Vt[k, rank[k]:].T
            Un, Ut, X, Y = self.contact(z[regular])
            bad = violations(Un, Ut, X, Y, self.Ur, friction, force_scale=self.F,
                             disp_scale=self.D)
            ok = np.all(np.stack(list(bad.values())) <= FEASIBLE_TOL, axis=0)
            isolated += list(z[regular][ok])
            for i, N in nullspaces.items():  # singular: a continuum if solvable and feasible
                scale = max(self.F, np.abs(b[i]).max())
                if np.abs(A[i] @ z[i] - b[i]).max() > FEASIBLE_TOL * scale:
                    continue
                found = self._continuum(codes[i], z[i], N, friction)
                if isinstance(found, Continuum):
                    branches.append(found)
                elif found is not None:
                    isolated.append(found)
        kept: list[Continuum] = []
        for br in branches:  # the same continuum may come from two status combinations
            zs = [np.concatenate([e.X, e.Y]) for e in [br.point] + (br.ends or []) if e]
            if not any(all(self._on(z, k) for z in zs) for k in kept):
                kept.append(br)
        points = [self.point(z, friction) for z in _unique(isolated, self._norm)
                  if not any(self._on(z, br) for br in kept)]
        return Enumeration(float(friction), points, kept)

    def _norm(self, z: np.ndarray) -> np.ndarray:
        return self.cz.norm(z)

    def _continuum(self, code, z0, N, friction):
        """The feasible part of z0 + span(N): a Continuum, a single point (z) or None."""
        G, h = self.inequalities(code, friction)
        d = N.shape[1]
        for slack in (0.0, FEASIBLE_TOL):  # exact ends if feasible, else within the tolerance
            found = _extent(G @ N, h + slack - G @ z0)
            if found is not None:
                break
        else:
            return None
        lo, hi, vertices = found
        centre = np.mean(vertices, axis=0) if vertices else np.zeros(d)
        if not np.max(hi - lo) > SAME_TOL * self.F:
            return z0 + N @ centre
        ends = None
        if d == 1:
            ends = [None if not np.isfinite(c) else self.point(z0 + N[:, 0] * c, friction)
                    for c in (lo[0], hi[0])]
        return Continuum([LABELS[s] for s in code], self.point(z0 + N @ centre, friction),
                      [self._direction(N[:, j]) for j in range(d)], ends, code, friction)

    def _direction(self, n: np.ndarray) -> Solution:
        """A null direction n of the forces with its displacements, the largest U_t > 0."""
        du, p = self.cz.C @ n, self.p
        ref = du[p:] if np.any(du[p:]) else n
        sign = np.sign(ref[np.argmax(np.abs(ref))]) or 1.0
        du, n = sign * du, sign * n
        return Solution(du[:p], du[p:], n[:p], n[p:], [])

    def _on(self, z: np.ndarray, branch: Continuum) -> bool:
        """Whether the point z lies on (the closure of) a branch."""
        Z0 = np.concatenate([branch.point.X, branch.point.Y])
        N = np.array([np.concatenate([d.X, d.Y]) for d in branch.directions]).T
        proj = Z0 + N @ np.linalg.lstsq(N, z - Z0, rcond=None)[0]
        if np.abs(self._norm(proj) - self._norm(z)).max() > SAME_TOL:
            return False
        G, h = self.inequalities(branch.code, branch.friction)
        return bool(np.all(G @ proj <= h + SAME_TOL))


def _extent(A: np.ndarray, beta: np.ndarray):
    """Bounds (lo, hi) of each coordinate of {c : A c <= beta} and the LP vertices found, or
    None if the set is empty."""
    d = A.shape[1]
    lo, hi, vertices = np.full(d, -np.inf), np.full(d, np.inf), []
    for j in range(d):  # two LPs per null direction (d is 1 but for degenerate cases)
        for sign, store in ((1.0, lo), (-1.0, hi)):
            res = linprog(sign * np.eye(d)[j], A_ub=A, b_ub=beta, bounds=[(None, None)] * d,
                          method="highs")
            if res.status == 2:
                return None
            if res.status == 0:
                store[j] = res.x[j]
                vertices.append(res.x)
    return lo, hi, vertices


def _unique(points: list[np.ndarray], norm) -> list[np.ndarray]:
    """Drop repeats (same normalized point to within SAME_TOL)."""
    kept, keys = [], []
    for z in points:  # a handful of feasible points
        key = norm(z)
        if not any(np.abs(key - k).max() <= SAME_TOL for k in keys):
            kept.append(z)
            keys.append(key)
    return kept


def enumerate_solutions(problem: StaticProblem, frictions) -> list[Enumeration]:
    """Every solution of (2.8) at each friction value (one condensation for all)."""
    enum = Enumerator(problem)
    return [enum(float(f)) for f in np.atleast_1d(frictions)]


def parse_frictions(text: str) -> np.ndarray:
    """'a:b:N' (N values from a to b) or one value -> friction values (CaseError if bad)."""

    allowed = (f"a:b:N (1 <= N <= {MAX_VALUES} values from a to b, a, b >= 0) or one value "
               ">= 0, in plain (ASCII) numbers")
    parts = str(text).split(":")
    if len(parts) not in (1, 3):
        raise CaseError(f"got {shown(text)}; allowed: {allowed}", key="--friction")
    ends = [plain_number(p, "--friction", allowed=allowed, within=text) for p in parts[:2]]
    n = plain_integer(parts[2], "--friction", allowed=allowed, within=text) \
        if len(parts) == 3 else 1
    if not 1 <= n <= MAX_VALUES:
        raise CaseError(f"got {shown(text)}; allowed: {allowed}", key="--friction")
    values = np.linspace(ends[0], ends[-1], n)
    if not np.all(np.isfinite(values) & (values >= 0)):
        raise CaseError(f"got {shown(text)}; allowed: {allowed}", key="--friction")
    return values


def solutions_of_case(case, frictions, *, prepared=None) -> list[Enumeration]:
    """Every solution of the static problem of a case's [load] at each friction value
    (CaseError where the enumeration would be too large: over MAX_NODES contact nodes, or
    over ENUMERATED systems)."""
    problem = static_problem(case, prepared, friction=0.0)
    p, n = problem.system.n_contact, len(np.atleast_1d(frictions))
    if p > MAX_NODES:
        raise CaseError(f"the mesh has {p} contact nodes: every solution is found among the "
                        f"4^p contact states; allowed: at most {MAX_NODES} contact nodes (a "
                        "coarser mesh on Gamma_C, or `critfric path`, which follows the "
                        "solutions from one)", file=case.source, key="mesh.size")
    if n * 4**p > ENUMERATED:
        raise CaseError(f"got {n} friction values: with {p} contact nodes each enumerates "
                        f"{4**p} contact states, about {n * 4**p * 8.4e-6 / 60:.0f} minutes; "
                        f"allowed: at most {ENUMERATED // 4**p} values", key="--friction")
    return enumerate_solutions(problem, frictions)


def report_solutions(sweep: list[Enumeration]) -> str:
    """A plain-text table of a sweep: per friction value, its solutions and branches."""
    f4 = lambda a: "[" + ", ".join(f"{v:.6g}" for v in a) + "]"
    lines = [f"{'friction':>12} {'count':>5} {'branch':>6}  solutions: status, U_t, X (along t)"]
    for e in sweep:
        lines.append(f"{e.friction:>12.8g} {e.count:>5d} {'yes' if e.branch else 'no':>6}")
        for s in e.solutions:
            lines.append(f"{'':>27}isolated {' '.join(s.status)}  U_t = {f4(s.Ut)}  "
                         f"X = {f4(s.X)}")
        for b in e.branches:
            ends = b.ends or [None, None]
            span = " .. ".join("unbounded" if q is None else f"U_t = {f4(q.Ut)} X = {f4(q.X)}"
                               for q in ends)
            lines.append(f"{'':>27}branch ({len(b.directions)}-dim) {' '.join(b.status)}  "
                         f"{span}")
    return "\n".join(lines)
