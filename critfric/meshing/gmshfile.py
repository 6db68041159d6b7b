"""User geometries from gmsh files (``[geometry] shape = "file"``).

* ``.msh``: a mesh read by meshio (pure Python: nothing in the file is run). Its triangles or
  quadrangles form the body (only those of the physical surfaces named in ``[geometry]
  domain`` if given; second-order cells give their corners); every physical curve is a
  boundary edge group, by name (or by number if unnamed).
* ``.geo``: a gmsh script meshed by gmsh. The gmsh language can run programs and read or
  write files: a script is refused unless every statement is on the allow-list of geometry
  and meshing statements (:mod:`.geoscript`), or it is trusted (``--trust-geo``).

A mesh with volume cells or a script that defines volumes is a 3D body (:mod:`.gmshfile3d`:
tetrahedra or hexahedra, physical volumes and surfaces). Both are read in a limited child
process (:mod:`.sandbox`), from a private copy of the file's bytes: the same bytes that were
checked.

Both give first-order cells; P2/Q2 midpoints are then added on straight edges
(:func:`critfric.meshing.mesh.inline_mesh`, which also checks the cells and the boundary edges).
"""

from __future__ import annotations

import contextlib
import functools
import io
import math
import warnings
from collections.abc import Callable
from pathlib import Path

import numpy as np

from ..errors import CaseError, SolverError
from ..fem.arrays import distinct
from ..fem.mesh import Mesh
from ..guards import Footprint
from .geoscript import refusals
from .gmshfile3d import build as build_solid
from .gmshfile3d import domain_entities, has_solid_cells, mesh_solid_geo, read_solid_msh
from .mesh import _gmsh_session, check_group_names, inline_mesh
from .sandbox import max_nodes, read_input, run_in_child, set_stage

ENTRY = "critfric.meshing.gmshfile:child_mesh"  # what the sandboxed child runs

_TRI, _QUAD = {"triangle", "triangle6"}, {"quad", "quad8", "quad9"}
_LINES = {"line", "line3"}


def _read_text(path: Path) -> str:
    try:
        return path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise CaseError("no such file; allowed: an existing gmsh .msh or .geo file",
                        file=str(path), key="geometry.file") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise CaseError(f"cannot read this file ({exc})", file=str(path),
                        key="geometry.file") from None


def check_geo(path: Path, text: str) -> None:
    """Refuse a .geo script with anything outside the allow-list of geometry and meshing
    statements (:mod:`critfric.meshing.geoscript`)."""
    found = refusals(text)
    if found:
        shown = "; ".join(f"line {line}: {word} ({why})" for line, word, why in found[:5])
        more = f" and {len(found) - 5} more" if len(found) > 5 else ""
        raise CaseError(f"refused: this gmsh script says what critfric does not allow in an "
                        f"untrusted script: {shown}{more}. critfric meshes only scripts made of "
                        "geometry and meshing statements; remove these or, if you trust the "
                        "script, pass --trust-geo", file=str(path), key="geometry.file")


# ------------------------------------------------------------------------------ first order
def _build(points, cells, edges: dict, element: str, path: Path, name: str) -> Mesh:
    """A Mesh from first-order cells (n, 3 or 4) of any node numbering and edge node pairs."""
    family = ("P1", "P2") if cells.shape[1] == 3 else ("Q1", "Q2")
    kind = "triangles" if cells.shape[1] == 3 else "quadrangles"
    if element not in family:
        raise CaseError(f"got {element!r} for a mesh of {kind} ({name}); allowed: "
                        + " or ".join(family), file=str(path), key="mesh.element")
    points = np.asarray(points, dtype=np.float64)
    scale = float(np.ptp(points[:, :2], axis=0).max()) if len(points) else 0.0
    if points.shape[1] > 2 and np.abs(points[:, 2]).max(initial=0.0) > 1e-12 * max(scale, 1e-300):
        raise CaseError("the mesh is not in the plane z = 0; allowed: a 2D mesh in that plane, "
                        "or a 3D mesh with its cells (tetrahedra or hexahedra) in the file",
                        file=str(path), key="geometry.file")
    used = distinct(cells)
    lookup = np.full(len(points), -1, dtype=np.int64)
    lookup[used] = np.arange(len(used))
    groups = {}
    for name, pairs in edges.items():
        local = lookup[pairs]
        if np.any(local < 0):
            raise CaseError(f"physical curve {name!r} is not on the body (a node of it belongs "
                            "to no cell)", file=str(path), key="geometry.file")
        groups[name] = local
    try:
        return inline_mesh(points[used, :2], lookup[cells], groups, element)
    except CaseError as exc:
        what = (exc.key or "").removeprefix("geometry.")
        what = f"physical curve {what[6:]!r}" if what.startswith("edges.") else what
        raise CaseError(f"{what}: {exc.detail}", file=str(path), key="geometry.file") from None


