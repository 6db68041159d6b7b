"""3D bodies meshed by gmsh: boxes and prisms (polygons extruded along z), the estimate of
their node count before meshing, and the meshes of 3D cases.

Face names. A box [ox, ox + Lx] x [oy, oy + Ly] x [oz, oz + Lz] (``[geometry] origin``,
``size``) has the faces "x0" (x = ox), "x1" (x = ox + Lx), "y0", "y1", "z0", "z1": the axis
the face is normal to and the end of the box it lies at. These names say where a face is
without a convention of which way is up, and they are the names of a prism's end faces too.
A prism (``vertices``, ``edge_names``, ``depth``) has over each polygon edge i the side face
``edge_names[i]`` (default "e{i}", as for ``shape = "polygon"``; edges that share a name form
one group), and the end faces "z0" (z = 0) and "z1" (z = depth). A box is the prism of its
base rectangle, whose edges are y0, x1, y1, x0, lifted to z = oz.

Meshes. P1/P2: unstructured tetrahedra (gmsh's Delaunay mesher at size h; P2 by
``setOrder(2)`` on straight edges). Q1/Q2: hexahedra in layers: the base polygon meshed in
quadrangles (a box: transfinite, ceil(L / h) subdivisions per side; otherwise blossom
full-quad recombination), extruded in ceil(depth / h) recombined layers; Q2 by
``setOrder(2)`` with complete 27-node hexahedra. gmsh meshes the body translated and scaled to
unit extent (its tolerances are absolute), as for 2D bodies.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from ..case.checks import MAX_PRISM_VERTICES, PRISM_LIMIT
from ..case.geometry3d import END_FACES, SHAPES_3D
from ..case.geometry3d import is_solid as _solid_geometry
from ..errors import CaseError, CritfricError, SolverError
from ..fem.mesh import Mesh, orient
from .cells3d import facets, inline_solid, locate_faces, solid
from .geometry import Polygon, polygon, positive_number, validate
from .mesh import MIN_QUALITY, _canonical, _gmsh_session

BOX_SIDES = ("y0", "x1", "y1", "x0")  # the base rectangle's edges, counterclockwise
#: nodes per unit volume, area and edge length at mesh size h: vertices ~ a V / h^3 + b S /
#: h^2 + c E / h + corners, times order^3 for P2/Q2 (a P2 tetrahedral mesh has ~6.8 edges
#: per vertex, a Q2 hexahedral one (2n + 1)^3 nodes for n^3 cells, both below 8).
#: Hexahedra: exact for a box of n^3 cubes ((n + 1)^3 = V/h^3 + S/(2h^2) + E/(4h) + 1).
#: Tetrahedra: gmsh 4.15 (HXT, MeshSizeMin = Max = h) on boxes 1x1x1, 2x1x0.5, 1x1x0.1,
#: 1x0.3x0.3 at h = 0.2 ... 0.025: a least-squares fit gave a = 0.59, b = 0.89, c ~ 0; these
#: coefficients give 0.8-1.1 x the real counts, 1.0-1.1 x once the mesh is large (below only
#: for slabs thinner than h, where counts are small anyway).
DENSITY = {4: (0.6, 0.95, 0.5), 8: (1.0, 0.5, 0.25)}
FACET_AREA = {3: math.sqrt(3) / 2, 4: 1.0}  # a boundary facet's area / h^2
TET_ALGORITHM = 10  # gmsh's Mesh.Algorithm3D for tetrahedra: HXT
#: Features shorter than the mesh size (an edge of the base, the gap between a vertex and
#: another edge, the depth) can make gmsh slow out of all proportion to the mesh: a base of
#: 100 edges of h/10 took 16 s for 4.5 k nodes, a base of 100 edges of h/1000 87 s for 2 k
#: nodes (gmsh 4.15), against 35-45 us a node without them. Such a body is meshed in the
#: limited child of :mod:`.sandbox`, given CHILD_SECONDS of wall time (start-up included)
#: plus CHILD_SECONDS_PER_NODE for each node of the estimate.
SHORT_FEATURE = 1.0  # in mesh sizes
CHILD_SECONDS = 6.0
CHILD_SECONDS_PER_NODE = 1e-4
ENTRY = "critfric.meshing.solid:child_solid"


@dataclass(frozen=True)
class SolidFootprint:
    """What the node count of a 3D mesh depends on: volume, boundary area, total length of
    the body's edges, corner count (the 3D counterpart of :class:`critfric.guards.Footprint`,
    with the same methods)."""

    volume: float
    area: float
    edge_length: float
    n_vertices: int

    def _coefficients(self, element: str) -> np.ndarray:
        """Coefficients of the node count as a cubic in 1/h, highest power first."""
        spec = solid(element)
        a, b, c = DENSITY[spec.n_vertices]
        return spec.order**3 * np.array([a * self.volume, b * self.area,
                                          c * self.edge_length, float(self.n_vertices)])

    def nodes(self, h: float, element: str) -> float:
        """Estimated node count at mesh size ``h`` (a float: may be huge or inf)."""
        with np.errstate(over="ignore", divide="ignore", invalid="ignore"):
            nodes = np.polyval(self._coefficients(element), np.float64(1.0) / np.float64(h))
        return float(nodes) if np.isfinite(nodes) else math.inf

    def dofs(self, h: float, element: str) -> float:
        """Estimated DOF count at mesh size ``h``: three per node."""
        return 3.0 * self.nodes(h, element)

    def finest_size(self, max_dofs: float, element: str) -> float:
        """The smallest h with ``dofs(h) <= max_dofs`` (inf if even one cell is too many)."""
        coef = self._coefficients(element)
        if 3.0 * coef[-1] >= max_dofs:
            return math.inf
        lo, hi = 0.0, 1.0  # in x = 1/h, where the count grows
        while 3.0 * np.polyval(coef, hi) <= max_dofs and hi < 1e30:
            lo, hi = hi, 2.0 * hi
        for _ in range(100):
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if 3.0 * np.polyval(coef, mid) <= max_dofs else (lo, mid)
        return 1.0 / lo if lo > 0 else math.inf


def prism_footprint(poly: Polygon, depth: float) -> SolidFootprint:
    """The footprint of ``poly`` extruded by ``depth``."""
    seg = poly.segments
    perimeter = float(np.linalg.norm(seg[:, 1] - seg[:, 0], axis=1).sum())
    area = abs(poly.area)
    return SolidFootprint(area * depth, 2 * area + perimeter * depth,
                          2 * perimeter + poly.n_vertices * depth, 2 * poly.n_vertices)


def smallest_feature(poly: Polygon, depth: float) -> float:
    """The shortest length a mesh of the prism must resolve: its depth, an edge of the base,
    or the gap between a vertex and an edge not its own (two edges that do not meet are
    nearest at an end of one of them)."""
    a, b = poly.segments[:, 0], poly.segments[:, 1]
    d = b - a
    length2 = np.einsum("ij,ij->i", d, d)
    v = poly.vertices[:, None, :]  # (vertex, edge)
    t = np.clip(np.einsum("vej,ej->ve", v - a, d) / length2, 0.0, 1.0)
    gap = np.linalg.norm(v - (a + t[..., None] * d), axis=2)
    i = np.arange(poly.n_vertices)
    gap[(i[:, None] == i) | (i[:, None] == np.roll(i, -1))] = np.inf  # its own two edges
    return float(min(depth, np.sqrt(length2.min()), gap.min()))


def face_sizes(poly: Polygon, depth: float) -> dict[str, tuple[float, float]]:
    """Area and perimeter of each named face of the prism of ``poly``."""
    seg = poly.segments
    length = np.linalg.norm(seg[:, 1] - seg[:, 0], axis=1)
    out = {}
    for name in poly.group_names:
        total = float(length[poly.edge_indices(name)].sum())
        out[name] = (total * depth, 2 * (total + depth))
    ends = (abs(poly.area), float(length.sum()))
    return {**out, END_FACES[0]: ends, END_FACES[1]: ends}


# ------------------------------------------------------------------------------ shapes
def box_polygon(size, origin) -> tuple[Polygon, float, float]:
    """The base rectangle of a box, its bottom z and its height."""
    lx, ly, lz = (positive_number(s, "geometry.size") for s in size)
    ox, oy, oz = (float(o) for o in origin)
    vertices = np.array([[ox, oy], [ox + lx, oy], [ox + lx, oy + ly], [ox, oy + ly]])
    return Polygon(vertices, BOX_SIDES), oz, lz


def prism_polygon(vertices, edge_names=None) -> Polygon:
    """The validated base polygon of a prism; its edge names must differ from the end faces'."""
    poly = polygon(vertices, edge_names)
    if poly.n_vertices > MAX_PRISM_VERTICES:
        raise CaseError(f"got {poly.n_vertices} vertices; allowed: {PRISM_LIMIT}",
                        key="geometry.vertices")
    clash = sorted(set(poly.edge_names) & set(END_FACES))
    if clash:
        raise CaseError(f"edge name {clash[0]!r} is the name of a prism end face; allowed: "
                        "names other than " + ", ".join(END_FACES), key="geometry.edge_names")
    return poly


