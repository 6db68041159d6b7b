"""Stability of steady sliding: flutter and divergence thresholds of a case.

For each sliding direction (the state's own, f > 0, and the opposite one, f < 0) the
``modes`` lowest free-vibration branches kappa(f) = -s(f)^2 are followed from friction 0
(:mod:`.locus`), the first coalescence is located and sharpened on the reduced model and
found on the full pencil by Newton's method (:mod:`.fold`). One factorization of K_rr
serves the modes, the reduced basis, the sharpening and Newton's bordered solves of both
directions (freed before a bordered matrix is factored, where those stall). Divergence
(kappa = 0) happens exactly at the static critical coefficients, computed by the static
eigen stage itself (its analysis started during the assembly, as in ``solve``), first: K_rr's
analysis then runs in the background beside the mass assembly. From there on OpenBLAS runs
on one thread (:func:`.locus.blas_threads`), PARDISO on its own.
"""

from __future__ import annotations

import contextlib
import math
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..case.schema import Case, as_case
from ..errors import CaseError, SolverError
from ..fem.assembly import assemble_mass, lame
from ..fem.mesh import Mesh
from ..solve import Prepared, prepare
from ..solvers import eigen
from ..solvers.backends import resolve_backend
from ..solvers.eigen import ContactState
from ..solvers.eigenproblem import Problem
from ..solvers.from_case import check_dimension, contact_state
from ..solvers.ordering import fill_order
from . import fold, locus, shared
from .bordered import Deflated
from .pencil import kept_dofs, sliding_pencil
from .sharpen import sharpen

DIRECTIONS = ("positive", "negative")
DEFAULT_RANGE = 10.0  # friction range each way when the case has no real static coefficient
RANGE_FACTOR = 1.25  # default range: this times the larger |static coefficient|


def first_instability(flutter: float | None, divergence: float | None) -> str | None:
    """"flutter" or "divergence", whichever has the smaller |friction| (None: neither)."""
    if flutter is None and divergence is None:
        return None
    if divergence is None or (flutter is not None and abs(flutter) < abs(divergence)):
        return "flutter"
    return "divergence"


@dataclass
class StabilityResult:
    """Thresholds of one case, the branches behind them and the flutter modes."""

    case: Case
    flutter: dict[str, float | None]  # signed friction of the first coalescence, each way
    flutter_kappa: dict[str, float | None]  # kappa = omega^2 at the coalescence
    divergence: dict[str, float | None]  # the static critical coefficients (signed)
    frequencies: np.ndarray  # omega_k at friction 0, ascending (modes,)
    friction: np.ndarray  # signed friction grid of the branches (n_f,), ascending
    kappa: np.ndarray  # (n_f, modes) complex kappa = -s^2 of the followed branches
    flutter_modes: dict[str, np.ndarray]  # nodal shape (n_nodes, 2) at each onset
    mesh: Mesh
    contact_nodes: np.ndarray
    normal: np.ndarray
    n_dofs: int
    nu: float
    E: float
    density: float
    element: str
    size: float | None
    h: float
    backend: str
    seconds: float
    timings: dict[str, float] = field(default_factory=dict)
    newton_steps: dict[str, int] = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)

    @property
    def modes(self) -> int:
        return len(self.frequencies)

    def first(self, direction: str) -> str | None:
        """Which instability comes first that way: "flutter", "divergence" or None."""
        return first_instability(self.flutter[direction], self.divergence[direction])

    def growth(self) -> np.ndarray:
        """Growth rate Re s >= 0 of each branch, (n_f, modes): s = i sqrt(kappa)."""
        return np.abs((1j * np.sqrt(self.kappa.astype(complex))).real)

    def frequency(self) -> np.ndarray:
        """Angular frequency ``|Im s|`` of each branch, (n_f, modes)."""
        return np.abs((1j * np.sqrt(self.kappa.astype(complex))).imag)

    def summary(self) -> dict[str, Any]:
        """The JSON summary of ``critfric stability --json``."""
        opt = lambda v: None if v is None else float(v)
        return {
            "case": self.case.name,
            "flutter": {d: opt(self.flutter[d]) for d in DIRECTIONS},
            "divergence": {d: opt(self.divergence[d]) for d in DIRECTIONS},
            "first": {d: self.first(d) for d in DIRECTIONS},
            "flutter_frequency": {d: (None if self.flutter_kappa[d] is None else
                                      float(np.sqrt(max(self.flutter_kappa[d], 0.0))))
                                  for d in DIRECTIONS},
            "frequencies": [float(w) for w in self.frequencies],
            "friction_range": [float(self.friction[0]), float(self.friction[-1])],
            "modes": self.modes,
            "n_dofs": self.n_dofs,
            "n_contact": len(self.contact_nodes),
            "element": self.element,
            "nu": self.nu,
            "density": self.density,
            "h": self.h,
            "size": self.size,
            "backend": self.backend,
            "seconds": round(self.seconds, 4),
            "warnings": list(self.warnings),
        }

    def __repr__(self) -> str:
        fmt = lambda v: "none" if v is None else f"{v:.10g}"
        return (f"StabilityResult({self.case.name!r}, {self.element}, nu={self.nu:g}, "
                f"n_dofs={self.n_dofs}, flutter=({fmt(self.flutter['positive'])}, "
                f"{fmt(self.flutter['negative'])}), divergence=("
                f"{fmt(self.divergence['positive'])}, {fmt(self.divergence['negative'])}))")


