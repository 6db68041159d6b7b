"""`critfric verify` and `critfric solutions`: the branch of Theorem 3.3, built and checked."""

from __future__ import annotations

import json

import numpy as np
import pytest
from helpers import CASES, four_triangles_alpha, one_triangle_alpha, run_cli

import critfric
from critfric.case.schema import loads_case
from critfric.multiplicity import verify


@pytest.fixture(scope="module", params=["four_triangles", "unit_square", "inclined_body"])
def verified(request):
    return verify.verify(critfric.load_case(CASES / f"{request.param}.toml"))


def test_branch_holds_up_to_delta0_and_stops_there(verified):
    b = verified.critical
    assert b.delta0 > 0 and np.isfinite(b.delta0)
    inside = b.inside
    assert len(inside) >= 20 and max(abs(q.delta) for q in inside) == pytest.approx(b.delta0)
    for q in inside:  # every condition, every point, below 1e-10 (relative)
        assert q.max_residual <= 1e-10, (q.delta, q.residuals)
        assert set(q.residuals) == set(verify.CHECKS)
    assert b.stops and verified.passed
    beyond = [q for q in b.points if abs(q.delta) > 1.05 * b.delta0]
    assert any(q.max_residual > 1e-3 for q in beyond)


def test_one_percent_off_the_critical_value_fails(verified):
    crit = verified.critical.friction
    assert [o.friction for o in verified.off_critical] == pytest.approx([0.99 * crit, 1.01 * crit])
    for o in verified.off_critical:
        assert not o.passed and o.max_residual > 1e-6
        assert all(q.residuals["equilibrium"] <= 1e-10 for q in o.points)  # only the law fails


def test_each_point_is_a_fixed_point_of_the_newton_solver(verified):
    b = verified.critical
    for q in b.inside[1::5]:  # |delta| < delta0: every node slips strictly
        sol = verify.newton_check(b, q)
        assert sol.iterations == 0 and sol.residual <= 1e-10
        np.testing.assert_allclose(sol.Ut, q.Ut, rtol=0, atol=1e-10 * np.abs(q.Ut).max())
        np.testing.assert_allclose(sol.X, q.X, rtol=0, atol=1e-10 * np.abs(q.X).max())
        assert set(sol.labels) == {"slip+"}


def test_critical_values_are_the_papers():
    v = verify.verify(critfric.load_case(CASES / "four_triangles.toml"))
    assert v.critical.friction == pytest.approx(four_triangles_alpha(0.3), rel=1e-12)
    b = verify.branch(CASES / "one_triangle.toml")
    assert b.friction == pytest.approx(one_triangle_alpha(0.3), rel=1e-12) and b.passed


def _leaning_mesh(element: str, rotation: float, n: int = 4) -> str:
    """An inline n x n mesh of a leaning quadrilateral (contact at the base, top clamped),
    rotated by ``rotation`` radians: the same mesh in any orientation."""
    corners = np.array([[0.0, 0.0], [1.0, 0.0], [1.3, 1.0], [0.2, 1.0]])
    a, b = np.meshgrid(np.linspace(0, 1, n + 1), np.linspace(0, 1, n + 1))
    a, b = a.ravel()[:, None], b.ravel()[:, None]
    pts = ((1 - a) * (1 - b) * corners[0] + a * (1 - b) * corners[1] + a * b * corners[2]
           + (1 - a) * b * corners[3])
    c, s = np.cos(rotation), np.sin(rotation)
    pts = pts @ np.array([[c, s], [-s, c]])
    k = lambda i, j: j * (n + 1) + i
    quads = [[k(i, j), k(i + 1, j), k(i + 1, j + 1), k(i, j + 1)]
             for j in range(n) for i in range(n)]
    triangles = [[q[0], q[1], q[2]] for q in quads] + [[q[0], q[2], q[3]] for q in quads]
    cells = f"quads = {quads}" if element[0] == "Q" else f"triangles = {triangles}"
    edges = {"base": [[k(i, 0), k(i + 1, 0)] for i in range(n)],
             "top": [[k(i, n), k(i + 1, n)] for i in range(n)],
             "right": [[k(n, j), k(n, j + 1)] for j in range(n)],
             "left": [[k(0, j), k(0, j + 1)] for j in range(n)]}
    return f"""
[geometry]
shape = "mesh"
nodes = {pts.tolist()}
{cells}
[geometry.edges]
""" + "".join(f"{name} = {pairs}\n" for name, pairs in edges.items()) + f"""
[boundary]
contact = ["base"]
dirichlet = ["top"]
[mesh]
element = "{element}"
"""


