"""Sweeps over the Poisson ratio, the mesh size, the element and (3D) the slip angle, with
h -> 0 limits and the body's coefficient over slip directions.

A sweep point is (nu, size, element[, slip angle]). Points sharing (size, element) share one
mesh and one assembly (``prepare``): only ``lam K_lam + G K_G``, the contact basis (turned
from the kept stiffness parts, :func:`critfric.solve.turned`) and the eigenproblem change with
nu and the angle. Each worker keeps a small cache of prepared systems and the scheduler
(:mod:`critfric.workers`) hands a worker all the points of a (size, element) group, split only
to balance the load. After the points of an angle sweep, a second pass locates the minimum
over directions of each (nu, size, element) (:mod:`.directions`) on new workers of the same
kind (a worker meshes each of its groups once more; in this process, ``-j 1``, the cached
mesh serves both passes).

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
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path

from ..case.schema import SWEEP_GRADING, Case, from_dict
from ..errors import CaseError
from ..files import sweepfile
from ..guards import usable_cpus
from ..meshing.from_case import preflight, singular_of
from ..meshing.solid import is_solid
from ..solve import Prepared, prepare, solve_prepared, turned
from ..stability import stability_prepared
from . import workers
from .directions import (
    MINIMUM_KEYS,
    MinimumTask,
    failed_minimum,
    minimum_key,
    minimum_tasks,
    task_minimum,
)
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
    parse_slip_angles,
)
from .report import report_sweep  # noqa: F401 -- re-exported for the command line

CACHE_SIZE = 2  # prepared systems kept per worker process
TURNED_SIZE = 1  # ... and contact bases turned to another slip angle


def sweep_case(case: Case, sizes) -> tuple[Case, str | None]:
    """The case a sweep over ``sizes`` meshes: with three sizes or more (h -> 0 limits) and
    no ``[mesh] grading``, gmsh meshes are graded at every singular point (size
    ``SWEEP_GRADING`` h there); the second value is a note saying so (None: unchanged)."""
    m, shape = case.mesh, case.geometry["shape"]
    if (len([s for s in sizes if s is not None]) < 3 or m["grading"] is not None
            or m["structured"] or shape in ("mesh", "file") or is_solid(case)):
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
    out = {"material.nu": point.nu, "mesh.size": point.size, "mesh.element": point.element}
    return out if point.slip_angle is None else {**out, "solve.slip_angle": point.slip_angle}


# ------------------------------------------------------------------------------ one point
_CACHE: OrderedDict[tuple, Prepared] = OrderedDict()
_TURNED: OrderedDict[tuple, Prepared] = OrderedDict()
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
    """The prepared mesh of ``point``'s (size, element), its contact basis turned to the
    point's slip angle (both cached: one mesh serves every nu and angle of a group)."""
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
        prep = _CACHE[key]
        if point.slip_angle is not None and prep.mesh.dim == 3:
            key += (point.slip_angle,)
            if key not in _TURNED:
                _TURNED[key] = turned(prep, case)
                while len(_TURNED) > TURNED_SIZE:
                    _TURNED.popitem(last=False)
            prep = _TURNED[key]
        _keep_only(prep)
        return prep


def _keep_only(prep: Prepared | None) -> None:
    """Free the factorizations that this process's cached meshes other than ``prep`` keep
    between points (solve_prepared's keep_analysis): one a worker, as the memory guard
    counts; None: every one (a sweep run in this process ends, its meshes stay cached)."""
    for other in list(_CACHE.values()) + list(_TURNED.values()):
        if other is not prep:
            other.plan = None


def run_point(spec: dict, point: Point | MinimumTask) -> dict:
    """Solve one point (in a worker), or locate one minimum over directions; a failure is
    returned as a row, never raised."""
    if isinstance(point, MinimumTask):
        return _run_minimum(spec, point)
    t0 = time.perf_counter()
    try:
        base = from_dict(spec["raw"], source=spec["source"], name=spec["name"],
                         text=spec["text"])
        case = base.with_overrides(_overrides(point))
        if spec.get("quantity", "critical") == "flutter":
            return _flutter_row(point, stability_prepared(_prepared(spec, case, point), case),
                                t0)
        prep = _prepared(spec, case, point)
        if point.slip_angle is not None and prep.mesh.dim != 3:
            raise CaseError("applies to 3D bodies; this mesh is 2D", file=case.source,
                            key="--slip-angle")
        result = solve_prepared(prep, case, keep_analysis=spec["reuse"])
    except Exception as exc:
        return empty_row(point, f"failed: {type(exc).__name__}: {exc}",
                         time.perf_counter() - t0)
    count = spec["count"]
    pos, neg = result.positive[:count], result.negative[:count]
    row = empty_row(point, "ok" if len(pos) or len(neg) else "no-real-eigenvalue")
    row.update(h=result.h, n_dofs=result.n_dofs, n_contact=result.n_contact,
               positive=[float(v) for v in pos], negative=[float(v) for v in neg],
               r_positive=[float(v) for v in result.r_of(pos)] if result.dim == 3 else [],
               complex_count=result.complex_count, seconds=time.perf_counter() - t0)
    return row