def read_msh(path: Path, *, element: str, domain: list[str] | None = None,
             shown: str | None = None) -> Mesh:
    """The mesh of a gmsh .msh file (formats 2.2 and 4.1, ASCII or binary); ``shown``: the
    file's name in messages."""
    import meshio

    name = shown or path.name
    if not path.is_file():
        _read_text(path)  # raises the right message
    try:
        with warnings.catch_warnings(), contextlib.redirect_stderr(io.StringIO()), \
                contextlib.redirect_stdout(io.StringIO()):
            warnings.simplefilter("ignore")
            m = meshio.read(path, file_format="gmsh")
    except MemoryError:
        raise CaseError("reading this mesh needs far more memory than its size justifies (it "
                        "declares huge node counts or tags); allowed: a gmsh .msh file whose "
                        "node tags and counts match its contents", file=str(path),
                        key="geometry.file") from None
    except Exception as exc:  # meshio reports malformed files with many exception types
        raise CaseError(f"cannot read this gmsh mesh ({type(exc).__name__}: {exc}); allowed: a "
                        "gmsh .msh file, format 2.2 or 4.1", file=str(path),
                        key="geometry.file") from None
    names = {str(k): (int(v[0]), int(v[1])) for k, v in (m.field_data or {}).items()
             if np.size(v) >= 2}
    check_group_names(names, path)
    physical = m.cell_data.get("gmsh:physical") or [None] * len(m.cells)
    sets = m.cell_sets or {}

    def rows(i: int, name: str, tag: int) -> np.ndarray:
        """Rows of cell block i in physical group (name, tag)."""
        hit = np.zeros(len(m.cells[i].data), dtype=bool)
        if physical[i] is not None:
            hit |= np.asarray(physical[i]) == tag
        chosen = sets.get(name)
        if chosen is not None and i < len(chosen) and chosen[i] is not None:
            hit[np.asarray(chosen[i], dtype=np.int64)] = True
        return hit

    if has_solid_cells(m):
        return read_solid_msh(m, rows, names, path, element=element, domain=domain, name=name)
    blocks2 = [i for i, c in enumerate(m.cells) if c.type in _TRI | _QUAD]
    if not blocks2:
        raise CaseError("the mesh has no cells; allowed: a gmsh mesh of triangles or "
                        "quadrangles (2D), or of tetrahedra or hexahedra (3D)",
                        file=str(path), key="geometry.file")
    if domain:
        surfaces = {n: t for n, (t, d) in names.items() if d == 2}
        missing = [n for n in domain if n not in surfaces]
        if missing:
            raise CaseError(f"no physical surface {missing[0]!r} in {name}; allowed: "
                            + (", ".join(sorted(surfaces)) or "none defined"), file=str(path),
                            key="geometry.domain")
        picked = [(i, np.any([rows(i, n, surfaces[n]) for n in domain], axis=0))
                  for i in blocks2]
    else:
        picked = [(i, np.ones(len(m.cells[i].data), dtype=bool)) for i in blocks2]
    tri = [m.cells[i].data[k, :3] for i, k in picked if m.cells[i].type in _TRI and k.any()]
    quad = [m.cells[i].data[k, :4] for i, k in picked if m.cells[i].type in _QUAD and k.any()]
    if tri and quad:
        raise CaseError("the mesh mixes triangles and quadrangles; allowed: one kind",
                        file=str(path), key="geometry.file")
    if not tri and not quad:
        raise CaseError(f"the domain {domain} has no cells", file=str(path),
                        key="geometry.domain")
    cells = np.concatenate(tri or quad).astype(np.int64)

    lines = [i for i, c in enumerate(m.cells) if c.type in _LINES]
    curves = {n: t for n, (t, d) in names.items() if d == 1}
    for i in lines:  # unnamed physical curves are known by their number
        if physical[i] is not None:
            for t in np.unique(physical[i]):
                if int(t) > 0 and int(t) not in curves.values():
                    curves[str(int(t))] = int(t)
    edges = {}
    for name, tag in curves.items():
        parts = [m.cells[i].data[rows(i, name, tag), :2] for i in lines]
        pairs = np.concatenate(parts) if parts else np.zeros((0, 2), dtype=np.int64)
        if len(pairs):
            edges[name] = pairs.astype(np.int64)
    return _build(m.points, cells, edges, element, path, name)


