"""Flutter onset on the full pencil: the friction at which two real kappa meet.

At a coalescence (f*, kappa*) the matrix L(f, kappa) of :mod:`.pencil` is singular and kappa*
is a double root of det L(f*, .). With the bordered matrix

    [[L, b], [c^T, 0]] [v; sigma] = [0; 1]      (b, c: the null vectors' approximations)

sigma(f, kappa) vanishes exactly where L is singular, and its derivatives come from the same
factorization (Govaerts, Numerical methods for bifurcations of dynamical equilibria, 2000):
sigma_x = -w^T L_x v with w from the transposed system. Newton's method on

    sigma(f, kappa) = 0,   sigma_kappa(f, kappa) = 0

(a double root in kappa) converges quadratically: 3-4 steps from 5e-5, one from the
sharpened guess of :func:`critfric.stability.sharpen.sharpen` (its first correction is below
FOLD_TOL). The Jacobian's first row (sigma_f, sigma_kappa) comes with sigma from v and w; its
second row takes four more solves (v and w differentiated), or, at a sharpened guess, comes
from the sharpened model's own Newton (its Jacobian ``model``, taken where its first row
agrees with the full pencil's to MODEL_TOL): it only scales a correction of ~1e-10, and an
error e in it leaves e times that (the first step's solves stay on the full pencil). The
bordered solves: :class:`.bordered.Deflated` (GMRES on the factorization of
K_rr, given as ``solver``) or :class:`.bordered.Bordered` (an LU of the bordered matrix, and
iterative refinement on it for the further steps), which also takes over where the deflated
solves stall. Each solve's residual is checked on the bordered matrix itself, down to
rounding for sigma and the null vectors (the Jacobian's solves to ROUGH_TOL).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..errors import SolverError
from .bordered import Bordered, Deflated, NotConverged, drive, solve_jointly
from .pencil import SlidingPencil

FOLD_TOL = 1e-9  # relative Newton step after which the coalescence is converged: the
# convergence is quadratic, and the steps after it stall at the rounding of the bordered
# solves at a double root (1e-11 to 3e-10 relative, measured): the onset to ~1e-10
MAX_STEPS = 25
MODEL_TOL = 1e-3  # a reduced model's Jacobian serves the first step where its first row is
# the full pencil's to this (relative): its second row is then as close, and scales the step


@dataclass
class Fold:
    friction: float
    kappa: float
    right: np.ndarray  # the (real) flutter mode at onset, kept DOFs, unit 2-norm
    left: np.ndarray
    steps: int
    residual: float  # ||L v|| / (||L|| ||v||) at the solution
    solver: Bordered | Deflated | None = field(default=None, repr=False)  # for the next run
    jacobian: np.ndarray | None = field(default=None, repr=False)  # the last step's, 2 x 2


def find_fold(pencil: SlidingPencil, f0: float, kappa0: float, right: np.ndarray,
              left: np.ndarray, model: np.ndarray | None = None, *, backend: str = "scipy",
              order=None, solver: Bordered | Deflated | None = None) -> Fold:
    """Newton's method for the coalescence nearest (f0, kappa0); SolverError if it fails.
    ``model``: the Jacobian at the start from a reduced model (module docstring: its second
    row may spare the first step four solves). ``solver``: a :class:`Deflated` on the
    pencil's K_rr, or the solver of an earlier call on the same pencil (the other direction;
    PARDISO reuses a :class:`Bordered`'s analysis); None: :class:`Bordered`."""
    F = Bordered(backend, order) if solver is None else solver.renewed()
    return drive([_newton(pencil, f0, kappa0, right, left, model, F, backend, order)],
                  _each)[0]


def _each(requests: list[tuple]) -> list:
    """Each request (solver, systems, rough) solved on its own solver; a stall is thrown
    into its run (which then factors the bordered matrix)."""
    out = []
    for F, systems, rough in requests:
        try:
            out.append(F.solve_many(systems, rough))
        except NotConverged as stalled:
            out.append(stalled)
    return out


def find_folds(pencil: SlidingPencil, starts: list[tuple], *, backend: str = "scipy",
               order=None, solver: Bordered | Deflated | None = None) -> list[Fold]:
    """:func:`find_fold` from each start (f0, kappa0, right, left[, model]). With a
    :class:`Deflated` solver, their Newton steps run in lockstep, every GMRES iteration's
    solves with K_rr in one call (:func:`.bordered.solve_jointly`); if any of them stalls,
    one after the other from their starts (the solver passed on, as it falls back on an
    LU)."""
    if isinstance(solver, Deflated) and len(starts) > 1:
        try:
            return _lockstep(pencil, starts, solver, backend, order)
        except NotConverged:
            pass
    found = []
    for start in starts:
        found.append(find_fold(pencil, *_padded(start), backend=backend, order=order,
                               solver=solver))
        solver = found[-1].solver
    return found


def _lockstep(pencil: SlidingPencil, starts: list[tuple], solver: Deflated, backend: str,
              order) -> list[Fold]:
    runs = [_newton(pencil, *_padded(start), solver if i == 0 else solver.sibling(), backend,
                    order) for i, start in enumerate(starts)]
    return drive(runs, solve_jointly)  # NotConverged: given up


