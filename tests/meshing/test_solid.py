"""3D meshes: gmsh boxes and prisms, user .msh/.geo files with volume cells, inline meshes of
tetrahedra and hexahedra, the node-count estimate, and the refusal of wrong 3D keys. Areas and
volumes are computed here from the vertex coordinates, independently of critfric."""

from __future__ import annotations

import dataclasses
import functools

import gmsh
import numpy as np
import pytest

from critfric import loads_case
from critfric.errors import CaseError
from critfric.fem.mesh import orient
from critfric.meshing.cells3d import solid
from critfric.meshing.gmshfile import file_mesh
from critfric.meshing.solid import (
    SolidFootprint,
    box_polygon,
    build_solid,
    check_solid,
    prism_footprint,
    solid_mesh,
)

pytestmark = pytest.mark.once  # the same on both installs: run by `make test` only

ELEMENTS = ["P1", "P2", "Q1", "Q2"]
NV = {"P1": 4, "P2": 4, "Q1": 8, "Q2": 8}
# the 6 tetrahedra around the diagonal 0-6 of a hexahedron (gmsh vertex order)
HEX_TETS = np.array([[0, 1, 2, 6], [0, 2, 3, 6], [0, 3, 7, 6], [0, 7, 4, 6], [0, 4, 5, 6],
                     [0, 5, 1, 6]])
SIZE, ORIGIN = (2.0, 1.0, 0.5), (1.0, -2.0, 3.0)
AXIS = {"x": 0, "y": 1, "z": 2}


def tet_volumes(x):
    """Signed volumes of tetrahedra (..., 4, 3)."""
    return np.einsum("...i,...i->...", x[..., 1, :] - x[..., 0, :],
                     np.cross(x[..., 2, :] - x[..., 0, :], x[..., 3, :] - x[..., 0, :])) / 6


def volumes(m):
    x = m.points[m.cells[:, :NV[m.element]]]
    return tet_volumes(x) if NV[m.element] == 4 else tet_volumes(x[:, HEX_TETS]).sum(axis=1)


def facet_vectors(m, facets):
    """Area vectors (area x unit normal, right-hand rule) of triangles or planar quads."""
    x = m.points[facets[:, :3 if NV[m.element] == 4 else 4]]
    if x.shape[1] == 3:
        return 0.5 * np.cross(x[:, 1] - x[:, 0], x[:, 2] - x[:, 0])
    return 0.5 * np.cross(x[:, 2] - x[:, 0], x[:, 3] - x[:, 1])


@functools.cache
def gmsh_reference_nodes(gmsh_type: int) -> np.ndarray:
    """(n_local, 3) reference coordinates of the nodes of a gmsh element type, from gmsh."""
    owner = not gmsh.isInitialized()
    if owner:
        gmsh.initialize(readConfigFiles=False)
    try:
        return np.reshape(gmsh.model.mesh.getElementProperties(gmsh_type)[4], (-1, 3))
    finally:
        if owner:
            gmsh.finalize()


def all_faces_named(m):
    """``m`` with every boundary face in one group (check_mesh wants the whole boundary)."""
    spec = solid(m.element)
    cells_faces = m.cells[:, spec.facet_local].reshape(-1, spec.facet_nodes)
    keys = np.sort(cells_faces[:, :spec.facet_vertices], axis=1)
    _, first, count = np.unique(keys, axis=0, return_index=True, return_counts=True)
    return dataclasses.replace(m, faces={"all": cells_faces[first[count == 1]]})


def boundary_keys(m):
    """Sorted vertex sets of the cell faces that belong to one cell (in the test's own face
    lists: 4 triangles of a tetrahedron, 6 quadrilaterals of a hexahedron)."""
    local = ([[0, 1, 2], [0, 1, 3], [0, 2, 3], [1, 2, 3]] if NV[m.element] == 4 else
             [[0, 1, 2, 3], [4, 5, 6, 7], [0, 1, 5, 4], [1, 2, 6, 5], [2, 3, 7, 6], [3, 0, 4, 7]])
    faces = np.sort(m.cells[:, local].reshape(-1, len(local[0])), axis=1)
    keys, count = np.unique(faces, axis=0, return_counts=True)
    return keys[count == 1]


