"""Properties of the eigen stage: independent formulations agree, symmetries hold."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg as la
from helpers import CASES, four_triangles_alpha, square_case

import critfric
from critfric.case.schema import loads_case
from critfric.fem.assembly import lame
from critfric.solvers import eigen


def _solve(text, **over):
    return critfric.solve_case(loads_case(text), overrides=over or None)


def assert_same_spectrum(a, b, rtol):
    """Two lists of (complex) eigenvalues agree as multisets."""
    a, b = np.asarray(a), np.asarray(b)
    assert len(a) == len(b)
    for x in a:
        assert np.min(np.abs(b - x)) <= rtol * abs(x), x


def full_pencil_eigenvalues(system, K, gamma=1.0):
    """Third formulation (METHOD.md, pencil form): A z = alpha M z with z = (Phi, X), dense QZ."""
    m, p = K.shape[0], system.n_contact
    Bn = np.zeros((m, p))
    Bt = np.zeros((m, p))
    Bn[system.cn, np.arange(p)] = 1.0
    Bt[system.ct, np.arange(p)] = 1.0
    A = np.block([[K.toarray(), -Bn], [-Bn.T, np.zeros((p, p))]])
    M = np.block([[np.zeros((m, m)), gamma * Bt], [np.zeros((p, m + p))]])
    w = la.eigvals(A, M)
    w = w[np.isfinite(w) & (np.abs(w) < 1e8)]
    return np.sort_complex(w)


def test_three_formulations_agree(coarse_square):
    case, prep = coarse_square
    K = prep.system.stiffness(*lame(1.0, 0.3))
    dense = eigen.solve(K, prep.system, method="dense", count=3)
    arpack = eigen.solve(K, prep.system, method="arpack", count=3)
    pencil = full_pencil_eigenvalues(prep.system, K)
    assert_same_spectrum(dense.alpha, pencil, rtol=1e-8)
    np.testing.assert_allclose(arpack.positive[:3], dense.positive[:3], rtol=1e-10)
    np.testing.assert_allclose(arpack.negative[:3], dense.negative[:3], rtol=1e-10)
    # Proposition 3.1: p0 eigenvalues in all (finite or infinite)
    assert len(dense.alpha) + dense.n_infinite == prep.system.n_contact


def test_shifted_pencil_finds_the_same_values(coarse_square):
    case, prep = coarse_square
    K = prep.system.stiffness(*lame(1.0, 0.3))
    ref = eigen.solve(K, prep.system, method="dense", count=1)
    near = eigen.solve(K, prep.system, method="arpack", count=1, shift=ref.positive[0] + 0.3)
    assert near.method == "arpack-shift"
    np.testing.assert_allclose(near.positive[0], ref.positive[0], rtol=1e-10)


def test_modes_satisfy_the_eigenproblem(coarse_square):
    case, prep = coarse_square
    s = prep.system
    K = s.stiffness(*lame(1.0, 0.3))
    for method in ("dense", "arpack"):
        spec = eigen.solve(K, s, method=method, count=2)
        for mode in spec.modes:
            F = K @ mode.phi
            interior = np.setdiff1d(np.arange(K.shape[0]), np.concatenate([s.cn, s.ct]))
            assert np.abs(F[interior]).max() < 1e-9 * np.abs(F).max()
            assert np.abs(mode.phi[s.cn]).max() == 0.0  # Phi_n = 0 on slipping nodes
            np.testing.assert_allclose(mode.Y, mode.alpha * mode.X, rtol=1e-8,
                                       atol=1e-10 * np.abs(mode.Y).max())
            u = s.to_xy(mode.phi)
            assert np.isclose(np.abs(u).max(), 1.0)
            dirichlet = prep.mesh.edge_nodes(["top"])
            assert np.all(u[dirichlet] == 0.0)


def test_gamma_minus_one_flips_every_eigenvalue():
    plus = _solve(square_case(size=0.2, method="dense"))
    minus = _solve(square_case(size=0.2, method="dense"), **{"solve.gamma": -1})
    np.testing.assert_allclose(minus.positive, -plus.negative, rtol=1e-10)
    np.testing.assert_allclose(minus.negative, -plus.positive, rtol=1e-10)


def test_young_modulus_does_not_matter():
    a = _solve(square_case(size=0.2))
    b = _solve(square_case(size=0.2), **{"material.E": 2.1e11})
    assert_same_spectrum(a.alpha, b.alpha, rtol=1e-9)


def _rotated_four_triangles(angle: float, shift=(3.0, -2.0)) -> str:
    c, s = np.cos(angle), np.sin(angle)
    pts = np.array([[0, 0], [1, 0], [1, 1], [0, 1], [0.5, 0.5]]) @ np.array([[c, s], [-s, c]])
    pts += shift
    nodes = ", ".join(f"[{float(x)!r}, {float(y)!r}]" for x, y in pts)
    return f"""
