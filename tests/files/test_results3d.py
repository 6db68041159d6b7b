"""3D solve files: written with their faces, r and slip directions, read back exactly, refused
when a shape or an index is wrong, listed by ``critfric table`` and exported for ParaView in
VTK's node order; 2D files keep their layout."""

from __future__ import annotations

import shutil

import h5py
import meshio
import numpy as np
import pytest
from helpers import box_case, run_cli, square_case

import critfric
from critfric.case.schema import loads_case
from critfric.errors import CaseError
from critfric.fem.assembly import cell_stress, lame, von_mises
from critfric.fem.contact3d import plane_axes
from critfric.files.catalog import static_table, summaries
from critfric.files.export import export_file, read_solve
from critfric.files.results import r_of, read_summary, write_result

RULES = """
[solve]
count = 2
slip_angle = 30
direction_law = "{law}"
[contact]
rules = [{{from = [0.0, 0.0], to = [0.45, 1.0], status = "slip", slip_angle = 120.0}}]
"""


def _solved(tmp_path_factory, element: str, size: float, law: str = "rate"):
    """A 3D box solved, its system and its file (two slip angles over the contact face)."""
    case = loads_case(box_case(element=element, size=size, depth=0.8, extra=RULES.format(law=law)), name=f"box{element}")
    result = critfric.solve_case(case)
    path = tmp_path_factory.mktemp("box") / "box.h5"
    write_result(result, path)
    return result, critfric.prepare(case).system, path


@pytest.fixture(scope="module")
def tet(tmp_path_factory):
    return _solved(tmp_path_factory, "P2", 0.45)


@pytest.fixture(scope="module")
def hexa(tmp_path_factory):
    return _solved(tmp_path_factory, "Q2", 0.45, law="frozen")


@pytest.mark.parametrize("which", ["tet", "hexa"])
def test_a_3d_result_round_trips(which, request):
    result, system, path = request.getfixturevalue(which)
    data = read_solve(path)
    mesh = result.mesh
    assert data.dim == 3 and data.mesh.element == result.element
    np.testing.assert_array_equal(data.mesh.points, mesh.points)
    np.testing.assert_array_equal(data.mesh.cells, mesh.cells)
    assert data.mesh.edges == {} and sorted(data.mesh.faces) == sorted(mesh.faces)
    for name, faces in mesh.faces.items():
        np.testing.assert_array_equal(data.mesh.faces[name], faces)
    np.testing.assert_array_equal(data.contact_nodes, result.contact_nodes)
    np.testing.assert_array_equal(data.alpha, result.alpha)
    np.testing.assert_array_equal(data.positive, result.positive)
    np.testing.assert_array_equal(data.r, result.r)
    np.testing.assert_array_equal(data.r_of(data.positive), result.r_of(result.positive))
    np.testing.assert_array_equal(data.slip, system.slip)  # the two angles of the rules
    assert len(np.unique(np.round(data.slip, 9), axis=0)) == 2
    np.testing.assert_array_equal(data.normal, system.normal)
    np.testing.assert_array_equal(data.tangent, system.tangent)
    assert data.attrs["law"] == result.law and data.attrs["slip_angle"] == 30.0
    assert data.attrs["dim"] == 3 and data.attrs["schema_version"] == 3
    stored = list(data.modes.values())
    assert len(stored) == len(result.modes) == 4
    for mode in result.modes:
        (match,) = [m for m in stored if m["alpha"] == mode["alpha"]]
        for key in ("phi", "theta_n", "theta_t"):
            np.testing.assert_array_equal(match[key], mode[key])
        assert match["phi"].shape == (mesh.n_nodes, 3) and match["r"] == mode["r"]
    summary = read_summary(path)
    assert summary["dim"] == 3 and summary["law"] == result.law
    assert summary["r_positive"] == result.r_of(result.positive).tolist()
    assert summary["positive"] == result.summary()["positive"]
    with h5py.File(path) as f:
        assert f["mesh/faces/y0"].attrs["long_name"].endswith("'y0'")
        assert f["mesh/points"].attrs["long_name"] == "node coordinates (x, y, z)"


