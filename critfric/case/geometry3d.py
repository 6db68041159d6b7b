"""The ``[geometry]`` keys of 3D bodies, and the consistency of bodies given by their mesh.

* ``shape = "box"``: ``size = [Lx, Ly, Lz]`` (default [1, 1, 1]) and ``origin = [x, y, z]``
  (the corner with the smallest coordinates, default [0, 0, 0]). Its faces are "x0" (x =
  origin x), "x1" (x = origin x + Lx), "y0", "y1", "z0", "z1".
* ``shape = "prism"``: the polygon ``vertices`` (and ``edge_names``) of ``shape = "polygon"``
  extruded along z from 0 to ``depth`` (default 1). The side face over a polygon edge has the
  edge's name (default "e{i}"); the end faces are "z0" (z = 0) and "z1" (z = depth).
* ``shape = "mesh"`` in 3D: ``nodes`` as [x, y, z] triples, ``tetrahedra = [[a, b, c, d],
  ...]`` (P1, P2) or ``hexahedra = [[8 vertices], ...]`` (Q1, Q2; gmsh's vertex order: 0-3 one
  face counterclockwise seen from the other, 4-7 above 0-3), and ``[geometry.faces]`` naming
  boundary triangles (tetrahedra) or quadrilaterals (hexahedra) by their vertices, as
  ``[geometry.edges]`` names boundary edges in 2D.

The values are checked here; the cells, faces and polygons themselves when they are meshed
(:mod:`critfric.meshing.cells3d`, :mod:`critfric.meshing.solid`).
"""

from __future__ import annotations

from ..case import checks as c
from ..errors import CaseError

SHAPES_3D = ("box", "prism")
BOX_FACES = ("x0", "x1", "y0", "y1", "z0", "z1")
END_FACES = ("z0", "z1")  # a prism's ends
CELL_KEYS = {"triangles": ("P1", "P2"), "quads": ("Q1", "Q2"),
             "tetrahedra": ("P1", "P2"), "hexahedra": ("Q1", "Q2")}
SOLID_CELLS = ("tetrahedra", "hexahedra")

KEYS = {
    "size": c.Key(c.triple(lo=0.0), [1.0, 1.0, 1.0], "box: edge lengths [Lx, Ly, Lz]"),
    "origin": c.Key(c.triple(), [0.0, 0.0, 0.0],
                    "box: the corner with the smallest coordinates [x, y, z]"),
    "depth": c.Key(c.number(0.0, lo_open=True), 1.0,
                   "prism: length along z (end faces z0 at z = 0, z1 at z = depth)"),
    "tetrahedra": c.Key(c.index_rows((4,)), None, "mesh: tetrahedra [[a, b, c, d], ...]"),
    "hexahedra": c.Key(c.index_rows((8,)), None,
                       "mesh: hexahedra [[8 vertices], ...] in gmsh's vertex order"),
    "faces": c.Key(c.face_table, None, "mesh (3D): named boundary faces {name = [[a, b, c], "
                   "...]} (triangles of tetrahedra, [a, b, c, d] quadrilaterals of hexahedra)"),
}
SHAPE_KEYS = {"box": {"size", "origin"}, "prism": {"vertices", "edge_names", "depth"}}
MESH_KEYS = {"tetrahedra", "hexahedra", "faces"}  # of shape = "mesh", beside the 2D ones


def _gmsh_mesh_keys(mesh: dict, source: str) -> None:
    if mesh.get("size") is None:
        raise CaseError("missing key (target element size h, a positive number)",
                        file=source, key="mesh.size")
    for key in ("structured", "grading"):
        if mesh.get(key) not in (None, False):
            raise CaseError("not available for 3D bodies (hexahedra are always structured "
                            "layers, tetrahedra unstructured; no grading yet)", file=source,
                            key=f"mesh.{key}")


def solid_names(geo: dict, mesh: dict, source: str) -> set[str]:
    """The face names of a box or prism case, after the checks of its keys."""
    _gmsh_mesh_keys(mesh, source)
    if geo["shape"] == "box":
        return set(BOX_FACES)
    n = len(geo["vertices"])
    if n > c.MAX_PRISM_VERTICES:
        raise CaseError(f"got {n} vertices; allowed: {c.PRISM_LIMIT}", file=source,
                        key="geometry.vertices")
    names = geo["edge_names"] or [f"e{i}" for i in range(n)]
    if geo["edge_names"] is not None and len(names) != n:
        raise CaseError(f"got {len(names)} names for {n} edges; allowed: one name per edge",
                        file=source, key="geometry.edge_names")
    clash = sorted(set(names) & set(END_FACES))
    if clash:
        raise CaseError(f"got edge name {clash[0]!r}, the name of a prism end face; allowed: "
                        "names other than " + ", ".join(END_FACES), file=source,
                        key="geometry.edge_names")
    return set(names) | set(END_FACES)


def inline_names(geo: dict, mesh: dict, source: str) -> set[str]:
    """The boundary group names of an inline mesh (2D: edges, 3D: faces), after the checks
    that its keys fit together (one kind of cell, nodes of the cells' dimension, the element
    of that cell, no gmsh mesh keys)."""
    given = [k for k in CELL_KEYS if geo.get(k) is not None]
    if len(given) != 1:
        raise CaseError("give exactly one of " + ", ".join(repr(k) for k in CELL_KEYS)
                        + (f" (got {', '.join(given)})" if given else ""), file=source,
                        key=f"geometry.{given[1] if len(given) > 1 else 'triangles'}")
    kind = given[0]
    solid = kind in SOLID_CELLS
    dim = len(geo["nodes"][0])
    if dim != (3 if solid else 2):
        allowed = ("[x, y, z] triples with tetrahedra or hexahedra" if solid else
                   "[x, y] pairs with triangles or quads ([x, y, z] with tetrahedra or "
                   "hexahedra)")
        raise CaseError(f"got points of {dim} coordinates; allowed: {allowed}", file=source,
                        key="geometry.nodes")
    groups, other = ("faces", "edges") if solid else ("edges", "faces")
    if geo.get(other) is not None:
        raise CaseError(f"does not apply to a mesh of {kind}; allowed: [geometry.{groups}]",
                        file=source, key=f"geometry.{other}")
    if geo.get(groups) is None:
        raise CaseError(f"missing key (named boundary {groups} of the {kind})", file=source,
                        key=f"geometry.{groups}")
    if mesh["element"] not in CELL_KEYS[kind]:
        raise CaseError(f"got {mesh['element']!r} for this inline mesh of {kind}; allowed: "
                        + " or ".join(CELL_KEYS[kind]), file=source, key="mesh.element")
    for key in ("size", "structured", "grading"):
        if mesh.get(key) not in (None, False):
            raise CaseError("does not apply to an inline mesh (shape = 'mesh')",
                            file=source, key=f"mesh.{key}")
    return set(geo[groups])


def is_solid(geo: dict) -> bool:
    """Whether a checked ``[geometry]`` describes a 3D body by itself (a gmsh file's
    dimension is known when it is read)."""
    return geo["shape"] in SHAPES_3D or (geo["shape"] == "mesh" and any(
        geo.get(k) is not None for k in SOLID_CELLS))

