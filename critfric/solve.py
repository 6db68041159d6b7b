"""The solve pipeline: case -> mesh -> assembly -> contact system -> eigenproblem -> Result.

``prepare`` does everything that does not depend on the Poisson ratio (mesh, the two stiffness
parts, the contact DOF basis) so that a sweep over nu reuses it; ``solve_prepared`` does the
rest. ``solve_case`` chains them, with the stiffness assembled at the case's nu alone: it is
what ``critfric solve`` calls.
"""

from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .case.schema import Case, as_case
from .errors import CaseError, SolverError
from .fem.assembly import assemble_elasticity, assemble_stiffness, lame
from .fem.contact import ContactSystem, check_held, contact_layout, contact_system
from .fem.contact3d import contact_layout3d, contact_system3d, slip_directions
from .fem.mesh import Mesh
from .fem.quality import skewed_contact_cells
from .guards import check_dofs
from .meshing.from_case import make_mesh
from .solvers import eigen
from .solvers.backends import resolve_backend
from .solvers.from_case import check_dimension, contact_state, plane_positions, slip_angles
from .solvers.ordering import dissect_beside, dissects


@dataclass
class Prepared:
    """Mesh, stiffness parts and contact basis of a case: everything independent of nu (or,
    prepared for one Poisson ratio, the stiffness at that nu, kept in ``made_from``)."""

    mesh: Mesh
    system: ContactSystem
    seconds: dict[str, float]
    made_from: dict = field(default_factory=dict)  # the case sections that made the mesh
    plan: Any = field(default=None, repr=False)  # eigen.plan_dense of the stiffness, used once
    parts: Any = field(default=None, repr=False)  # 3D: (K_lam, K_G) in xyz, to turn the slip
    slip: Any = None  # 3D: the slip directions' inputs the system was made with
    warnings: list[str] = field(default_factory=list)  # of the mesh, given with every result

    def __repr__(self) -> str:
        return (f"Prepared({self.mesh!r}, {self.system.n_dofs} DOFs, "
                f"{self.system.n_contact} contact nodes)")

    def check_case(self, case: Case) -> None:
        """Refuse a case whose geometry, mesh or boundary differ from the ones this was
        prepared from (its result would describe a mesh that was not solved)."""
        for key, value in (_mesh_inputs(case) | {"material.nu": case.material["nu"]}).items():
            if key in self.made_from and self.made_from[key] != value:
                raise CaseError(f"is {value!r} in this case but {self.made_from[key]!r} in the "
                                "prepared mesh; allowed: the prepared values (or prepare() "
                                "the case again)", file=case.source, key=key)


@dataclass
class Result:
    """The critical friction coefficients of one case, with the data to write or plot them."""

    case: Case
    positive: np.ndarray
    negative: np.ndarray
    alpha: np.ndarray
    modes: list[dict]
    mesh: Mesh
    contact_nodes: np.ndarray
    normal: np.ndarray
    n_dofs: int
    nu: float
    E: float
    element: str
    size: float | None
    h: float
    solver: str
    applications: int
    n_infinite: int
    seconds: float
    timings: dict[str, float] = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    backend: str = "scipy"  # sparse linear solver used (critfric.solvers.backends)
    complete: bool = True  # every eigenvalue found (False: ARPACK, complete within a radius)
    r: np.ndarray | None = None  # 3D: r of each eigenvalue of alpha (0: an exact static branch)
    law: str = "rate"  # 3D: the law of the slip direction
    slip_angle: float = 0.0  # 3D: [solve] slip_angle
    slip: np.ndarray | None = None  # 3D: (p, 3) slip direction s of each contact node

    @property
    def dim(self) -> int:
        return self.mesh.dim

    def r_of(self, values: np.ndarray) -> np.ndarray:
        """r of the eigenvalues ``values`` (of ``positive`` or ``negative``); 3D only."""
        if self.r is None or not len(values):
            return np.zeros(len(values))
        at = np.abs(self.alpha[None, :] - np.asarray(values)[:, None]).argmin(axis=1)
        return np.asarray(self.r)[at]

    @property
    def n_contact(self) -> int:
        return len(self.contact_nodes)

    def __repr__(self) -> str:
        lowest = lambda v: f"{v[0]:.10g}" if len(v) else "none"
        return (f"Result({self.case.name!r}, {self.element}, nu={self.nu:g}, "
                f"h={self.h:.4g}, n_dofs={self.n_dofs}, critical={lowest(self.positive)}, "
                f"lowest negative={lowest(self.negative)}, {len(self.alpha)} eigenvalues)")

    @property
    def complex_count(self) -> int:
        return len(self.alpha) - len(self.positive) - len(self.negative)

    @property
    def critical(self) -> float:
        """The critical friction coefficient, the lowest positive eigenvalue (NaN if none)."""
        return float(self.positive[0]) if len(self.positive) else float("nan")

    def summary(self) -> dict[str, Any]:
        """The JSON summary of ``critfric solve --json``."""
        return {
            "case": self.case.name,
            "positive": [float(a) for a in self.positive],
            "negative": [float(a) for a in self.negative],
            "complex_count": self.complex_count,
            "n_dofs": self.n_dofs,
            "n_contact": self.n_contact,
            "element": self.element,
            "nu": self.nu,
            "h": self.h,
            "size": self.size,
            "method": self.solver,
            "backend": self.backend,
            "complete": self.complete,
            "seconds": round(self.seconds, 4),
            "warnings": list(self.warnings),
            "notes": list(self.notes),
            **({"dim": 3, "law": self.law, "slip_angle": self.slip_angle,
                "r_positive": [float(x) for x in self.r_of(self.positive)],
                "r_negative": [float(x) for x in self.r_of(self.negative)]}
               if self.dim == 3 else {}),
        }