def test_r_of_picks_the_real_eigenvalue_nearest_each_value():
    alpha = np.array([1.0 + 0j, -2.0, 1.5 + 0.1j, 1.5 - 0.1j, 3.0, -0.5])
    r = np.array([0.1, 0.2, 0.9, 0.9, 0.3, 0.4])
    np.testing.assert_array_equal(r_of(alpha, r, [1.0, 3.0, -2.0, -0.5, 1.4]),
                                  [0.1, 0.3, 0.2, 0.4, 0.1])
    assert r_of(alpha, r, []).shape == (0,)


def test_a_2d_file_keeps_its_layout(tmp_path):
    path = tmp_path / "sq.h5"
    write_result(critfric.solve_case(loads_case(square_case(size=0.5))), path)
    names = []
    with h5py.File(path) as f:
        f.visit(names.append)
        assert f.attrs["schema_version"] == 2 and f.attrs["dim"] == 2
        assert f.attrs["normal"].shape == f.attrs["tangent"].shape == (2,)
        assert f["mesh/points"].attrs["long_name"] == "node coordinates (x, y)"
        assert "law" not in f.attrs and "slip_angle" not in f.attrs
    assert not [n for n in names if n in ("eigen/r", "mesh/faces", "mesh/slip")]
    assert {"eigen/alpha", "critical/positive", "critical/negative", "mesh/points",
            "mesh/cells", "mesh/contact_nodes", "mesh/edges/bottom",
            "modes/positive_0/phi"} <= set(names)
    summary = read_summary(path)
    assert "dim" not in summary and read_solve(path).r is None
    assert "dim" not in static_table([summary])  # the 2D table as before


def test_the_table_shows_dim_law_slip_angle_and_r(tet, tmp_path):
    result, _, path = tet
    sq = tmp_path / "sq.h5"
    write_result(critfric.solve_case(loads_case(square_case(size=0.5))), sq)
    rows, skipped = summaries([path, sq])
    assert not skipped
    text = static_table(rows)
    head, _, box, square = text.splitlines()
    assert head.split()[:4] == ["case", "dim", "law", "slip"]
    assert box.split()[1:4] == ["3", "rate", "30"]
    assert f"(r {result.r_of(result.positive)[0]:.3f})" in box
    assert square.split()[1:4] == ["2", "-", "-"] and "(r" not in square


def _replace(f, key, value):
    del f[key]
    f[key] = value


def _out_of_range(f):
    name = min(f["mesh/faces"])
    faces = f[f"mesh/faces/{name}"][()]
    faces[0, 0] = len(f["mesh/points"]) + 5
    _replace(f, f"mesh/faces/{name}", faces)


