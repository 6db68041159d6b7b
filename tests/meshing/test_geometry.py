"""Polygons: constructors, orientation, validation, straight runs, size estimates."""

import numpy as np
import pytest

from critfric.errors import CaseError
from critfric.meshing.geometry import (
    Polygon,
    collinear_run,
    parallelogram,
    polygon,
    rectangle,
    signed_area,
    validate,
)

pytestmark = pytest.mark.once  # the same on both installs: run by `make test` only

# a pentagon-like hexagon whose bottom side is split into three named parts
SPLIT = [(0, 0), (0.3, 0), (0.7, 0), (1, 0), (1.2, 0.8), (0.1, 1)]
SPLIT_NAMES = ["b", "c", "b", "r", "t", "l"]


def edge_map(poly):
    """{frozenset of the two end points: name} of every edge."""
    seg = poly.segments
    return {frozenset(map(tuple, s.tolist())): n for s, n in zip(seg, poly.edge_names)}


def test_rectangle_and_parallelogram():
    r = rectangle(2.0, 1.0)
    np.testing.assert_array_equal(r.vertices, [[0, 0], [2, 0], [2, 1], [0, 1]])
    assert r.edge_names == ("bottom", "right", "top", "left")
    assert r.area == pytest.approx(2.0)
    p = parallelogram(3.0, 2.0, -0.5)
    np.testing.assert_allclose(p.vertices, [[0, 0], [3, 0], [2.5, 2], [-0.5, 2]])
    assert p.area == pytest.approx(6.0)
    assert validate(p) is p
    with pytest.raises(CaseError, match="geometry.width"):
        rectangle(0.0, 1.0)
    with pytest.raises(CaseError, match="geometry.offset"):
        parallelogram(1.0, 1.0, float("inf"))


def test_polygon_default_names_and_collinear_vertices():
    p = polygon(SPLIT)
    assert p.edge_names == tuple(f"e{i}" for i in range(6))
    q = polygon(SPLIT, SPLIT_NAMES)
    assert q.group_names == ("b", "c", "r", "t", "l")
    np.testing.assert_array_equal(q.edge_indices("b"), [0, 2])
    np.testing.assert_array_equal(q.edge_indices(["c", "r"]), [1, 3])


def test_clockwise_input_is_reversed_keeping_names():
    ccw = polygon(SPLIT, SPLIT_NAMES)
    # the same polygon listed clockwise: vertex i -> i+1 edges get the names of the same sides
    cw_vertices = SPLIT[::-1]
    n = len(SPLIT)
    cw_names = [SPLIT_NAMES[(n - 2 - j) % n] for j in range(n)]
    cw = polygon(cw_vertices, cw_names)
    assert cw.area > 0
    assert edge_map(cw) == edge_map(ccw)
    # a clockwise triangle with distinct names
    t = polygon([(0, 0), (0, 1), (1, 0)], ["left", "hyp", "bottom"])
    assert t.area == pytest.approx(0.5)
    names = edge_map(t)
    assert names[frozenset({(0.0, 0.0), (0.0, 1.0)})] == "left"
    assert names[frozenset({(0.0, 0.0), (1.0, 0.0)})] == "bottom"
    assert names[frozenset({(1.0, 0.0), (0.0, 1.0)})] == "hyp"


@pytest.mark.parametrize(
    "vertices, message",
    [
        ([(0, 0), (1, 0)], "at least 3"),
        ([(0, 0), (1, 0), (1, 0), (0, 1)], "coincide"),
        ([(0, 0), (1, 0), (1, 1), (0, 0), (0, 1)], "coincide"),
        ([(0, 0), (1, 0), (2, 0)], "zero area"),
        ([(0, 0), (1, 1), (1, 0), (0, 1)], "intersects itself"),  # bow tie
        ([(0, 0), (2, 0), (2, 2), (1, 0), (0, 2)], "intersects itself"),  # vertex on an edge
        ([(0, 0), (2, 0), (1, 0), (1, 1)], "intersects itself"),  # folds back on itself
        ([(0, 0), (1, 0), (float("nan"), 1)], "finite"),
    ],
)
def test_invalid_polygons_raise(vertices, message):
    with pytest.raises(CaseError, match=message) as info:
        polygon(vertices)
    assert info.value.key == "geometry.vertices"


def test_wrong_names_and_direct_construction():
    with pytest.raises(CaseError, match="edge names") as info:
        polygon([(0, 0), (1, 0), (0, 1)], ["a", "b"])
    assert info.value.key == "geometry.edge_names"
    with pytest.raises(CaseError, match="counterclockwise"):
        validate(Polygon(np.array([[0.0, 0], [0, 1], [1, 0]]), ("a", "b", "c")))
    with pytest.raises(CaseError, match="pairs"):
        polygon([1.0, 2.0, 3.0])


def test_collinear_run():
    seg = polygon(SPLIT, SPLIT_NAMES).segments
    start, end, u = collinear_run(seg[[0, 1, 2]])
    np.testing.assert_allclose(start, [0, 0])
    np.testing.assert_allclose(end, [1, 0])
    np.testing.assert_allclose(u, [1, 0])
    # points given from the other end: start is the extreme nearest the first point
    start, end, u = collinear_run([[1, 1], [0.5, 0.5], [0, 0]])
    np.testing.assert_allclose([start, end, u], [[1, 1], [0, 0], [-2**-0.5, -2**-0.5]])
    with pytest.raises(CaseError, match="straight line"):
        collinear_run(seg[[2, 3]], key="boundary.contact")
    with pytest.raises(CaseError, match="connected"):
        collinear_run(seg[[0, 2]])  # the gap of edge 1 between them
    with pytest.raises(CaseError, match="zero length"):
        collinear_run([[1, 1], [1, 1]])


def test_signed_area_sign():
    assert signed_area([(0, 0), (1, 0), (0, 1)]) == pytest.approx(0.5)
    assert signed_area([(0, 0), (0, 1), (1, 0)]) == pytest.approx(-0.5)
