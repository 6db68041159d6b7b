"""Singular points of the eigenproblem and meshes graded at every one of them."""

import math

import numpy as np
import pytest

import critfric
from critfric.case.schema import from_dict
from critfric.errors import CaseError
from critfric.guards import ESTIMATE_SLACK
from critfric.meshing.from_case import singular_of
from critfric.meshing.geometry import polygon, rectangle
from critfric.meshing.mesh import build_mesh
from critfric.meshing.singular import singular_points, state_junctions

pytestmark = pytest.mark.once  # the same on both installs: run by `make test` only

#: a 2 x 1 block: stuck on [0, 0.5], slip + on [0.5, 1.3], slip - on [1.3, 2] of its base
MIXED = {"geometry": {"shape": "rectangle", "width": 2.0, "height": 1.0},
         "mesh": {"size": 0.2, "element": "P1"},
         "contact": {"rules": [{"from": 0.0, "to": 0.5, "status": "stuck"},
                               {"from": 0.5, "to": 1.3, "status": "slip", "gamma": 1},
                               {"from": 1.3, "to": 2.0, "status": "slip", "gamma": -1}]}}


def _points(sp):
    return {(round(float(x), 9), round(float(y), 9)): k for (x, y), k in zip(sp.points, sp.kind)}


def test_shipped_cases_are_singular_at_contact_ends_and_clamped_corners():
    square = _points(singular_of(critfric.load_case("unit-square")))
    assert square == {(0, 0): "contact end", (1, 0): "contact end",
                      (1, 1): "condition change", (0, 1): "condition change"}
    inclined = singular_of(critfric.load_case("inclined-body"))
    assert _points(inclined) == {(0, 0): "contact end", (1, 0): "contact end",
                                 (0, 3): "condition change", (-1, 3): "condition change"}
    np.testing.assert_allclose(np.degrees(inclined.angle),
                               [108.43494882, 71.56505118, 108.43494882, 71.56505118])
    assert len(inclined.junctions) == 0 and inclined.run_length == pytest.approx(1.0)


def test_a_polygon_has_its_reentrant_corner_and_no_regular_one():
    # an L: contact at the bottom, clamped on top, the notch corner (1, 1) re-entrant
    poly = polygon([[0, 0], [2, 0], [2, 1], [1, 1], [1, 2], [0, 2]],
                   ["bottom", "right", "notch", "notch", "top", "left"])
    sp = singular_points(poly, ["bottom"], ["top"])
    assert _points(sp) == {(0, 0): "contact end", (2, 0): "contact end",
                           (1, 1): "re-entrant corner", (1, 2): "condition change",
                           (0, 2): "condition change"}  # (2, 1): convex, free-free
    assert np.degrees(sp.angle[sp.kind.index("re-entrant corner")]) == pytest.approx(270)
    # a Dirichlet edge meeting a free one in the middle of a straight side is singular too
    split = polygon([[0, 0], [1, 0], [1, 0.5], [1, 1], [0, 1]], ["c", "d", "f", "t", "l"])
    assert _points(singular_points(split, "c", ["d", "t"]))[(1, 0.5)] == "condition change"


def test_state_junctions_are_where_status_or_slip_sign_changes():
    rules = MIXED["contact"]["rules"]
    rules = [{**r, "gamma": r.get("gamma", 1)} for r in rules]
    np.testing.assert_allclose(state_junctions(rules, "slip", 1, 2.0), [0.5, 1.3])
    same = [{"from": 0.0, "to": 0.7, "status": "slip", "gamma": 1},
            {"from": 0.7, "to": 2.0, "status": "slip", "gamma": 1}]
    assert len(state_junctions(same, "slip", 1, 2.0)) == 0  # no change at 0.7
    covered = [{"from": 0.4, "to": 0.9, "status": "free", "gamma": 1}]
    np.testing.assert_allclose(state_junctions(covered, "stuck", 1, 2.0), [0.4, 0.9])
    sp = singular_of(from_dict(MIXED))
    assert sorted(sp.kind) == sorted(["contact end"] * 2 + ["condition change"] * 2
                                     + ["state junction"] * 2)
    np.testing.assert_allclose(sp.points[sp.junctions], [[0.5, 0], [1.3, 0]])


@pytest.mark.parametrize("element", ["P1", "Q2"])
def test_a_mesh_graded_at_a_state_junction_has_a_node_and_small_cells_there(element):
    case = from_dict(MIXED).with_overrides({"mesh.grading": 0.1, "mesh.element": element})
    mesh = critfric.prepare(case).mesh
    h = 0.2
    for s in (0.5, 1.3):
        assert np.min(np.linalg.norm(mesh.points - [s, 0], axis=1)) < 1e-12  # a node there
    facets = mesh.points[mesh.edges["bottom"]][:, [0, -1] if element == "P1" else [0, 1]]
    length = np.linalg.norm(facets[:, 1] - facets[:, 0], axis=1)
    mid = facets.mean(axis=1)[:, 0]
    for s in (0.5, 1.3):
        assert length[np.abs(mid - s) < 0.05].max() < 0.25 * h
    assert length[np.abs(mid - 0.9) < 0.1].min() > 0.25 * h  # far from every singular point


def test_clamped_corners_are_graded_too():
    poly = rectangle(1.0, 1.0)
    m = build_mesh(poly, size=0.1, element="P1", grading=0.1, contact="bottom",
                   dirichlet=["top"])
    top = m.points[m.edges["top"]]
    length = np.linalg.norm(top[:, 1] - top[:, 0], axis=1)
    x = top.mean(axis=1)[:, 0]
    assert length[(x < 0.05) | (x > 0.95)].max() < 0.03 < length[np.abs(x - 0.5) < 0.1].min()


@pytest.mark.parametrize("grading", [0.3, 0.03])
def test_graded_meshes_stay_within_the_guard_estimate(grading):
    """The resource guard counts every singular point (junctions inside Gamma_C too), from
    above but not far above (a 2 x 1 block at P2, h = 0.0125, g = 0.1 was refused at 3e6
    estimated DOFs for the 0.86e6 it has)."""
    from critfric.guards import polygon_footprint

    case = from_dict(MIXED).with_overrides({"mesh.grading": grading, "mesh.size": 0.1})
    mesh = critfric.prepare(case).mesh
    sp = singular_of(case)
    fp = polygon_footprint(rectangle(2.0, 1.0).vertices)
    sectors = 1.25 * float(sp.angle.sum()) / (1.5 * math.pi)  # as critfric.solve counts them
    estimate = fp.dofs(0.1, "P1") + 2 * fp.graded_nodes(0.1, "P1", grading, 1.0, points=sectors)
    assert 2 * mesh.n_nodes <= estimate <= 3 * 2 * mesh.n_nodes
    with pytest.raises(CaseError, match="DOFs"):  # and the guard refuses what does not fit
        critfric.prepare(case, max_dofs=int(0.9 * estimate / ESTIMATE_SLACK))


def test_junctions_outside_the_contact_run_are_case_errors():
    with pytest.raises(CaseError, match="inside Gamma_C"):
        singular_points(rectangle(1.0, 1.0), "bottom", ["top"], junctions=[1.5])