def build_solid(poly: Polygon, *, depth: float, element: str, size: float, z0: float = 0.0,
                structured: bool = False) -> Mesh:
    """Mesh the prism ``poly`` x [z0, z0 + depth] with gmsh (built-in kernel); one face group
    per edge name and the end faces "z0", "z1" (see the module's docstring).

    element   : "P1", "P2" (tetrahedra), "Q1", "Q2" (hexahedra).
    structured: hexahedra only, a 4-vertex base: a transfinite base, ceil(length / size)
                subdivisions per edge (the larger count of each pair of opposite edges).
    """
    import gmsh

    spec = solid(element)
    validate(poly)
    h = positive_number(size, "mesh.size")
    depth = positive_number(depth, "geometry.depth")
    hexes = spec.n_vertices == 8
    if structured and (poly.n_vertices != 4 or not hexes):
        raise CaseError("a structured 3D mesh needs hexahedra (Q1, Q2) on a 4-vertex base",
                        key="mesh.structured")
    shift = np.append(poly.vertices.min(axis=0), z0)
    unit = float(max(np.ptp(poly.vertices, axis=0).max(), depth))
    base = Polygon(np.round((poly.vertices - shift[:2]) / unit * 2.0**40) / 2.0**40,
                   poly.edge_names)
    h0, d0 = _canonical(h / unit), _canonical(depth / unit)
    with _gmsh_session():
        try:
            groups = _build_prism(base, d0, h0, hexes, structured)
            gmsh.model.mesh.generate(3)
            if spec.order == 2:
                gmsh.option.setNumber("Mesh.SecondOrderIncomplete", 0)  # 27-node hexahedra
                gmsh.option.setNumber("Mesh.SecondOrderLinear", 1)  # straight edges
                gmsh.model.mesh.setOrder(2)
            mesh = _extract(spec, groups)
        except CritfricError:
            raise
        except Exception as exc:  # gmsh reports failures as bare Exceptions
            raise SolverError(f"gmsh failed to mesh the {'box' if structured else 'prism'}: "
                              f"{exc}; try another mesh size or element") from exc
    return dataclasses.replace(mesh, points=mesh.points * unit + shift)