def _run_minimum(spec: dict, task: MinimumTask) -> dict:
    """Locate the minimum over directions of ``task`` (:mod:`.directions`): every evaluation
    one solve of the group's prepared mesh at that angle."""
    t0 = time.perf_counter()
    try:
        base = from_dict(spec["raw"], source=spec["source"], name=spec["name"],
                         text=spec["text"])
        point = Point(task.nu, task.size, task.element)
        case = base.with_overrides(_overrides(point))
        prep = _prepared(spec, case, point)

        def alpha_at(angle: float) -> tuple[float, float]:
            result = solve_prepared(prep, case.with_overrides({"solve.slip_angle": angle}),
                                    keep_analysis=spec["reuse"])
            if not len(result.positive):
                return math.inf, math.nan
            return float(result.positive[0]), float(result.r_of(result.positive[:1])[0])

        row = task_minimum(task, alpha_at)
    except Exception as exc:
        return failed_minimum(task, f"failed: {type(exc).__name__}: {exc}",
                              time.perf_counter() - t0)
    return {**row, "seconds": time.perf_counter() - t0}


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
    """A finished sweep: its file, every point (grid order), the limits and what ran now;
    for an angle sweep also the minima over directions, one per (nu, size, element)."""

    path: Path
    grid: Grid
    rows: list[dict]
    limits: list[Limit]
    computed: int
    seconds: float
    minima: list[dict] = field(default_factory=list)
    located: int = 0  # minima located now

    @property
    def failed(self) -> int:
        """Points whose solve failed (their status says why)."""
        return sum(str(r["status"]).startswith("failed") for r in self.rows)

    def summary(self) -> dict:
        """The JSON of ``critfric sweep --json``."""
        keys = ("nu", "size", "element", "h", "n_dofs", "n_contact", "positive", "negative",
                "complex_count", "status", "seconds")
        if self.grid.slip_angle is not None:
            keys = keys[:3] + ("slip_angle",) + keys[3:8] + ("r_positive",) + keys[8:]
        points = [{k: _json_value(r[k]) for k in keys} for r in self.rows]
        out = {"points": points, "limits": [lim.to_json() for lim in self.limits]}
        if self.grid.slip_angle is not None:
            out["minima"] = [{k: _json_value(m[k]) for k in MINIMUM_KEYS} for m in self.minima]
        return out

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
            for family in ("positive", "negative", "r_positive"):
                if family in row:
                    row[family] = row[family][0] if row[family] else math.nan
        return pd.DataFrame(table)

    def __repr__(self) -> str:
        ok = sum(r["status"] == "ok" for r in self.rows)
        minima = f", {len(self.minima)} minima over directions" if self.minima else ""
        return (f"Sweep({str(self.path)!r}, {len(self.rows)} points ({ok} ok, {self.computed} "
                f"computed now), {len(self.limits)} limits{minima})")


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
    """Run (or resume) a sweep into ``output``; return every point and the h -> 0 limits
    (and, over two slip directions or more, the minimum over directions of each (nu, size,
    element), located after the points: :mod:`.directions`).

    Parameters
    ----------
    jobs
        Local worker processes (default: all cores); 1 runs in this process.
    scheduler
        Address of a Dask distributed scheduler, instead of local processes.
    force
        Discard an existing ``output`` written for another case or grid.
    reuse
        Reuse meshes and assemblies across nu and angles (off only to measure it).
    on_point
        Called as ``on_point(row, done, total)`` after each point (or minimum) is written,
        and once with row None before the first (done: those already in the file).
    max_dofs, trust_geo
        The guards of :func:`critfric.solve.prepare`, for every point.
    """

    t0 = time.perf_counter()
    case = sweep_case(case, grid.size)[0]
    path = Path(output)
    client = workers.connect_dask(scheduler) if scheduler else None
    try:
        done = sweepfile.open_sweep(path, case=case, grid=grid, force=force)
        points = grid.points()
        todo = [p for p in points if p.key not in done]
        with_minima = grid.directions >= 2
        located = {minimum_key(m): m for m in sweepfile.read_sweep(path)["minima"]}
        total = len(points) + (len(grid.nu) * len(grid.size) * len(grid.element)
                               if with_minima else 0)
        finished = len(points) - len(todo) + len(located)
        if on_point is not None:
            on_point(None, finished, total)
        spec = worker_spec(case, reuse=reuse, max_dofs=max_dofs, trust_geo=trust_geo,
                           quantity=grid.quantity)
        with _stream(spec, todo, jobs, client) as stream:
            for point, row in stream:
                sweepfile.append_point(path, row)  # before anything else: never lost
                finished += 1
                if on_point is not None:
                    on_point(row, finished, total)
        stored = {sweepfile.row_key(r): r for r in sweepfile.read_sweep(path)["rows"]}
        rows = [stored[p.key] for p in points]
        tasks = minimum_tasks(rows, set(located)) if with_minima else []
        with _stream(spec, tasks, jobs, client) as stream:
            for task, found in stream:
                if "bracket_lo" not in found:  # the worker died: a point's failed row
                    found = failed_minimum(task, found["status"], found["seconds"])
                sweepfile.append_minimum(path, found)
                located[minimum_key(found)] = found
                finished += 1
                if on_point is not None:
                    value = found["positive"]
                    on_point({**found, "status": f"minimum over directions: {found['status']}",
                              "positive": [value] if math.isfinite(value) else []},
                             finished, total)
    finally:
        if client is not None:
            client.close()
        with _CACHE_LOCK:
            _keep_only(None)
    minima = sorted(located.values(), key=lambda m: (grid.element.index(m["element"])
                                                     if m["element"] in grid.element else 99,
                                                     -1.0 if m["size"] is None else -m["size"],
                                                     m["nu"]))
    limits = limits_of(rows, minima)
    sweepfile.write_limits(path, limits, grid, rows, minima)
    return Sweep(path, grid, rows, limits, len(todo), time.perf_counter() - t0, minima,
                 len(tasks))


