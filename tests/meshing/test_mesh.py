"""Meshes: gmsh meshes of polygons (counts, orientation, midpoints, edge groups, grading) and
inline meshes from case files."""

import gmsh
import numpy as np
import pytest

import critfric.meshing.mesh as mesh_module
from critfric.errors import CaseError, SolverError
from critfric.fem.elements import get_element
from critfric.fem.mesh import Mesh, orient, signed_areas
from critfric.meshing.geometry import parallelogram, polygon, rectangle
from critfric.meshing.mesh import build_mesh, inline_mesh

pytestmark = pytest.mark.once  # the same on both installs: run by `make test` only

ELEMENTS = ["P1", "P2", "Q1", "Q2"]
NV = {"P1": 3, "P2": 3, "Q1": 4, "Q2": 4}
# bottom side split into named parts b | c | b (collinear vertices), contact "c" in the middle
SPLIT = polygon([(0, 0), (0.3, 0), (0.7, 0), (1, 0), (1.2, 0.8), (0.1, 1)],
                ["b", "c", "b", "r", "t", "l"])
SHAPES = {
    "split": SPLIT,
    "triangle": polygon([(0, 0), (1, 0), (0.3, 0.9)]),
    "parallelogram": parallelogram(2.0, 1.0, -0.7),
}


# ---------------------------------------------------------------------------- checks


def check_cells(m):
    """Counterclockwise, non-degenerate (quads: convex), every node used."""
    assert m.cells.dtype == np.int64 and m.cells.shape[1] == {"P1": 3, "P2": 6, "Q1": 4,
                                                              "Q2": 9}[m.element]
    assert np.all(signed_areas(m.points, m.cells, m.element) > 0)
    v = m.points[m.cells[:, : NV[m.element]]]
    d = np.roll(v, -1, axis=1) - v
    corner = d[..., 0] * np.roll(d, -1, axis=1)[..., 1] - d[..., 1] * np.roll(d, -1, axis=1)[..., 0]
    assert np.all(corner > 0)
    np.testing.assert_array_equal(np.unique(m.cells), np.arange(m.n_nodes))


def check_midpoints(m):
    if m.element == "P2":
        pairs = [(0, 1), (1, 2), (2, 0)]
    elif m.element == "Q2":
        pairs = [(0, 1), (1, 2), (2, 3), (3, 0)]
        np.testing.assert_allclose(m.points[m.cells[:, 8]],
                                   m.points[m.cells[:, :4]].mean(axis=1), atol=1e-12)
    else:
        return
    for k, (a, b) in enumerate(pairs):
        mid = 0.5 * (m.points[m.cells[:, a]] + m.points[m.cells[:, b]])
        np.testing.assert_allclose(m.points[m.cells[:, NV[m.element] + k]], mid, atol=1e-12)
    for facets in m.edges.values():
        mid = 0.5 * (m.points[facets[:, 0]] + m.points[facets[:, 1]])
        np.testing.assert_allclose(m.points[facets[:, 2]], mid, atol=1e-12)


def boundary_keys(m):
    """Sorted-vertex keys of the cell edges that belong to exactly one cell."""
    nv = NV[m.element]
    e = m.cells[:, np.stack([np.arange(nv), np.roll(np.arange(nv), -1)], axis=1)].reshape(-1, 2)
    keys, count = np.unique(np.sort(e, axis=1) @ [m.n_nodes, 1], return_counts=True)
    return keys[count == 1]


def check_edges(m, poly):
    """Each group's facets lie on its polygon edges, run along them (domain on the left), cover
    their length; together the groups are exactly the mesh boundary."""
    seg = poly.segments
    for name in poly.group_names:
        facets = m.edges[name]
        assert facets.shape[1] == (3 if m.element in ("P2", "Q2") else 2)
        p, q = m.points[facets[:, 0]], m.points[facets[:, 1]]
        edges = seg[poly.edge_indices(name)]
        a, b = edges[:, 0], edges[:, 1]  # (k, 2)
        u = (b - a) / np.linalg.norm(b - a, axis=1)[:, None]
        # each facet end point on (within) one of the named edges, facet parallel to it
        on = []
        for x in (p, q):
            r = x[:, None, :] - a[None]  # (f, k, 2)
            t = np.einsum("fkj,kj->fk", r, u)
            dist = np.abs(r[..., 0] * u[:, 1] - r[..., 1] * u[:, 0])
            on.append((dist < 1e-12) & (t > -1e-12) & (t < np.linalg.norm(b - a, axis=1) + 1e-12))
        both = on[0] & on[1]
        assert np.all(both.any(axis=1)), name
        k = np.argmax(both, axis=1)
        assert np.all(np.einsum("fj,fj->f", q - p, u[k]) > 0), name  # same direction
        assert np.linalg.norm(q - p, axis=1).sum() == pytest.approx(
            np.linalg.norm(b - a, axis=1).sum(), rel=1e-12)
    groups = np.concatenate([np.sort(f[:, :2], axis=1) @ [m.n_nodes, 1] for f in m.edges.values()])
    np.testing.assert_array_equal(np.sort(groups), boundary_keys(m))