# ------------------------------------------------------------------------------ .geo scripts
def _footprint(surfaces: list[int], size: float | None) -> tuple[Footprint, float]:
    """Area, perimeter and corner count of the surfaces, and the expected mesh size."""
    import gmsh

    area = perimeter = 0.0
    for s in surfaces:
        for _, c in gmsh.model.getBoundary([(2, s)], oriented=True, recursive=False):
            lo, hi = gmsh.model.getParametrizationBounds(1, abs(c))
            xyz = np.reshape(gmsh.model.getValue(1, abs(c), np.linspace(lo[0], hi[0], 65)),
                             (-1, 3))[:, :2]
            xyz = xyz[::-1] if c < 0 else xyz
            area += 0.5 * float(np.sum(xyz[:-1, 0] * xyz[1:, 1] - xyz[1:, 0] * xyz[:-1, 1]))
            perimeter += float(np.linalg.norm(np.diff(xyz, axis=0), axis=1).sum())
    return Footprint(abs(area), perimeter, len(gmsh.model.getEntities(0))), _expected_size(size)


def _expected_size(size: float | None) -> float:
    """The mesh size gmsh will use: the smallest of the points' sizes, ``size`` and the
    script's ``Mesh.MeshSizeMax`` (else a tenth of the bounding box diagonal), times
    ``Mesh.MeshSizeFactor``, at least ``Mesh.MeshSizeMin``."""
    import gmsh

    points = gmsh.model.getEntities(0)
    sizes = [float(s) for s in gmsh.model.mesh.getSizes(points) if s > 0] if points else []
    cap = gmsh.option.getNumber("Mesh.MeshSizeMax")
    sizes += [x for x in (size, cap if cap < 1e22 else None) if x]
    if not sizes:  # gmsh's default: about a tenth of the bounding box diagonal
        x0, y0, z0, x1, y1, z1 = gmsh.model.getBoundingBox(-1, -1)
        sizes = [0.1 * math.hypot(x1 - x0, y1 - y0, z1 - z0)]
    return max(min(sizes) * gmsh.option.getNumber("Mesh.MeshSizeFactor"),
               gmsh.option.getNumber("Mesh.MeshSizeMin"))


def _longest_segment() -> float:
    """The longest segment of the curves' mesh: every cell of an unstructured surface mesh
    (sizes extended from its boundary) or a transfinite one is about that size or smaller."""
    import gmsh

    tags, coords, _ = gmsh.model.mesh.getNodes(1, -1, includeBoundary=True)
    _, nodes = gmsh.model.mesh.getElementsByType(1)[:2]
    if not len(nodes):
        return math.inf
    index = np.zeros(int(np.max(tags)) + 1, dtype=np.int64)
    index[np.asarray(tags, dtype=np.int64)] = np.arange(len(tags))
    x = np.reshape(coords, (-1, 3))[index[np.reshape(nodes, (-1, 2)).astype(np.int64)]]
    return float(np.linalg.norm(x[:, 1] - x[:, 0], axis=1).max())


