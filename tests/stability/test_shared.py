"""The static stage from K_rr's factorization (SciPy): the Schur complement, the extension
and the critical coefficients against the static solver's own path, for contact states
with slipping, stuck and free nodes."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse.linalg as spla

from critfric.case.schema import load_case
from critfric.fem.assembly import lame
from critfric.fem.contact import FREE, SLIP, STUCK
from critfric.solve import prepare
from critfric.solvers import eigen
from critfric.solvers.eigen import ContactState
from critfric.solvers.eigenproblem import Problem
from critfric.solvers.ordering import fill_order
from critfric.stability import shared, stability_case
from critfric.stability.pencil import kept_dofs


@pytest.fixture(scope="module")
def square():
    prep = prepare(load_case("unit-square", overrides={"mesh.size": 0.05,
                                                       "solve.backend": "scipy"}))
    return prep.system, prep.system.stiffness(*lame(1.0, 0.3))


def states(p: int) -> list[ContactState]:
    """All slipping; slipping, stuck and free nodes mixed, both slip signs."""
    rng = np.random.default_rng(7)
    mixed = rng.choice([SLIP, SLIP, STUCK, FREE], size=p).astype(np.int8)
    mixed[0] = SLIP
    return [ContactState.all_slipping(p), ContactState(mixed, rng.choice([-1.0, 1.0], size=p))]


@pytest.mark.parametrize("which", [0, 1])
def test_the_schur_complement_and_the_spectrum_equal_the_static_path(square, which):
    system, K = square
    state = states(system.n_contact)[which]
    _, kept = kept_dofs(system, state)
    problem = Problem(K, system, state)
    Krr = K[kept][:, kept].tocsr()
    one = shared.SharedFactor.of(K, Krr, problem, kept, fill_order(system, kept))
    # S against the Schur complement by the inverse: (K^-1)_cc = S^-1
    c = problem.contact_dofs
    E = np.zeros((K.shape[0], len(c)))
    E[c, np.arange(len(c))] = 1.0
    S_inv = spla.splu(K.tocsc()).solve(E)[c]
    np.testing.assert_allclose(one.S @ S_inv, np.eye(len(c)), atol=1e-9)
    # K_rr^-1 and the extension
    b = np.random.default_rng(1).standard_normal(len(kept))
    assert np.linalg.norm(Krr @ one.solve(b) - b) < 1e-10 * np.linalg.norm(b)
    xc = np.random.default_rng(2).standard_normal((len(c), 2))
    x = one.extend(xc)
    np.testing.assert_array_equal(x[c], xc)
    interior = np.setdiff1d(np.arange(K.shape[0]), c)
    assert np.abs((K @ x)[interior]).max() < 1e-10 * np.abs(K @ x).max()
    # the critical coefficients as the static solver finds them
    mine = eigen.solve(K, system, state, count=2, backend="scipy", made=one)
    theirs = eigen.solve(K, system, state, count=2, backend="scipy")
    for a, b in ((mine.positive, theirs.positive), (mine.negative, theirs.negative),
                 (np.sort_complex(mine.alpha), np.sort_complex(theirs.alpha))):
        np.testing.assert_allclose(a, b, rtol=1e-10)
    for m, t in zip(mine.modes, theirs.modes):
        assert m.alpha == pytest.approx(t.alpha, rel=1e-10)
        assert abs(abs(np.vdot(m.phi, t.phi)) - np.vdot(t.phi, t.phi).real) < 1e-8 * np.vdot(
            t.phi, t.phi).real


def test_rows_coupled_to_the_eliminated_ones_are_boundary_rows(square):
    system, K = square
    state = states(system.n_contact)[1]
    _, kept = kept_dofs(system, state)
    problem = Problem(K, system, state)
    J = shared.boundary_rows(K, kept, problem.contact_dofs)
    others = np.setdiff1d(np.arange(len(kept)), J)
    eliminated = np.setdiff1d(np.arange(K.shape[0]), kept)
    assert K[kept[others]][:, eliminated].nnz == 0
    assert set(kept[J]) >= set(problem.contact_dofs) - set(eliminated)


def test_scipy_alone_takes_the_shared_factorization(square):
    system, _ = square
    state = ContactState.all_slipping(system.n_contact)
    assert shared.applies(system, state, "auto", "scipy")
    assert not shared.applies(system, state, "auto", "pardiso")
    assert not shared.applies(system, state, "arpack", "scipy")


def test_a_boundary_too_large_for_the_dense_elimination_factors_apart(square, monkeypatch):
    """Above DENSE_MAX rows of A: no shared factorization, and the command's static stage and
    thresholds are those of the two factorizations."""
    system, K = square
    state = ContactState.all_slipping(system.n_contact)
    _, kept = kept_dofs(system, state)
    problem = Problem(K, system, state)
    Krr = K[kept][:, kept].tocsr()
    order = fill_order(system, kept)
    assert shared.SharedFactor.of(K, Krr, problem, kept, order) is not None
    case = load_case("unit-square", overrides={"mesh.size": 0.05, "solve.backend": "scipy",
                                               "stability.modes": 4})
    both = stability_case(case)
    monkeypatch.setattr(shared, "DENSE_MAX", 10)
    assert shared.SharedFactor.of(K, Krr, problem, kept, order) is None
    apart = stability_case(case)
    for key in ("positive", "negative"):
        assert both.divergence[key] == pytest.approx(apart.divergence[key], rel=1e-10)
        assert both.flutter[key] == pytest.approx(apart.flutter[key], rel=1e-9)