# ---------------------------------------------------------------------------- gmsh meshes


@pytest.mark.parametrize("element, nodes, cells", [
    ("P1", 9 * 5, 2 * 8 * 4), ("P2", 17 * 9, 2 * 8 * 4),
    ("Q1", 9 * 5, 8 * 4), ("Q2", 17 * 9, 8 * 4),
])
def test_structured_counts(element, nodes, cells):
    m = build_mesh(rectangle(2.0, 1.0), size=0.25, element=element, structured=True)
    assert (m.n_nodes, m.n_cells) == (nodes, cells)
    assert {k: len(v) for k, v in m.edges.items()} == {"bottom": 8, "right": 4, "top": 8,
                                                       "left": 4}
    check_cells(m)
    check_midpoints(m)
    check_edges(m, rectangle(2.0, 1.0))


def test_structured_subdivisions_round_up_and_match_opposite_edges():
    # 1.1 / 0.1 is 11.000000000000002 in floating point: still 11 subdivisions
    m = build_mesh(rectangle(1.1, 0.3), size=0.1, element="Q1", structured=True)
    assert (m.n_nodes, m.n_cells) == (12 * 4, 11 * 3)
    # slanted sides sqrt(0.5^2 + 1) = 1.118 -> 5 subdivisions, bottom/top 1.0 -> 4
    p = parallelogram(1.0, 1.0, 0.5)
    m = build_mesh(p, size=0.25, element="P1", structured=True)
    assert (m.n_nodes, m.n_cells) == (5 * 6, 2 * 4 * 5)
    check_cells(m)
    check_edges(m, p)


@pytest.mark.parametrize("shape", SHAPES)
@pytest.mark.parametrize("element", ELEMENTS)
def test_unstructured_meshes_are_valid(shape, element):
    poly = SHAPES[shape]
    m = build_mesh(poly, size=0.15, element=element)
    check_cells(m)
    check_midpoints(m)
    check_edges(m, poly)


@pytest.mark.parametrize("element", ELEMENTS)
def test_orientation_fix_keeps_gmsh_node_order(element):
    m = build_mesh(SPLIT, size=0.2, element=element)
    cells = m.cells.copy()
    cells[::2] = cells[::2][:, get_element(element).flip]  # clockwise, midpoints consistent
    flipped = Mesh(m.points, cells, element)
    check_midpoints(flipped)
    assert np.all(signed_areas(m.points, cells, element)[::2] < 0)
    fixed, _ = orient(m.points, cells, element)
    np.testing.assert_array_equal(fixed, m.cells)


def test_collinear_vertices_keep_separate_groups():
    m = build_mesh(SPLIT, size=0.1, element="P1")
    assert set(m.edges) == {"b", "c", "r", "t", "l"}
    xb = m.points[m.edges["b"]][..., 0]
    xc = m.points[m.edges["c"]][..., 0]
    assert np.all((xb <= 0.3 + 1e-12) | (xb >= 0.7 - 1e-12))
    assert xc.min() == pytest.approx(0.3) and xc.max() == pytest.approx(0.7)
    np.testing.assert_array_equal(np.intersect1d(m.edge_nodes(["b"]), m.edge_nodes(["c"])).size, 2)


