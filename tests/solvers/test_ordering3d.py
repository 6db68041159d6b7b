"""Nested dissection and substructuring pieces of 3D meshes: permutations that give the
natural order's results, pieces that partition the rows, separators that K respects."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
from helpers import box_case

from critfric.case.schema import loads_case
from critfric.fem.assembly import lame
from critfric.solve import prepare
from critfric.solvers import backends as linsolve
from critfric.solvers import eigen, ordering

SIZES = {"P1": 0.1, "P2": 0.2, "Q1": 0.1, "Q2": 0.2}  # 2-4 k DOFs each


@pytest.fixture(scope="module", params=list(SIZES))
def box(request):
    prep = prepare(loads_case(box_case(element=request.param, size=SIZES[request.param])))
    return prep.system, prep.system.stiffness(*lame(1.0, 0.3))


@pytest.fixture(autouse=True)
def dissect_small_meshes(monkeypatch):
    monkeypatch.setattr(ordering, "ND_MIN_DOFS_3D", 0)


def test_the_order_is_a_permutation_that_follows_the_nodes(box):
    system, _ = box
    order = ordering.fill_order(system)
    n = len(system.free)
    np.testing.assert_array_equal(np.sort(order), np.arange(n))
    rank = ordering.mesh_rank(system.mesh)
    np.testing.assert_array_equal(np.sort(rank), np.arange(system.mesh.n_nodes))
    np.testing.assert_array_equal(order, ordering.dof_order(system.free // 3, rank))
    node = system.free[order] // 3  # a node's DOFs stay together, in the nodes' order
    assert np.all(np.diff(rank[node]) >= 0)
    sub = np.arange(0, n, 5)  # an order of some of the DOFs
    np.testing.assert_array_equal(np.sort(ordering.fill_order(system, sub)),
                                  np.arange(len(sub)))


def test_the_order_gives_the_natural_orders_eigenvalues_and_solves(box, monkeypatch):
    system, K = box
    order = ordering.fill_order(system)
    nd = eigen.solve(K, system, method="dense", count=3, backend="scipy")
    monkeypatch.setattr(eigen, "fill_order", lambda s, dofs=None: np.arange(len(s.free)))
    natural = eigen.solve(K, system, method="dense", count=3, backend="scipy")
    assert len(nd.alpha) == len(natural.alpha) > 0
    np.testing.assert_allclose(np.sort_complex(nd.alpha), np.sort_complex(natural.alpha),
                               rtol=1e-10)
    b = np.random.default_rng(2).standard_normal(K.shape[0])
    x = linsolve.ScipyFactor(K, symmetric=True, order=np.arange(K.shape[0])).solve(b)
    y = linsolve.ScipyFactor(K, symmetric=True, order=order).solve(b)
    np.testing.assert_allclose(y, x, rtol=0, atol=1e-10 * np.abs(x).max())


def test_the_pieces_partition_the_rows_and_k_joins_none(box):
    system, K = box
    piece = ordering.pieces(system)
    assert piece.shape == (K.shape[0],)  # one label a row: every row in one piece exactly
    labels = set(np.unique(piece))  # small meshes: some parts too small to split
    assert labels <= set(range(-1, 2**ordering.PIECE_LEVELS)) and len(labels) >= 5
    assert np.count_nonzero(piece == -1) < 0.5 * len(piece)  # small meshes: thick separators
    A = sp.coo_matrix(K)
    inside = (piece[A.row] >= 0) & (piece[A.col] >= 0)
    np.testing.assert_array_equal(piece[A.row][inside], piece[A.col][inside])
    # the same pieces whether the mesh is dissected for the order or for the pieces alone
    np.testing.assert_array_equal(piece, ordering.pieces(system, np.arange(K.shape[0])))


def test_substructured_schur_equals_one_factorization_in_3d(box):
    system, K = box
    index = np.concatenate([system.cn, system.ct, system.ce])
    order = ordering.fill_order(system)
    whole = linsolve.ScipySchur(K, index, order=order)
    split = linsolve.SplitSchur(K, index, ordering.pieces(system), order=order, workers=2)
    np.testing.assert_allclose(split.S, whole.S, rtol=0, atol=1e-11 * np.abs(whole.S).max())
    xc = np.random.default_rng(3).standard_normal((len(index), 2))
    np.testing.assert_allclose(split.extend(xc), whole.extend(xc), rtol=0,
                               atol=1e-10 * np.abs(xc).max())


def test_order_two_meshes_dissect_their_vertices():
    """P2: separators of vertices, edge nodes placed with their edges' vertices: less fill
    than dissecting every node (whose separators are two node layers thick)."""
    prep = prepare(loads_case(box_case(element="P2", size=0.15)))
    system, mesh = prep.system, prep.mesh
    K = system.stiffness(*lame(1.0, 0.3))
    every = ordering.dof_order(system.free // 3,
                               ordering.nested_dissection(mesh.points, mesh.cells))
    fill = [linsolve.ScipyFactor(K, symmetric=True, order=o)._lu.nnz
            for o in (ordering.fill_order(system), every)]
    assert fill[0] < 0.9 * fill[1]
