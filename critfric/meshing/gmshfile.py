"""User geometries from gmsh files (``[geometry] shape = "file"``).

* ``.msh``: a mesh read by meshio (pure Python: nothing in the file is run). Its triangles or
  quadrangles form the body (only those of the physical surfaces named in ``[geometry]
  domain`` if given; second-order cells give their corners); every physical curve is a
  boundary edge group, by name (or by number if unnamed).
* ``.geo``: a gmsh script meshed by gmsh in-process. The gmsh language can run programs and
  read or write files (``GEO_HAZARDS``); a script that mentions any such statement is refused
  unless it is trusted (``--trust-geo``). The check looks at every word of the file, comments
  and strings included: it may refuse a harmless script, never the reverse.

Both give first-order cells; P2/Q2 midpoints are then added on straight edges
(:func:`critfric.mesh.inline_mesh`, which also checks the cells and the boundary edges).
"""

from __future__ import annotations

import bisect
import contextlib
import io
import math
import re
import warnings
from pathlib import Path
from typing import Callable

import numpy as np

from ..errors import CaseError, SolverError
from ..fem.mesh import Mesh
from ..guards import Footprint
from .mesh import _gmsh_session, inline_mesh

_RUNS = "runs a shell command"
_READS = "reads another file (a .py file would be run)"
#: words of the gmsh .geo language that reach outside the mesh, and what they do
GEO_HAZARDS = {
    "SystemCall": _RUNS, "NonBlockingSystemCall": _RUNS, "System": _RUNS,
    "OnelabRun": "runs an external program (ONELAB client)",
    "Solver": "configures an external solver program",
    "Plugin": "runs a gmsh plugin",
    "Include": "reads and runs another script",
    "Merge": _READS, "MergeWithBoundingBox": _READS,
    "ShapeFromFile": "reads a CAD file", "ListFromFile": "reads another file",
    "Save": "writes a file", "Print": "writes a file", "CreateDir": "creates a directory",
    "SendToServer": "sends data to another program",
    "StringToName": "makes a command name from a string (it can hide any of these)",
    "S2N": "makes a command name from a string (it can hide any of these)",
    "Exit": "ends the program running it (critfric itself)",
    "Sleep": "pauses the program running it",
}
# gmsh's tokens: numbers first (flex longest match), then names, then any single character
_TOKEN = re.compile(r"(?P<num>\d+\.\d*(?:[Ee][-+]?\d+)?|\d*\.\d+(?:[Ee][-+]?\d+)?"
                    r"|\d+[Ee][-+]?\d+|\d+)|(?P<name>[A-Za-z_][A-Za-z0-9_]*)|.", re.S)
_TRI, _QUAD = {"triangle", "triangle6"}, {"quad", "quad8", "quad9"}
_LINES = {"line", "line3"}


def geo_hazards(text: str) -> list[tuple[int, str, str]]:
    """(line, word, what it does) for every statement of a .geo script that reaches outside."""
    newlines = [m.start() for m in re.finditer("\n", text)]
    found = []
    for m in _TOKEN.finditer(text):
        word = m.group("name")
        if word is None:
            continue
        why = GEO_HAZARDS.get(word)
        if word == "Printf" and ">" in text[m.end():]:  # Printf(...) > "file", even with
            why = "may write a file (Printf ... > file)"  # comments in between
        if why:
            found.append((bisect.bisect_left(newlines, m.start()) + 1, word, why))
    return found


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
    """Refuse a .geo script that can run programs or touch other files."""
    hazards = geo_hazards(text)
    if hazards:
        shown = "; ".join(f"line {line}: {word} ({why})" for line, word, why in hazards[:5])
        more = f" and {len(hazards) - 5} more" if len(hazards) > 5 else ""
        raise CaseError(f"refused: this gmsh script can reach outside the mesh: {shown}{more}. "
                        "critfric meshes only self-contained scripts; remove these statements "
                        "or, if you trust the script, pass --trust-geo", file=str(path),
                        key="geometry.file")


# ------------------------------------------------------------------------------ first order
def _build(points, cells, edges: dict, element: str, path: Path) -> Mesh:
    """A Mesh from first-order cells (n, 3 or 4) of any node numbering and edge node pairs."""
    family = ("P1", "P2") if cells.shape[1] == 3 else ("Q1", "Q2")
    kind = "triangles" if cells.shape[1] == 3 else "quadrangles"
    if element not in family:
        raise CaseError(f"got {element!r} for a mesh of {kind} ({path.name}); allowed: "
                        + " or ".join(family), file=str(path), key="mesh.element")
    points = np.asarray(points, dtype=np.float64)
    scale = float(np.ptp(points[:, :2], axis=0).max()) if len(points) else 0.0
    if points.shape[1] > 2 and np.abs(points[:, 2]).max(initial=0.0) > 1e-12 * max(scale, 1e-300):
        raise CaseError("the mesh is not in the plane z = 0; allowed: a 2D mesh",
                        file=str(path), key="geometry.file")
    used = np.unique(cells)
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


