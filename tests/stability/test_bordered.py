"""Newton's bordered solves on the factorization of K_rr (stability/bordered.py): deflated
GMRES against the LU of the bordered matrix, and the fall-back on that LU."""

from __future__ import annotations

import threading

import numpy as np
import pytest
import scipy.sparse.linalg as spla
from helpers import case_pencil

from critfric.case.schema import load_case
from critfric.stability import bordered, fold, locus
from critfric.stability.sharpen import sharpen


@pytest.fixture(scope="module")
def sharpened():
    """The unit square, P1, h = 0.05 (2.6 k kept DOFs): its positive onset, sharpened."""
    pencil = case_pencil(load_case("unit-square", overrides={"mesh.size": 0.05}))
    factor = locus.factor_of(pencil, "scipy", None)
    red = locus.reduce(pencil, 6, factor=factor)
    guess = locus.locate_flutter(red, locus.follow(red, 6, np.linspace(0, 2.0, 201)))
    return pencil, factor, red, sharpen(red, pencil, factor, [guess])[0]


def _unit(x):
    return x / np.linalg.norm(x)


def test_deflated_solves_reach_the_lu_solves(sharpened):
    pencil, factor, red, sharp = sharpened
    n = pencil.size
    L = pencil.L(sharp.friction, sharp.kappa)
    b, c = _unit(sharp.left), _unit(sharp.right)
    A = bordered.bordered(L, b, c)
    norm = abs(A).sum(axis=1).max()
    lu = spla.splu(A.tocsc())
    D = bordered.Deflated(factor, red.modes0)
    D.set(L, b, c)
    e = np.zeros(n + 1)
    e[n] = 1.0
    derivative = np.concatenate([pencil.B(sharp.friction) @ sharp.right, [0.0]])
    for rhs, rough, tol in ((e, False, bordered.REFINE_TOL), (derivative, True,
                                                               bordered.ROUGH_TOL)):
        for transpose in (False, True):
            x = D.solve(rhs, transpose=transpose, rough=rough)
            ref = lu.solve(rhs, trans="T" if transpose else "N")
            residual = (A.T if transpose else A) @ x - rhs
            assert np.abs(residual).max() <= tol * norm * np.abs(x).max()
            assert np.abs(x - ref).max() <= 1e3 * tol * np.abs(ref).max()
    assert D.lus == 0 and 0 < D.iterations <= 4 * bordered.GMRES_MAX


def test_newton_on_deflated_solves_lands_where_the_lu_newton_does(sharpened):
    pencil, factor, red, sharp = sharpened
    args = (pencil, sharp.friction, sharp.kappa, sharp.right, sharp.left)
    on_lu = fold.find_fold(*args)
    deflated = fold.find_fold(*args, solver=bordered.Deflated(factor, red.modes0))
    assert isinstance(on_lu.solver, bordered.Bordered) and on_lu.solver.lus >= 1
    assert isinstance(deflated.solver, bordered.Deflated) and deflated.solver.lus == 0
    assert deflated.steps == on_lu.steps == 1
    assert deflated.friction == pytest.approx(on_lu.friction, rel=1e-11)
    assert deflated.kappa == pytest.approx(on_lu.kappa, rel=1e-11)
    assert deflated.residual <= 1e-12
    # the other direction's run takes the same solver on
    again = fold.find_fold(*args, solver=deflated.solver)
    assert again.solver is deflated.solver and again.friction == deflated.friction


def test_stalled_gmres_hands_over_to_the_lu(sharpened, monkeypatch):
    pencil, factor, red, sharp = sharpened
    args = (pencil, sharp.friction, sharp.kappa, sharp.right, sharp.left)
    on_lu = fold.find_fold(*args)
    monkeypatch.setattr(bordered, "GMRES_MAX", 0)
    D = bordered.Deflated(factor, red.modes0)
    found = fold.find_fold(*args, solver=D)
    assert D.factor is None  # K_rr's factorization released before the LU is made
    assert isinstance(found.solver, bordered.Bordered) and found.solver.lus >= 1
    assert found.friction == pytest.approx(on_lu.friction, rel=1e-12)


def test_from_a_raw_guess_newton_on_deflated_solves_converges(sharpened):
    """The Jacobian's rough solves cost no accuracy: from the reduced model's raw guess
    (~1e-4 off) Newton on the deflated solves ends where the LU's does."""
    pencil, factor, red, sharp = sharpened
    guess = locus.locate_flutter(red, locus.follow(red, 6, np.linspace(0, 2.0, 201)))
    args = (pencil, guess.friction, guess.kappa, guess.right, guess.left)
    on_lu = fold.find_fold(*args)
    deflated = fold.find_fold(*args, solver=bordered.Deflated(factor, red.modes0))
    assert isinstance(deflated.solver, bordered.Deflated) and deflated.steps >= 2
    assert deflated.friction == pytest.approx(on_lu.friction, rel=1e-11)
    assert deflated.friction == pytest.approx(sharp.friction, rel=1e-7)


class _Counting:
    """A factorization that counts its solve calls."""

    def __init__(self, factor):
        self.factor, self.calls = factor, 0

    def solve(self, b):
        self.calls += 1
        return self.factor.solve(b)