def check_nodes(m):
    """Second-order nodes where gmsh puts them: the affine (tetrahedra) or trilinear
    (hexahedra) map of gmsh's reference nodes, whatever the cells' orientation."""
    spec = solid(m.element)
    if spec.order == 2:
        ref = gmsh_reference_nodes(spec.gmsh_cell)
        x = m.points[m.cells]
        if spec.n_vertices == 4:
            lam = np.column_stack([1 - ref.sum(axis=1), ref])  # (n_local, 4)
        else:
            lam = np.prod(1 + ref[:, None, :] * ref[None, :8, :], axis=2) / 8  # (n_local, 8)
        np.testing.assert_allclose(x, np.einsum("kv,cvi->cki", lam, x[:, :spec.n_vertices]),
                                   atol=1e-12)


def check_mesh(m):
    """Positive cells, every node used, second-order nodes where gmsh puts them (its
    reference coordinates), the named faces exactly the boundary faces."""
    assert m.dim == 3 and m.cells.shape[1] == {"P1": 4, "P2": 10, "Q1": 8, "Q2": 27}[m.element]
    assert np.all(volumes(m) > 0)
    np.testing.assert_array_equal(np.unique(m.cells), np.arange(m.n_nodes))
    check_nodes(m)
    spec = solid(m.element)
    named = np.concatenate([np.sort(f[:, :spec.facet_vertices], axis=1)
                            for f in m.faces.values()])
    assert len(np.unique(named, axis=0)) == len(named)
    np.testing.assert_array_equal(np.unique(named, axis=0), boundary_keys(m))


# ------------------------------------------------------------------------------ boxes
def box_case(element, size=0.25, extra=""):
    return loads_case(f"""
[geometry]
shape = "box"
size = {list(SIZE)}
origin = {list(ORIGIN)}
{extra}
[boundary]
contact = ["z0"]
dirichlet = ["z1"]
[mesh]
element = "{element}"
size = {size}
""")


@pytest.mark.parametrize("element", ELEMENTS)
def test_box_faces_lie_on_their_planes_point_out_and_have_the_right_areas(element):
    m = solid_mesh(box_case(element))
    check_mesh(m)
    assert sorted(m.faces) == ["x0", "x1", "y0", "y1", "z0", "z1"]
    nodes = {"P1": 3, "P2": 6, "Q1": 4, "Q2": 9}[element]
    for name, facets in m.faces.items():
        assert facets.shape[1] == nodes
        k, end = AXIS[name[0]], int(name[1])
        plane = ORIGIN[k] + end * SIZE[k]
        np.testing.assert_allclose(m.points[facets][..., k], plane, atol=1e-12)
        area = facet_vectors(m, facets)
        outward = np.zeros(3)
        outward[k] = 1.0 if end else -1.0
        np.testing.assert_allclose(area / np.linalg.norm(area, axis=1)[:, None],
                                   np.broadcast_to(outward, area.shape), atol=1e-12)
        others = [SIZE[i] for i in range(3) if i != k]
        assert np.linalg.norm(area, axis=1).sum() == pytest.approx(others[0] * others[1],
                                                                   rel=1e-12)


@pytest.mark.parametrize("element", ELEMENTS)
def test_box_cells_fill_the_box(element):
    m = solid_mesh(box_case(element))
    assert volumes(m).sum() == pytest.approx(np.prod(SIZE), rel=1e-12)
    np.testing.assert_allclose(m.points.min(axis=0), ORIGIN, atol=1e-12)
    np.testing.assert_allclose(m.points.max(axis=0), np.add(ORIGIN, SIZE), atol=1e-12)


@pytest.mark.parametrize("element, cells, nodes", [
    ("Q1", 8 * 4 * 2, 9 * 5 * 3), ("Q2", 8 * 4 * 2, 17 * 9 * 5)])
def test_box_hexahedra_are_structured(element, cells, nodes):
    m = solid_mesh(box_case(element))
    assert (m.n_cells, m.n_nodes) == (cells, nodes)
    assert m.diameter == pytest.approx(np.sqrt(3 * 0.25**2), rel=1e-9)