def read_msh(path: Path, *, element: str, domain: list[str] | None = None) -> Mesh:
    """The mesh of a gmsh .msh file (formats 2.2 and 4.1, ASCII or binary)."""
    import meshio

    if not path.is_file():
        _read_text(path)  # raises the right message
    try:
        with warnings.catch_warnings(), contextlib.redirect_stderr(io.StringIO()), \
                contextlib.redirect_stdout(io.StringIO()):
            warnings.simplefilter("ignore")
            m = meshio.read(path, file_format="gmsh")
    except Exception as exc:  # meshio reports malformed files with many exception types
        raise CaseError(f"cannot read this gmsh mesh ({type(exc).__name__}: {exc}); allowed: a "
                        "gmsh .msh file, format 2.2 or 4.1", file=str(path),
                        key="geometry.file") from None
    names = {str(k): (int(v[0]), int(v[1])) for k, v in (m.field_data or {}).items()
             if np.size(v) >= 2}
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

    blocks2 = [i for i, c in enumerate(m.cells) if c.type in _TRI | _QUAD]
    if not blocks2:
        raise CaseError("the mesh has no triangles or quadrangles; allowed: a 2D gmsh mesh",
                        file=str(path), key="geometry.file")
    if domain:
        surfaces = {n: t for n, (t, d) in names.items() if d == 2}
        missing = [n for n in domain if n not in surfaces]
        if missing:
            raise CaseError(f"no physical surface {missing[0]!r} in {path.name}; allowed: "
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
    return _build(m.points, cells, edges, element, path)


# ------------------------------------------------------------------------------ .geo scripts
def _surfaces(domain: list[str] | None, path: Path) -> list[int]:
    import gmsh

    if not domain:
        return [tag for _, tag in gmsh.model.getEntities(2)]
    groups = {gmsh.model.getPhysicalName(2, t) or str(t): t
              for _, t in gmsh.model.getPhysicalGroups(2)}
    missing = [n for n in domain if n not in groups]
    if missing:
        raise CaseError(f"no physical surface {missing[0]!r} in {path.name}; allowed: "
                        + (", ".join(sorted(groups)) or "none defined"), file=str(path),
                        key="geometry.domain")
    return sorted({int(e) for n in domain
                   for e in gmsh.model.getEntitiesForPhysicalGroup(2, groups[n])})


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
    points = gmsh.model.getEntities(0)
    sizes = [float(s) for s in gmsh.model.mesh.getSizes(points) if s > 0] if points else []
    cap = gmsh.option.getNumber("Mesh.MeshSizeMax")
    sizes += [x for x in (size, cap if cap < 1e22 else None) if x]
    if not sizes:  # gmsh's default: about a tenth of the bounding box diagonal
        x0, y0, _, x1, y1, _ = gmsh.model.getBoundingBox(-1, -1)
        sizes = [0.1 * math.hypot(x1 - x0, y1 - y0)]
    h = max(min(sizes) * gmsh.option.getNumber("Mesh.MeshSizeFactor"),
            gmsh.option.getNumber("Mesh.MeshSizeMin"))
    return Footprint(abs(area), perimeter, len(points)), h


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


def mesh_geo(path: Path, *, element: str, size: float | None = None,
             domain: list[str] | None = None, trust: bool = False,
             check: Callable[[Footprint, float], None] | None = None) -> Mesh:
    """Mesh a gmsh .geo script (refused if it can reach outside, unless ``trust``).

    size  : upper bound on the element size (``Mesh.MeshSizeMax``); the script's own sizes
            apply below it.
    check : called with the footprint and the expected mesh size before meshing (resource
            guard); it raises to refuse.
    """
    import gmsh

    text = _read_text(path)
    if not trust:
        check_geo(path, text)
    with _gmsh_session():
        try:
            gmsh.merge(str(path))
        except Exception as exc:  # gmsh reports script errors as bare Exceptions
            raise CaseError(f"gmsh cannot read this script: {exc}", file=str(path),
                            key="geometry.file") from None
        surfaces = _surfaces(domain, path)
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
            gmsh.model.mesh.generate(2)
        except Exception as exc:
            raise SolverError(f"gmsh failed to mesh {path}: {exc}; try another mesh size")
        points, cells, edges = _extract(surfaces)
    if len(cells) == 0:
        raise CaseError("gmsh made no cells from this script", file=str(path),
                        key="geometry.file")
    return _build(points, cells, edges, element, path)


def check_file(case, *, trust_geo: bool = False) -> Path:
    """The geometry file of a case, refused before any meshing if missing or, for a .geo
    script that can reach outside, unless ``trust_geo``."""
    from ..case.schema import geometry_file

    path = geometry_file(case)
    if not path.is_file():
        raise CaseError(f"got {case.geometry['file']!r}: no such file ({path}); allowed: an "
                        "existing gmsh .msh or .geo file", file=case.source, key="geometry.file")
    if path.suffix.lower() == ".geo" and not trust_geo:
        check_geo(path, _read_text(path))
    return path


def file_mesh(case, *, max_dofs: int | None = None, trust_geo: bool = False) -> Mesh:
    """The mesh of a ``shape = "file"`` case, after the resource guard."""
    from ..guards import check_dofs

    path = check_file(case, trust_geo=trust_geo)
    element, domain = case.mesh["element"], case.geometry["domain"]
    if path.suffix.lower() == ".msh":
        mesh = read_msh(path, element=element, domain=domain)
        check_dofs(2.0 * mesh.n_nodes, element=element, what=f"the mesh {path.name}",
                   source=case.source, key="geometry.file", max_dofs=max_dofs)
        return mesh

    def check(footprint: Footprint, h: float) -> None:
        check_dofs(footprint.dofs(h, element), element=element,
                   what=f"{path.name} at mesh size about {h:.3g}", source=case.source,
                   footprint=footprint, max_dofs=max_dofs)

    mesh = mesh_geo(path, element=element, size=case.mesh["size"], domain=domain,
                    trust=trust_geo, check=check)
    # the estimate misses size fields and transfinite counts: check the real mesh too
    check_dofs(2.0 * mesh.n_nodes, element=element, what=f"the mesh of {path.name}",
               source=case.source, key="geometry.file", max_dofs=max_dofs)
    return mesh