@pytest.fixture(scope="module")
def both_ways(sharpened):
    """The sharpened onsets of both directions, as starts (f, kappa, right, left)."""
    pencil, factor, red, _ = sharpened
    guesses = [locus.locate_flutter(red, locus.follow(red, 6, np.linspace(0, end, 201)))
               for end in (-2.0, 2.0)]
    return [(s.friction, s.kappa, s.right, s.left)
            for s in sharpen(red, pencil, factor, guesses)]


def test_both_directions_in_lockstep_land_where_each_alone_does(sharpened, both_ways):
    pencil, factor, red, _ = sharpened
    alone_factor, joint_factor = _Counting(factor), _Counting(factor)
    D = bordered.Deflated(alone_factor, red.modes0)
    alone = [fold.find_fold(pencil, *start, solver=D) for start in both_ways]
    D = bordered.Deflated(joint_factor, red.modes0)
    together = fold.find_folds(pencil, both_ways, solver=D)
    assert together[0].solver is D and together[1].solver.factor is joint_factor
    assert together[0].friction < 0 < together[1].friction
    for one, joint in zip(alone, together):
        assert joint.steps == one.steps == 1
        assert joint.friction == pytest.approx(one.friction, rel=1e-12)
        assert joint.kappa == pytest.approx(one.kappa, rel=1e-12)
    # each GMRES iteration's solves of both directions in one call
    assert 0 < joint_factor.calls < alone_factor.calls


def test_runs_resumed_in_two_threads_give_the_same_numbers(sharpened, both_ways,
                                                           monkeypatch):
    """drive() resumes the lockstep's runs two at a time in two threads (two CPUs, malloc
    with one arena): bit for bit what one thread gives, and no thread of it outlives the
    call; without the malloc settings, one thread."""
    pencil, factor, red, _ = sharpened
    threads = []
    resume = bordered.resume

    def seen(run, value=None):
        threads.append(threading.current_thread().name)
        return resume(run, value)

    monkeypatch.setattr(bordered, "resume", seen)
    monkeypatch.setattr(bordered, "usable_cpus", lambda: 2)
    monkeypatch.setattr(bordered, "freed_memory_kept", lambda: True)
    two = fold.find_folds(pencil, both_ways, solver=bordered.Deflated(factor, red.modes0))
    assert any(name.startswith("critfric-drive") for name in threads)
    for cpus, kept in ((1, True), (2, False)):
        threads.clear()
        monkeypatch.setattr(bordered, "usable_cpus", lambda cpus=cpus: cpus)
        monkeypatch.setattr(bordered, "freed_memory_kept", lambda kept=kept: kept)
        one = fold.find_folds(pencil, both_ways, solver=bordered.Deflated(factor, red.modes0))
        assert set(threads) == {threading.main_thread().name}
    for a, b in zip(two, one):
        assert (a.friction, a.kappa, a.steps) == (b.friction, b.kappa, b.steps)
        np.testing.assert_array_equal(a.right, b.right)
        assert a.solver.iterations == b.solver.iterations > 0


def test_a_stall_in_lockstep_hands_over_to_one_after_the_other(sharpened, both_ways,
                                                               monkeypatch):
    pencil, factor, red, _ = sharpened
    on_lu = fold.find_folds(pencil, both_ways)
    monkeypatch.setattr(bordered, "GMRES_MAX", 0)
    D = bordered.Deflated(factor, red.modes0)
    found = fold.find_folds(pencil, both_ways, solver=D)
    assert D.factor is None  # released before the first LU was made
    assert found[1].solver is found[0].solver  # the LU's analysis passed on
    assert isinstance(found[0].solver, bordered.Bordered)
    for lu, one in zip(on_lu, found):
        assert one.friction == pytest.approx(lu.friction, rel=1e-12)


def test_orthonormal_bases_of_nearly_dependent_columns():
    """Columns of condition ~1e6 (and one exactly dependent, dropped): one Gram pass leaves
    them orthonormal to ~1e-16 cond^2 only; the basis is orthonormal to rounding and spans
    the columns."""
    rng = np.random.default_rng(7)
    A = rng.standard_normal((5000, 6))
    W = np.column_stack([A, A[:, :3] + 1e-6 * rng.standard_normal((5000, 3)), A[:, 0] + A[:, 1]])
    Q = bordered.orthonormal(W)
    assert Q.shape == (5000, 9)  # the exactly dependent column dropped
    np.testing.assert_allclose(Q.T @ Q, np.eye(9), atol=1e-12)
    residual = W - Q @ (Q.T @ W)
    assert np.abs(residual).max() <= 1e-10 * np.abs(W).max()


@pytest.mark.parametrize("order", ["C", "F"])
def test_orthonormal_over_its_input_is_the_same_basis(order):
    """``overwrite``: the basis written in W's memory (row-major, W's leading entries) is
    the one a new array gets, with a column dropped too."""
    rng = np.random.default_rng(8)
    A = rng.standard_normal((3000, 5))
    W = np.column_stack([A, A[:, :2] + 1e-6 * rng.standard_normal((3000, 2)), A[:, 0] - A[:, 4]])
    expected = bordered.orthonormal(W)
    mine = np.array(W, order=order)
    Q = bordered.orthonormal(mine, overwrite=True)
    assert Q.shape == expected.shape == (3000, 7)
    assert np.shares_memory(Q, mine) and Q.flags.c_contiguous
    np.testing.assert_array_equal(Q, expected)