def stability_prepared(prep: Prepared, case: Case) -> StabilityResult:
    """Thresholds of a prepared case at its Poisson ratio, density and [stability] keys."""
    # ``threads``: what the stages leave running (OpenBLAS limits, background analyses),
    # put back and waited for on the way out, whatever the way
    with contextlib.ExitStack() as threads:
        plan, prep.plan = prep.plan, None  # the static stage's analysis, if started in prepare
        if plan is not None:  # waited for at the end, if unused (an error came first)
            threads.callback(plan.close)
        prep.check_case(case)
        check_dimension(case, prep.mesh.dim, "critfric stability")
        return _stability(prep, case, plan, threads)


def _stability(prep: Prepared, case: Case, plan, threads: contextlib.ExitStack
               ) -> StabilityResult:
    t0 = time.perf_counter()
    E, nu, rho = case.material["E"], case.material["nu"], case.material["density"]
    s, st = case.solve, case.stability
    backend = resolve_backend(s["backend"])
    system = prep.system
    state = contact_state(case, system) or ContactState.all_slipping(system.n_contact,
                                                                     s["gamma"])
    slip, kept = kept_dofs(system, state)
    modes = min(st["modes"], len(kept))
    _check_work(st["steps"], locus.reduced_size(len(kept), len(slip), modes), modes,
                case.source)  # before any factorization
    K = system.stiffness(*lame(1.0, nu))
    Krr = K[kept][:, kept].tocsr()
    order = one = None
    if shared.applies(system, state, s["method"], backend) and len(kept) > locus.FULL_MAX:
        # SciPy: one factorization of K_rr serves the static stage too (:mod:`.shared`)
        order = fill_order(system, kept)
        one = shared.SharedFactor.of(K, Krr, Problem(K, system, state), kept, order)
    # PARDISO's analysis started in prepare: K with its pattern's zero entries
    static = eigen.solve(K if plan is None else system.stiffness(*lame(1.0, nu), keep_zeros=True),
                         system, state, method=s["method"], count=1, tol=s["tol"],
                         maxiter=s["maxiter"], real_tol=s["real_tol"], backend=backend,
                         plan=plan, made=one)
    divergence = {"positive": float(static.positive[0]) if len(static.positive) else None,
                  "negative": float(static.negative[0]) if len(static.negative) else None}
    t1 = time.perf_counter()
    outer = locus.openblas_threads()  # the caller's, for large dense eigenproblems
    threads.enter_context(locus.blas_threads(1))  # after the static stage (as in solve)
    # solved at E = density = 1 and the body's extent ell = 1 (M / ell^2): the thresholds do
    # not depend on them, kappa = omega^2 scales as E / (density ell^2)
    ell = float(np.ptp(prep.mesh.points, axis=0).max())
    krr_plan = None if one else locus.plan_of(Krr, backend)  # beside the mass assembly
    if krr_plan is not None:
        threads.callback(krr_plan.close)
    M = system.restrict(assemble_mass(prep.mesh, 1.0)) / ell**2
    pencil = sliding_pencil(system, K, M, state, Krr=Krr)
    del K, Krr, M  # the pencil holds its blocks
    t2 = time.perf_counter()
    notes, warnings = list(static.notes), list(static.warnings)
    if modes < st["modes"]:
        notes.append(f"only {pencil.size} degrees of freedom: {modes} modes followed")
    if order is None and backend == "scipy":
        order = fill_order(system, pencil.kept)
    # one factorization of K_rr serves the modes, the reduced basis and the sharpening
    factor = one or (locus.factor_of(pencil, backend, order, krr_plan)
                     if pencil.size > locus.FULL_MAX else None)
    krr_plan = one = None
    red = locus.reduce(pencil, modes, backend=backend, order=order, factor=factor,
                       threads=outer)
    if np.any(red.omega2[:modes] <= 0):
        raise SolverError("a free-vibration eigenvalue is not positive: check that the "
                          "Dirichlet edges hold the body")
    scale = _kappa_scale(E, rho, ell, float(red.omega2[modes - 1]), case.source)
    lo, hi = st["friction"] or _default_range(divergence)
    for direction, inside in (("positive", lambda v: v <= hi), ("negative", lambda v: v >= lo)):
        value = divergence[direction]
        if value is not None and not inside(value):  # reported within the range only
            notes.append(f"the {direction} divergence threshold {value:.10g} (the static "
                         f"critical coefficient) lies outside the friction range [{lo:g}, "
                         f"{hi:g}]")
            divergence[direction] = None
    t3 = time.perf_counter()
    flutter, flutter_kappa, shapes, steps, parts, guesses = {}, {}, {}, {}, [], {}
    for direction, end in (("negative", lo), ("positive", hi)):
        flutter[direction] = flutter_kappa[direction] = None
        if end == 0.0:
            continue
        grid = np.linspace(0.0, end, st["steps"] + 1)
        branches = locus.follow(red, modes, grid)
        parts.append(branches)
        guess = locus.locate_flutter(red, branches)
        if guess is None:
            notes.append(f"no flutter of the {modes} lowest modes for {direction} friction "
                         f"up to |friction| = {abs(end):g}")
            continue
        guesses[direction] = guess
    # both directions' sharpening rounds in lockstep (one solve with K_rr a round)
    sharp = dict(zip(guesses, sharpen(red, pencil, factor, list(guesses.values()))))
    # Newton's bordered solves on K_rr's factorization (freed if they fall back on an LU),
    # both directions' in lockstep
    solver = None if factor is None else Deflated(factor, red.modes0)
    factor = None
    t4 = time.perf_counter()
    starts = [(g.friction, g.kappa, g.right, g.left, g.jacobian) for g in sharp.values()]
    founds = fold.find_folds(pencil, starts, backend=backend, order=order, solver=solver)
    for (direction, guess), found in zip(guesses.items(), founds):
        if abs(found.friction - guess.friction) > 1e-3 * abs(guess.friction):
            warnings.append(f"the {direction} flutter onset moved from {guess.friction:.6g} "
                            f"(reduced model of {modes} modes) to {found.friction:.6g} on the "
                            "full pencil, the value given; check with more --modes, with "
                            "which the two should meet (if they do not, the full pencil's "
                            "may be another coalescence)")
        flutter[direction] = float(found.friction)
        flutter_kappa[direction] = float(found.kappa) * scale
        shapes[direction] = pencil.shape_xy(found.right)
        steps[direction] = found.steps
    solver = founds = None
    t5 = time.perf_counter()
    friction, kappa = _merge(parts)
    timings = dict(prep.seconds, static=t1 - t0, mass=t2 - t1, modes=t3 - t2, branches=t4 - t3,
                   newton=t5 - t4)
    return StabilityResult(
        case=case, flutter=flutter, flutter_kappa=flutter_kappa, divergence=divergence,
        frequencies=np.sqrt(red.omega2[:modes]) * (math.sqrt(E) / math.sqrt(rho) / ell),
        friction=friction, kappa=kappa * scale,
        flutter_modes=shapes, mesh=prep.mesh, contact_nodes=system.nodes,
        normal=system.normal, n_dofs=system.n_dofs, nu=nu, E=E, density=rho,
        element=case.mesh["element"], size=case.mesh["size"], h=prep.mesh.diameter,
        backend=backend, seconds=sum(timings.values()), timings=timings, newton_steps=steps,
        warnings=warnings, notes=notes)


