"""Exact enumeration of the solutions of (2.8) for small problems: section 4.1 and cross-checks."""

from __future__ import annotations

import numpy as np
import pytest
from helpers import CASES, one_triangle_alpha, square_case

import critfric
from critfric.case.schema import loads_case
from critfric.errors import CaseError, SolverError
from critfric.fem.assembly import lame
from critfric.multiplicity import verify
from critfric.multiplicity.enumeration import Enumerator, enumerate_solutions, parse_frictions
from critfric.multiplicity.problems import static_problem
from critfric.solvers import coulomb


@pytest.fixture(scope="module")
def triangle():
    return static_problem(critfric.load_case(CASES / "one_triangle.toml"))


def test_one_triangle_bifurcation_of_fig_2(triangle):
    """Section 4.1: one solution below 3 - 4 nu, a branch at it, two isolated ones above,
    with the closed forms U_t = 2 F1/(lambda + G) (slip) and U = 0, X = -F1, Y = -F2 (stick)."""
    lam, G = lame(1.0, 0.3)
    F1, F2 = 0.5, 0.9
    assert F1 / F2 == pytest.approx((lam + G) / (lam + 3 * G), rel=1e-14)
    slip = 2 * F1 / (lam + G)
    crit = one_triangle_alpha(0.3)
    below, at, above = enumerate_solutions(triangle, [0.5 * crit, crit, 1.5 * crit])

    assert below.count == 1 and not below.branch
    (s,) = below.solutions
    assert s.Ut[0] == pytest.approx(slip, rel=1e-12) and abs(s.Un[0]) < 1e-12
    assert abs(s.X[0]) < 1e-12 and abs(s.Y[0]) < 1e-12

    assert at.branch and at.count == 0  # both solutions are the ends of the branch
    (b,) = at.branches
    assert b.status == ["slip+"] and len(b.directions) == 1
    ends = sorted(b.ends, key=lambda e: e.Ut[0])
    assert ends[0].Ut[0] == pytest.approx(0, abs=1e-12) and ends[0].X[0] == pytest.approx(-F1)
    assert ends[1].Ut[0] == pytest.approx(slip) and ends[1].X[0] == pytest.approx(0, abs=1e-12)
    d = b.directions[0]  # along the branch: U_n = 0, Y = crit X, X = (lambda + G)/2 U_t - F1
    assert abs(d.Un[0]) < 1e-12 and d.Y[0] == pytest.approx(crit * d.X[0])
    assert d.X[0] == pytest.approx(0.5 * (lam + G) * d.Ut[0])

    assert above.count == 2 and not above.branch
    stick = min(above.solutions, key=lambda e: abs(e.Ut[0]))
    assert stick.status == ["stuck"] and abs(stick.Ut[0]) < 1e-12
    assert stick.X[0] == pytest.approx(-F1) and stick.Y[0] == pytest.approx(-F2)
    assert max(e.Ut[0] for e in above.solutions) == pytest.approx(slip)


def test_sweep_counts_and_json(triangle):
    sweep = enumerate_solutions(triangle, parse_frictions("1:3:11"))
    counts = [(e.friction, e.count, e.branch) for e in sweep]
    assert [c for f, c, _ in counts] == [1, 1, 1, 1, 0, 2, 2, 2, 2, 2, 2]
    assert [f for f, _, br in counts if br] == [pytest.approx(1.8)]
    js = sweep[4].to_json()
    assert set(js) == {"friction", "count", "branch", "solutions"}
    assert js["solutions"][0]["kind"] == "branch" and len(js["solutions"][0]["ends"]) == 2


def test_enumeration_contains_the_newton_solution():
    """A mixed free/stuck/slip case with 8 contact nodes: 4^8 systems; the Newton solution is
    one of the enumerated ones, and every enumerated one satisfies (2.9)-(2.11)."""
    text = """
[geometry]
shape = "rectangle"
width = 1.0
height = 0.5
[mesh]
size = 0.143
structured = true
[load]
friction = 1.0
displacement = { top = [[0.004, 0.0, 0.0], [-0.03, 0.045, 0.0]] }
"""
    prob = static_problem(loads_case(text))
    assert prob.system.n_contact == 8
    enum = Enumerator(prob)
    for friction in (0.3, 1.0):
        sol = coulomb.solve(prob, friction)
        e = enum(friction)
        assert not e.branch and e.count >= 1
        assert len(set(sol.labels)) >= 2
        match = [s for s in e.solutions if np.allclose(s.Ut, sol.Ut, atol=1e-9 * enum.D)
                 and np.allclose(s.X, sol.X, atol=1e-9 * enum.F)]
        assert len(match) == 1 and match[0].status == sol.labels
        for s in e.solutions:
            bad = coulomb.violations(s.Un, s.Ut, s.X, s.Y, prob.reference, friction,
                                     force_scale=enum.F, disp_scale=enum.D)
            assert max(bad.values()) <= 1e-9


def test_branch_of_the_explicit_example_is_the_eigenfunction():
    """Four triangles with section 5's loading at the critical coefficient: the enumerated
    branch is u + delta Phi, and its ends are where the walk of `verify` stops (delta0)."""
    case = critfric.load_case(CASES / "four_triangles.toml")
    b = verify.branch(case)
    e = Enumerator(b.construction.problem)(b.friction)
    (br,) = [br for br in e.branches if br.status == ["slip+", "slip+"]]
    X0, Xt = b.construction.X, b.mode.X
    ends = sorted((e_.X - X0) @ Xt / (Xt @ Xt) for e_ in br.ends)
    np.testing.assert_allclose(ends, [-b.delta0_sides[0], b.delta0_sides[1]], rtol=1e-8)
    d = br.directions[0]
    phi_t = b.mode.phi[b.construction.problem.system.ct]
    np.testing.assert_allclose(d.Ut / np.linalg.norm(d.Ut), np.sign(d.Ut @ phi_t) * phi_t
                               / np.linalg.norm(phi_t), atol=1e-9)


def test_limits_and_bad_ranges():
    prob = static_problem(loads_case(square_case(size=0.1)), friction=0.5)
    with pytest.raises(SolverError, match="p = 11 contact nodes is above 8"):
        Enumerator(prob)
    for bad in ("1:2", "a:b:3", "1:2:0", "-1", "1:2:2.5"):
        with pytest.raises(CaseError) as err:
            parse_frictions(bad)
        assert err.value.key == "--friction" and "a:b:N" in str(err.value)
    np.testing.assert_allclose(parse_frictions("0:1:3"), [0, 0.5, 1])


def test_enumeration_of_an_unloaded_case_raises_no_warning():
    """Zero load: every scale is zero; the checks must not divide 0 by 0. Floating-point
    errors raise (numpy's state is this thread's) and every warning of this thread is
    recorded: the process-wide filter "error" would also reach the worker's other threads.
    ResourceWarnings are not this computation's: the garbage collector emits them for
    whatever it frees, at any allocation."""
    import threading
    import warnings

    this, shown = threading.current_thread(), []

    def record(message, category, *args, **kwargs):
        if threading.current_thread() is this and not issubclass(category, ResourceWarning):
            shown.append(f"{category.__name__}: {message}")

    with np.errstate(divide="raise", over="raise", invalid="raise"), warnings.catch_warnings():
        warnings.simplefilter("always")
        warnings.showwarning = record
        for name in ("four_triangles", "one_triangle"):
            out = enumerate_solutions(static_problem(critfric.load_case(CASES / f"{name}.toml")),
                                      [0.5, 1.8, 2.5])
            assert len(out) == 3
    assert shown == []