def _build_prism(poly: Polygon, depth: float, h: float, hexes: bool,
                 structured: bool) -> dict[str, list[int]]:
    """The extruded geometry and its mesh settings; the surfaces of each face name."""
    import gmsh

    geo = gmsh.model.geo
    pts = [geo.addPoint(float(x), float(y), 0.0, h) for x, y in poly.vertices]
    nv = len(pts)
    lines = [geo.addLine(pts[i], pts[(i + 1) % nv]) for i in range(nv)]
    surface = geo.addPlaneSurface([geo.addCurveLoop(lines)])
    layers = max(1, math.ceil(depth / h - 1e-9))
    out = geo.extrude([(2, surface)], 0.0, 0.0, depth, numElements=[layers] if hexes else [],
                      recombine=hexes)
    geo.synchronize()
    top = out[0][1]
    sides = {}  # base line -> the side surface above it
    for dim, tag in out[2:]:
        bounding = {abs(t) for _, t in gmsh.model.getBoundary([(dim, tag)], oriented=False)}
        sides[next(i for i, line in enumerate(lines) if line in bounding)] = tag
    if hexes:
        gmsh.model.mesh.setRecombine(2, surface)
        if structured:
            seg = poly.segments
            n = np.ceil(np.linalg.norm(seg[:, 1] - seg[:, 0], axis=1) / h - 1e-9).astype(int)
            n = np.maximum(n, np.roll(n, 2))  # opposite edges need the same count
            for line, count in zip(lines, n):
                gmsh.model.mesh.setTransfiniteCurve(line, int(count) + 1)
            gmsh.model.mesh.setTransfiniteSurface(surface, cornerTags=pts)
        else:
            gmsh.option.setNumber("Mesh.Algorithm", 8)
            gmsh.option.setNumber("Mesh.RecombinationAlgorithm", 3)  # blossom full-quad
    else:  # HXT: 12x faster than gmsh's default Delaunay at 90 k nodes, a better worst cell
        gmsh.option.setNumber("Mesh.Algorithm3D", TET_ALGORITHM)
    gmsh.option.setNumber("Mesh.MeshSizeFromPoints", 0)
    gmsh.option.setNumber("Mesh.MeshSizeFromCurvature", 0)
    gmsh.option.setNumber("Mesh.MeshSizeMax", h)
    gmsh.option.setNumber("Mesh.MeshSizeMin", h)
    groups = {name: [sides[i] for i in poly.edge_indices(name)] for name in poly.group_names}
    return {**groups, END_FACES[0]: [surface], END_FACES[1]: [top]}


