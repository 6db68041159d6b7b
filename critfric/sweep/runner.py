"""Sweeps over the Poisson ratio, the mesh size and the element, with h -> 0 limits.

A sweep point is (nu, size, element). Points sharing (size, element) share one mesh and one
assembly (``prepare``): only ``lam K_lam + G K_G`` and the eigenproblem change with nu. Each
worker keeps a small cache of prepared systems and the scheduler (:mod:`critfric.workers`)
hands a worker all the points of a (size, element) group, split only to balance the load.

Every finished point is appended to the sweep file (:mod:`critfric.sweepfile`) by the parent
at once, so an interrupted sweep re-run with the same arguments computes only what is missing.
"""

from __future__ import annotations

import hashlib
import json
import math
import threading
import time
from collections import OrderedDict
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from ..case.schema import SWEEP_GRADING, Case, from_dict
from ..errors import CaseError
from ..files import sweepfile
from ..guards import usable_cpus
from ..solve import Prepared, preflight, prepare, singular_of, solve_prepared
from ..stability import stability_prepared
from . import workers
from .extrapolate import Limit, limits_of
from .grid import (
    MAX_POINTS,
    QUANTITIES,
    Grid,
    Point,
    empty_row,
    parse_elements,
    parse_nu,
    parse_sizes,
)

CACHE_SIZE = 2  # prepared systems kept per worker process


def sweep_case(case: Case, sizes) -> tuple[Case, str | None]:
    """The case a sweep over ``sizes`` meshes: with three sizes or more (h -> 0 limits) and
    no ``[mesh] grading``, gmsh meshes are graded at every singular point (size
    ``SWEEP_GRADING`` h there); the second value is a note saying so (None: unchanged)."""
    m, shape = case.mesh, case.geometry["shape"]
    if (len([s for s in sizes if s is not None]) < 3 or m["grading"] is not None
            or m["structured"] or shape in ("mesh", "file")):
        return case, None
    graded = case.with_overrides({"mesh.grading": SWEEP_GRADING})
    try:
        count = len(singular_of(graded))
    except CaseError as exc:
        raise exc.located(case.source) from None
    return graded, (f"meshes graded to size {SWEEP_GRADING:g} h at the {count} singular points "
                    "(contact ends, state junctions, corners where the boundary condition "
                    "changes, re-entrant corners): the default of sweeps with 3 or more sizes; "
                    "--grading 1 for uniform meshes")


# ------------------------------------------------------------------------------ the grid


def _overrides(point: Point) -> dict:
    return {"material.nu": point.nu, "mesh.size": point.size, "mesh.element": point.element}


# ------------------------------------------------------------------------------ one point
_CACHE: OrderedDict[tuple, Prepared] = OrderedDict()
_CACHE_LOCK = threading.Lock()  # Dask runs tasks in threads; gmsh is not thread-safe


def worker_spec(case: Case, *, reuse: bool = True, max_dofs: int | None = None,
                trust_geo: bool = False, quantity: str = "critical") -> dict:
    """What a worker needs to rebuild the case of any point (plain, picklable data)."""
    ident = hashlib.sha1(case.to_toml().encode()).hexdigest()
    return {"raw": case.raw, "source": case.source, "name": case.name, "text": case.text,
            "count": case.solve["count"], "reuse": reuse, "id": ident,
            "quantity": quantity,
            "guards": {"max_dofs": max_dofs, "trust_geo": trust_geo}}


def _prepared(spec: dict, case: Case, point: Point) -> Prepared:
    guards = spec.get("guards", {})
    if not spec["reuse"]:
        with _CACHE_LOCK:
            return prepare(case, **guards)
    key = (spec["id"], point.size, point.element)
    with _CACHE_LOCK:
        if key not in _CACHE:
            _CACHE[key] = prepare(case, **guards)
            while len(_CACHE) > CACHE_SIZE:
                _CACHE.popitem(last=False)
        _CACHE.move_to_end(key)
        return _CACHE[key]


def run_point(spec: dict, point: Point) -> dict:
    """Solve one point (in a worker); a failure is returned as a row, never raised."""
    t0 = time.perf_counter()
    try:
        base = from_dict(spec["raw"], source=spec["source"], name=spec["name"],
                         text=spec["text"])
        case = base.with_overrides(_overrides(point))
        if spec.get("quantity", "critical") == "flutter":
            return _flutter_row(point, stability_prepared(_prepared(spec, case, point), case),
                                t0)
        result = solve_prepared(_prepared(spec, case, point), case)
    except Exception as exc:
        return empty_row(point, f"failed: {type(exc).__name__}: {exc}",
                         time.perf_counter() - t0)
    count = spec["count"]
    pos, neg = result.positive[:count], result.negative[:count]
    row = empty_row(point, "ok" if len(pos) or len(neg) else "no-real-eigenvalue")
    row.update(h=result.h, n_dofs=result.n_dofs, n_contact=result.n_contact,
               positive=[float(v) for v in pos], negative=[float(v) for v in neg],
               complex_count=result.complex_count, seconds=time.perf_counter() - t0)
    return row