@pytest.mark.parametrize("element", ELEMENTS)
def test_the_flip_reverses_a_cell_and_keeps_its_nodes_in_place(element):
    m = solid_mesh(box_case(element, size=0.5))
    flipped = dataclasses.replace(m, cells=m.cells[:, solid(element).flip])
    assert np.all(volumes(flipped) < 0)
    check_nodes(flipped)
    cells, volume = orient(m.points, flipped.cells, element)
    np.testing.assert_array_equal(cells, m.cells)
    assert np.all(volume < 0)


def test_box_tetrahedra_have_about_the_size_asked_for():
    m = solid_mesh(box_case("P1", size=0.2))
    x = m.points[m.cells]
    edges = np.linalg.norm(x[:, [0, 0, 0, 1, 1, 2]] - x[:, [1, 2, 3, 2, 3, 3]], axis=-1)
    assert 0.12 < np.median(edges) < 0.3 and m.diameter < 0.45


# ------------------------------------------------------------------------------ prisms
PRISM_VERTICES = [[0, 0], [0.4, 0], [1, 0], [1.2, 0.8], [0.1, 1]]
PRISM_NAMES = ["pad", "base", "base", "slope", "top"]


def prism_case(element, vertices=PRISM_VERTICES, names=PRISM_NAMES, depth=0.6):
    names_line = f"edge_names = {names}" if names else ""
    return loads_case(f"""
[geometry]
shape = "prism"
vertices = {vertices}
{names_line}
depth = {depth}
[boundary]
contact = ["{names[0] if names else 'e0'}"]
dirichlet = ["z1"]
[mesh]
element = "{element}"
size = 0.2
""")


@pytest.mark.parametrize("element", ELEMENTS)
def test_prism_side_faces_are_named_after_the_polygon_edges(element):
    depth = 0.6
    m = solid_mesh(prism_case(element, depth=depth))
    check_mesh(m)
    v = np.array(PRISM_VERTICES, dtype=float)
    length = np.linalg.norm(np.roll(v, -1, axis=0) - v, axis=1)
    expected = {name: 0.0 for name in PRISM_NAMES}
    for name, edge_length in zip(PRISM_NAMES, length):
        expected[name] += edge_length * depth
    polygon_area = 0.5 * abs(np.sum(v[:, 0] * np.roll(v[:, 1], -1) - np.roll(v[:, 0], -1)
                                    * v[:, 1]))
    expected.update(z0=polygon_area, z1=polygon_area)
    assert sorted(m.faces) == sorted(expected)
    for name, area in expected.items():
        vectors = facet_vectors(m, m.faces[name])
        assert np.linalg.norm(vectors, axis=1).sum() == pytest.approx(area, rel=1e-9), name
    # the pad's faces lie over the edge [0, 0] - [0.4, 0]
    pad = m.points[m.faces["pad"]]
    np.testing.assert_allclose(pad[..., 1], 0.0, atol=1e-12)
    assert pad[..., 0].min() > -1e-12 and pad[..., 0].max() < 0.4 + 1e-12
    assert volumes(m).sum() == pytest.approx(polygon_area * depth, rel=1e-9)


def test_prism_default_names_follow_the_edges_of_a_clockwise_polygon():
    clockwise = [[0, 0], [0, 1], [1, 1], [1, 0]]  # e0 is the left side x = 0
    m = solid_mesh(prism_case("P1", vertices=clockwise, names=None, depth=0.5))
    assert sorted(m.faces) == ["e0", "e1", "e2", "e3", "z0", "z1"]
    np.testing.assert_allclose(m.points[m.faces["e0"]][..., 0], 0.0, atol=1e-12)
    np.testing.assert_allclose(m.points[m.faces["e1"]][..., 1], 1.0, atol=1e-12)


# ------------------------------------------------------------------------------ gmsh files
FILE_CASE = """
[geometry]
shape = "file"
file = "{file}"
{extra}
[boundary]
contact = ["bottom"]
dirichlet = ["top"]
[mesh]
element = "{element}"
"""


