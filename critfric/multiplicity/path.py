"""``critfric path``: the solution curves of the static problem (2.8) along the friction or
the load, with their kinks, folds and branch points and the critical coefficients of the
contact state of every piece.

One factorization of K (the condensation onto Gamma_C, :mod:`.states`); everything after it
lives on the 2p contact unknowns. The curves start from the solutions at the start of the
range (every one, by enumeration, on problems with at most MAX_NODES contact nodes; else the
Newton solution) and are followed piece by piece (:mod:`.explore`). On problems with at most
MAX_NODES contact nodes every solution is also enumerated at each sample value, and one that
no curve passes through seeds a curve of its own (an isola, or a pair born away from the
start), so that the diagram holds every solution at every sample value.
"""

from __future__ import annotations

import dataclasses
import time
from pathlib import Path
from typing import Any

import numpy as np
from threadpoolctl import threadpool_limits

from ..case.schema import Case, as_case
from ..errors import CaseError
from ..fem.static import StaticProblem
from ..solve import prepare
from ..solvers import coulomb
from ..solvers.from_case import arc_length, case_problem, check_dimension
from .arcs import Track
from .enumeration import ENUMERATED, MAX_NODES, Enumerator
from .explore import SAME_TOL, Explorer
from .pathresult import PathResult
from .states import Condensed

MAX_VALUE = 1e6  # |a|, |b| of a range (friction: 1 / INFINITE_TOL of the eigen stage)
PIECE_SECONDS = 1e-10  # a piece costs about this x (2p)^3 s (401 nodes: 0.05 s measured)
MAX_SECONDS = 3600  # refuse a path whose p pieces (one a node, at least) need longer
MAX_STORED = 5 * 10**7  # sample values x contact nodes, the size of one curve's points


def _options(case: Case) -> dict:
    opts = dict(getattr(case, "path", None) or {})
    opts.setdefault("parameter", "friction")
    for key, default in (("start", "auto"), ("samples", 101), ("node", None), ("load", None),
                         ("max_pieces", 20000)):
        opts.setdefault(key, default)
    span = opts.get("range")
    if span is None:
        raise CaseError("missing key: the range [a, b] of the parameter ([path] range, or "
                        "--range A:B)", file=case.source, key="path.range")
    a, b = map(float, span)
    if not a < b or (opts["parameter"] == "friction" and a < 0) or max(-a, b) > MAX_VALUE:
        raise CaseError(f"got {[a, b]}; allowed: two numbers [a, b] with a < b, |a|, |b| <= "
                        f"{MAX_VALUE:g} (a >= 0 for the friction: critical coefficients above "
                        f"{MAX_VALUE:g} count as infinite)", file=case.source, key="path.range")
    opts["range"] = (a, b)
    return opts


def path_case(case: Case | dict | str | Path, *, overrides: dict[str, Any] | None = None,
              max_dofs: int | None = None, trust_geo: bool = False) -> PathResult:
    """Follow the solution curves of a case's static problem along ``[path] parameter``."""
    started = time.perf_counter()
    case = as_case(case, overrides=overrides)
    opts = _options(case)
    a, b = opts["range"]
    friction = None
    if opts["parameter"] == "load":
        friction = case.load["friction"]
        if friction is None:
            raise CaseError("a load path needs the friction coefficient; allowed: a number "
                            ">= 0", file=case.source, key="load.friction")
        if not opts["load"]:
            raise CaseError("a load path needs the second load L1 of L0 + t L1; allowed: a "
                            "table with traction, body_force, points or displacement",
                            file=case.source, key="path.load")
    prepared = prepare(case, max_dofs=max_dofs, trust_geo=trust_geo)
    check_dimension(case, prepared.mesh.dim, "critfric path")
    system = prepared.system
    _guard(case, system.n_contact, opts)
    if opts["node"] is not None and opts["node"] >= system.n_contact:
        raise CaseError(f"got node {opts['node']}; allowed: a contact node index below "
                        f"{system.n_contact}", file=case.source, key="path.node")
    if opts["start"] == "enumerate" and system.n_contact > MAX_NODES:
        raise CaseError(f"exact enumeration needs at most {MAX_NODES} contact nodes, the "
                        f"mesh has {system.n_contact}; allowed: start = 'newton' or 'auto'",
                        file=case.source, key="path.start")
    problem = case_problem(case, system, friction=0.0)
    second = None
    if opts["parameter"] == "load":
        second = case_problem(case, system, load=opts["load"], key="path.load")
    result = follow(problem, opts["parameter"], (a, b), second=second, friction=friction,
                    samples=opts["samples"], start=opts["start"],
                    max_pieces=opts["max_pieces"])
    result.s = arc_length(system, case.boundary["contact"])
    result.node = opts["node"] if opts["node"] is not None else result.node
    result.case, result.mesh, result.contact_nodes = case, prepared.mesh, system.nodes
    result.seconds = time.perf_counter() - started
    return result