def prepare(case: Case, *, max_dofs: int | None = None, trust_geo: bool = False,
            _plan: bool = False, _single: bool = False) -> Prepared:
    """Mesh, assemble and classify the boundary of a case (independent of nu).

    Parameters
    ----------
    max_dofs
        Refuse a mesh estimated above this many DOFs (default: what memory allows).
    trust_geo
        Mesh a .geo script even if it can run programs or read or write files.
    _plan
        Start the eigen stage's factorization analysis from the stiffness pattern as soon as
        it is known (:func:`critfric.solvers.eigen.plan_dense`), for the one solve of
        ``case`` that follows.
    _single
        Assemble the stiffness at the case's Poisson ratio alone (2D; one matrix instead of
        two parts and their sum): the result solves that Poisson ratio only.
    """
    t0 = time.perf_counter()
    try:
        mesh = make_mesh(case, max_dofs=max_dofs, trust_geo=trust_geo)
    except CaseError as exc:
        raise exc.located(case.source) from None
    check_dimension(case, mesh.dim)
    contact = [name for name in case.boundary["contact"] if name in mesh.facets]
    held = _facet_nodes(mesh, [n for n in case.boundary["dirichlet"] if n in mesh.facets])
    check_dofs(mesh.dim * (mesh.n_nodes - len(held)), element=mesh.element,
               what="the mesh made",
               source=case.source, max_dofs=max_dofs, dim=mesh.dim,
               backend=case.solve["backend"],
               n_contact=len(_facet_nodes(mesh, contact)))  # what is real
    t1 = time.perf_counter()
    layout = _layout(case, mesh)
    t2 = time.perf_counter()
    plan = []

    def start(pattern) -> None:  # the analysis runs while the values are assembled
        # K's pattern: the free block's upper triangle (the n/t rotation moves no entry)
        ptr, col = pattern.upper(layout.position)
        s = case.solve
        plan.append(eigen.plan_dense(ptr, col, layout.contact_dofs, method=s["method"],
                                     shift=s["shift"], backend=s["backend"], dim=mesh.dim))

    try:  # SciPy orders by the mesh's nested dissection: made beside the assembly, joined below
        scipy = dissects(mesh) and resolve_backend(case.solve["backend"]) == "scipy"
    except SolverError:  # an unknown or missing backend: reported where the solver is chosen
        scipy = False
    ordering = dissect_beside(mesh) if scipy else None
    single = lame(1.0, case.material["nu"]) if _single and mesh.dim == 2 else None
    try:
        on_pattern = start if _plan else None
        if single is None:
            K_lam, K_G = assemble_elasticity(mesh, on_pattern=on_pattern)
        else:
            K_lam, K_G = assemble_stiffness(mesh, *single, on_pattern=on_pattern), None
        t3 = time.perf_counter()
        # checked once the analysis has started (beside it), the mesh's diameter made there
        if len(held):  # unknown names are reported by contact_layout
            check_held(mesh, held, source=case.source)
        _ = mesh.diameter
        if mesh.dim == 3:
            system = contact_system3d(mesh, K_lam, K_G, contact=case.boundary["contact"],
                                      dirichlet=case.boundary["dirichlet"],
                                      source=case.source, layout=layout)
        else:
            system = contact_system(mesh, K_lam, K_G, contact=case.boundary["contact"],
                                    dirichlet=case.boundary["dirichlet"], source=case.source,
                                    layout=layout, lame=single)
    except BaseException:
        _close(plan[0] if plan else None)
        raise
    finally:
        if ordering is not None:
            ordering.join()
    t4 = time.perf_counter()
    return Prepared(mesh, system, {"mesh": t1 - t0, "assembly": t3 - t2,
                                   "contact": t4 - t3 + t2 - t1},
                    made_from=_mesh_inputs(case) | ({"material.nu": case.material["nu"]}
                                                    if single is not None else {}),
                    plan=plan[0] if plan else None,
                    parts=(K_lam, K_G) if mesh.dim == 3 else None,
                    slip=_slip_inputs(case) if mesh.dim == 3 else None,
                    warnings=[w for w in [skewed_contact_cells(mesh, system.nodes)] if w])