def _write_box_msh(path, *, order=1, hexes=False, named=True, wedge=False):
    """A 1 x 1 x 0.5 box meshed and written by gmsh, with physical groups."""
    gmsh.initialize(readConfigFiles=False)
    gmsh.option.setNumber("General.Terminal", 0)
    try:
        gmsh.model.add("box")
        geo = gmsh.model.geo
        p = [geo.addPoint(x, y, 0, 0.3) for x, y in [(0, 0), (1, 0), (1, 1), (0, 1)]]
        lines = [geo.addLine(p[i], p[(i + 1) % 4]) for i in range(4)]
        base = geo.addPlaneSurface([geo.addCurveLoop(lines)])
        out = geo.extrude([(2, base)], 0, 0, 0.5, numElements=[2] if hexes or wedge else [],
                          recombine=hexes or wedge)  # a triangle base: wedges
        geo.synchronize()
        if hexes:
            for line in lines:
                gmsh.model.mesh.setTransfiniteCurve(line, 4)
            gmsh.model.mesh.setTransfiniteSurface(base)
            gmsh.model.mesh.setRecombine(2, base)
        gmsh.model.addPhysicalGroup(2, [base], name="bottom" if named else "")
        gmsh.model.addPhysicalGroup(2, [out[0][1]], name="top" if named else "")
        gmsh.model.addPhysicalGroup(2, [t for _, t in out[2:]], name="sides")
        gmsh.model.addPhysicalGroup(3, [out[1][1]], name="body")
        gmsh.model.mesh.generate(3)
        if order == 2:
            gmsh.option.setNumber("Mesh.SecondOrderIncomplete", 0)
            gmsh.model.mesh.setOrder(2)
        gmsh.write(str(path))
    finally:
        gmsh.finalize()


def _file_case(tmp_path, name, element="P1", extra=""):
    return loads_case(FILE_CASE.format(file=(tmp_path / name).as_posix(), element=element,
                                       extra=extra),
                      source=str(tmp_path / "case.toml"))


@pytest.mark.parametrize("order, hexes, element", [
    (1, False, "P1"), (2, False, "P2"), (1, True, "Q1"), (2, True, "Q2"), (2, False, "P1")])
def test_a_box_msh_written_by_gmsh_is_read_back(tmp_path, order, hexes, element):
    _write_box_msh(tmp_path / "box.msh", order=order, hexes=hexes)
    m = file_mesh(_file_case(tmp_path, "box.msh", element, 'domain = "body"'))
    check_mesh(m)
    assert sorted(m.faces) == ["bottom", "sides", "top"]
    assert volumes(m).sum() == pytest.approx(0.5, rel=1e-12)
    for name, area, z in [("bottom", 1.0, 0.0), ("top", 1.0, 0.5), ("sides", 2.0, None)]:
        vectors = facet_vectors(m, m.faces[name])
        assert np.linalg.norm(vectors, axis=1).sum() == pytest.approx(area, rel=1e-12)
        if z is not None:
            np.testing.assert_allclose(m.points[m.faces[name]][..., 2], z, atol=1e-12)
            assert np.all(vectors[:, 2] * (z - 0.25) > 0)  # out of the body


def test_unnamed_physical_surfaces_are_known_by_number(tmp_path):
    _write_box_msh(tmp_path / "box.msh", named=False)
    m = file_mesh(_file_case(tmp_path, "box.msh"))
    assert sorted(m.faces) == ["1", "2", "sides"]


@pytest.mark.parametrize("element", ["P2", "Q1"])
def test_a_geo_script_with_a_volume_is_meshed_in_3d(tmp_path, element):
    layers = "Layers{2}; Recombine;" if element == "Q1" else ""
    quads = "Transfinite Curve{1:4} = 4; Transfinite Surface{1}; Recombine Surface{1};"
    (tmp_path / "box.geo").write_text(f"""
Point(1) = {{0, 0, 0, 0.3}}; Point(2) = {{1, 0, 0, 0.3}};
Point(3) = {{1, 1, 0, 0.3}}; Point(4) = {{0, 1, 0, 0.3}};
Line(1) = {{1, 2}}; Line(2) = {{2, 3}}; Line(3) = {{3, 4}}; Line(4) = {{4, 1}};
Curve Loop(1) = {{1, 2, 3, 4}}; Plane Surface(1) = {{1}};
{quads if element == "Q1" else ""}
out[] = Extrude {{0, 0, 0.5}} {{ Surface{{1}}; {layers} }};
Physical Surface("bottom") = {{1}};
Physical Surface("top") = {{out[0]}};
Physical Volume("body") = {{out[1]}};
""")
    m = file_mesh(_file_case(tmp_path, "box.geo", element))
    check_mesh(all_faces_named(m))
    assert m.element == element and sorted(m.faces) == ["bottom", "top"]
    assert volumes(m).sum() == pytest.approx(0.5, rel=1e-12)
    if element == "Q1":
        assert m.n_cells == 3 * 3 * 2


