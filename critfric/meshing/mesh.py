"""Meshes built by gmsh from a polygon, and meshes given inline in a case file."""

from __future__ import annotations

import dataclasses
import math
from contextlib import contextmanager

import numpy as np

from ..errors import CaseError, CritfricError, SolverError
from ..fem.arrays import distinct, unused_nodes
from ..fem.elements import get_element
from ..fem.mesh import MAX_GROUP_NAME, Mesh, group_name_ok, orient
from .cells3d import index_array as _index_array
from .geometry import Polygon, positive_number, validate
from .overlap import check_tiling_2d
from .refine import renumber, second_order, split
from .singular import singular_points, split_at_junctions

#: unstructured meshes finer than this fraction of the body's extent are nested: gmsh meshes
#: the body once at the coarse size h 2^n in [NEST_FRACTION, 2 NEST_FRACTION) x the extent,
#: and n uniform splits (:func:`.refine.split`) give size h. The meshes of h, h/2, h/4, ...
#: are then refinements of one mesh, their coefficients a smooth function of h: inclined body,
#: graded, limits from 0.1 ... 0.0125 within 6.1e-7 (P1), 2.1e-6 (Q1), 2.3e-7 (P2), 9.2e-8
#: (Q2) of the reference, against 6.7e-6, 1.3e-5, 3.2e-7, 1.7e-7 with one gmsh mesh per size
#: (its mesh noise). 1/8 and 1/16 nest more sizes, no more accurately, and round the coarse
#: mesh's edge counts more (up to 1/8 off the size asked for, against 1/32 here). Splitting is
#: also ~10x faster than gmsh at the same size.
NEST_FRACTION = 1 / 32
MIN_QUALITY = 1e-6  # inline and file meshes: area / longest edge^2 of every cell at least this


def check_group_names(names, path) -> None:
    """Refuse a physical group name of a gmsh file that cannot name a boundary group."""
    for name in names:
        if not group_name_ok(name):
            raise CaseError(f"physical group name {str(name)[:MAX_GROUP_NAME]!r} is not "
                            f"printable text; allowed: names of 1 to {MAX_GROUP_NAME} "
                            "printable characters", file=str(path), key="geometry.file")


# ---------------------------------------------------------------------------------------------
# gmsh


@contextmanager
def _gmsh_session():
    """A silent gmsh session with a fresh model; always finalized (or the model removed when
    gmsh was already initialized by the caller)."""
    import gmsh  # imported lazily: only meshing needs the gmsh library
    from threadpoolctl import ThreadpoolController

    # gmsh sets the OpenMP thread count of the process to General.NumThreads (HXT does, on
    # MKL's OpenMP runtime too): put every runtime's count back after the session, or the
    # sparse factorization that follows runs on one thread
    openmp = ThreadpoolController().select(user_api="openmp")
    counts = [lib.num_threads for lib in openmp.lib_controllers]
    owner = not gmsh.isInitialized()
    if owner:
        try:  # interruptible=False: leave Python's SIGINT handler alone
            gmsh.initialize(argv=["critfric"], readConfigFiles=False, interruptible=False)
        except TypeError:  # older gmsh without the keyword
            gmsh.initialize(argv=["critfric"], readConfigFiles=False)
        _python_signals()
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.option.setNumber("General.Verbosity", 1)
        # threads gain < 10% on a single surface and make meshes non-reproducible
        gmsh.option.setNumber("General.NumThreads", 1)
        gmsh.model.add("critfric")
        yield
    finally:
        if owner:
            gmsh.finalize()
            _python_signals()
        else:
            gmsh.model.remove()
        for lib, count in zip(openmp.lib_controllers, counts):
            lib.set_num_threads(count)


def _python_signals() -> None:
    """Python's own SIGINT and SIGTERM handlers put back at the C level: gmsh installs
    handlers of its own (SIGTERM then killed the process outright, with no message, the
    output lock left behind), while ``signal.getsignal`` still names Python's."""
    import signal
    import threading

    if threading.current_thread() is threading.main_thread():
        for number in (signal.SIGINT, signal.SIGTERM):
            handler = signal.getsignal(number)
            if handler is not None:
                signal.signal(number, handler)