def _check_work(steps: int, d: int, modes: int, source: str) -> None:
    """CaseError if following ``steps`` friction steps each way on a reduced model of size d
    would exceed locus.WORK_MAX."""
    if 2 * steps * float(d) ** 3 > locus.WORK_MAX:
        minutes = 2 * steps * float(d) ** 3 * locus.SECONDS_PER_D3 / 60
        raise CaseError(f"{steps} friction steps on a reduced model of size {d} "
                        f"({modes} modes) would take about {minutes:.0f} minutes: "
                        "2 x steps x size^3 must be at most "
                        f"{locus.WORK_MAX:.0e}; lower [stability] steps (at most "
                        f"{int(locus.WORK_MAX / (2 * d ** 3))}) or modes",
                        key="stability.steps").located(source)


def _kappa_scale(E: float, density: float, ell: float, top: float, source: str) -> float:
    """E / (density ell^2), the factor of kappa = omega^2 (``top``: the largest kappa
    followed, at E = density = ell = 1); CaseError where kappa leaves the normal floats."""
    scale = E / density / ell**2
    if not (1e-300 <= scale and math.isfinite(scale * top * 1e6)):
        raise CaseError(f"E / density = {E:g} / {density:g} on a body of extent {ell:g} puts "
                        f"the squared frequencies (kappa, {top:.3g} at E = density = extent = "
                        "1) beyond the floats; allowed: E and density nearer each other",
                        file=source, key="material.density")
    return scale