@pytest.mark.parametrize("make, words, key", [
    ({"hexes": True}, ("'P1'", "hexahedra", "Q1 or Q2"), "mesh.element"),
    ({"wedge": True}, ("wedge", "tetrahedra only or hexahedra only"), "geometry.file"),
])
def test_wrong_3d_msh_files_are_refused(tmp_path, make, words, key):
    _write_box_msh(tmp_path / "box.msh", **make)
    with pytest.raises(CaseError) as err:
        file_mesh(_file_case(tmp_path, "box.msh", "P1"))
    assert err.value.key == key and "box.msh" in str(err.value)
    for word in words:
        assert word in str(err.value)


def test_a_missing_physical_volume_is_refused(tmp_path):
    _write_box_msh(tmp_path / "box.msh")
    with pytest.raises(CaseError) as err:
        file_mesh(_file_case(tmp_path, "box.msh", extra='domain = "steel"'))
    assert err.value.key == "geometry.domain"
    assert "'steel'" in str(err.value) and "body" in str(err.value)


def test_a_msh_with_tetrahedra_and_hexahedra_is_refused(tmp_path):
    import meshio

    points = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0, 0, 1], [1, 0, 1],
                       [1, 1, 1], [0, 1, 1], [0.5, 0.5, 2]], dtype=float)
    mesh = meshio.Mesh(points, [("hexahedron", [[0, 1, 2, 3, 4, 5, 6, 7]]),
                                ("tetra", [[4, 5, 6, 8]]), ("quad", [[0, 3, 2, 1]])],
                       cell_data={"gmsh:physical": [[1], [1], [2]],
                                  "gmsh:geometrical": [[1], [1], [2]]},
                       field_data={"body": np.array([1, 3]), "bottom": np.array([2, 2])})
    mesh.write(tmp_path / "mixed.msh", file_format="gmsh22", binary=False)
    with pytest.raises(CaseError) as err:
        file_mesh(_file_case(tmp_path, "mixed.msh", "Q1"))
    assert err.value.key == "geometry.file" and "mixes tetrahedra and hexahedra" in str(err.value)


# ------------------------------------------------------------------------------ inline meshes
CUBE = [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]]
# the unit cube as 6 tetrahedra around its diagonal 0-6, some given with negative orientation
CUBE_TETS = [[0, 1, 2, 6], [0, 3, 2, 6], [0, 3, 7, 6], [0, 4, 7, 6], [0, 4, 5, 6], [0, 1, 5, 6]]


def inline_case(element="P1", cells=CUBE_TETS, kind="tetrahedra", nodes=CUBE, faces=None):
    faces = {"bottom": [[0, 1, 2], [0, 2, 3]], "top": [[4, 5, 6], [4, 6, 7]], **(faces or {})}
    lines = "\n".join(f"{k} = {v}" for k, v in faces.items())
    return loads_case(f"""
[geometry]
shape = "mesh"
nodes = {nodes}
{kind} = {cells}
[geometry.faces]
{lines}
[boundary]
contact = ["bottom"]
dirichlet = ["top"]
[mesh]
element = "{element}"
""")


@pytest.mark.parametrize("element", ["P1", "P2"])
def test_an_inline_tetrahedron_mesh(element):
    m = solid_mesh(inline_case(element))
    assert m.n_cells == 6 and m.n_nodes == (8 if element == "P1" else 8 + 19)
    assert np.all(volumes(m) > 0) and volumes(m).sum() == pytest.approx(1.0)
    np.testing.assert_array_equal(m.points[:8], CUBE)  # the given nodes keep their numbers
    check_mesh(all_faces_named(m))
    for name, z, sign in [("bottom", 0.0, -1), ("top", 1.0, 1)]:
        vectors = facet_vectors(m, m.faces[name])
        np.testing.assert_allclose(m.points[m.faces[name]][..., 2], z)
        assert np.all(vectors[:, 2] * sign > 0)  # out of the body
        assert np.linalg.norm(vectors, axis=1).sum() == pytest.approx(1.0)