@pytest.mark.parametrize("element", ["P2", "Q1", "Q2"])
def test_any_element_and_any_orientation_of_gamma_c(element):
    """The same mesh, level and rotated by 30 degrees: same critical value, same verdict."""
    results = []
    for rotation in (0.0, np.pi / 6):
        v = verify.verify(loads_case(_leaning_mesh(element, rotation)))
        assert v.passed and v.critical.max_residual <= 1e-10
        results.append(v.critical.friction)
    assert results[1] == pytest.approx(results[0], rel=1e-10)


def test_negative_family_when_no_positive_value():
    """The one triangle mirrored (B = (1, 0)): its only critical value is for slip along -t
    (alpha = -(3 - 4 nu)); verify walks that branch."""
    text = """
[geometry]
shape = "mesh"
nodes = [[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]]
triangles = [[0, 1, 2]]
[geometry.edges]
contact = [[0, 1]]
clamped = [[1, 2]]
free = [[2, 0]]
[boundary]
contact = ["contact"]
dirichlet = ["clamped"]
"""
    v = verify.verify(loads_case(text))
    assert v.critical.gamma == -1 and v.passed
    assert v.critical.friction == pytest.approx(one_triangle_alpha(0.3), rel=1e-12)
    assert v.critical.alpha == pytest.approx(-v.critical.friction)
    assert set(verify.newton_check(v.critical, v.critical.inside[1]).labels) == {"slip-"}


def test_cli_verify_json_and_plot(tmp_path):
    png = tmp_path / "branch.png"
    res = run_cli("verify", CASES / "four_triangles.toml", "--json", "--plot", png)
    assert res.exit_code == 0, res.output
    out = json.loads(res.stdout)
    assert set(out) == {"friction", "delta0", "max_residual", "passed", "off_critical"}
    assert set(out["off_critical"]) == {"friction", "max_residual", "passed"}
    assert out["passed"] is True and out["off_critical"]["passed"] is False
    assert out["friction"] == pytest.approx(four_triangles_alpha(0.3))
    assert out["max_residual"] <= 1e-10 and png.stat().st_size > 10_000
    table = run_cli("verify", "four-triangles", "--no-plot", "--off", 0.02)
    assert table.exit_code == 0 and "verification PASSED" in table.stdout
    assert "newton" in table.stdout and "delta0" in table.stdout
    bad = run_cli("verify", "four-triangles", "--no-plot", "--off", 0)
    assert bad.exit_code == 2 and "--off" in bad.output


def test_cli_solutions_json_and_plot(tmp_path):
    png = tmp_path / "fig2.png"
    res = run_cli("solutions", CASES / "one_triangle.toml", "--friction", "1:3:11", "--json",
              "--plot", png)
    assert res.exit_code == 0, res.output
    out = json.loads(res.stdout)
    assert [r["count"] for r in out] == [1, 1, 1, 1, 0, 2, 2, 2, 2, 2, 2]
    assert [r["branch"] for r in out] == [False] * 4 + [True] + [False] * 6
    assert all(set(r) == {"friction", "count", "branch", "solutions"} for r in out)
    assert png.stat().st_size > 10_000
    text = run_cli("solutions", "one-triangle", "--friction", "2.5", "--no-plot")
    assert text.exit_code == 0 and "stuck" in text.stdout and "slip+" in text.stdout
    bad = run_cli("solutions", "one-triangle", "--friction", "3:1")
    assert bad.exit_code == 2 and "--friction" in bad.output
    big = run_cli("solutions", "unit-square", "--friction", "1", "--no-plot")
    assert big.exit_code == 2 and "at most 8 contact nodes" in big.output  # the case's mesh
    assert "unit_square.toml: [mesh.size]" in big.output
    many = run_cli("solutions", "one-triangle", "--friction", "0:3:100000000", "--no-plot")
    assert many.exit_code == 2 and "N <= 10001" in many.output