def _extract(surfaces: list[int]):
    """Nodes, first-order cells of the surfaces and node pairs of every physical curve."""
    import gmsh

    tags, coords, _ = gmsh.model.mesh.getNodes()
    tags = np.asarray(tags, dtype=np.int64)
    index = np.full(tags.max(initial=0) + 1, -1, dtype=np.int64)
    index[tags] = np.arange(len(tags))
    points = np.reshape(coords, (-1, 3))
    width = {2: 3, 3: 4}  # gmsh element types: 3-node triangle, 4-node quadrangle
    blocks = {2: [], 3: []}
    for s in surfaces:
        for etype, _, nodes in zip(*gmsh.model.mesh.getElements(2, s)):
            if int(etype) not in blocks:
                raise SolverError(f"gmsh made surface elements of type {int(etype)}; expected "
                                  "first-order triangles or quadrangles")
            blocks[int(etype)].append(np.reshape(nodes, (-1, width[int(etype)])))
    if blocks[2] and blocks[3]:
        raise SolverError("gmsh left a mesh of both triangles and quadrangles; try another "
                          "mesh size or a triangle element (P1, P2)")
    cells = np.concatenate(blocks[2] or blocks[3] or [np.zeros((0, 3), dtype=np.int64)])
    edges = {}
    for dim, group in gmsh.model.getPhysicalGroups(1):
        name = gmsh.model.getPhysicalName(dim, group) or str(group)
        parts = [np.reshape(nodes, (-1, 2))
                 for curve in gmsh.model.getEntitiesForPhysicalGroup(dim, group)
                 for etype, _, nodes in zip(*gmsh.model.mesh.getElements(1, int(curve)))
                 if int(etype) == 1]
        if parts:
            edges[name] = index[np.concatenate(parts).astype(np.int64)]
    return points, index[cells.astype(np.int64)], edges


#: the most passes an untrusted script may ask of gmsh's mesh smoother (each pass costs about
#: a meshing; a billion kept the CPU busy until the sandbox stopped it)
MAX_PASSES = {"Mesh.Smoothing": 100}


def _check_passes(path: Path) -> None:
    """Refuse an untrusted script whose options ask gmsh for more passes than MAX_PASSES."""
    import gmsh

    for option, most in MAX_PASSES.items():
        value = gmsh.option.getNumber(option)
        if not value <= most:
            raise CaseError(f"sets {option} = {value:g}; allowed: at most {most} in a script "
                            "that is not trusted (--trust-geo lifts this)", file=str(path),
                            key="geometry.file")


def mesh_geo(path: Path, *, element: str, size: float | None = None,
             domain: list[str] | None = None, trust: bool = False,
             check: Callable[..., None] | None = None,
             shown: str | None = None, stage: Callable[[str], None] | None = None) -> Mesh:
    """Mesh a gmsh .geo script (refused if it can reach outside, unless ``trust``).

    size  : upper bound on the element size (``Mesh.MeshSizeMax``); the script's own sizes
            apply below it.
    check : called with the footprint and the expected mesh size before meshing (resource
            guard), and (2D) with the footprint, the longest segment of the curves once they
            are meshed and ``curves=True`` (transfinite counts, size fields); it raises to
            refuse.
    stage : called with "geometry" before the script is evaluated, "meshing 2" (or 3: the
            body's dimension) after.
    """
    import gmsh

    name = shown or path.name
    text = _read_text(path)
    if not trust:
        check_geo(path, text)
    stage = stage or (lambda _: None)
    with _gmsh_session():
        stage("geometry")
        try:
            gmsh.merge(str(path))
        except Exception as exc:  # gmsh reports script errors as bare Exceptions
            raise CaseError(f"gmsh cannot read this script: {exc}", file=str(path),
                            key="geometry.file") from None
        if not trust:
            _check_passes(path)
        stage(f"meshing {3 if gmsh.model.getEntities(3) else 2}")
        if gmsh.model.getEntities(3):  # a 3D body: its volumes are meshed
            gmsh.option.setNumber("Mesh.ElementOrder", 1)
            h = _expected_size(size)
            if size:
                gmsh.option.setNumber("Mesh.MeshSizeMax", size)
            solid = mesh_solid_geo(path, h=h, domain=domain, check=check, name=name)
            return build_solid(*solid, element, path, name)
        surfaces = domain_entities(2, domain, path, name)
        if not surfaces:
            raise CaseError("the script defines no surface; allowed: a 2D geometry with a "
                            "plane surface", file=str(path), key="geometry.file")
        if check is not None:
            check(*_footprint(surfaces, size))
        quads = element in ("Q1", "Q2")
        gmsh.option.setNumber("Mesh.ElementOrder", 1)
        gmsh.option.setNumber("Mesh.RecombineAll", 1 if quads else 0)
        if quads:
            gmsh.option.setNumber("Mesh.Algorithm", 8)
            gmsh.option.setNumber("Mesh.RecombinationAlgorithm", 3)
        if size:
            gmsh.option.setNumber("Mesh.MeshSizeMax", size)
        try:
            gmsh.model.mesh.generate(1)
            if check is not None:  # the curves' own counts and sizes, before the surfaces
                check(_footprint(surfaces, size)[0], _longest_segment(), curves=True)
            gmsh.model.mesh.generate(2)
        except CaseError:
            raise
        except Exception as exc:
            raise SolverError(f"gmsh failed to mesh {name}: {exc}; try another mesh size")
        points, cells, edges = _extract(surfaces)
        check_group_names(edges, path)
    if len(cells) == 0:
        raise CaseError("gmsh made no cells from this script", file=str(path),
                        key="geometry.file")
    return _build(points, cells, edges, element, path, name)


