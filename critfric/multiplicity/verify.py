"""The explicit non-uniqueness example of the end of section 5, built and checked on any case.

Construction (METHOD.md, written in the frame (t, m) with m = -n so that it holds for any
straight Gamma_C): with s = (x - x0) . m the distance from the line of Gamma_C into the body,
kappa = 2 friction (1 - nu)/(1 - 2 nu) and a0 > 0,

    U_h(x) = gamma (a0 + kappa s) t + s n

(for n = (0, -1): the paper's (a0 + kappa x2, -x2)). Its stress is constant:
sigma_tt = -lam, sigma_mm = -(lam + 2G), sigma_tm = gamma friction (lam + 2G). The load is
U_h on Gamma_D, the traction sigma n on every other boundary facet off Gamma_C, f = 0, u^r = 0.
Then u = U_h, X = F(sigma_nn), Y = F(sigma_nt) = gamma friction X (X < 0) solve (2.8) with
every contact node slipping along gamma t: at friction = a critical coefficient alpha (with
its eigenfunction Phi, X_theta, Y_theta of (3.2)), (u + delta Phi, X + delta X_theta,
Y + delta Y_theta) solves (2.8) for |delta| <= delta0 (Theorem 3.3), where

    delta0 = min over nodes of |X_i / X_theta_i| (where X_i + delta X_theta_i would turn
             positive) and |w_i / Phi_t_i| (where the slip w_i + delta Phi_t_i would turn).

:func:`branch` walks u + delta Phi and checks each point: the equilibrium rows, each condition
of (2.9)-(2.11) (:func:`critfric.coulomb.violations`) and, independently of the construction,
the Alart-Curnier residual of the Newton solver (:mod:`critfric.coulomb`). A point passes when
every relative residual is <= PASS_TOL. :func:`verify` does this at the critical coefficient,
then at friction (1 -/+ off): there the same perturbation must fail.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..case.schema import Case, load_case
from ..errors import CaseError, SolverError
from ..fem.assembly import lame
from ..fem.loads import boundary_facets, facet_load, facets_in
from ..fem.static import StaticProblem, build
from ..solve import prepare
from ..solvers import eigen
from ..solvers.coulomb import Complementarity, Condensed, violations
from ..solvers.coulomb import solve as coulomb_solve
from ..solvers.eigen import ContactState
from ..solvers.from_case import check_dimension

PASS_TOL = 1e-10
SLIP = 1.0  # a0: the tangential displacement of Gamma_C in the construction
WALK = np.linspace(-2.0, 2.0, 41)  # default walk: delta = WALK * delta0
CHECKS = ("equilibrium", "X<=0", "Un<=0", "X.Un=0", "|Y|<=-fX", "Y.w<=0", "stick", "newton")


@dataclass
class Construction:
    """The explicit solution of section 5 at one friction value, and its static problem."""

    problem: StaticProblem
    U: np.ndarray  # free DOFs (n/t)
    X: np.ndarray
    Y: np.ndarray
    gamma: int


@dataclass
class BranchPoint:
    delta: float
    Un: np.ndarray
    Ut: np.ndarray
    X: np.ndarray
    Y: np.ndarray
    residuals: dict[str, float]

    @property
    def max_residual(self) -> float:
        return max(self.residuals.values())

    @property
    def passed(self) -> bool:
        return self.max_residual <= PASS_TOL


@dataclass
class Branch:
    """The walk u + delta Phi at one friction value (the eigenfunction of ``alpha``)."""

    friction: float
    alpha: float
    gamma: int
    delta0: float
    delta0_sides: tuple[float, float]  # (towards -delta, towards +delta)
    points: list[BranchPoint]
    node: int  # contact node (index along t) with the largest |Phi_t|, for plots
    construction: Construction = field(repr=False)
    mode: eigen.Mode = field(repr=False, default=None)
    condensed: tuple = field(repr=False, default=None)

    @property
    def inside(self) -> list[BranchPoint]:
        """Points with |delta| <= delta0 (to round-off)."""
        return [q for q in self.points if abs(q.delta) <= self.delta0 * (1 + 1e-9)]

    @property
    def max_residual(self) -> float:
        return max(q.max_residual for q in self.inside)

    @property
    def passed(self) -> bool:
        return all(q.passed for q in self.inside)

    @property
    def stops(self) -> bool:
        """Some walked point beyond delta0, on the side that limits it, fails."""
        side = -1.0 if self.delta0_sides[0] <= self.delta0_sides[1] else 1.0
        beyond = [q for q in self.points if side * q.delta > self.delta0 * (1 + 1e-6)]
        return bool(beyond) and any(not q.passed for q in beyond)


@dataclass
class Verification:
    case: Case
    critical: Branch
    off_critical: list[Branch]

    @property
    def passed(self) -> bool:
        return (self.critical.passed and self.critical.stops
                and not any(b.passed for b in self.off_critical))

    def summary(self) -> dict:
        """The JSON of ``critfric verify --json``; ``off_critical`` is the weaker counter-check
        (the smaller residual) of friction (1 - off) and (1 + off)."""
        weak = min(self.off_critical, key=lambda b: b.max_residual)
        return {"friction": self.critical.friction, "delta0": self.critical.delta0,
                "max_residual": self.critical.max_residual, "passed": self.passed,
                "off_critical": {"friction": weak.friction, "max_residual": weak.max_residual,
                                 "passed": weak.passed}}


def construction(system, E: float, nu: float, friction: float, contact: list[str],
                 dirichlet: list[str], *, gamma: int = 1, slip: float = SLIP) -> Construction:
    """The loading and the exact solution of the end of section 5, for any straight Gamma_C."""
    mesh = system.mesh
    lam, G = lame(E, nu)
    n, t = system.normal, system.tangent
    m = -n
    x0 = mesh.points[system.nodes[0]]
    s = (mesh.points - x0) @ m
    kappa = 2.0 * friction * (1.0 - nu) / (1.0 - 2.0 * nu)
    u = gamma * (slip + kappa * s)[:, None] * t + s[:, None] * n
    s_tt, s_mm, s_tm = -lam, -(lam + 2 * G), gamma * friction * (lam + 2 * G)
    sigma = (s_tt * np.outer(t, t) + s_mm * np.outer(m, m)
             + s_tm * (np.outer(t, m) + np.outer(m, t)))
    facets, normals = boundary_facets(mesh)
    on_c, on_d = facets_in(facets, mesh, contact), facets_in(facets, mesh, dirichlet)
    neumann = ~on_c & ~on_d
    load = facet_load(mesh, facets[neumann], normals[neumann] @ sigma)
    weight = facet_load(mesh, facets[on_c], [1.0, 0.0])[0::2][system.nodes]  # int psi_i
    problem = build(system, lam, G, load_xy=load, fixed_xy=u.ravel(), reference=0.0,
                    friction=friction)
    lam_n = n @ sigma @ n
    lam_t = t @ sigma @ n
    return Construction(problem, system.from_xy(u.ravel()), lam_n * weight, lam_t * weight,
                        gamma)


def _critical(prep, case: Case):
    """The lowest positive critical coefficient (gamma = +1) or, if none, the lowest for
    gamma = -1, with its eigenfunction."""
    s = case.solve
    lam, G = lame(1.0, case.material["nu"])  # E = 1: see branch()
    K = prep.system.stiffness(lam, G)
    spec = eigen.solve(K, prep.system, ContactState.all_slipping(prep.system.n_contact, 1),
                       method=s["method"], count=1, shift=s["shift"], tol=s["tol"],
                       maxiter=s["maxiter"], real_tol=s["real_tol"],
                       backend=s.get("backend", "auto"))
    if len(spec.positive):
        alpha, gamma = float(spec.positive[0]), 1
    elif len(spec.negative):
        alpha, gamma = float(spec.negative[0]), -1
    else:
        raise SolverError("the eigenproblem (3.2) has no real eigenvalue for this case: there "
                          "is no critical friction coefficient to verify")
    mode = next(md for md in spec.modes if md.alpha == alpha)
    return mode, gamma


def branch(case: Case | str | Path, *, friction: float | None = None, mode=None, gamma=None,
           deltas=None, prepared=None, slip: float = SLIP, factor: Condensed | None = None
           ) -> Branch:
    """Walk u + delta Phi from the explicit solution of section 5 and check every point.

    Parameters
    ----------
    friction
        The friction coefficient (default: the critical one, ``|alpha|`` of ``mode``).
    mode
        Eigenfunction (:class:`critfric.solvers.eigenproblem.Mode`) of (3.2) for all nodes
        slipping (default: that of the critical coefficient); ``gamma`` its slip sign.
    deltas
        The walk (default: ``WALK * delta0``).
    factor
        The factored K (:class:`critfric.solvers.coulomb.Condensed`) of this case, to reuse.
    """

    case = case if isinstance(case, Case) else load_case(case)
    prep = prepared or prepare(case)
    check_dimension(case, prep.mesh.dim, "critfric verify")
    if mode is None:
        mode, gamma = _critical(prep, case)
    gamma = gamma or 1
    alpha = abs(mode.alpha)
    friction = alpha if friction is None else float(friction)
    # the construction at E = 1: delta0, the residuals and the verdict do not depend on E,
    # the forces of its points scale with it
    E = case.material["E"]
    cons = construction(prep.system, 1.0, case.material["nu"], friction,
                        case.boundary["contact"], case.boundary["dirichlet"], gamma=gamma,
                        slip=slip)
    problem, sys_ = cons.problem, prep.system
    phi_t = mode.phi[sys_.ct]
    w = cons.U[sys_.ct]
    sides = []
    for sign in (-1.0, 1.0):  # |delta| allowed towards each side (Theorem 3.3's proof)
        dX, dw = sign * mode.X, sign * gamma * phi_t
        lim = np.concatenate([np.abs(cons.X)[dX > 0] / dX[dX > 0],
                              np.abs(w)[dw < 0] / -dw[dw < 0]])
        sides.append(float(lim.min()) if len(lim) else np.inf)
    delta0 = min(sides)
    if deltas is None:
        deltas = WALK * (delta0 if np.isfinite(delta0) else slip / np.abs(phi_t).max())
    cond = factor or Condensed(problem.K, sys_)
    u0 = cond.solve(problem.rhs)[cond.cdofs]
    comp = Complementarity(cond.S, u0, problem.reference, friction)
    F = max(np.abs(cons.X).max(), np.abs(cons.Y).max())
    D = max(np.abs(cons.U[sys_.cn]).max(), np.abs(w).max())
    points = []
    for delta in deltas:  # one point at a time: each is a full-size field
        U = cons.U + delta * mode.phi
        X, Y = cons.X + delta * mode.X, cons.Y + delta * mode.Y
        Un, Ut = U[sys_.cn], U[sys_.ct]
        res = {"equilibrium": problem.equilibrium(U, X, Y)}
        res.update({k: float(v) for k, v in violations(
            Un, Ut, X, Y, problem.reference, friction, force_scale=F, disp_scale=D).items()})
        res["newton"] = comp.residual(np.concatenate([Un, Ut]))
        points.append(BranchPoint(float(delta), Un, Ut, E * X, E * Y, res))
    node = int(np.argmax(np.abs(phi_t)))
    return Branch(friction, float(mode.alpha), gamma, delta0, tuple(sides), points, node, cons,
                  mode, (cond, u0))


def newton_check(b: Branch, point: BranchPoint):
    """Run the Newton solver of :mod:`critfric.coulomb` from a branch point: a solution of
    (2.8) is accepted at once (0 iterations) and returned unchanged."""
    return coulomb_solve(b.construction.problem, b.friction, condensed=b.condensed,
                         start=np.concatenate([point.Un, point.Ut]))


def verify(case: Case | str | Path, *, off: float = 0.01, deltas=None,
           prepared=None) -> Verification:
    """The critical branch, and the counter-checks at friction (1 - off) and (1 + off)."""

    if not 0 < off < 1:
        raise CaseError(f"got {off!r}; allowed: a relative offset in (0, 1), such as 0.01",
                        key="--off")
    case = case if isinstance(case, Case) else load_case(case)
    prep = prepared or prepare(case)
    crit = branch(case, deltas=deltas, prepared=prep)
    inside = [q.delta for q in crit.inside if q.delta != 0.0]
    others = [branch(case, friction=crit.friction * (1 + k * off), mode=crit.mode,
                     gamma=crit.gamma,
                     deltas=inside or [crit.delta0], prepared=prep, factor=crit.condensed[0])
              for k in (-1.0, 1.0)]
    return Verification(case, crit, others)


def report_verification(v: Verification) -> str:
    """The table of ``critfric verify``: the largest violation of each condition per delta."""
    b = v.critical
    lines = [f"critical friction coefficient {b.friction:.10g} (slip along "
             f"{'+' if b.gamma > 0 else '-'}t, all {len(b.points[0].X)} contact nodes "
             f"slipping); delta0 = {b.delta0:.6g}",
             "relative residuals of u + delta Phi (pass: all <= "
             f"{PASS_TOL:g}; newton: Alart-Curnier residual of critfric.coulomb)",
             f"{'delta':>11} " + " ".join(f"{c:>11}" for c in CHECKS) + "  ok"]
    for q in b.points:
        lines.append(f"{q.delta:>11.4g} " + " ".join(f"{q.residuals[c]:>11.2e}" for c in CHECKS)
                     + ("  yes" if q.passed else "  no"))
    lines.append(f"at the critical value: max residual {b.max_residual:.2e} for |delta| <= "
                 f"delta0: {'solutions' if b.passed else 'NOT solutions'}; beyond delta0: "
                 f"{'stops' if b.stops else 'does NOT stop'} being a solution")
    for o in v.off_critical:
        verdict = "still solutions (unexpected)" if o.passed else "not solutions (expected)"
        lines.append(f"off critical, friction {o.friction:.10g}: max residual "
                     f"{o.max_residual:.2e}: {verdict}")
    lines.append("verification " + ("PASSED" if v.passed else "FAILED"))
    return "\n".join(lines)
