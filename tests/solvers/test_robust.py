"""Numerical robustness at the edges of the input space, and determinism."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np
import pytest
from helpers import CASES, REPO, four_triangles_alpha, one_triangle_alpha

from critfric import loads_case, solve_case, write_result
from critfric.errors import SolverError
from critfric.files.results import read_summary, text_list
from critfric.solvers import eigen


def both(case, **overrides):
    """The same case solved by the dense and the ARPACK paths."""
    return [solve_case(case, overrides={**overrides, "solve.method": m})
            for m in ("dense", "arpack")]


def agree(a, b, rtol=1e-8):
    np.testing.assert_allclose(a.positive[:1], b.positive[:1], rtol=rtol)
    np.testing.assert_allclose(a.negative[:1], b.negative[:1], rtol=rtol)


@pytest.mark.parametrize("nu", [0.0, 0.4999])
def test_closed_forms_at_both_ends_of_nu(nu):
    for r in both(CASES / "one_triangle.toml", **{"material.nu": nu}):
        assert r.positive == pytest.approx([one_triangle_alpha(nu)], rel=1e-10)
    if nu > 0:
        for r in both(CASES / "four_triangles.toml", **{"material.nu": nu}):
            assert r.positive == pytest.approx([four_triangles_alpha(nu)], rel=1e-10)


def test_no_real_eigenvalue_is_a_result_not_an_error(tmp_path):
    """Four triangles at nu = 0: the closed form is infinite, no real coefficient exists."""
    for r in both(CASES / "four_triangles.toml", **{"material.nu": 0.0}):
        assert len(r.positive) == 0 and np.isnan(r.critical)
        assert any("only 0 real positive" in w for w in r.warnings)
    write_result(r, tmp_path / "r.h5")
    assert read_summary(tmp_path / "r.h5")["positive"] == []


@pytest.mark.parametrize("width,height,size", [(1.0, 100.0, 0.25), (100.0, 1.0, 0.5)])
def test_aspect_ratio_100(width, height, size):
    case = loads_case(f'[geometry]\nshape = "rectangle"\nwidth = {width}\nheight = {height}\n'
                      f'[mesh]\nsize = {size}\n')
    dense, arpack = both(case)
    assert dense.n_dofs > 500 and len(dense.positive) and len(dense.negative)
    # cond(K) = 1.3e10 for the 1 x 100 column: the four paths (dense/ARPACK x SciPy/PARDISO)
    # and T formed explicitly agree to 5e-8 (measured), which is what double precision
    # allows here (cond * eps = 3e-6), not to 1e-8
    agree(dense, arpack, rtol=1e-7)


def test_a_contact_edge_with_a_single_free_node():
    """Bottom nodes x = 0, 1/2, 1 with both ends clamped (a skew body: on a symmetric one the
    single node's normal and tangential DOFs decouple and alpha is infinite)."""
    case = loads_case('[geometry]\nshape = "parallelogram"\nbase = 1.0\nheight = 1.0\n'
                      'offset = 0.4\n[boundary]\ndirichlet = ["left", "right"]\n'
                      '[mesh]\nsize = 0.5\nstructured = true\n')
    dense, arpack = both(case)
    assert dense.n_contact == 1 and len(dense.positive) == 1
    agree(dense, arpack)


ONE_CELL = {
    "P2": ("triangles = [[0, 1, 2]]", "[[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]]", "[[1, 2]]"),
    "Q1": ("quads = [[0, 1, 2, 3]]", "[[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]]",
           "[[2, 3]]"),
    "Q2": ("quads = [[0, 1, 2, 3]]", "[[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]]",
           "[[2, 3]]"),
}


@pytest.mark.parametrize("element", sorted(ONE_CELL))
def test_meshes_of_one_element(element):
    cells, nodes, top = ONE_CELL[element]
    case = loads_case(f"""
[geometry]
shape = "mesh"
nodes = {nodes}
{cells}
[geometry.edges]
bottom = [[0, 1]]
top = {top}
[mesh]
element = "{element}"
""")
    dense, arpack = both(case)
    assert dense.mesh.n_cells == 1 and dense.n_contact >= 1
    assert len(dense.alpha) == len(arpack.alpha)
    np.testing.assert_allclose(np.sort_complex(dense.alpha), np.sort_complex(arpack.alpha),
                               rtol=1e-8)


def test_arpack_non_convergence_falls_back_and_says_so(tmp_path):
    over = {"mesh.size": 0.05, "solve.method": "arpack", "solve.maxiter": 1, "solve.count": 3,
            "solve.tol": 0.0}  # machine precision: not reached in one iteration
    capped = solve_case("unit-square", overrides=over)
    assert any("did not converge" in n for n in capped.notes)
    assert capped.solver == "arpack+explicit"
    dense = solve_case("unit-square", overrides={**over, "solve.method": "dense"})
    agree(capped, dense)
    write_result(capped, tmp_path / "r.h5")
    import h5py

    with h5py.File(tmp_path / "r.h5") as f:
        assert any("did not converge" in n for n in text_list(f.attrs["notes"]))


def test_arpack_non_convergence_without_fallback_fails_clearly(monkeypatch):
    monkeypatch.setattr(eigen, "EXPLICIT_T_MAX", 3)
    with pytest.raises(SolverError, match="ARPACK did not converge.*too many to form T.*try"):
        solve_case("unit-square", overrides={"mesh.size": 0.01, "solve.method": "arpack",
                                             "solve.maxiter": 1, "solve.count": 3})


def test_arpack_says_how_far_its_search_is_complete(monkeypatch):
    """Where T is too large to form, ARPACK's converged eigenvalues are kept with the radius
    within which the spectrum is complete: flagged, warned, never silently partial."""
    monkeypatch.setattr(eigen, "EXPLICIT_T_MAX", 3)
    over = {"mesh.size": 0.05, "solve.method": "arpack", "solve.count": 40}
    r = solve_case("unit-square", overrides=over)
    dense = solve_case("unit-square", overrides={**over, "solve.method": "dense"})
    assert not r.complete and dense.complete and not r.summary()["complete"]
    assert any("complete only for |alpha| <" in w for w in r.warnings)
    radius = float(next(w for w in r.warnings if "complete only" in w).split("< ")[1].split(":")[0])
    for got, ref in ((r.positive, dense.positive), (r.negative, dense.negative)):
        inside = ref[np.abs(ref) < 0.999 * radius]
        np.testing.assert_allclose(got[:len(inside)], inside, rtol=1e-8)


def test_same_case_same_eigenvalues_in_process():
    over = {"mesh.size": 0.1, "solve.method": "arpack", "solve.count": 2}
    a, b = (solve_case("unit-square", overrides=over) for _ in range(2))
    np.testing.assert_array_equal(a.mesh.points, b.mesh.points)
    np.testing.assert_allclose(a.alpha, b.alpha, rtol=1e-12, atol=0)


def test_same_case_same_eigenvalues_across_processes(tmp_path):
    env = dict(os.environ, PYTHONPATH=str(REPO), OMP_NUM_THREADS="1")
    cmd = [sys.executable, "-c", "from critfric.cli import main; main()", "solve",
           "unit-square", "--size", "0.05", "--method", "arpack", "--count", "2", "--json"]
    procs = [subprocess.Popen(cmd + ["-o", str(tmp_path / f"r{i}.h5")], env=env,
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
             for i in range(2)]
    runs = []
    for p in procs:
        out, err = p.communicate(timeout=120)
        assert p.returncode == 0, err
        runs.append(json.loads(out))
    assert runs[0]["n_dofs"] == runs[1]["n_dofs"]
    for key in ("positive", "negative"):
        np.testing.assert_allclose(runs[0][key], runs[1][key], rtol=1e-12, atol=0)