EDITS = {  # what is changed -> the words the message must hold
    "phi with 2 columns": (lambda f: _replace(f, "modes/positive_0/phi",
                                              f["modes/positive_0/phi"][:, :2]),
                           ["modes/positive_0/phi", "shape"]),
    "points with 4 coordinates": (lambda f: _replace(f, "mesh/points", np.zeros((
        len(f["mesh/points"]), 4))), ["mesh/points", "2 or 3 coordinates"]),
    "a face index out of range": (_out_of_range, ["mesh/faces/", "outside"]),
    "2D cells in a 3D mesh": (lambda f: _replace(f, "mesh/cells", f["mesh/cells"][:, :6]),
                              ["mesh/cells", "shape"]),
    "faces of the wrong width": (lambda f: _replace(f, "mesh/faces/y0",
                                                    f["mesh/faces/y0"][:, :3]),
                                 ["mesh/faces/y0", "shape"]),
    "r for fewer eigenvalues": (lambda f: _replace(f, "eigen/r", f["eigen/r"][1:]),
                                ["eigen/r", "eigenvalues"]),
    "r above 1": (lambda f: _replace(f, "eigen/r", f["eigen/r"][()] + 2.0),
                  ["eigen/r", "[0, 1]"]),
    "no slip directions": (lambda f: f.__delitem__("mesh/slip"), ["mesh/slip", "missing"]),
    "slip directions not unit": (lambda f: _replace(f, "mesh/slip", 2 * f["mesh/slip"][()]),
                                 ["mesh/slip", "unit"]),
    "slip for fewer nodes": (lambda f: _replace(f, "mesh/slip", f["mesh/slip"][1:]),
                             ["mesh/slip", "contact nodes"]),
    "an unknown law": (lambda f: f.attrs.__setitem__("law", "sideways"), ["'law'"]),
    "a 2D normal": (lambda f: f.attrs.__setitem__("normal", np.array([0.0, -1.0])),
                    ["'normal'"]),
    "a dim that is not the points'": (lambda f: f.attrs.__setitem__("dim", 2), ["'dim'"]),
    "3D points in a version-2 file": (lambda f: f.attrs.__setitem__("schema_version", 2),
                                      ["mesh/points", "version-2"]),
    "edges in a 3D mesh": (lambda f: f.__setitem__("mesh/edges/bottom", np.zeros((1, 3), int)),
                           ["mesh/edges", "3D"]),
    "forces for fewer nodes": (lambda f: _replace(f, "modes/positive_0/theta_n",
                                                  f["modes/positive_0/theta_n"][1:]),
                               ["modes/positive_0/theta_n", "contact node"]),
    "a mode r above 1": (lambda f: f["modes/negative_0"].attrs.__setitem__("r", 1.5),
                         ["modes/negative_0", "'r'"]),
    "a group among the modes": (lambda f: f.create_group("modes/extra"), ["modes/extra"]),
}


@pytest.mark.parametrize("edit", sorted(EDITS))
def test_a_3d_file_with_a_wrong_shape_is_refused(tet, tmp_path, edit):
    change, words = EDITS[edit]
    bad = tmp_path / "bad.h5"
    shutil.copy(tet[2], bad)
    with h5py.File(bad, "r+") as f:
        change(f)
    for read in (read_solve, read_summary):
        with pytest.raises(CaseError) as info:
            read(bad)
        message = str(info.value)
        assert "bad.h5" in message and "not a valid critfric solve file" in message
        for word in words:
            assert word in message, (word, message)


def test_a_refused_3d_file_is_one_message_on_the_command_line(tet, tmp_path):
    bad = tmp_path / "bad.h5"
    shutil.copy(tet[2], bad)
    with h5py.File(bad, "r+") as f:
        _out_of_range(f)
    for args in (["table", bad], ["plot", bad], ["export", bad]):
        res = run_cli(*args)
        assert res.exit_code == 2 and "Traceback" not in res.output, res.output
        assert res.output.count("critfric: error:") == 1 and "mesh/faces/" in res.output
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.h5"]


def test_a_2d_file_with_faces_is_refused(tmp_path):
    path = tmp_path / "sq.h5"
    write_result(critfric.solve_case(loads_case(square_case(size=0.5))), path)
    with h5py.File(path, "r+") as f:
        f["mesh/faces/bottom"] = f["mesh/edges/bottom"][()]
    with pytest.raises(CaseError, match="mesh/faces"):
        read_solve(path)


# VTK's reference coordinates of its quadratic cells (vtkQuadraticTetra,
# vtkTriQuadraticHexahedron), on the unit tetrahedron and the unit cube
VTK_TETRA10 = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [.5, 0, 0], [.5, .5, 0],
                        [0, .5, 0], [0, 0, .5], [.5, 0, .5], [0, .5, .5]])
VTK_HEXAHEDRON27 = np.array(
    [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1],
     [.5, 0, 0], [1, .5, 0], [.5, 1, 0], [0, .5, 0], [.5, 0, 1], [1, .5, 1], [.5, 1, 1],
     [0, .5, 1], [0, 0, .5], [1, 0, .5], [1, 1, .5], [0, 1, .5],
     [0, .5, .5], [1, .5, .5], [.5, 0, .5], [.5, 1, .5], [.5, .5, 0], [.5, .5, 1],
     [.5, .5, .5]])