@contextmanager
def _stream(spec: dict, items: list, jobs: int | None, client) -> Iterator:
    """(item, row) pairs as the points or minimum tasks ``items`` finish: on the Dask cluster
    of ``client``, on ``jobs`` local workers, or here (one job); the workers stop when the
    block ends, also on an exception or Ctrl-C."""
    jobs = max(1, min(jobs or usable_cpus(), len(items)))
    if not items:
        stream = iter(())
    elif client is not None:
        stream = workers.run_dask(client, run_point, spec, items)
    elif jobs == 1:
        stream = _in_process(spec, items)
    else:
        stream = workers.run_local(jobs, run_point, spec, items)
    try:
        yield stream
    finally:
        if hasattr(stream, "close"):
            stream.close()


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


def make_grid(case: Case, *, nu: str | None = None, size: str | None = None,
              element: str | None = None, max_dofs: int | None = None,
              trust_geo: bool = False, quantity: str = "critical",
              slip_angle: str | None = None) -> Grid:
    """The grid of a sweep of ``case``; options left out take the case's own value
    (``slip_angle``: None sweeps no angle, the case's own ``[solve] slip_angle`` is used).

    Every (size, element) is validated against the case here, before any work is done, with
    the checks of a solve that need no mesh (resource estimate, .geo safety).
    """
    nus, notes = parse_nu(nu) if nu is not None else ([case.material["nu"]], [])
    sizes = parse_sizes(size) if size is not None else [case.mesh["size"]]
    case, graded = sweep_case(case, sizes)
    notes = notes + ([graded] if graded else [])
    elements = parse_elements(element) if element is not None else [case.mesh["element"]]
    if quantity not in QUANTITIES:
        raise CaseError(f"got {quantity!r}; allowed: " + ", ".join(QUANTITIES),
                        key="--quantity")
    angles = None
    if slip_angle is not None:
        angles, more = parse_slip_angles(slip_angle)
        notes += more + _check_angles(case, quantity, angles)
    total = len(nus) * len(sizes) * len(elements) * len(angles or [None])
    if total > MAX_POINTS:
        raise CaseError(f"{len(nus)} nu x {len(sizes)} sizes x {len(elements)} elements"
                        + (f" x {len(angles)} slip angles" if angles else "") + f" = {total} "
                        f"points; allowed: at most {MAX_POINTS} points per sweep", key="--nu")
    for s in sizes:
        for el in elements:
            preflight(case.with_overrides(_overrides(Point(nus[0], s, el))),
                      max_dofs=max_dofs, trust_geo=trust_geo)
    return Grid(nus, sizes, elements, notes, quantity, angles)


def _check_angles(case: Case, quantity: str, angles: list[float]) -> list[str]:
    """Refuse a slip-angle axis that the case cannot take; the notes about it."""
    shape = case.geometry["shape"]
    if quantity != "critical":
        raise CaseError(f"applies to --quantity critical, not {quantity}", key="--slip-angle")
    if not is_solid(case) and shape != "file":  # a file's dimension is known once read
        raise CaseError(f"applies to 3D bodies (box, prism, a 3D mesh or mesh file); this "
                        f"case's body is 2D (geometry.shape = {shape!r}; the 2D slip sign is "
                        "[solve] gamma)", file=case.source, key="--slip-angle")
    if any(r["slip_angle"] is not None for r in case.contact["rules"] or []):
        raise CaseError("sets the slip angle of some contact nodes; allowed with --slip-angle: "
                        "rules without slip_angle (the swept angle turns every slipping node, "
                        "which the minimum over directions and alpha(angle + 180) = "
                        "-alpha(angle) need)", file=case.source, key="contact.rules")
    for angle in (min(angles), max(angles)):  # what [solve] slip_angle accepts
        try:
            case.with_overrides({"solve.slip_angle": angle})
        except CaseError as exc:
            raise CaseError(f"got {angle:g}: {exc.detail}", key="--slip-angle") from None
    if Grid([], [], [], slip_angle=angles).directions < 2:
        return [("one slip direction (and its reverse) only: no minimum over directions is "
                 "located; give two angles or more that differ modulo 180")]
    return []
