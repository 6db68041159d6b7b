"""A case's mesh: the polygon of its geometry, the singular points a graded mesh refines at,
the resource guard's estimate before meshing, and the mesh itself (gmsh shapes and polygons,
3D bodies, files and inline meshes)."""

from __future__ import annotations

import math

import numpy as np

from ..case.schema import Case
from ..fem.elements import get_element
from ..fem.mesh import Mesh
from ..guards import check_dofs, polygon_footprint
from .geometry import parallelogram, polygon, rectangle, validate
from .gmshfile import check_file, file_mesh
from .mesh import build_mesh, inline_mesh
from .singular import contact_run, singular_points, state_junctions
from .solid import check_solid, is_solid, solid_mesh


def geometry_polygon(case: Case):
    """The validated polygon of a gmsh-meshed case."""
    g = case.geometry
    shape = g["shape"]
    if shape == "square":
        poly = rectangle(g["side"], g["side"])
    elif shape == "rectangle":
        poly = rectangle(g["width"], g["height"])
    elif shape == "parallelogram":
        poly = parallelogram(g["base"], g["height"], g["offset"])
    else:
        poly = polygon(np.asarray(g["vertices"], dtype=float), g["edge_names"])
    return validate(poly)


def singular_of(case: Case, poly=None):
    """The singular points (:mod:`critfric.meshing.singular`) where a graded mesh of a
    gmsh-meshed ``case`` refines: contact ends, corners where the boundary condition changes,
    re-entrant corners and the junctions between the states of ``[contact] rules`` (a
    ``source = 'coulomb'`` state is known only after the mesh: its junctions are not graded)."""
    poly = geometry_polygon(case) if poly is None else poly
    return singular_points(poly, case.boundary["contact"], case.boundary["dirichlet"],
                           _junctions(case, poly))


def _junctions(case: Case, poly) -> np.ndarray:
    """Arc lengths along Gamma_C where the state of ``[contact] rules`` changes."""
    c = case.contact
    if c["source"] != "rules":
        return np.zeros(0)
    _, _, length = contact_run(poly, case.boundary["contact"])
    return state_junctions(c["rules"], c["default"], case.solve["gamma"], length)


def polygon_estimate(case: Case, poly=None) -> tuple[float, float]:
    """The DOFs and contact nodes the mesh of a polygon case will have, estimated before
    meshing (grading counted): what the resource guard is given."""
    poly = geometry_polygon(case) if poly is None else poly
    m = case.mesh
    h, element, g = m["size"], m["element"], m["grading"]
    footprint = polygon_footprint(poly.vertices)
    contact = [n for n in case.boundary["contact"] if n in poly.edge_names]
    seg = poly.segments[poly.edge_indices(contact)] if contact else np.zeros((0, 2, 2))
    length = float(np.linalg.norm(seg[:, 1] - seg[:, 0], axis=1).sum())
    order = get_element(element).order
    n_contact = order * length / h
    dofs = footprint.dofs(h, element)
    if g is not None and g < 1:
        sing = singular_of(case, poly)
        radius = 0.5 * sing.run_length  # build_mesh grades over half the contact run
        # a sector of 1.25 x the interior angle a point (graded_nodes counts sectors of
        # 3 pi / 2); measured against gmsh (P1; g = 0.03 ... 0.3; square, inclined body,
        # L-shape, mixed states): 1.2-3.3 x the extra nodes, overlapping zones counted twice
        sectors = 1.25 * float(sing.angle.sum()) / (1.5 * math.pi)
        dofs += 2.0 * footprint.graded_nodes(h, element, g, radius, points=sectors)
        sides = 2 + 2 * len(sing.junctions)  # graded stretches of Gamma_C
        n_contact += order * sides * radius * math.log(1 / g) / (h * (1 - g))
    return dofs, n_contact


def _checked_polygon(case: Case, max_dofs: int | None):
    """The polygon of a case, after the resource guard on the mesh it will give (grading
    and the dense stage on the contact nodes counted)."""
    poly = geometry_polygon(case)
    h, g = case.mesh["size"], case.mesh["grading"]
    dofs, n_contact = polygon_estimate(case, poly)
    check_dofs(dofs, element=case.mesh["element"], what=f"mesh.size = {h:g}"
               + (f" graded by {g:g}" if g is not None else ""), source=case.source,
               footprint=polygon_footprint(poly.vertices), max_dofs=max_dofs,
               n_contact=n_contact, backend=case.solve["backend"], estimate=True)
    return poly


def preflight(case: Case, *, max_dofs: int | None = None, trust_geo: bool = False) -> None:
    """The checks of :func:`make_mesh` that need no mesh (geometry, resource estimate, .geo
    safety): a sweep runs them for every mesh of its grid before it starts."""
    shape = case.geometry["shape"]
    if shape == "file":
        check_file(case, trust_geo=trust_geo)
    elif is_solid(case):
        check_solid(case, max_dofs=max_dofs)
    elif shape != "mesh":
        _checked_polygon(case, max_dofs)


def make_mesh(case: Case, *, max_dofs: int | None = None, trust_geo: bool = False) -> Mesh:
    """The mesh of a case; gmsh shapes pass the resource guard first (:mod:`.guards`)."""
    g, m = case.geometry, case.mesh
    if is_solid(case):
        return solid_mesh(case, max_dofs=max_dofs)
    if g["shape"] == "mesh":
        cells = g["triangles"] if g["triangles"] is not None else g["quads"]
        return inline_mesh(np.asarray(g["nodes"], dtype=float), np.asarray(cells),
                           g["edges"], m["element"])
    if g["shape"] == "file":
        return file_mesh(case, max_dofs=max_dofs, trust_geo=trust_geo)
    poly = _checked_polygon(case, max_dofs)
    graded = m["grading"] is not None and not m["structured"]
    return build_mesh(poly, size=m["size"], element=m["element"],
                      structured=m["structured"], grading=m["grading"],
                      contact=case.boundary["contact"], dirichlet=case.boundary["dirichlet"],
                      junctions=_junctions(case, poly) if graded else ())