[geometry]
shape = "mesh"
nodes = [{nodes}]
triangles = [[0, 1, 4], [1, 2, 4], [2, 3, 4], [3, 0, 4]]
[geometry.edges]
bottom = [[0, 1]]
right = [[1, 2]]
top = [[2, 3]]
left = [[3, 0]]
[material]
nu = 0.3
[mesh]
element = "P1"
"""


@pytest.mark.parametrize("angle", [0.3, 2.0, -2.5])
def test_rotated_and_translated_body_gives_the_same_values(angle):
    r = _solve(_rotated_four_triangles(angle))
    np.testing.assert_allclose(r.positive, [four_triangles_alpha(0.3)], rtol=1e-10)
    np.testing.assert_allclose(r.normal, [np.sin(angle), -np.cos(angle)], atol=1e-12)


@pytest.mark.parametrize("element", ["P1", "P2", "Q1", "Q2"])
def test_rotated_polygon_with_structured_mesh(element):
    angle = 0.7
    c, s = np.cos(angle), np.sin(angle)
    v = np.array([[0, 0], [1, 0], [1, 1], [0, 1]]) @ np.array([[c, s], [-s, c]])
    verts = ", ".join(f"[{float(x)!r}, {float(y)!r}]" for x, y in v)
    rotated = f"""
[geometry]
shape = "polygon"
vertices = [{verts}]
edge_names = ["bottom", "right", "top", "left"]
[mesh]
element = "{element}"
size = 0.25
structured = true
"""
    a = _solve(rotated)
    b = _solve(square_case(element=element, size=0.25, structured=True))
    np.testing.assert_allclose(a.positive[0], b.positive[0], rtol=1e-9)


def test_deterministic_runs():
    a = _solve(square_case(size=0.1, method="arpack"))
    b = _solve(square_case(size=0.1, method="arpack"))
    assert np.array_equal(a.positive, b.positive)
    assert np.array_equal(a.modes[0]["phi"], b.modes[0]["phi"])


@pytest.mark.parametrize("name", ["one_triangle", "four_triangles", "unit_square",
                                  "inclined_body"])
def test_dense_and_arpack_agree_on_shipped_cases(name):
    over = {"mesh.size": 0.05} if name in ("unit_square", "inclined_body") else {}
    d = critfric.solve_case(CASES / f"{name}.toml", overrides={**over, "solve.method": "dense"})
    a = critfric.solve_case(CASES / f"{name}.toml", overrides={**over, "solve.method": "arpack"})
    np.testing.assert_allclose(a.positive[:1], d.positive[:1], rtol=1e-8)
    if len(d.negative) and len(a.negative):
        np.testing.assert_allclose(a.negative[0], d.negative[0], rtol=1e-8)


def test_count_widens_the_arpack_search():
    r = _solve(square_case(size=0.05, method="arpack", extra="count = 3"))
    d = _solve(square_case(size=0.05, method="dense"))
    assert len(d.positive) == 3
    np.testing.assert_allclose(r.positive[:3], d.positive, rtol=1e-9)
    assert len(r.modes) >= 3


@pytest.mark.parametrize("nu", [0.02, 0.05])
def test_real_eigenvalue_behind_the_complex_cluster_is_found(nu):
    # at small nu the lowest real alpha of the square lies beyond a cluster of nearly
    # imaginary eigenvalues at |alpha| ~ 2 (1 - nu) / (1 - 2 nu): ARPACK alone misses it
    text = square_case(size=0.04, nu=nu, method="arpack")
    r, d = _solve(text), _solve(text.replace('"arpack"', '"dense"'))
    assert d.positive[0] > 2 * (1 - nu) / (1 - 2 * nu)
    np.testing.assert_allclose(r.positive[0], d.positive[0], rtol=1e-9)
    assert r.solver == "arpack+explicit" and not r.warnings


def test_no_positive_eigenvalue_is_reported_not_invented():
    # nu = 0 on the four triangles: the closed form is infinite, no real eigenvalue exists
    r = critfric.solve_case(CASES / "four_triangles.toml", overrides={"material.nu": 0.0})
    assert len(r.positive) == 0 and np.isnan(r.critical)
    assert any("real positive" in w for w in r.warnings)