def check_file(case, *, trust_geo: bool = False) -> Path:
    """The geometry file of a case, refused before any meshing if missing or, for a .geo
    script outside the allow-list, unless ``trust_geo``."""
    from ..case.schema import geometry_file

    path = geometry_file(case)
    if not path.is_file():
        what = ("no such file" if not path.exists() else "a directory" if path.is_dir()
                else "not a regular file (a device, pipe or socket)")
        raise CaseError(f"got {case.geometry['file']!r}: {what} ({path}); allowed: an "
                        "existing gmsh .msh or .geo file", file=case.source, key="geometry.file")
    if path.suffix.lower() == ".geo" and not trust_geo:
        check_geo(path, _decode(read_input(path), path))
    return path


def _decode(data: bytes, path: Path) -> str:
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise CaseError(f"is not UTF-8 text ({exc.reason} at byte {exc.start}); allowed: a "
                        "gmsh .geo script in UTF-8", file=str(path), key="geometry.file") from None


def file_mesh(case, *, max_dofs: int | None = None, trust_geo: bool = False) -> Mesh:
    """The mesh of a ``shape = "file"`` case: the file's bytes checked (a .geo against the
    allow-list unless ``trust_geo``), then read or meshed in a limited child process
    (:mod:`critfric.meshing.sandbox`), then the resource guard on the real mesh."""
    from ..guards import check_dofs

    path = check_file(case, trust_geo=trust_geo)
    data = read_input(path)  # the bytes checked here are the bytes meshed
    kind = path.suffix.lower().lstrip(".")
    if kind == "geo" and not trust_geo:
        check_geo(path, _decode(data, path))
    element = case.mesh["element"]
    job = {"kind": kind, "element": element, "size": case.mesh["size"],
           "domain": case.geometry["domain"], "max_dofs": max_dofs, "trust": trust_geo,
           "max_nodes": max_nodes(max_dofs, element) if kind == "geo" else None}
    mesh = run_in_child(path, data, job, entry=ENTRY, source=case.source)
    # the estimate misses size fields and transfinite counts: check the real mesh too
    check_dofs(mesh.dim * mesh.n_nodes, element=element, what=f"the mesh of {path.name}",
               source=case.source, key="geometry.file", max_dofs=max_dofs, estimate=True)
    return mesh


def child_mesh(work: Path, job: dict) -> Mesh:
    """In the sandboxed child: read or mesh ``work/job["input"]``."""
    from ..guards import check_dofs

    path, element, shown = work / job["input"], job["element"], job["shown"]
    if job["kind"] == "msh":
        return read_msh(path, element=element, domain=job["domain"], shown=shown)

    def check(footprint: Footprint, h: float, curves: bool = False) -> None:
        where = (f"its curves meshed with segments up to {h:.3g} (transfinite counts, size "
                 "fields)" if curves else f"mesh size about {h:.3g}")
        check_dofs(footprint.dofs(h, element), element=element, what=f"{shown} at {where}",
                   source=str(path) if curves else None,
                   key="geometry.file" if curves else "mesh.size", footprint=footprint,
                   max_dofs=job["max_dofs"])

    return mesh_geo(path, element=element, size=job["size"], domain=job["domain"],
                    trust=job["trust"], check=check, shown=shown,
                    stage=functools.partial(set_stage, work))