@pytest.mark.parametrize("element", ["P1", "Q2"])
def test_refined_path_matches_direct_meshing(monkeypatch, element):
    monkeypatch.setattr(mesh_module, "NEST_FRACTION", 1e-9)  # gmsh at h
    assert mesh_module._refinements(SPLIT, 0.025) == 0
    direct = build_mesh(SPLIT, size=0.025, element=element)
    monkeypatch.setattr(mesh_module, "NEST_FRACTION", 0.04 / 1.2)  # gmsh at 2h, split once
    assert mesh_module._refinements(SPLIT, 0.025) == 1
    refined = build_mesh(SPLIT, size=0.025, element=element)
    assert refined.n_nodes == pytest.approx(direct.n_nodes, rel=0.15)
    for m in (direct, refined):
        check_cells(m)
        check_midpoints(m)
        check_edges(m, SPLIT)


def test_meshes_of_halved_sizes_are_nested():
    from scipy.spatial import cKDTree

    """h, h/2 and h/4 below the canonical coarse size: one gmsh mesh, split 1, 2 and 3 times
    (every node of the coarser mesh is a node of the finer one, cells 4x)."""
    extent = float(np.ptp(SPLIT.vertices, axis=0).max())
    h = mesh_module.NEST_FRACTION * extent / 2
    meshes = [build_mesh(SPLIT, size=h / 2**k, element="P1") for k in range(3)]
    for coarse, fine in zip(meshes, meshes[1:]):
        assert fine.n_cells == 4 * coarse.n_cells
        near, _ = cKDTree(fine.points).query(coarse.points)
        assert near.max() < 1e-12 * extent


@pytest.mark.parametrize("element", ["P1", "Q1"])
def test_grading_refines_near_contact_ends(element):
    poly = rectangle(1.0, 0.5)
    uniform = build_mesh(poly, size=0.1, element=element)
    m = build_mesh(poly, size=0.1, element=element, grading=0.2, contact=["bottom"])
    check_cells(m)
    check_edges(m, poly)
    facets = m.points[m.edges["bottom"]]  # (f, 2, 2)
    length = np.linalg.norm(facets[:, 1] - facets[:, 0], axis=1)
    x = facets.mean(axis=1)[:, 0]
    near, middle = length[(x < 0.1) | (x > 0.9)], length[np.abs(x - 0.5) < 0.1]
    assert near.max() < middle.min()
    assert near.min() < 0.5 * 0.1
    assert m.n_cells > uniform.n_cells


def test_invalid_requests_raise_case_errors():
    with pytest.raises(CaseError, match="4-vertex"):
        build_mesh(SPLIT, size=0.1, element="P1", structured=True)
    with pytest.raises(CaseError, match="unknown element"):
        build_mesh(SPLIT, size=0.1, element="P3")
    with pytest.raises(CaseError, match="mesh.size"):
        build_mesh(SPLIT, size=-1, element="P1")
    with pytest.raises(CaseError, match="contact"):
        build_mesh(SPLIT, size=0.1, element="P1", grading=0.5)
    with pytest.raises(CaseError, match="unknown edge"):
        build_mesh(SPLIT, size=0.1, element="P1", grading=0.5, contact=["nope"])
    with pytest.raises(CaseError, match="straight"):
        build_mesh(SPLIT, size=0.1, element="P1", grading=0.5, contact=["c", "r"])
    with pytest.raises(CaseError, match="grading"):
        build_mesh(SPLIT, size=0.1, element="P1", grading=1.5, contact="c")
    assert gmsh.isInitialized() == 0


def test_gmsh_finalized_after_error_inside_build(monkeypatch):
    def broken(element):
        raise RuntimeError("boom")

    monkeypatch.setattr(mesh_module, "_extract", broken)
    with pytest.raises(SolverError, match="boom"):
        build_mesh(SPLIT, size=0.2, element="P1")
    assert gmsh.isInitialized() == 0
    monkeypatch.undo()
    build_mesh(SPLIT, size=0.2, element="P2", grading=0.5, contact="c")  # still usable
    assert gmsh.isInitialized() == 0


def test_meshing_is_silent_and_reproducible(capfd):
    a = build_mesh(SPLIT, size=0.1, element="Q2", grading=0.5, contact="c")
    out, err = capfd.readouterr()
    assert out == "" and err == ""
    b = build_mesh(SPLIT, size=0.1, element="Q2", grading=0.5, contact="c")
    np.testing.assert_array_equal(a.points, b.points)
    np.testing.assert_array_equal(a.cells, b.cells)


