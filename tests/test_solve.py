"""The pipeline's face: prepare / solve_prepared / solve_case."""

from __future__ import annotations

import numpy as np
import pytest
from helpers import square_case

import critfric
from critfric import CaseError, loads_case


def test_solve_prepared_refuses_a_mesh_it_was_not_prepared_for():
    case = loads_case(square_case(size=0.25))
    prepared = critfric.prepare(case)
    for over in ({"mesh.element": "P2"}, {"mesh.size": 0.1}):
        with pytest.raises(CaseError, match="prepared") as err:
            critfric.solve_prepared(prepared, case.with_overrides(over))
        assert err.value.key == next(iter(over))
    other = critfric.solve_prepared(prepared, case.with_overrides({"material.nu": 0.2}))
    direct = critfric.solve_case(case.with_overrides({"material.nu": 0.2}))
    assert other.element == direct.element == "P1" and other.size == direct.size == 0.25
    np.testing.assert_allclose(other.positive, direct.positive, rtol=1e-12)


POLYGON = ('[geometry]\nshape = "polygon"\nvertices = {v}\nedge_names = ["bottom", "right", '
           '"top", "left"]\n[mesh]\nsize = {h!r}\n[solve]\ncount = 2\n')


@pytest.mark.parametrize("scale", [1e-12, 1e-3, 1e6, 1e12])
def test_coefficients_do_not_depend_on_the_length_unit(scale):
    """The same body and relative mesh size in another length unit: the same mesh up to the
    unit, the same coefficients (gmsh meshes the body scaled to unit extent)."""
    quad = np.array([[0.0, 0.0], [1.0, 0.0], [1.3, 0.9], [0.2, 1.1]])
    ref = critfric.solve_case(loads_case(POLYGON.format(v=quad.tolist(), h=0.1)))
    got = critfric.solve_case(loads_case(POLYGON.format(v=(scale * quad).tolist(),
                                                        h=0.1 * scale)))
    assert got.n_dofs == ref.n_dofs
    def rows(points):  # the nodes, whatever their numbering
        return points[np.lexsort(np.round(points, 9).T[::-1])]

    np.testing.assert_allclose(rows(got.mesh.points / scale), rows(ref.mesh.points),
                               rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(got.positive[:2], ref.positive[:2], rtol=1e-10)
    np.testing.assert_allclose(got.negative[:2], ref.negative[:2], rtol=1e-10)
    assert got.h == pytest.approx(scale * ref.h, rel=1e-12)


def test_the_python_api_takes_any_form_of_a_case_and_prints_short():
    as_dict = {"geometry": {"shape": "square"}, "mesh": {"size": 0.25}}
    by_dict = critfric.solve_case(as_dict)
    by_name = critfric.solve_case("unit-square", overrides={"mesh.size": 0.25})
    by_case = critfric.solve_case(loads_case(square_case(size=0.25)))
    assert by_dict.critical == pytest.approx(by_name.critical, rel=1e-12)
    assert by_case.critical == pytest.approx(by_name.critical, rel=1e-12)
    for obj in (by_dict, by_dict.mesh, critfric.prepare(loads_case(square_case(size=0.25)))):
        text = repr(obj)
        assert len(text) < 200 and "array(" not in text, text
    assert "critical=1.9" in repr(by_dict)


def test_a_sweep_is_a_table(tmp_path):
    pd = pytest.importorskip("pandas")
    from critfric.sweep import make_grid, run_sweep

    case = critfric.load_case("four-triangles")
    sweep = run_sweep(case, make_grid(case, nu="0.1,0.3"), output=tmp_path / "s.h5", jobs=1)
    frame = sweep.to_dataframe()
    assert isinstance(frame, pd.DataFrame) and list(frame["nu"]) == [0.1, 0.3]
    assert frame["positive"].iloc[1] == pytest.approx(1.8358568491, rel=1e-9)
    assert "2 points" in repr(sweep)


L_SHAPE = """[geometry]
shape = "polygon"
vertices = [[0.0, 0.0], [2.0, 0.0], [2.0, 0.5], [0.8, 0.5], [0.8, 1.5], [0.0, 1.5]]
edge_names = ["bottom", "r1", "step", "r2", "top", "left"]
[boundary]
contact = ["bottom"]
dirichlet = ["top"]
[mesh]
element = "{element}"
size = 0.05
"""


def test_skewed_cells_along_the_contact_edge_are_a_warning():
    """gmsh's quads of this L-shape fan out at up to 150 degrees on Gamma_C: mesh-scale modes
    give real eigenvalues from 1.92 where the body's coefficient is about 2.33 (P1 on the
    same body: cells below 90 degrees there, no warning, 2.31)."""
    quads = critfric.solve_case(loads_case(L_SHAPE.format(element="Q1")))
    assert quads.critical < 2.0
    (warning,) = [w for w in quads.warnings if "Gamma_C have corners" in w]
    assert "up to 150 degrees" in warning
    triangles = critfric.solve_case(loads_case(L_SHAPE.format(element="P1")))
    assert not any("Gamma_C have corners" in w for w in triangles.warnings)
    assert 2.25 < triangles.critical < 2.35
    for name in ("unit-square", "inclined-body", "one-triangle", "four-triangles"):
        assert not critfric.solve_case(name).warnings