@pytest.mark.parametrize("element", ["Q1", "Q2"])
def test_an_inline_hexahedron_mesh(element):
    nodes = CUBE + [[2, 0, 0], [2, 1, 0], [2, 0, 1], [2, 1, 1]]
    cells = [[0, 1, 2, 3, 4, 5, 6, 7], [1, 5, 6, 2, 8, 10, 11, 9]]  # the second inverted
    faces = {"bottom": [[0, 1, 2, 3], [1, 8, 9, 2]], "top": [[4, 5, 6, 7], [5, 10, 11, 6]]}
    m = solid_mesh(inline_case(element, cells, "hexahedra", nodes, faces))
    assert np.all(volumes(m) > 0) and volumes(m).sum() == pytest.approx(2.0)
    check_mesh(all_faces_named(m))
    assert m.n_nodes == (12 if element == "Q1" else 12 + 20 + 11 + 2)
    assert m.faces["bottom"].shape == (2, 4 if element == "Q1" else 9)
    assert np.all(facet_vectors(m, m.faces["bottom"])[:, 2] < 0)


BAD_INLINE = [
    ("index out of range", {"cells": [[0, 1, 2, 6], [0, 3, 2, 9]]}, "geometry.tetrahedra",
     "0..7"),
    ("non-boundary face", {"faces": {"bottom": [[0, 1, 2]], "inner": [[0, 2, 6]]}},
     "geometry.faces.inner", "interior face"),
    ("not a face", {"faces": {"bottom": [[0, 1, 2]], "top": [[0, 1, 7]]}},
     "geometry.faces.top", "not a face of any cell"),
    ("flat tetrahedron", {"cells": CUBE_TETS + [[0, 1, 2, 3]]}, "geometry.tetrahedra", "flat"),
    ("unused node", {"nodes": CUBE + [[5, 5, 5]]}, "geometry.nodes", "node 8"),
    ("quadrilateral for a tetrahedron", {"faces": {"bottom": [[0, 1, 2, 3]]}},
     "geometry.faces.bottom", "rows of 3"),
    ("twisted hexahedron", {"kind": "hexahedra", "cells": [[0, 1, 3, 2, 4, 5, 6, 7]],
                            "element": "Q1", "faces": {"bottom": [[0, 1, 2, 3]]}},
     "geometry.hexahedra", "not convex"),
]


@pytest.mark.parametrize("what, change, key, words", BAD_INLINE,
                         ids=[b[0] for b in BAD_INLINE])
def test_wrong_inline_meshes_are_refused_with_the_key(what, change, key, words):
    with pytest.raises(CaseError) as err:
        solid_mesh(inline_case(**change))
    assert err.value.key == key and words in str(err.value)


# ------------------------------------------------------------------------------ case keys
BOX_TEXT = """
[geometry]
shape = "box"
{geometry}
[boundary]
contact = ["z0"]
dirichlet = ["z1"]
[mesh]
size = 0.25
{mesh}
"""