def _flutter_row(point: Point, result, t0: float) -> dict:
    """A flutter sweep's row: the thresholds in the positive/negative columns."""
    pos, neg = result.flutter["positive"], result.flutter["negative"]
    row = empty_row(point, "ok" if pos is not None or neg is not None else "no-flutter")
    row.update(h=result.h, n_dofs=result.n_dofs, n_contact=len(result.contact_nodes),
               positive=[] if pos is None else [float(pos)],
               negative=[] if neg is None else [float(neg)], complex_count=0,
               seconds=time.perf_counter() - t0)
    return row


# ------------------------------------------------------------------------------ the sweep
@dataclass
class Sweep:
    """A finished sweep: its file, every point (grid order), the limits and what ran now."""

    path: Path
    grid: Grid
    rows: list[dict]
    limits: list[Limit]
    computed: int
    seconds: float

    def summary(self) -> dict:
        """The JSON of ``critfric sweep --json``."""
        keys = ("nu", "size", "element", "h", "n_dofs", "n_contact", "positive", "negative",
                "complex_count", "status", "seconds")
        points = [{k: _json_value(r[k]) for k in keys} for r in self.rows]
        return {"points": points, "limits": [lim.to_json() for lim in self.limits]}

    def to_dataframe(self):
        """The points as a pandas DataFrame (one row a point, grid order; ``positive`` and
        ``negative`` hold the lowest coefficient of each family, NaN if none). Needs pandas;
        ``xarray.open_dataset(sweep.path, engine="h5netcdf")`` gives the gridded view."""
        try:
            import pandas as pd
        except ImportError:
            raise ImportError("Sweep.to_dataframe needs pandas: pip install pandas; "
                              "Sweep.summary()['points'] is the same table as plain data") from None
        table = self.summary()["points"]
        for row in table:
            for family in ("positive", "negative"):
                row[family] = row[family][0] if row[family] else math.nan
        return pd.DataFrame(table)

    def __repr__(self) -> str:
        ok = sum(r["status"] == "ok" for r in self.rows)
        return (f"Sweep({str(self.path)!r}, {len(self.rows)} points ({ok} ok, {self.computed} "
                f"computed now), {len(self.limits)} limits)")


def _json_value(v):
    if isinstance(v, float) and not math.isfinite(v):
        return None
    if isinstance(v, int) and v < 0:
        return None
    return v


def run_sweep(case: Case, grid: Grid, *, output: Path | str, jobs: int | None = None,
              scheduler: str | None = None, force: bool = False, reuse: bool = True,
              on_point: Callable[[dict, int, int], None] | None = None,
              max_dofs: int | None = None, trust_geo: bool = False) -> Sweep:
    """Run (or resume) a sweep into ``output``; return every point and the h -> 0 limits.

    jobs      : local worker processes (default: all cores); 1 runs in this process.
    scheduler : address of a Dask distributed scheduler, instead of local processes.
    force     : discard an existing ``output`` written for another case or grid.
    reuse     : reuse meshes and assemblies across nu (off only to measure its benefit).
    on_point  : called as on_point(row, done, total) after each point is written, and once
                with row None before the first (done: the points already in the file).
    max_dofs, trust_geo : the guards of :func:`critfric.solve.prepare`, for every point.
    """

    t0 = time.perf_counter()
    case = sweep_case(case, grid.size)[0]
    path = Path(output)
    client = workers.connect_dask(scheduler) if scheduler else None
    try:
        done = sweepfile.open_sweep(path, case=case, grid=grid, force=force)
        points = grid.points()
        todo = [p for p in points if p.key not in done]
        finished = len(points) - len(todo)
        if on_point is not None:
            on_point(None, finished, len(points))
        spec = worker_spec(case, reuse=reuse, max_dofs=max_dofs, trust_geo=trust_geo,
                           quantity=grid.quantity)
        jobs = max(1, min(jobs or usable_cpus(), len(todo)))
        if not todo:
            stream = iter(())
        elif client is not None:
            stream = workers.run_dask(client, run_point, spec, todo)
        elif jobs == 1:
            stream = _in_process(spec, todo)
        else:
            stream = workers.run_local(jobs, run_point, spec, todo)
        try:
            for point, row in stream:
                sweepfile.append_point(path, row)  # before anything else: never lost
                finished += 1
                if on_point is not None:
                    on_point(row, finished, len(points))
        finally:
            if hasattr(stream, "close"):
                stream.close()  # stops the workers, also on Ctrl-C
    finally:
        if client is not None:
            client.close()
    stored = {sweepfile.row_key(r): r for r in sweepfile.read_sweep(path)["rows"]}
    rows = [stored[p.key] for p in points]
    limits = limits_of(rows)
    sweepfile.write_limits(path, limits, grid, rows)
    return Sweep(path, grid, rows, limits, len(todo), time.perf_counter() - t0)