def _extract(spec, groups: dict[str, list[int]]) -> Mesh:
    """The current gmsh mesh as a Mesh: compact numbering, positive cells, and the boundary
    facets of the surfaces of each group, oriented out of the body."""
    import gmsh

    types = {int(t) for t in gmsh.model.mesh.getElementTypes(3)}
    if types != {spec.gmsh_cell}:
        raise SolverError(f"gmsh produced volume element types {sorted(types)}, expected only "
                          f"{spec.gmsh_cell} for {spec.name}; try another mesh size")
    _, tags = gmsh.model.mesh.getElementsByType(spec.gmsh_cell)
    tags = np.asarray(tags, dtype=np.int64).reshape(-1, spec.n_local)
    node_tags, coords, _ = gmsh.model.mesh.getNodes()
    node_tags = np.asarray(node_tags, dtype=np.int64)
    position = np.empty(node_tags.max() + 1, dtype=np.int64)
    position[node_tags] = np.arange(len(node_tags))
    used = np.unique(tags)
    points = np.asarray(coords, dtype=np.float64).reshape(-1, 3)[position[used]]
    lookup = np.full(node_tags.max() + 1, -1, dtype=np.int64)
    lookup[used] = np.arange(len(used))
    cells, volume = orient(points, lookup[tags], spec.name)
    if np.any(np.abs(volume) <= 1e-12 * np.max(np.abs(volume))):
        raise SolverError("gmsh produced degenerate cells; try a different mesh size")
    rows = {name: np.concatenate([
        np.asarray(gmsh.model.mesh.getElementsByType(spec.gmsh_facet, s)[1],
                   dtype=np.int64).reshape(-1, spec.facet_nodes)[:, :spec.facet_vertices]
        for s in surfaces]) for name, surfaces in groups.items()}
    every = np.concatenate(list(rows.values()))
    cell, local, boundary = locate_faces(cells, spec, lookup[every])  # the cell faces ranked once
    ok = (cell >= 0) & boundary & (lookup[every] >= 0).all(axis=1)
    ends = np.cumsum([len(r) for r in rows.values()])[:-1]
    faces = {}
    for name, c, loc, good in zip(rows, np.split(cell, ends), np.split(local, ends),
                                  np.split(ok, ends)):
        if not good.all():
            raise SolverError(f"gmsh's faces of {name!r} are not boundary faces of its cells")
        faces[name] = facets(cells, spec, c, loc)
    return Mesh(points, cells, spec.name, faces=faces)


# ------------------------------------------------------------------------------ cases
def is_solid(case) -> bool:
    """Whether ``case`` describes a 3D body by itself (a box, a prism, an inline mesh of
    tetrahedra or hexahedra); a gmsh file's dimension is known when it is read."""
    return _solid_geometry(case.geometry)


def solid_geometry(case) -> tuple[Polygon, float, float]:
    """The base polygon, bottom z and depth of a box or prism case."""
    g = case.geometry
    if g["shape"] == "box":
        return box_polygon(g["size"], g["origin"])
    return prism_polygon(np.asarray(g["vertices"], dtype=float), g["edge_names"]), 0.0, \
        float(g["depth"])