BAD_KEYS = [
    (BOX_TEXT.format(geometry="size = [1.0, 0.0, 1.0]", mesh=""), "geometry.size", "above 0"),
    (BOX_TEXT.format(geometry="size = [1.0, 1.0]", mesh=""), "geometry.size", "[x, y, z]"),
    (BOX_TEXT.format(geometry="origin = [0, 0, nan]", mesh=""), "geometry.origin", "finite"),
    (BOX_TEXT.format(geometry="depth = 2.0", mesh=""), "geometry.depth", "unknown key"),
    (BOX_TEXT.format(geometry="", mesh="structured = true"), "mesh.structured", "3D"),
    (BOX_TEXT.format(geometry="", mesh="grading = 0.1"), "mesh.grading", "3D"),
    (BOX_TEXT.format(geometry="", mesh="").replace('["z0"]', '["bottom"]'), "boundary.contact",
     "unknown face 'bottom'"),
    (('[geometry]\nshape = "prism"\nvertices = [[0, 0], [1, 0], [0, 1]]\ndepth = 0\n'
     '[mesh]\nsize = 0.1'), "geometry.depth", "(0, inf]"),
    (('[geometry]\nshape = "prism"\nvertices = [[0, 0], [1, 0], [0, 1]]\n'
     'edge_names = ["a", "z0", "b"]\n[mesh]\nsize = 0.1'), "geometry.edge_names", "end face"),
    (('[geometry]\nshape = "mesh"\nnodes = [[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]]\n'
     'tetrahedra = [[0, 1, 2, 3]]\n[geometry.edges]\nb = [[0, 1]]\n'), "geometry.edges",
     "[geometry.faces]"),
    (('[geometry]\nshape = "mesh"\nnodes = [[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]]\n'
     'tetrahedra = [[0, 1, 2, 3]]\n'), "geometry.faces", "missing key"),
    (('[geometry]\nshape = "mesh"\nnodes = [[0, 0], [1, 0], [0, 1], [1, 1]]\n'
     'tetrahedra = [[0, 1, 2, 3]]\n[geometry.faces]\nb = [[0, 1, 2]]\n'), "geometry.nodes",
     "[x, y, z]"),
    (('[geometry]\nshape = "mesh"\nnodes = [[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]]\n'
     'tetrahedra = [[0, 1, 2]]\n[geometry.faces]\nb = [[0, 1, 2]]\n'), "geometry.tetrahedra",
     "rows of 4"),
    (('[geometry]\nshape = "mesh"\nnodes = [[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]]\n'
     'tetrahedra = [[0, 1, 2, 3]]\n[geometry.faces]\nb = [[0, 1, 2]]\n[mesh]\nelement = "Q1"'),
     "mesh.element", "P1 or P2"),
    (('[geometry]\nshape = "mesh"\nnodes = [[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]]\n'
     'tetrahedra = [[0, 1, 2, 3]]\nhexahedra = [[0, 1, 2, 3, 0, 1, 2, 3]]\n'
     '[geometry.faces]\nb = [[0, 1, 2]]\n'), "geometry.hexahedra", "exactly one of"),
    (('[geometry]\nshape = "mesh"\nnodes = [[0, 0, 0], [1, 0, 0], [0, 1], [0, 0, 1]]\n'
     'tetrahedra = [[0, 1, 2, 3]]\n[geometry.faces]\nb = [[0, 1, 2]]\n'), "geometry.nodes",
     "all of one kind"),
]


@pytest.mark.parametrize("text, key, words", BAD_KEYS, ids=[b[1] + ": " + b[2] for b in BAD_KEYS])
def test_wrong_3d_keys_are_refused_with_the_key(text, key, words):
    with pytest.raises(CaseError) as err:
        loads_case(text, source="bad.toml")
    assert err.value.key == key and str(err.value).startswith("bad.toml")
    assert words in str(err.value)


def test_defaults_of_a_box_and_a_prism():
    box = loads_case(BOX_TEXT.format(geometry="", mesh=""))
    assert box.geometry["size"] == [1.0, 1.0, 1.0] and box.geometry["origin"] == [0.0] * 3
    prism = prism_case("P1")
    assert prism.geometry["depth"] == 0.6


# ------------------------------------------------------------------------------ resources
@pytest.mark.parametrize("element", ELEMENTS)
def test_the_node_estimate_is_near_the_real_count(element):
    m = solid_mesh(box_case(element, size=0.125))
    poly, _, depth = box_polygon(SIZE, ORIGIN)
    estimate = prism_footprint(poly, depth).nodes(0.125, element)
    assert 1.0 < estimate / m.n_nodes < 1.6  # (measured 1.18, 1.48, 1.01, 1.22)


def test_finest_size_inverts_the_dof_estimate():
    footprint = SolidFootprint(2.0, 10.0, 12.0, 8)
    for element in ELEMENTS:
        h = footprint.finest_size(1e6, element)
        assert footprint.dofs(h, element) == pytest.approx(1e6, rel=1e-9)
    assert footprint.finest_size(10, "Q2") == np.inf


def test_a_box_too_fine_for_memory_is_refused_before_meshing():
    with pytest.raises(CaseError) as err:
        check_solid(box_case("P2", size=0.002), max_dofs=10**6)
    message = str(err.value)
    assert err.value.key == "mesh.size" and "finest mesh size" in message
    assert "--max-dofs" in message


def test_build_solid_refuses_a_structured_tetrahedral_mesh():
    poly, z0, depth = box_polygon(SIZE, ORIGIN)
    with pytest.raises(CaseError) as err:
        build_solid(poly, depth=depth, z0=z0, size=0.5, element="P1", structured=True)
    assert err.value.key == "mesh.structured"