def build_mesh(poly: Polygon, *, size: float, element: str, structured: bool = False,
               grading: float | None = None, contact=None, dirichlet=(),
               junctions=()) -> Mesh:
    """Mesh ``poly`` with gmsh (built-in kernel); one edge group per edge name.

    size      : target element size (edge length).
    element   : "P1", "P2" (straight 6-node triangles), "Q1", "Q2" (9-node quads).
    structured: transfinite mesh of a 4-vertex polygon, ceil(length / size) subdivisions per
                edge (the larger count of each pair of opposite edges).
    grading   : g in (0, 1]: size g*size at every singular point (:mod:`.singular`: the ends
                of the straight run of the ``contact`` edges, the state ``junctions`` on it,
                corners where the condition changes, re-entrant corners), growing linearly to
                ``size`` at half the run's length from them; junctions become mesh nodes.
    contact   : edge name or names of the contact boundary (needed by ``grading``).
    dirichlet : Dirichlet edge names (their corners with other conditions are singular).
    junctions : arc lengths along Gamma_C where the contact state changes
                (:func:`.singular.state_junctions`).
    """
    import gmsh

    get_element(element)
    validate(poly)
    h = positive_number(size, "mesh.size")
    if structured and poly.n_vertices != 4:
        raise CaseError(f"a structured mesh needs a 4-vertex polygon, got {poly.n_vertices} "
                        "vertices", key="mesh.structured")
    ends = None
    if grading is not None:
        g = float(grading)
        if not (0 < g <= 1):
            raise CaseError(f"must be in (0, 1], got {grading!r}", key="mesh.grading")
        if structured:
            raise CaseError("grading is not available for structured meshes", key="mesh.grading")
        if not contact:
            raise CaseError("grading needs the contact edges", key="mesh.grading")
        ends = singular_points(poly, contact, dirichlet, junctions)
        run_length = ends.run_length
    n_refine = 0 if structured else _refinements(poly, h)
    linear = "P1" if get_element(element).reference == "triangle" else "Q1"
    # gmsh meshes the body scaled to unit extent: its tolerances are absolute, so the mesh
    # (and every coefficient) would otherwise depend on the length unit
    # (canonical: rounded to 2^-40 and 12 digits, so that one body in two units gives the
    # same numbers to gmsh, not numbers one ulp apart that its smoothing would amplify)
    unit = float(np.ptp(poly.vertices, axis=0).max())
    if ends is not None:  # junctions inside an edge become vertices (mesh nodes)
        poly, tags = split_at_junctions(poly, ends)
    poly = Polygon(np.round(poly.vertices / unit * 2.0**40) / 2.0**40, poly.edge_names)
    h, h0 = _canonical(h / unit), _canonical(h * 2**n_refine / unit)
    if ends is not None:
        run_length = _canonical(run_length / unit)
    with _gmsh_session():
        try:
            _build_geometry(poly, h0)
            if structured:
                _set_transfinite(poly, h, element)
            else:
                quads = get_element(element).reference == "quad"
                gmsh.option.setNumber("Mesh.Algorithm", 8 if quads else 6)
                gmsh.option.setNumber("Mesh.MeshSizeFromPoints", 0)
                gmsh.option.setNumber("Mesh.MeshSizeFromCurvature", 0)
                gmsh.option.setNumber("Mesh.MeshSizeMax", h0)
                gmsh.option.setNumber("Mesh.MeshSizeMin", h0 if ends is None else g * h0)
                if quads:
                    gmsh.option.setNumber("Mesh.RecombinationAlgorithm", 3)  # blossom full-quad
                    gmsh.model.mesh.setRecombine(2, 1)
                if ends is not None:
                    _set_grading(tags + 1, g * h0, h0, 0.5 * run_length)
            gmsh.model.mesh.generate(2)
            mesh = _extract(linear)
        except CritfricError:
            raise
        except Exception as exc:  # gmsh reports failures as bare Exceptions
            raise SolverError(f"gmsh failed to mesh the polygon: {exc}; try another mesh size "
                              "or element") from exc
    # uniform refinement and P2/Q2 nodes by index arithmetic (what gmsh's refine() and
    # setOrder(2) with straight edges give, ~10x faster), in gmsh's unit-extent frame
    for _ in range(n_refine):
        mesh = split(mesh)
    if linear != element:
        mesh = second_order(mesh, element)
    if n_refine:  # a large mesh: neighbours numbered near each other
        mesh = renumber(mesh)
    return dataclasses.replace(mesh, points=mesh.points * unit)


def _canonical(x: float) -> float:
    """``x`` rounded to 12 significant digits."""
    return float(f"{x:.12g}")


def _refinements(poly: Polygon, h: float) -> int:
    """Number of uniform refinements: the base mesh at the canonical coarse size
    (``NEST_FRACTION``), but not coarser than the shortest edge."""
    seg = poly.segments
    shortest = float(np.min(np.linalg.norm(seg[:, 1] - seg[:, 0], axis=1)))
    coarse = NEST_FRACTION * float(np.ptp(poly.vertices, axis=0).max())
    # (a relative 1e-9 slack: a size given as coarse / 2^n is split n times, not n + 1)
    by_size = max(0, math.ceil(math.log2(coarse / h) - 1e-9))
    by_geometry = max(0, math.floor(math.log2(shortest / h) + 1e-9))
    return min(by_size, by_geometry)