def follow(problem: StaticProblem, parameter: str, span: tuple[float, float], *,
           second: StaticProblem | None = None, friction: float | None = None,
           samples: int = 101, start: str = "auto", max_pieces: int = 20000) -> PathResult:
    """Every solution curve of a static problem along the friction (its load fixed) or the
    load factor t of L0 + t L1 (``second``: the problem of L1, whose U^r is ignored; the
    friction fixed), over ``span``."""
    started = time.perf_counter()
    a, b = span
    cond, u0 = coulomb.condense(problem)
    u0b = None if second is None else cond.solve(second.rhs)[cond.cdofs]
    reach = max(abs(a), abs(b), 1e-300)  # the scales F, D cover the load all along the range
    cz = Condensed.of(problem, (cond, u0), extra=() if u0b is None else (reach * u0b,))
    track = Track(cz, parameter, friction, u0b, (a, b))
    values = np.linspace(a, b, samples)
    explorer = Explorer(track, values, max_pieces)
    p, notes, enumerate_at = cz.p, [], None
    if p <= MAX_NODES:
        enum = Enumerator(None, cz)
        enumerate_at = lambda t: _at(enum, cz, track, t)
    if start != "newton" and enumerate_at is not None:
        starts = enumerate_at(a)
    else:
        first = coulomb.solve(problem, track.friction(a), condensed=(cond, track.u0(a)))
        starts = [np.concatenate([first.X, first.Y])]
        if track.friction(a) > 0:
            notes.append(f"the curves start from the Newton solution at {a:g}; other "
                         f"solutions there, if any, are not followed (enumeration needs at "
                         f"most {MAX_NODES} contact nodes)")
    # one BLAS thread for the small dense matrices of the path (as the eigen stage does)
    with threadpool_limits(1 if 2 * p < 1500 else None, user_api="blas"):
        for z in starts:
            explorer.seed(a, z, "start")
        isolated = _complete(explorer, enumerate_at, values) if enumerate_at else []
        explorer.finish()
    if isolated:
        notes.append(f"{len(isolated)} solution(s) found by the enumeration lie on no curve "
                     "that could be followed: listed as isolated")
    return PathResult(
        parameter=parameter, range=(a, b), curves=explorer.curves, events=explorer.events,
        n_dofs=problem.K.shape[0], n_contact=p, seconds=time.perf_counter() - started,
        friction=friction, samples=values, isolated=isolated, node=_moving(explorer),
        notes=notes + explorer.notes)


def _guard(case: Case, p: int, opts: dict) -> None:
    each = PIECE_SECONDS * (2 * p) ** 3
    if p * each > MAX_SECONDS:
        raise CaseError(f"the mesh has {p} contact nodes: a path of at least {p} pieces (one a "
                        f"node) of about {each:.2g} s each (dense {2 * p} x {2 * p} systems) "
                        f"takes about {p * each / 60:.0f} minutes or more; allowed: about "
                        f"{MAX_SECONDS // 60} minutes (some 1400 contact nodes): a coarser mesh "
                        "on Gamma_C", file=case.source, key="mesh.size")
    if p <= MAX_NODES and opts["samples"] * 4**p > ENUMERATED:
        most = ENUMERATED // 4**p
        raise CaseError(f"got {opts['samples']} samples: with {p} contact nodes every solution "
                        f"is enumerated at each ({4**p} contact states), about "
                        f"{opts['samples'] * 4**p * 8.4e-6 / 60:.0f} minutes; allowed: at most "
                        f"{most} samples", file=case.source, key="path.samples")
    if p * opts["samples"] > MAX_STORED:
        raise CaseError(f"got {opts['samples']} samples for {p} contact nodes: each curve "
                        f"would hold {p * opts['samples']} values; allowed: samples x contact "
                        f"nodes up to {MAX_STORED}", file=case.source, key="path.samples")


def _at(enum: Enumerator, cz: Condensed, track: Track, t: float) -> list[np.ndarray]:
    """Every solution at parameter t (the continua by a point of each), as forces z."""
    here = dataclasses.replace(cz, u0=track.u0(t))
    enum.cz, enum.u0 = here, here.u0
    found = enum(track.friction(t))
    zs = [np.concatenate([s.X, s.Y]) for s in found.solutions]
    for br in found.branches:
        ends = [e for e in (br.ends or []) if e is not None] or [br.point]
        zs += [np.concatenate([e.X, e.Y]) for e in ends]
    return zs


def _complete(explorer: Explorer, enumerate_at, samples) -> list:
    """Seed a curve from every enumerated solution no curve passes through; return those
    that still lie on none, as (value, PathPoint). A solution of the enumeration (products
    Y w within its tolerance) that is not one to CONSISTENT_TOL in each value is passed
    over."""
    missing, track = [], explorer.track
    for k, t in enumerate(samples):  # every sample value: at most a few solutions each
        for z in enumerate_at(t):
            exact = explorer.cz.consistent(z, track.friction(t), track.u0(t)).any(axis=1)
            if not exact.all():  # within the enumeration's tolerance, not a solution to ours
                continue
            if not _on_curve(explorer, k, t, z):
                explorer.seed(float(t), z, {"value": float(t)})
                if not _on_curve(explorer, k, t, z):
                    missing.append((float(t), explorer.point(t, z, 0)))
    return missing


def _on_curve(explorer: Explorer, k: int, t: float, z: np.ndarray) -> bool:
    key = explorer.key(t, z)
    return any(np.abs(h - key).max() <= 10 * SAME_TOL for h in explorer.hits.get(k, []))


def _moving(explorer: Explorer) -> int:
    """The contact node whose tangential displacement varies most over the curves."""
    Ut = np.array([pt.Ut for c in explorer.curves for pt in c.points])
    return int(np.argmax(np.ptp(Ut, axis=0))) if len(Ut) else 0