# ---------------------------------------------------------------------------- inline meshes

SQUARE_NODES = [[0, 0], [1, 0], [1, 1], [0, 1], [0.5, 0.5]]
# four triangles around the centre node; the last one given clockwise
SQUARE_TRIANGLES = [[0, 1, 4], [1, 2, 4], [2, 3, 4], [3, 4, 0]]
SQUARE_EDGES = {"bottom": [[1, 0]], "right": [[1, 2]], "top": [[2, 3]], "left": [[3, 0]]}


def test_inline_one_triangle():
    m = inline_mesh([[0, 0], [1, 0], [0, 1]], [[0, 1, 2]],
                    {"contact": [[0, 1]], "fixed": [[1, 2], [2, 0]]}, "P1")
    np.testing.assert_array_equal(m.cells, [[0, 1, 2]])
    np.testing.assert_array_equal(m.edges["contact"], [[0, 1]])
    np.testing.assert_array_equal(m.edges["fixed"], [[1, 2], [2, 0]])
    m2 = inline_mesh([[0, 0], [1, 0], [0, 1]], [[0, 2, 1]], {"contact": [[0, 1]]}, "P2")
    assert m2.n_nodes == 6
    check_cells(m2)
    check_midpoints(m2)
    np.testing.assert_allclose(m2.points[m2.edges["contact"][0]], [[0, 0], [1, 0], [0.5, 0]])


@pytest.mark.parametrize("element", ["P1", "P2"])
def test_inline_four_triangles(element):
    m = inline_mesh(SQUARE_NODES, SQUARE_TRIANGLES, SQUARE_EDGES, element)
    assert (m.n_nodes, m.n_cells) == ((5, 4) if element == "P1" else (13, 4))
    check_cells(m)
    check_midpoints(m)
    check_edges(m, polygon([(0, 0), (1, 0), (1, 1), (0, 1)], ["bottom", "right", "top", "left"]))
    np.testing.assert_array_equal(m.cells[3, :3], [3, 0, 4])  # clockwise cell reordered
    np.testing.assert_array_equal(m.edges["bottom"][0, :2], [0, 1])  # facet along its cell


@pytest.mark.parametrize("element", ["Q1", "Q2"])
def test_inline_quads(element):
    nodes = [[0, 0], [1, 0], [2, 0], [0, 1], [1, 1.2], [2, 1]]
    m = inline_mesh(nodes, [[0, 1, 4, 3], [1, 4, 5, 2]],
                    {"bottom": [[0, 1], [1, 2]], "top": [[3, 4], [4, 5]]}, element)
    assert (m.n_nodes, m.n_cells) == ((6, 2) if element == "Q1" else (6 + 7 + 2, 2))
    check_cells(m)
    check_midpoints(m)


@pytest.mark.parametrize("cells, edges, key, message", [
    ([[0, 1, 5]], {}, "geometry.triangles", "in 0..4"),
    ([[0, 1, 1]], {}, "geometry.triangles", "repeats"),
    ([[0, 1, 2], [0, 2, 3]], {}, "geometry.nodes", "no cell"),
    ([[0, 1, 4.5]], {}, "geometry.triangles", "integer"),
    (SQUARE_TRIANGLES, {"inner": [[0, 4]]}, "geometry.edges.inner", "interior edge"),
    (SQUARE_TRIANGLES, {"diag": [[0, 2]]}, "geometry.edges.diag", "not an edge"),
    (SQUARE_TRIANGLES, {"bottom": [[0, 9]]}, "geometry.edges.bottom", "in 0..4"),
    (SQUARE_TRIANGLES, {"bottom": []}, "geometry.edges.bottom", "at least one"),
])
def test_inline_errors(cells, edges, key, message):
    with pytest.raises(CaseError, match=message) as info:
        inline_mesh(SQUARE_NODES, cells, edges, "P1")
    assert info.value.key == key


def test_inline_degenerate_cells():
    with pytest.raises(CaseError, match="degenerate"):
        inline_mesh([[0, 0], [1, 0], [2, 0]], [[0, 1, 2]], {}, "P1")
    with pytest.raises(CaseError, match="not convex"):  # arrow-shaped quad
        inline_mesh([[0, 0], [2, 0], [1, 0.5], [1, 2]], [[0, 1, 2, 3]], {}, "Q1")