def _in_process(spec: dict, points: list[Point]):
    """Points run here, with BLAS/OpenMP pools held to one thread like the workers' (measured:
    a 33-point sweep took 7.6-13.8 s with OpenBLAS's two threads, 2.4-2.7 s with one)."""
    from threadpoolctl import threadpool_limits

    with threadpool_limits(limits=1):
        for p in points:
            yield p, run_point(spec, p)


def default_output(case: Case, grid: Grid) -> Path:
    """``<case name>_sweep_<digest>.h5`` in the current directory, the digest naming the case
    and the grid: the same command resumes the same file, another grid never clashes."""
    key = json.dumps([case.to_toml(), grid.to_json()], sort_keys=True).encode()
    return Path(f"{case.name}_sweep_{hashlib.sha1(key).hexdigest()[:6]}.h5")


def report_sweep(sweep: Sweep) -> str:
    """The text summary of ``critfric sweep``: every point, then the h -> 0 limits."""
    def num(v, fmt):
        return "-" if v is None or (isinstance(v, float) and not math.isfinite(v)) else fmt % v

    rows = sweep.rows
    lines = [f"sweep {sweep.path}: {len(rows)} points ({len(sweep.grid.nu)} nu x "
             f"{len(sweep.grid.size)} size x {len(sweep.grid.element)} element), "
             f"{sweep.computed} computed now in {sweep.seconds:.1f} s"]
    head = (f"{'nu':>7} {'element':<7} {'size':>8} {'h':>8} {'n_dofs':>8} {'p':>5} "
            f"{'lowest > 0':>14} {'lowest < 0':>14} {'complex':>7} {'seconds':>8}  status")
    lines += [head, "-" * len(head)]
    for r in rows:
        v = {k: _json_value(r[k]) for k in ("size", "h", "n_dofs", "n_contact",
                                            "complex_count")}
        pos = r["positive"][0] if r["positive"] else None
        neg = r["negative"][0] if r["negative"] else None
        lines.append(f"{r['nu']:>7.4g} {r['element']:<7} {num(v['size'], '%.4g'):>8} "
                     f"{num(v['h'], '%.4g'):>8} {num(v['n_dofs'], '%d'):>8} "
                     f"{num(v['n_contact'], '%d'):>5} {num(pos, '%.10f'):>14} "
                     f"{num(neg, '%.8f'):>14} {num(v['complex_count'], '%d'):>7} "
                     f"{r['seconds']:>8.2f}  {r['status']}")
    if not sweep.limits:
        lines.append("h -> 0 limits: need at least three sizes (--size h1,h2,h3)")
        return "\n".join(lines)
    lines.append("")
    lines.append("h -> 0 limits (a fit f0 + C h^p to the four finest sizes, Richardson's "
                 "extrapolation with three; observed order p; - where not extrapolated)")
    head = f"{'nu':>7} {'element':<7} {'family':<8} {'limit':>14} {'error':>9} {'p':>5}  status"
    lines += [head, "-" * len(head)]
    for lim in sweep.limits:
        lines.append(f"{lim.nu:>7.4g} {lim.element:<7} {lim.family:<8} "
                     f"{num(lim.limit, '%.10f'):>14} {num(lim.error, '%.1e'):>9} "
                     f"{num(lim.order, '%.2f'):>5}  {lim.status}")
    return "\n".join(lines)


def make_grid(case: Case, *, nu: str | None = None, size: str | None = None,
              element: str | None = None, max_dofs: int | None = None,
              trust_geo: bool = False, quantity: str = "critical") -> Grid:
    """The grid of a sweep of ``case``; options left out take the case's own value.

    Every (size, element) is validated against the case here, before any work is done, with
    the checks of a solve that need no mesh (resource estimate, .geo safety).
    """
    nus, notes = parse_nu(nu) if nu is not None else ([case.material["nu"]], [])
    sizes = parse_sizes(size) if size is not None else [case.mesh["size"]]
    case, graded = sweep_case(case, sizes)
    notes = notes + ([graded] if graded else [])
    elements = parse_elements(element) if element is not None else [case.mesh["element"]]
    total = len(nus) * len(sizes) * len(elements)
    if total > MAX_POINTS:
        raise CaseError(f"{len(nus)} nu x {len(sizes)} sizes x {len(elements)} elements = "
                        f"{total} points; allowed: at most {MAX_POINTS} points per sweep",
                        key="--nu")
    for s in sizes:
        for el in elements:
            preflight(case.with_overrides(_overrides(Point(nus[0], s, el))),
                      max_dofs=max_dofs, trust_geo=trust_geo)
    if quantity not in QUANTITIES:
        raise CaseError(f"got {quantity!r}; allowed: " + ", ".join(QUANTITIES),
                        key="--quantity")
    return Grid(nus, sizes, elements, notes, quantity)