def _padded(start: tuple) -> tuple:
    """A start (f0, kappa0, right, left[, model]), its model None if not given."""
    return tuple(start) + (None,) * (5 - len(start))


def _newton(pencil: SlidingPencil, f0: float, kappa0: float, right: np.ndarray,
            left: np.ndarray, model: np.ndarray | None, F, backend: str, order):
    """Newton's method from (f0, kappa0) on solver F, as a generator: it yields its
    bordered solves as requests (solver, systems, rough), is sent their solutions (or
    thrown NotConverged: it then factors the bordered matrix, :class:`Bordered`) and
    returns the Fold. ``model``: a reduced model's Jacobian at the start (module
    docstring)."""
    n = pencil.size
    f, kappa = float(f0), float(kappa0)
    c, b = _unit(right), _unit(left)
    L_kf = pencil.L_kappa_f()
    for step in range(1, MAX_STEPS + 1):
        B = pencil.B(f)  # L = A(f) - kappa B(f) and dL/dkappa = -B(f) from one B(f)
        L, Lk = (pencil.A(f) - kappa * B).tocsr(), -B
        given = model if step == 1 else None
        try:
            df, dk, v, w, J = yield from _step(F, pencil, L, Lk, L_kf, f, kappa, b, c, given)
        except NotConverged:  # the deflated solves stalled: factor the bordered matrix
            F.release()
            F = Bordered(backend, order)
            df, dk, v, w, J = yield from _step(F, pencil, L, Lk, L_kf, f, kappa, b, c, given)
        f, kappa = f + df, kappa + dk
        c, b = _unit(v), _unit(w)  # better borders: the current null vectors
        if abs(df) <= FOLD_TOL * max(abs(f), 1e-300) and abs(dk) <= FOLD_TOL * abs(kappa):
            # |L| from the last step's matrix: its entries differ by the step, ~1e-10
            res = (np.linalg.norm(pencil.apply_L(f, kappa, c))
                   / max(abs(L).max() * np.sqrt(n), 1e-300))
            return Fold(f, kappa, c, b, step, float(res), solver=F, jacobian=J)
        if not (np.isfinite(f) and np.isfinite(kappa)):
            break
    raise SolverError(f"Newton's method for the flutter onset did not converge from friction "
                      f"{f0:.6g} (kappa {kappa0:.6g}); try more --steps or a finer mesh")


def _step(F, pencil: SlidingPencil, L, Lk, L_kf, f: float, kappa: float, b: np.ndarray,
          c: np.ndarray, model: np.ndarray | None):
    """One Newton step on (sigma, sigma_kappa) = 0 at L = L(f, kappa), Lk = dL/dkappa:
    (df, dkappa), the null vectors v, w and the Jacobian (a generator, as :func:`_newton`);
    its second row ``model``'s where that agrees (module docstring), else from four more
    solves."""
    n = pencil.size
    F.set(L, b, c)
    e = np.zeros(n + 1)
    e[n] = 1.0
    vs, ws = yield F, [(e, False), (e, True)], False
    v, sigma, w = vs[:n], vs[n], ws[:n]
    Lf = pencil.L_f(kappa)
    Lkv, Lfv = Lk @ v, Lf @ v
    s_k, s_f = -w @ Lkv, -w @ Lfv
    first = np.array([s_f, s_k])
    if model is not None and (np.linalg.norm(model[0] - first)
                              <= MODEL_TOL * np.linalg.norm(first)):
        row = model[1]
    else:
        row = yield from _second_row(F, L_kf, Lk, Lf, v, w, Lkv, Lfv)
    J = np.array([first, row])
    try:
        df, dk = np.linalg.solve(J, -np.array([sigma, s_k]))
    except np.linalg.LinAlgError:
        raise SolverError("the coalescence is degenerate (singular Newton matrix at "
                          f"friction {f:.6g}); try more --steps") from None
    return float(df), float(dk), v, w, J


def _second_row(F, L_kf, Lk, Lf, v: np.ndarray, w: np.ndarray, Lkv: np.ndarray,
                Lfv: np.ndarray):
    """(sigma_kappa_f, sigma_kappa_kappa) from v_kappa, v_f, w_kappa, w_f (four bordered
    solves, to ROUGH_TOL; a generator, as :func:`_newton`)."""
    n = len(v)

    def bordered_rhs(x: np.ndarray) -> np.ndarray:
        return np.concatenate([x, [0.0]])

    v_k, v_f, w_k, w_f = (x[:n] for x in (yield F, [
        (bordered_rhs(-Lkv), False), (bordered_rhs(-Lfv), False),
        (bordered_rhs(-(Lk.T @ w)), True), (bordered_rhs(-(Lf.T @ w)), True)], True))
    s_kk = -(w_k @ Lkv + w @ (Lk @ v_k))
    s_kf = -(w_f @ Lkv + w @ (L_kf @ v) + w @ (Lk @ v_f))
    return s_kf, s_kk


def _unit(x: np.ndarray) -> np.ndarray:
    x = np.asarray(x).real
    return x / np.linalg.norm(x)
