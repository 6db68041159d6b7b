"""Case files: strict validation with messages that name the file and the key."""

from __future__ import annotations

import pytest
from helpers import square_case

import critfric
from critfric.case.schema import load_case, loads_case, shipped_cases
from critfric.errors import CaseError

pytestmark = pytest.mark.once  # the same on both installs: run by `make test` only

GOOD = square_case(size=0.2)


def test_shipped_cases_validate_and_have_names():
    names = shipped_cases()
    assert {"one-triangle", "four-triangles", "unit-square", "inclined-body"} <= set(names)
    for path in names.values():
        load_case(path)
    assert load_case("inclined-body").geometry["offset"] == -1.0


def test_defaults_are_filled():
    case = loads_case(GOOD)
    assert case.material == {"E": 1.0, "nu": 0.3, "density": 1.0}
    assert case.boundary == {"contact": ["bottom"], "dirichlet": ["top"]}
    assert case.solve["method"] == "auto" and case.solve["count"] == 1
    assert case.solve["gamma"] == 1 and case.output["modes"] is True


def test_round_trip_of_the_effective_case():
    case = loads_case(GOOD, overrides={"material.nu": 0.41})
    again = loads_case(case.to_toml())
    assert again.material["nu"] == 0.41 and again.mesh == case.mesh


BAD = [
    ("[geometry\nshape = 'square'", None, "TOML syntax error"),
    (GOOD + "\n[extra]\na = 1\n", "extra", "unknown section"),
    (GOOD.replace("[material]", "[material]\ncolour = 'red'"), "material.colour", "unknown key"),
    (GOOD.replace("nu = 0.3", "nu = 0.5"), "material.nu", "[0, 0.5)"),
    (GOOD.replace("nu = 0.3", "nu = -0.1"), "material.nu", "[0, 0.5)"),
    (GOOD.replace("nu = 0.3", "nu = 'soft'"), "material.nu", "a number"),
    (GOOD.replace("size = 0.2", "size = -0.1"), "mesh.size", "(0, inf]"),
    (GOOD.replace("size = 0.2", ""), "mesh.size", "missing key"),
    (GOOD.replace('element = "P1"', 'element = "P3"'), "mesh.element", "'Q2'"),
    (GOOD.replace('shape = "square"', 'shape = "circle"'), "geometry.shape", "'polygon'"),
    (GOOD + "\n[boundary]\ndirichlet = []\n", "boundary.dirichlet", "non-empty list"),
    (GOOD + "\n[boundary]\ncontact = ['floor']\n", "boundary.contact", "unknown edge 'floor'"),
    (GOOD + "\n[boundary]\ncontact = ['top']\ndirichlet = ['top']\n", "boundary.dirichlet",
     "both contact and Dirichlet"),
    (GOOD.replace('method = "auto"', 'method = "magic"'), "solve.method", "'arpack'"),
    (GOOD.replace('method = "auto"', 'count = 0'), "solve.count", "an integer"),
    (GOOD.replace("[material]", "[material]\nE = 0"), "material.E", "(0, inf]"),
    ('[geometry]\nshape = "square"\nwidth = 2\n[mesh]\nsize = 0.1', "geometry.width",
     "unknown key"),
    ('[geometry]\nshape = "mesh"\nnodes = [[0, 0], [1, 0], [0, 1]]\n'
     'triangles = [[0, 1, 2]]\n[geometry.edges]\nbottom = [[0, 1]]\ntop = [[1, 2]]\n'
     '[mesh]\nelement = "Q1"', "mesh.element", "allowed: P1 or P2"),
]


@pytest.mark.parametrize("text,key,what", BAD)
def test_bad_cases_name_the_key(text, key, what):
    with pytest.raises(CaseError) as info:
        loads_case(text, source="bad.toml")
    message = str(info.value)
    assert message.startswith("bad.toml")
    if key:
        assert f"[{key}]" in message and info.value.key == key
    assert what in message


def test_contact_edge_not_straight():
    text = GOOD + "\n[boundary]\ncontact = ['bottom', 'right']\n"
    with pytest.raises(CaseError, match=r"boundary\.contact.*not one straight segment"):
        critfric.solve_case(loads_case(text, source="bent.toml"))


def test_missing_case_names_the_shipped_ones():
    with pytest.raises(CaseError, match="unit-square"):
        load_case("no/such/case.toml")


def test_collinear_polygon_edges_form_a_partial_contact():
    text = """
[geometry]
shape = "polygon"
vertices = [[0, 0], [0.4, 0], [1, 0], [1, 1], [0, 1]]
edge_names = ["pad", "rest", "right", "top", "left"]
[boundary]
contact = ["pad"]
dirichlet = ["top"]
[mesh]
size = 0.1
"""
    r = critfric.solve_case(loads_case(text))
    x = r.mesh.points[r.contact_nodes, 0]
    assert x.min() == 0.0 and abs(x.max() - 0.4) < 1e-12
    assert r.n_contact == 5
