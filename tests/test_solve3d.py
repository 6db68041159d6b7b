"""3D bodies through the whole pipeline: case file -> mesh -> assembly -> contact plane ->
eigenproblem -> Result, against closed forms and the pipeline's own symmetries."""

from __future__ import annotations

import math

import numpy as np
import pytest
from helpers import box_case, run_cli

import critfric
from critfric import CaseError, loads_case

# The corner tetrahedron 0, e_x, e_y, e_z: e_x, e_y, e_z clamped (their face), the origin the
# one contact node on the plane y = 0 (n = -e_y, t1 = e_x, t2 = e_z).
CORNER = """
[geometry]
shape = "mesh"
nodes = [[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]]
tetrahedra = [[0, 1, 2, 3]]
[geometry.faces]
base = [[0, 1, 3]]
far = [[1, 2, 3]]
[boundary]
contact = ["base"]
dirichlet = ["far"]
[material]
nu = {nu}
[solve]
slip_angle = {angle}
direction_law = "{law}"
"""


def corner(nu: float, angle: float, law: str) -> float:
    """The closed form: w = -(cos phi + sin phi), c0 = 3 (1 - 2 nu); rate w + c0 / w,
    frozen (2 + c0) / w."""
    phi = math.radians(angle)
    w, c0 = -(math.cos(phi) + math.sin(phi)), 3 * (1 - 2 * nu)
    return w + c0 / w if law == "rate" else (2 + c0) / w


@pytest.mark.parametrize("law", ["rate", "frozen"])
@pytest.mark.parametrize("nu,angle", [(0.3, 180.0), (0.3, 225.0), (0.1, 200.0), (0.45, 250.0),
                                      (0.3, 20.0)])
def test_the_corner_tetrahedron_case_gives_the_closed_form(nu, angle, law):
    res = critfric.solve_case(loads_case(CORNER.format(nu=nu, angle=angle, law=law)))
    expected = corner(nu, angle, law)
    values = res.positive if expected > 0 else res.negative
    assert res.dim == 3 and res.n_contact == 1 and len(values) == 1
    assert values[0] == pytest.approx(expected, rel=1e-12)


def test_the_corner_tetrahedron_at_nu_0_3_from_the_issue():
    case = loads_case(CORNER.format(nu=0.3, angle=180.0, law="rate"))
    assert critfric.solve_case(case).critical == pytest.approx(2.2, rel=1e-12)
    frozen = case.with_overrides({"solve.direction_law": "frozen"})
    assert critfric.solve_case(frozen).critical == pytest.approx(3.2, rel=1e-12)
    mirror = critfric.solve_case(case.with_overrides({"solve.slip_angle": 225.0}))
    assert mirror.critical == pytest.approx((5 - 6 * 0.3) / math.sqrt(2), rel=1e-12)
    assert mirror.r_of(mirror.positive)[0] < 1e-12  # on the mirror plane: an exact branch


@pytest.fixture(scope="module")
def box():
    return loads_case(box_case(size=0.3, depth=0.8, extra="[solve]\ncount = 3\nslip_angle = 30.0"))


def test_a_box_reversed_slip_direction_flips_every_coefficient(box):
    a = critfric.solve_case(box)
    b = critfric.solve_case(box.with_overrides({"solve.slip_angle": 210.0}))
    np.testing.assert_allclose(a.positive, -b.negative, rtol=1e-10)
    np.testing.assert_allclose(a.negative, -b.positive, rtol=1e-10)
    g = critfric.solve_case(box.with_overrides({"solve.gamma": -1}))  # the same reversal
    np.testing.assert_allclose(g.positive, b.positive, rtol=1e-10)


def test_a_box_dense_and_arpack_agree_and_E_does_not_matter(box):
    dense = critfric.solve_case(box.with_overrides({"solve.method": "dense"}))
    arpack = critfric.solve_case(box.with_overrides({"solve.method": "arpack"}))
    np.testing.assert_allclose(arpack.positive[:3], dense.positive[:3], rtol=1e-9)
    stiff = critfric.solve_case(box.with_overrides({"material.E": 2.1e11}))
    np.testing.assert_allclose(stiff.positive, dense.positive, rtol=1e-10)


def test_a_prepared_box_turns_its_slip_direction_as_a_fresh_solve_does(box):
    prepared = critfric.prepare(box)
    for angle in (30.0, 75.0, 300.0):
        case = box.with_overrides({"solve.slip_angle": angle, "material.nu": 0.2})
        turned = critfric.solve_prepared(prepared, case)
        fresh = critfric.solve_case(case)
        np.testing.assert_allclose(turned.positive, fresh.positive, rtol=1e-10)
        assert turned.slip_angle == angle


def test_rules_set_status_and_slip_angle_per_region_of_the_contact_plane(box):
    # every node slipping at 30 degrees, written as a rule over the whole face
    ruled = box.with_overrides({"solve.slip_angle": 0.0, "contact.rules": [
        {"from": [-1.0, -1.0], "to": [2.0, 2.0], "status": "slip", "slip_angle": 30.0}]})
    np.testing.assert_allclose(critfric.solve_case(ruled).positive,
                               critfric.solve_case(box).positive, rtol=1e-12)
    # half of the face stuck: fewer slipping nodes, another spectrum
    half = box.with_overrides({"contact.rules": [
        {"from": [0.0, 0.0], "to": [0.5, 1.0], "status": "stuck"}]})
    res = critfric.solve_case(half)
    assert len(res.positive) and not np.allclose(res.positive[:1], critfric.solve_case(
        box).positive[:1])


def test_a_hexahedral_box_converges_towards_the_tetrahedral_one():
    values = {e: critfric.solve_case(loads_case(box_case(element=e, size=0.2, depth=0.8)))
              .critical for e in ("P2", "Q2")}
    assert values["P2"] == pytest.approx(values["Q2"], rel=2e-2)


@pytest.mark.parametrize("args,key", [
    (["solve", "unit-square", "--slip-angle", "30"], "solve.slip_angle"),
    (["solve", "unit-square", "--direction-law", "frozen"], "solve.direction_law"),
    (["solve", "unit-square", "--direction-law", "sideways"], "solve.direction_law"),
])
def test_3d_keys_on_a_2d_body_are_refused(args, key, tmp_path):
    out = run_cli(*args, "-o", tmp_path / "r.h5")
    assert out.exit_code == 2 and key in out.output


@pytest.mark.parametrize("command", [["path", "--range", "0:1"], ["stability"], ["verify"]])
def test_2d_only_commands_refuse_a_3d_body(command, tmp_path):
    case = tmp_path / "corner.toml"
    case.write_text(CORNER.format(nu=0.3, angle=180.0, law="rate"))
    out = run_cli(command[0], case, *command[1:])
    assert out.exit_code == 2 and "for 2D bodies" in out.output


def test_3d_rules_need_pairs_in_the_contact_plane(box):
    with pytest.raises(CaseError, match=r"pairs \[s1, s2\]") as err:
        critfric.solve_case(box.with_overrides({"contact.rules": [
            {"from": 0.0, "to": 0.5, "status": "stuck"}]}))
    assert err.value.key == "contact.rules"