def _vtk_positions(vertices: np.ndarray, reference: np.ndarray) -> np.ndarray:
    """Where VTK puts each node of straight-sided cells with these (VTK-ordered) vertices:
    the affine (tetrahedra) or trilinear (hexahedra) map of its reference coordinates."""
    x, y, z = reference.T
    if len(vertices[0]) == 4:
        weights = np.column_stack([1 - x - y - z, x, y, z])
    else:
        weights = np.column_stack([(1 - x) * (1 - y) * (1 - z), x * (1 - y) * (1 - z),
                                   x * y * (1 - z), (1 - x) * y * (1 - z), (1 - x) * (1 - y) * z,
                                   x * (1 - y) * z, x * y * z, (1 - x) * y * z])
    return np.einsum("nv,cvi->cni", weights, vertices)


@pytest.mark.parametrize("which,cell,facet,reference", [
    ("tet", "tetra10", "triangle6", VTK_TETRA10),
    ("hexa", "hexahedron27", "quad9", VTK_HEXAHEDRON27)])
@pytest.mark.parametrize("fmt", ["vtu", "xdmf"])
def test_the_export_writes_vtk_cells_in_vtk_node_order(which, cell, facet, reference, fmt,
                                                       request, tmp_path):
    result, system, path = request.getfixturevalue(which)
    out = export_file(path, fmt=fmt, output=tmp_path / f"modes.{fmt}")
    back = meshio.read(out)
    mesh = result.mesh
    assert back.cells[0].type == cell and len(back.cells[0].data) == mesh.n_cells
    np.testing.assert_array_equal(back.points, mesh.points)
    cells = back.cells[0].data
    assert sorted(map(sorted, cells.tolist())) == sorted(map(sorted, mesh.cells.tolist()))
    corners = back.points[cells[:, :4 if cell == "tetra10" else 8]]
    np.testing.assert_allclose(back.points[cells], _vtk_positions(corners, reference),
                               atol=1e-12)
    if fmt == "vtu":  # the boundary faces as a tagged second block
        assert back.cells[1].type == facet
        assert len(back.cells[1].data) == sum(len(f) for f in mesh.faces.values())
        assert set(back.cell_data["boundary_tag"][1]) == set(range(1, len(mesh.faces) + 1))
    mode = result.modes[0]
    name = "positive_0" if mode["alpha"] > 0 else "negative_0"
    peak = np.max(np.linalg.norm(mode["phi"], axis=1))
    phi = back.point_data[f"{name}_phi"]
    np.testing.assert_allclose(phi, mode["phi"] / peak, atol=1e-12)
    force = back.point_data[f"{name}_contact_force"]
    nodes = result.contact_nodes
    expected = (np.outer(mode["theta_n"], system.normal)
                + mode["theta_t"][:, None] * system.slip) / peak
    np.testing.assert_allclose(force[nodes], expected, atol=1e-12)
    assert np.count_nonzero(np.delete(force, nodes, axis=0)) == 0
    lam, G = lame(result.E, result.nu)
    stress = cell_stress(mesh, (mode["phi"] / peak).ravel(), lam, G, at="centroid")[:, 0]
    tensor = back.cell_data[f"{name}_stress"][0].reshape(-1, 3, 3)
    np.testing.assert_allclose(tensor, np.transpose(tensor, (0, 2, 1)))
    for k, (i, j) in enumerate([(0, 0), (1, 1), (2, 2), (1, 2), (0, 2), (0, 1)]):
        np.testing.assert_allclose(tensor[:, i, j], stress[:, k], atol=1e-10)
    np.testing.assert_allclose(back.cell_data[f"{name}_von_mises"][0], von_mises(stress),
                               atol=1e-10)


def test_the_vtu_field_data_holds_the_coefficients_and_their_r(tet, tmp_path):
    result, _, path = tet
    out = export_file(path, fmt="vtu", output=tmp_path / "m.vtu")
    text = out.read_text(errors="replace")
    for name in ("critical_positive", "r_positive", "r_negative", "y0"):
        assert f'Name="{name}"' in text
    r0 = result.r_of(result.positive)[0]
    assert f"{r0:.17g}" in text
    assert plane_axes(result.normal)[0].tolist() == read_solve(path).tangent.tolist()