def _slip_inputs(case: Case):
    """What a 3D contact system's slip directions are made from."""
    rules = case.contact["rules"] or []
    return (case.solve["slip_angle"], tuple((str(r["from"]), str(r["to"]), r["slip_angle"])
                                            for r in rules if r["slip_angle"] is not None))


def turned(prep: Prepared, case: Case) -> Prepared:
    """``prep`` for the slip directions of ``case`` (3D; the same Prepared if they are those
    it was made with): the contact basis turned, from the kept stiffness parts."""
    if prep.mesh.dim == 2 or prep.slip == _slip_inputs(case):
        return prep
    if prep.parts is None:
        raise CaseError("the prepared mesh kept no stiffness to turn the slip directions; "
                        "allowed: the slip_angle it was prepared with (or prepare() the case "
                        "again)", file=case.source, key="solve.slip_angle")
    t0 = time.perf_counter()
    layout = _layout(case, prep.mesh)
    system = contact_system3d(prep.mesh, *prep.parts, contact=case.boundary["contact"],
                              dirichlet=case.boundary["dirichlet"], source=case.source,
                              layout=layout)
    seconds = dict(prep.seconds, contact=time.perf_counter() - t0)
    return dataclasses.replace(prep, system=system, seconds=seconds, plan=None,
                               slip=_slip_inputs(case))


def _facet_nodes(mesh: Mesh, names: list[str]) -> np.ndarray:
    """Sorted unique nodes of the boundary groups ``names`` (edges in 2D, faces in 3D)."""
    parts = [np.asarray(mesh.facets[name]).ravel() for name in names]
    return np.unique(np.concatenate(parts)) if parts else np.zeros(0, dtype=np.int64)


def _layout(case: Case, mesh: Mesh):
    """The contact layout of a case's mesh; in 3D with the slip direction of each contact
    node ([solve] slip_angle, the slip_angle of [contact] rules)."""
    b = case.boundary
    if mesh.dim == 2:
        return contact_layout(mesh, contact=b["contact"], dirichlet=b["dirichlet"],
                              source=case.source)
    layout = contact_layout3d(mesh, contact=b["contact"], dirichlet=b["dirichlet"],
                              source=case.source)
    angle = slip_angles(case, layout.nodes, plane_positions(mesh.points, layout.nodes,
                                                             layout.normal, layout.tangent))
    return dataclasses.replace(layout, slip=slip_directions(
        layout.normal, layout.tangent, len(layout.nodes), angle=angle, source=case.source))


def _mesh_inputs(case: Case) -> dict:
    """Every case value that prepare() depends on, by dotted key."""
    return {f"{section}.{k}": v for section in ("geometry", "mesh", "boundary")
            for k, v in getattr(case, section).items()}


