"""The 2D contact system: the free block in the n/t basis, made in place, equals the sparse
product Q^T K Q; a system assembled at one Poisson ratio equals the two parts combined."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp

from critfric.case.schema import loads_case
from critfric.errors import CaseError
from critfric.fem.assembly import assemble_elasticity, assemble_stiffness, lame
from critfric.fem.contact import contact_system, rotation
from critfric.meshing.from_case import make_mesh
from critfric.solve import prepare, solve_prepared

SLANTED = """
[geometry]
shape = "polygon"
vertices = [[0.0, 0.0], [2.0, 0.7], [1.6, 1.9], [-0.3, 1.1]]
edge_names = ["bottom", "right", "top", "left"]
[boundary]
contact = ["bottom"]
dirichlet = ["right", "top"]
[material]
nu = 0.27
[mesh]
element = "{element}"
size = 0.4
"""
BOUNDARY = {"contact": ["bottom"], "dirichlet": ["right", "top"]}


def _mesh(element: str):
    return make_mesh(loads_case(SLANTED.format(element=element)))


@pytest.mark.parametrize("element", ["P1", "P2", "Q1", "Q2"])
def test_free_block_is_the_rotated_product(element):
    mesh = _mesh(element)
    K_lam, K_G = assemble_elasticity(mesh)
    system = contact_system(mesh, K_lam, K_G, **BOUNDARY)
    Q = rotation(mesh.n_nodes, system.nodes, system.normal, system.tangent)
    assert abs(system.normal[1]) < 0.99  # Gamma_C is slanted: the rotation mixes x and y
    free, fixed = system.free, system.fixed
    for part, coupling, K in ((system.K_lam, system.D_lam, K_lam), (system.K_G, system.D_G, K_G)):
        rotated = (Q.T @ K @ Q).toarray()
        scale = np.abs(rotated).max()
        np.testing.assert_allclose(part.toarray(), rotated[np.ix_(free, free)], atol=1e-14 * scale)
        np.testing.assert_allclose(coupling.toarray(), rotated[np.ix_(free, fixed)],
                                   atol=1e-14 * scale)
        assert part.has_sorted_indices
    np.testing.assert_array_equal(K_lam.toarray(), assemble_elasticity(mesh)[0].toarray())


@pytest.mark.parametrize("element", ["P1", "P2", "Q1", "Q2"])
def test_stiffness_at_one_poisson_ratio_is_the_parts_sum(element):
    mesh = _mesh(element)
    lam, G = lame(1.0, 0.27)
    K_lam, K_G = assemble_elasticity(mesh)
    K = assemble_stiffness(mesh, lam, G)
    np.testing.assert_array_equal(K.indptr, K_lam.indptr)
    np.testing.assert_array_equal(K.indices, K_lam.indices)
    np.testing.assert_array_equal(K.data, lam * K_lam.data + G * K_G.data)  # the same numbers
    one = contact_system(mesh, K, None, lame=(lam, G), **BOUNDARY)
    parts = contact_system(mesh, K_lam, K_G, **BOUNDARY)
    for keep in (False, True):
        a, b = one.stiffness(lam, G, keep_zeros=keep), parts.stiffness(lam, G, keep_zeros=keep)
        np.testing.assert_array_equal(a.indices, b.indices)
        np.testing.assert_allclose(a.data, b.data, rtol=0, atol=1e-15 * np.abs(b.data).max())
    np.testing.assert_allclose(one.coupling(lam, G).toarray(), parts.coupling(lam, G).toarray(),
                               atol=1e-15 * np.abs(b.data).max())
    for E in (210e9, 3e-5):  # another E: the same Poisson ratio, scaled
        scaled, reference = one.stiffness(*lame(E, 0.27)), parts.stiffness(*lame(E, 0.27))
        np.testing.assert_array_equal(scaled.indices, reference.indices)
        np.testing.assert_allclose(scaled.data, reference.data, rtol=0,
                                   atol=1e-14 * np.abs(reference.data).max())
        np.testing.assert_allclose(one.coupling(*lame(E, 0.27)).toarray(),
                                   parts.coupling(*lame(E, 0.27)).toarray(), rtol=0,
                                   atol=1e-14 * np.abs(reference.data).max())
    with pytest.raises(ValueError, match="one Poisson ratio"):
        one.stiffness(*lame(1.0, 0.3))
    with pytest.raises(ValueError):
        contact_system(mesh, K, None, **BOUNDARY)  # which Lame parameters?


def test_a_system_for_one_poisson_ratio_solves_that_ratio_alone():
    case = loads_case(SLANTED.format(element="P1"))
    prepared = prepare(case, _single=True)
    assert prepared.system.K_G is None
    same = solve_prepared(prepared, case)
    reference = solve_prepared(prepare(case), case)
    np.testing.assert_allclose(same.positive, reference.positive, rtol=1e-12)
    np.testing.assert_allclose(same.negative, reference.negative, rtol=1e-12)
    with pytest.raises(CaseError, match=r"material\.nu"):
        solve_prepared(prepared, case.with_overrides({"material.nu": 0.3}))


def test_matrices_with_duplicates_are_summed_and_left_unchanged():
    mesh = _mesh("P1")
    K_lam, K_G = assemble_elasticity(mesh)
    coo = K_lam.tocoo()
    half = sp.coo_matrix((np.concatenate([coo.data / 2, coo.data / 2]),
                          (np.tile(coo.row, 2), np.tile(coo.col, 2))), shape=K_lam.shape)
    doubled = half.tocsr()  # duplicate entries, not summed
    before = doubled.data.copy()
    a = contact_system(mesh, doubled, K_G, **BOUNDARY)
    b = contact_system(mesh, K_lam, K_G, **BOUNDARY)
    np.testing.assert_allclose(a.K_lam.toarray(), b.K_lam.toarray(), atol=1e-14)
    np.testing.assert_array_equal(doubled.data, before)