def _default_range(divergence: dict) -> tuple[float, float]:
    known = [abs(v) for v in divergence.values() if v is not None]
    end = RANGE_FACTOR * max(known) if known else DEFAULT_RANGE
    return -end, end


def _merge(parts: list) -> tuple[np.ndarray, np.ndarray]:
    """Both directions' branches on one ascending friction axis (friction 0 once)."""
    neg = [p for p in parts if p.friction[-1] < 0]
    pos = [p for p in parts if p.friction[-1] > 0]
    fr, ka = [], []
    for p in neg:
        fr.append(p.friction[::-1][:-1])
        ka.append(p.kappa[::-1][:-1])
    for p in pos:
        fr.append(p.friction)
        ka.append(p.kappa)
    if not pos and neg:  # friction 0 from the negative side
        fr.append(neg[0].friction[:1])
        ka.append(neg[0].kappa[:1])
    return np.concatenate(fr), np.concatenate(ka)


def stability_case(case: Case | dict | str | Path, *, overrides: dict[str, Any] | None = None,
                   max_dofs: int | None = None, trust_geo: bool = False) -> StabilityResult:
    """Load (if needed), mesh, assemble and analyse a case; what ``critfric stability`` calls.

    case: a :class:`Case`, a case file path, a shipped case name, or a dict of sections."""
    case = as_case(case, overrides=overrides)
    return stability_prepared(prepare(case, max_dofs=max_dofs, trust_geo=trust_geo, _plan=True,
                                      _single=True),
                              case)