def check_solid(case, *, max_dofs: int | None = None) -> None:
    """The resource guard of a box or prism case before meshing (:func:`critfric.guards.
    check_dofs` with a :class:`SolidFootprint`; the contact faces' nodes counted for the
    dense stage); nothing for an inline mesh (its size is the case file's)."""
    from ..guards import check_dofs

    if case.geometry["shape"] not in SHAPES_3D:
        return
    poly, _, depth = solid_geometry(case)
    h, element = case.mesh["size"], case.mesh["element"]
    spec = solid(element)
    sizes = face_sizes(poly, depth)
    c = FACET_AREA[spec.facet_vertices]
    n_contact = sum(spec.order**2 * (a / (c * h * h) + p / (2 * h) + 1)
                    for a, p in (sizes[n] for n in case.boundary["contact"] if n in sizes))
    footprint = prism_footprint(poly, depth)
    check_dofs(footprint.dofs(h, element), element=element, what=f"mesh.size = {h:g}",
               source=case.source, footprint=footprint, max_dofs=max_dofs,
               n_contact=n_contact, dim=3, backend=case.solve["backend"], estimate=True)


def solid_mesh(case, *, max_dofs: int | None = None) -> Mesh:
    """The mesh of a 3D case (:func:`is_solid`): a box or prism after the resource guard, or
    an inline mesh of tetrahedra or hexahedra."""
    g, m = case.geometry, case.mesh
    if g["shape"] == "mesh":
        cells = g["tetrahedra"] if g["tetrahedra"] is not None else g["hexahedra"]
        return inline_solid(np.asarray(g["nodes"], dtype=float), cells, g["faces"],
                            m["element"], min_quality=MIN_QUALITY)
    check_solid(case, max_dofs=max_dofs)
    poly, z0, depth = solid_geometry(case)
    job = {"depth": depth, "z0": z0, "size": m["size"], "element": m["element"],
           "structured": g["shape"] == "box" and solid(m["element"]).n_vertices == 8}
    feature = smallest_feature(poly, depth)
    if feature >= SHORT_FEATURE * m["size"]:
        return build_solid(poly, **job)
    return _child_solid(case, poly, job, feature, max_dofs=max_dofs)


def _child_solid(case, poly: Polygon, job: dict, feature: float, *,
                 max_dofs: int | None) -> Mesh:
    """:func:`build_solid` in the limited child of :mod:`.sandbox`, stopped past its wall
    time or its memory allowance."""
    from pathlib import Path

    from .sandbox import max_nodes, run_in_child

    h, element, shape = job["size"], job["element"], case.geometry["shape"]
    nodes = prism_footprint(poly, job["depth"]).nodes(h, element)
    seconds = max(CHILD_SECONDS, CHILD_SECONDS_PER_NODE * nodes)
    what = f"this {shape}"
    job = {**job, "vertices": poly.vertices.tolist(), "edge_names": list(poly.edge_names),
           "kind": shape, "max_dofs": max_dofs, "max_nodes": max_nodes(max_dofs, element),
           "wall_seconds": seconds, "what": what, "key": "mesh.size",
           "suspects": f"its depth, edges or gaps as short as {feature:.3g}",
           "slow": f"meshing {what} took more than {seconds:.3g} s of wall time and was "
                   f"stopped: its depth, edges or gaps are as short as {feature:.3g}, below "
                   f"mesh.size = {h:g}; allowed: a body gmsh meshes within {seconds:.3g} s "
                   "(merge the short edges of the base, or use a mesh size closer to them)"}
    return run_in_child(Path(case.source or "case.toml"), b"", job, entry=ENTRY,
                        source=case.source)


def child_solid(work, job: dict) -> Mesh:
    """In the sandboxed child: the mesh of the prism of ``job``."""
    from .sandbox import set_stage

    set_stage(work, "meshing 3")
    poly = Polygon(np.array(job["vertices"], dtype=float), tuple(job["edge_names"]))
    return build_solid(poly, depth=job["depth"], z0=job["z0"], size=job["size"],
                       element=job["element"], structured=job["structured"])
