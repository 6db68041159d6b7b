"""User gmsh files with 3D cells (``[geometry] shape = "file"``); called by
:mod:`.gmshfile`, in the same limited child process.

* ``.msh``: a mesh with volume cells is a 3D body. Its tetrahedra or hexahedra (second-order
  ones give their corners) form the body: those of the physical volumes named in
  ``[geometry] domain`` if given, else all. Every physical surface is a face group, by name
  (or by number if unnamed), its triangles or quadrangles matched to the cells' boundary faces.
* ``.geo``: a script that defines a volume is meshed in 3D, after the resource guard on the
  volume and area that a coarse mesh of its surfaces encloses. Hexahedra (Q1, Q2) come
  only from the script's own transfinite volumes or extrusions with recombined layers.

Both give first-order cells; P2/Q2 nodes are then added on straight edges
(:func:`.cells3d.inline_solid`, which also checks the cells and the faces).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import CaseError, SolverError
from ..fem.arrays import distinct
from ..fem.mesh import Mesh
from .cells3d import inline_solid
from .mesh import MIN_QUALITY, check_group_names
from .solid import SolidFootprint

SOLID_CELLS = {"tetra": 4, "tetra10": 4, "hexahedron": 8, "hexahedron20": 8,
               "hexahedron27": 8}
OTHER_CELLS = {"wedge", "wedge15", "wedge18", "pyramid", "pyramid13", "pyramid14"}
FACETS = {"triangle": 3, "triangle6": 3, "quad": 4, "quad8": 4, "quad9": 4}
_GMSH_CELLS = {4: 4, 5: 8}  # gmsh types of first-order tetrahedra, hexahedra: vertices
_GMSH_FACETS = {2: 3, 3: 4}  # of first-order triangles, quadrangles


def has_solid_cells(m) -> bool:
    """Whether a meshio mesh holds volume cells."""
    return any(c.type in SOLID_CELLS or c.type in OTHER_CELLS for c in m.cells)


def build(points, cells, faces: dict, element: str, path: Path, name: str) -> Mesh:
    """A Mesh from first-order cells (n, 4 or 8) of any node numbering and named faces by
    their vertices; errors name the file."""
    tets = cells.shape[1] == 4
    family = ("P1", "P2") if tets else ("Q1", "Q2")
    if element not in family:
        hint = ("; Q1/Q2 need hexahedra (a transfinite volume with recombined surfaces, or "
                "an extrusion with Layers and Recombine)") if tets else ""
        raise CaseError(f"got {element!r} for a mesh of {'tetrahedra' if tets else 'hexahedra'}"
                        f" ({name}); allowed: " + " or ".join(family) + hint, file=str(path),
                        key="mesh.element")
    points = np.asarray(points, dtype=np.float64)[:, :3]
    used = distinct(cells)
    lookup = np.full(len(points), -1, dtype=np.int64)
    lookup[used] = np.arange(len(used))
    groups = {}
    for group, rows in faces.items():
        local = lookup[rows]
        if np.any(local < 0):
            raise CaseError(f"physical surface {group!r} is not on the body (a node of it "
                            "belongs to no cell)", file=str(path), key="geometry.file")
        groups[group] = local
    try:
        return inline_solid(points[used], lookup[cells], groups, element,
                            min_quality=MIN_QUALITY)
    except CaseError as exc:
        what = (exc.key or "").removeprefix("geometry.")
        what = f"physical surface {what[6:]!r}" if what.startswith("faces.") else what
        raise CaseError(f"{what}: {exc.detail}", file=str(path), key="geometry.file") from None


def read_solid_msh(m, rows, names: dict, path: Path, *, element: str,
                   domain: list[str] | None, name: str) -> Mesh:
    """The 3D mesh of a meshio mesh ``m`` read from ``path``: ``rows(i, name, tag)`` selects
    the rows of cell block i in a physical group, ``names`` maps physical names to (tag,
    dimension)."""
    blocks = [i for i, c in enumerate(m.cells) if c.type in SOLID_CELLS or c.type in OTHER_CELLS]
    if domain:
        volumes = {n: t for n, (t, d) in names.items() if d == 3}
        missing = [n for n in domain if n not in volumes]
        if missing:
            raise CaseError(f"no physical volume {missing[0]!r} in {name}; allowed: "
                            + (", ".join(sorted(volumes)) or "none defined"), file=str(path),
                            key="geometry.domain")
        picked = [(i, np.any([rows(i, n, volumes[n]) for n in domain], axis=0))
                  for i in blocks]
    else:
        picked = [(i, np.ones(len(m.cells[i].data), dtype=bool)) for i in blocks]
    picked = [(i, k) for i, k in picked if k.any()]
    kinds = sorted({m.cells[i].type for i, _ in picked})
    other = [k for k in kinds if k in OTHER_CELLS]
    if other:
        raise CaseError(f"the mesh has {other[0]} cells; allowed: tetrahedra only or "
                        "hexahedra only", file=str(path), key="geometry.file")
    widths = {SOLID_CELLS[k] for k in kinds}
    if len(widths) > 1:
        raise CaseError("the mesh mixes tetrahedra and hexahedra; allowed: one kind",
                        file=str(path), key="geometry.file")
    if not widths:
        raise CaseError(f"the domain {domain} has no cells", file=str(path),
                        key="geometry.domain")
    nv = widths.pop()
    cells = np.concatenate([m.cells[i].data[k, :nv] for i, k in picked]).astype(np.int64)

    physical = m.cell_data.get("gmsh:physical") or [None] * len(m.cells)
    facet_blocks = [i for i, c in enumerate(m.cells) if c.type in FACETS]
    surfaces = {n: t for n, (t, d) in names.items() if d == 2}
    for i in facet_blocks:  # unnamed physical surfaces are known by their number
        if physical[i] is not None:
            for t in np.unique(physical[i]):
                if int(t) > 0 and int(t) not in surfaces.values():
                    surfaces[str(int(t))] = int(t)
    fv = 3 if nv == 4 else 4
    faces = {}
    for group, tag in surfaces.items():
        chosen = [(i, rows(i, group, tag)) for i in facet_blocks]
        chosen = [(i, k) for i, k in chosen if k.any()]
        wrong = [m.cells[i].type for i, _ in chosen if FACETS[m.cells[i].type] != fv]
        if wrong:
            raise CaseError(f"physical surface {group!r} has {wrong[0]} facets but the cells "
                            f"are {'tetrahedra' if nv == 4 else 'hexahedra'}; allowed: "
                            f"{'triangles' if fv == 3 else 'quadrangles'}", file=str(path),
                            key="geometry.file")
        if chosen:
            faces[group] = np.concatenate([m.cells[i].data[k, :fv] for i, k in chosen]
                                          ).astype(np.int64)
    if not faces:
        raise CaseError("the mesh has no physical surface; allowed: a 3D mesh whose boundary "
                        "faces (the contact and Dirichlet faces at least) are physical "
                        "surfaces", file=str(path), key="geometry.file")
    return build(m.points, cells, faces, element, path, name)


# ------------------------------------------------------------------------------ .geo scripts
def domain_entities(dim: int, domain: list[str] | None, path: Path, name: str) -> list[int]:
    """The tags of the body's entities of dimension ``dim`` (surfaces 2, volumes 3) in the
    current gmsh model: those of the physical groups ``domain``, or all of them."""
    import gmsh

    if not domain:
        return [tag for _, tag in gmsh.model.getEntities(dim)]
    groups = {gmsh.model.getPhysicalName(dim, t) or str(t): t
              for _, t in gmsh.model.getPhysicalGroups(dim)}
    check_group_names(groups, path)
    missing = [n for n in domain if n not in groups]
    if missing:
        what = "volume" if dim == 3 else "surface"
        raise CaseError(f"no physical {what} {missing[0]!r} in {name}; allowed: "
                        + (", ".join(sorted(groups)) or "none defined"), file=str(path),
                        key="geometry.domain")
    return sorted({int(e) for n in domain
                   for e in gmsh.model.getEntitiesForPhysicalGroup(dim, groups[n])})


def _footprint(volumes: list[int], h: float) -> SolidFootprint:
    """Volume and area enclosed by a coarse surface mesh of ``volumes`` (size at least a
    tenth of the bounding box diagonal, or ``h``; the divergence theorem on its triangles,
    oriented as gmsh's boundary; at most the bounding boxes' volume), the length of every
    curve and the number of geometry points. The coarse mesh is cleared afterwards."""
    import gmsh

    x0, y0, z0, x1, y1, z1 = gmsh.model.getBoundingBox(-1, -1)
    coarse = max(h, 0.1 * float(np.linalg.norm([x1 - x0, y1 - y0, z1 - z0])))
    options = ("Mesh.MeshSizeMin", "Mesh.MeshSizeMax")
    saved = [gmsh.option.getNumber(k) for k in options]
    for k in options:
        gmsh.option.setNumber(k, coarse)
    gmsh.model.mesh.generate(2)
    for k, v in zip(options, saved):
        gmsh.option.setNumber(k, v)
    coordinates = _coordinates()
    area = volume = 0.0
    for _, tag in gmsh.model.getBoundary([(3, v) for v in volumes], combined=True,
                                         oriented=True, recursive=False):
        for etype, width in _GMSH_FACETS.items():
            nodes = gmsh.model.mesh.getElementsByType(etype, abs(tag))[1]
            if not len(nodes):
                continue
            x = coordinates(np.reshape(nodes, (-1, width)))
            tri = x[:, [0, 1, 2]] if width == 3 else np.concatenate(
                [x[:, [0, 1, 2]], x[:, [0, 2, 3]]])
            cross = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
            area += 0.5 * float(np.linalg.norm(cross, axis=1).sum())
            volume += np.sign(tag) * float(np.einsum("ti,ti->", tri[:, 0], cross)) / 6.0
    box = 0.0
    for v in volumes:
        x0, y0, z0, x1, y1, z1 = gmsh.model.getBoundingBox(3, v)
        box += (x1 - x0) * (y1 - y0) * (z1 - z0)
    _, lines = gmsh.model.mesh.getElementsByType(1)[:2]
    length = 0.0
    if len(lines):
        x = coordinates(np.reshape(lines, (-1, 2)))
        length = float(np.linalg.norm(x[:, 1] - x[:, 0], axis=1).sum())
    gmsh.model.mesh.clear()
    return SolidFootprint(float(min(abs(volume), box)), area, length,
                          len(gmsh.model.getEntities(0)))


def _coordinates():
    """A function: gmsh node tags (...) -> their coordinates (..., 3), in the current mesh."""
    import gmsh

    tags, coords, _ = gmsh.model.mesh.getNodes()
    tags = np.asarray(tags, dtype=np.int64)
    index = np.zeros(tags.max(initial=0) + 1, dtype=np.int64)
    index[tags] = np.arange(len(tags))
    xyz = np.reshape(coords, (-1, 3))
    return lambda t: xyz[index[np.asarray(t, dtype=np.int64)]]


def mesh_solid_geo(path: Path, *, h: float, domain: list[str] | None, check, name: str):
    """Mesh the volumes of the merged script in 3D (first order): points, cells and the
    faces of every physical surface by their vertices. ``check(footprint, h)``: the resource
    guard, run before meshing at the expected size ``h`` (on a coarse surface mesh)."""
    import gmsh

    volumes = domain_entities(3, domain, path, name)
    try:
        if check is not None:
            check(_footprint(volumes, h), h)
        gmsh.model.mesh.generate(3)
    except CaseError:
        raise
    except Exception as exc:
        raise SolverError(f"gmsh failed to mesh {name}: {exc}; try another mesh size") from exc
    tags, coords, _ = gmsh.model.mesh.getNodes()
    tags = np.asarray(tags, dtype=np.int64)
    index = np.full(tags.max(initial=0) + 1, -1, dtype=np.int64)
    index[tags] = np.arange(len(tags))
    blocks = {4: [], 5: []}
    for v in volumes:
        for etype, _, nodes in zip(*gmsh.model.mesh.getElements(3, v)):
            if int(etype) not in blocks:
                raise CaseError(f"gmsh made volume elements of type {int(etype)} (prisms or "
                                "pyramids) from this script; allowed: tetrahedra only or "
                                "hexahedra only", file=str(path), key="geometry.file")
            blocks[int(etype)].append(np.reshape(nodes, (-1, _GMSH_CELLS[int(etype)])))
    if blocks[4] and blocks[5]:
        raise CaseError("gmsh made both tetrahedra and hexahedra from this script; allowed: "
                        "one kind", file=str(path), key="geometry.file")
    if not blocks[4] and not blocks[5]:
        raise CaseError("gmsh made no cells from this script", file=str(path),
                        key="geometry.file")
    cells = index[np.concatenate(blocks[4] or blocks[5]).astype(np.int64)]
    facet_type = 2 if cells.shape[1] == 4 else 3
    faces = {}
    for dim, group in gmsh.model.getPhysicalGroups(2):
        parts = [np.reshape(nodes, (-1, _GMSH_FACETS[facet_type]))
                 for s in gmsh.model.getEntitiesForPhysicalGroup(dim, group)
                 for etype, _, nodes in zip(*gmsh.model.mesh.getElements(2, int(s)))
                 if int(etype) == facet_type]
        if parts:
            name = gmsh.model.getPhysicalName(dim, group) or str(group)
            check_group_names([name], path)
            faces[name] = index[np.concatenate(parts).astype(np.int64)]
    if not faces:
        raise CaseError("the script has no physical surface; allowed: a 3D geometry whose "
                        "boundary faces (the contact and Dirichlet faces at least) are "
                        "physical surfaces", file=str(path), key="geometry.file")
    return np.reshape(coords, (-1, 3)), cells, faces