def _build_geometry(poly: Polygon, h: float) -> None:
    """Points, lines, curve loop, plane surface (tag 1); physical groups per edge name."""
    import gmsh

    geo = gmsh.model.geo
    pts = [geo.addPoint(float(x), float(y), 0.0, h) for x, y in poly.vertices]
    nv = len(pts)
    lines = [geo.addLine(pts[i], pts[(i + 1) % nv]) for i in range(nv)]
    surface = geo.addPlaneSurface([geo.addCurveLoop(lines)])
    geo.synchronize()
    for name in poly.group_names:
        gmsh.model.addPhysicalGroup(1, [lines[i] for i in poly.edge_indices(name)], name=name)
    gmsh.model.addPhysicalGroup(2, [surface], name="domain")


def _set_transfinite(poly: Polygon, h: float, element: str) -> None:
    import gmsh

    seg = poly.segments
    n = np.ceil(np.linalg.norm(seg[:, 1] - seg[:, 0], axis=1) / h - 1e-9).astype(int)
    n = np.maximum(n, np.roll(n, 2))  # opposite edges need the same count
    for curve, count in enumerate(n, start=1):
        gmsh.model.mesh.setTransfiniteCurve(curve, int(count) + 1)
    # "Alternate" diagonals: no preferred direction (one-way diagonals bias the eigenvalues)
    gmsh.model.mesh.setTransfiniteSurface(1, "Alternate", cornerTags=[1, 2, 3, 4])
    if element in ("Q1", "Q2"):
        gmsh.model.mesh.setRecombine(2, 1)


def _set_grading(point_tags, h_min: float, h_max: float, dist_max: float) -> None:
    import gmsh

    field = gmsh.model.mesh.field
    dist = field.add("Distance")
    field.setNumbers(dist, "PointsList", [int(t) for t in point_tags])
    thr = field.add("Threshold")
    field.setNumber(thr, "InField", dist)
    field.setNumber(thr, "SizeMin", h_min)
    field.setNumber(thr, "SizeMax", h_max)
    field.setNumber(thr, "DistMin", 0.0)
    field.setNumber(thr, "DistMax", dist_max)
    field.setAsBackgroundMesh(thr)
    gmsh.option.setNumber("Mesh.MeshSizeExtendFromBoundary", 0)


def _extract(element: str) -> Mesh:
    """Current gmsh mesh as a Mesh: compact numbering, unused nodes dropped, cells ccw."""
    import gmsh

    spec = get_element(element)
    cell_type = spec.gmsh_cell
    types = set(int(t) for t in gmsh.model.mesh.getElementTypes(2))
    if types != {cell_type}:
        raise SolverError(f"gmsh produced surface element types {sorted(types)}, expected only "
                          f"{cell_type} for {element}; try a different mesh size or P1/P2")
    _, cell_tags = gmsh.model.mesh.getElementsByType(cell_type)
    cell_tags = np.asarray(cell_tags, dtype=np.int64).reshape(-1, spec.n_local)
    node_tags, coords, _ = gmsh.model.mesh.getNodes()
    node_tags = np.asarray(node_tags, dtype=np.int64)
    position = np.empty(node_tags.max() + 1, dtype=np.int64)
    position[node_tags] = np.arange(len(node_tags))
    used = distinct(cell_tags)
    points = np.asarray(coords, dtype=np.float64).reshape(-1, 3)[position[used], :2]
    lookup = np.full(node_tags.max() + 1, -1, dtype=np.int64)
    lookup[used] = np.arange(len(used))
    cells, area = orient(points, lookup[cell_tags], element)
    if np.any(np.abs(area) <= 1e-12 * np.max(np.abs(area))):
        raise SolverError("gmsh produced degenerate cells; try a different mesh size")

    line_type = spec.gmsh_facet
    edges = {}
    for dim, group in gmsh.model.getPhysicalGroups(1):
        parts = [np.asarray(gmsh.model.mesh.getElementsByType(line_type, int(curve))[1],
                            dtype=np.int64)
                 for curve in gmsh.model.getEntitiesForPhysicalGroup(dim, group)]
        facets = lookup[np.concatenate(parts).reshape(-1, spec.facet_nodes)]
        if np.any(facets < 0):
            raise SolverError("gmsh boundary nodes are not nodes of any cell")
        edges[gmsh.model.getPhysicalName(dim, group)] = facets
    return Mesh(points, cells, element, edges)


# ---------------------------------------------------------------------------------------------
# inline meshes (given in a case file)