def solve_prepared(prep: Prepared, case: Case, *, keep_analysis: bool = False,
                   _release: bool = False) -> Result:
    """Solve the eigenproblem of a prepared case at the case's Poisson ratio (and [solve],
    [contact]); its geometry, mesh and boundary must be those ``prep`` was made from.

    ``keep_analysis``: where the eigen stage factors K with PARDISO (the dense path), its
    analysis (METIS and the symbolic factorization, about half of the factorization) is kept
    in ``prep`` for the next call, which then factors on it: K has one pattern for every
    Poisson ratio. The factor's memory stays allocated between the calls (a sweep over nu
    does this; ``prep.plan = None`` frees it)."""
    plans, prep.plan = [prep.plan], None  # prepare's analysis of K's pattern, if started
    try:
        result = _solve_prepared(prep, case, plans, _release, keep_analysis)
    finally:
        _close(plans[0])
    if keep_analysis and plans[0] is not None:
        prep.plan = plans[0].again()
    return result


def _close(plan) -> None:
    """Wait for a background analysis the solve did not use (an error came first)."""
    if plan is not None:
        plan.close()


def _solve_prepared(prep: Prepared, case: Case, plans: list, _release: bool,
                    keep: bool) -> Result:
    """The solve; ``plans[0]``: the analysis of K's pattern it factors on (one started here
    where ``keep`` asks for one and there is none)."""
    plan = plans[0]
    prep.check_case(case)
    check_dimension(case, prep.mesh.dim)
    if prep.mesh.dim == 3 and prep.slip != _slip_inputs(case):
        prep = turned(prep, case)
    t0 = time.perf_counter()
    E, nu = case.material["E"], case.material["nu"]
    lam, G = lame(1.0, nu)  # the eigenvalues and modes do not depend on E: solved at E = 1
    s = case.solve
    system = prep.system
    state = contact_state(case, system)  # None: all slipping ([contact])
    K = system.stiffness(lam, G, keep_zeros=plan is not None or keep)  # the planned pattern
    if plan is None and keep:  # its analysis kept for the next Poisson ratio
        plan = plans[0] = eigen.plan_for(K, system, method=s["method"], shift=s["shift"],
                                         backend=s["backend"])
    if plan is not None:
        plan.keep = keep
    if _release:  # solve_case's own prepared case: the parts are not needed again, and
        # at 1 M DOFs they are 0.4 GB beside the factorization (the peak)
        system = prep.system = dataclasses.replace(system, K_lam=None, K_G=None,
                                                   D_lam=None, D_G=None)
        prep.parts = None
    spec = eigen.solve(K, system, state, method=s["method"],
                       count=s["count"],
                       shift=s["shift"], tol=s["tol"], maxiter=s["maxiter"],
                       real_tol=s["real_tol"], gamma=s["gamma"], backend=s["backend"],
                       plan=plan, law=s["direction_law"])
    modes = [
        {
            "alpha": m.alpha,
            "phi": system.to_xy(m.phi),
            "theta_n": E * m.X,  # the contact forces of phi at the case's E
            "theta_t": E * m.Y,
            "residual": m.residual,
            "r": m.r,
        }
        for m in spec.modes
    ]
    t1 = time.perf_counter()
    timings = dict(prep.seconds, eigen=t1 - t0)
    return Result(
        case=case, positive=spec.positive, negative=spec.negative, alpha=spec.alpha,
        modes=modes, mesh=prep.mesh, contact_nodes=system.nodes, normal=system.normal,
        n_dofs=system.n_dofs, nu=nu, E=E, element=case.mesh["element"],
        size=case.mesh["size"], h=prep.mesh.diameter, solver=spec.method,
        applications=spec.applications, n_infinite=spec.n_infinite,
        seconds=sum(timings.values()), timings=timings, warnings=prep.warnings + spec.warnings,
        notes=spec.notes, backend=spec.backend, complete=spec.complete,
        r=spec.r if system.dim == 3 else None, law=s["direction_law"],
        slip_angle=s["slip_angle"], slip=system.slip,
    )


def solve_case(case: Case | dict | str | Path, *, overrides: dict[str, Any] | None = None,
               max_dofs: int | None = None, trust_geo: bool = False) -> Result:
    """Load (if needed), mesh, assemble and solve a case; return its :class:`Result`.

    case: a :class:`Case`, a case file path, a shipped case name ("unit-square"), or a dict
    of sections as in a case file ({"geometry": {"shape": "square"}, ...})."""
    case = as_case(case, overrides=overrides)
    return solve_prepared(prepare(case, max_dofs=max_dofs, trust_geo=trust_geo, _plan=True,
                                  _single=True),
                          case, _release=True)