def inline_mesh(nodes, cells, edges: dict, element: str) -> Mesh:
    """A mesh given explicitly: vertex ``nodes`` (n, 2), ``cells`` by their vertices only
    (triangles for P1/P2, quads for Q1/Q2, either orientation) and named boundary ``edges``
    {name: [[a, b], ...]}. P2/Q2 edge midpoints (and Q2 centres) are appended after the given
    nodes. Boundary facets are oriented like their cell (domain on the left)."""
    spec = get_element(element)
    points = np.asarray(nodes, dtype=np.float64)
    if points.ndim != 2 or points.shape[1] != 2 or len(points) < 3:
        raise CaseError(f"must be at least 3 [x, y] pairs, got shape {points.shape}",
                        key="geometry.nodes")
    if not np.all(np.isfinite(points)):
        raise CaseError("node coordinates must be finite numbers", key="geometry.nodes")
    n, nv = len(points), spec.n_vertices
    ckey = "geometry.triangles" if nv == 3 else "geometry.quads"
    cells = _index_array(cells, nv, n, ckey)
    if len(cells) == 0:
        raise CaseError("needs at least one cell", key=ckey)
    if np.any(np.sort(cells, axis=1)[:, 1:] == np.sort(cells, axis=1)[:, :-1]):
        raise CaseError("a cell repeats a node", key=ckey)
    scale = float(np.ptp(points, axis=0).max())
    cells, area = orient(points, cells, "P1" if nv == 3 else "Q1")  # vertices only so far
    bad = np.abs(area) <= 1e-12 * scale**2
    if nv == 4:  # a quad needs a positive Jacobian at every corner: strictly convex
        v = points[cells]
        d = np.roll(v, -1, axis=1) - v
        bad |= np.any(d[..., 0] * np.roll(d, -1, axis=1)[..., 1]
                      - d[..., 1] * np.roll(d, -1, axis=1)[..., 0] <= 1e-12 * scale**2, axis=1)
    if bad.any():
        raise CaseError(f"cell {int(np.argmax(bad))} is degenerate"
                        + (" or not convex" if nv == 4 else ""), key=ckey)
    v = points[cells]
    longest = np.max(np.sum((np.roll(v, -1, axis=1) - v) ** 2, axis=-1), axis=1)
    quality = np.abs(area) / longest  # 0.43 for an equilateral triangle, 1 for a square
    if quality.min() < MIN_QUALITY:
        i = int(np.argmin(quality))
        raise CaseError(f"cell {i} is a sliver (area / longest edge^2 = {quality[i]:.2g}, nodes "
                        f"{cells[i].tolist()}): its stiffness would be singular to rounding; "
                        f"allowed: cells with area / longest edge^2 >= {MIN_QUALITY:g}", key=ckey)
    unused = unused_nodes(cells, n)
    if len(unused):
        raise CaseError(f"node {int(unused[0])} belongs to no cell", key="geometry.nodes")

    local = spec.edges[:, :2]  # (nv, 2) ccw edges
    directed = cells[:, local].reshape(-1, 2)  # (n_cells * nv, 2)
    keys = directed.min(axis=1) * n + directed.max(axis=1)
    ukeys, first, inverse, count = np.unique(keys, return_index=True, return_inverse=True,
                                             return_counts=True)
    check_tiling_2d(points, cells, ckey)  # repeated, folded or overlapping cells
    if np.any(count > 2):
        raise CaseError("an edge is shared by more than two cells", key=ckey)
    order2 = spec.order == 2
    if order2:
        mid = n + np.arange(len(ukeys))
        ends = directed[first]
        new_points = [points, 0.5 * (points[ends[:, 0]] + points[ends[:, 1]])]
        new_cells = [cells, mid[inverse].reshape(len(cells), nv)]
        if nv == 4:
            new_points.append(points[cells].mean(axis=1))
            new_cells.append(n + len(ukeys) + np.arange(len(cells))[:, None])
        points, cells = np.concatenate(new_points), np.concatenate(new_cells, axis=1)

    groups = {}
    for name, pairs in edges.items():
        key = f"geometry.edges.{name}"
        pairs = _index_array(pairs, 2, n, key)
        if len(pairs) == 0:
            raise CaseError("needs at least one [a, b] pair", key=key)
        wanted = pairs.min(axis=1) * n + pairs.max(axis=1)
        at = np.minimum(np.searchsorted(ukeys, wanted), len(ukeys) - 1)
        missing = ukeys[at] != wanted
        interior = ~missing & (count[at] != 1)
        if missing.any() or interior.any():
            i = int(np.argmax(missing | interior))
            what = "is not an edge of any cell" if missing[i] else "is an interior edge"
            raise CaseError(f"[{pairs[i, 0]}, {pairs[i, 1]}] {what}; allowed: boundary edges "
                            "of the cells", key=key)
        facets = directed[first[at]]
        groups[str(name)] = np.column_stack([facets, mid[at]]) if order2 else facets
    return Mesh(points, cells, element, groups)
