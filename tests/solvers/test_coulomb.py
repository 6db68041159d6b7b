"""The semi-smooth Newton solver of the static Coulomb problem (2.8)-(2.11)."""

from __future__ import annotations

import numpy as np
import pytest
from helpers import CASES, square_case

import critfric
from critfric.case.schema import loads_case
from critfric.errors import SolverError
from critfric.multiplicity import verify
from critfric.multiplicity.problems import static_problem
from critfric.solve import prepare
from critfric.solvers import coulomb
from critfric.solvers.backends import factorize

MIXED = square_case(size=0.05) + """
[load]
friction = 1.0
displacement = { top = [[-0.002, 0.0, 0.0], [-0.03, 0.045, 0.0]] }
"""


def _scales(sol):
    return dict(force_scale=np.abs(np.concatenate([sol.X, sol.Y])).max(),
                disp_scale=np.abs(np.concatenate([sol.Un, sol.Ut])).max())


@pytest.mark.parametrize("element", ["P1", "Q2"])
def test_schur_complement_is_the_inverse_flexibility(element):
    case = loads_case(square_case(size=0.25, element=element))
    prep = prepare(case)
    prob = static_problem(case, prep)
    cond = coulomb.Condensed(prob.K, prep.system)
    m, c = prob.K.shape[0], cond.cdofs
    E = np.zeros((m, len(c)))
    E[c, np.arange(len(c))] = 1.0
    flex = factorize(prob.K).solve(E)[c]
    np.testing.assert_allclose(cond.S @ flex, np.eye(len(c)), atol=1e-10)
    b = np.random.default_rng(0).standard_normal(m)
    np.testing.assert_allclose(prob.K @ cond.solve(b), b, atol=1e-11)


@pytest.mark.parametrize("friction", [0.2, 0.45, 0.55])
def test_newton_reproduces_the_explicit_solution_on_the_inclined_body(friction):
    """Section 5's loading at friction below the critical one (about 0.585): the solution is
    the linear field U_h, every node slipping along +t."""
    case = critfric.load_case(CASES / "inclined_body.toml", overrides={"mesh.size": 0.05})
    prep = prepare(case)
    cons = verify.construction(prep.system, 1.0, 0.3, friction, ["bottom"], ["top"])
    sol = coulomb.solve(cons.problem)
    scale = np.abs(cons.U).max()
    np.testing.assert_allclose(sol.U, cons.U, atol=1e-10 * scale)
    np.testing.assert_allclose(sol.X, cons.X, atol=1e-10 * np.abs(cons.X).max())
    np.testing.assert_allclose(sol.Y, cons.Y, atol=1e-10 * np.abs(cons.X).max())
    assert sol.labels == ["slip+"] * prep.system.n_contact
    assert sol.iterations <= coulomb.MAXITER and sol.residual <= coulomb.TOL


def test_newton_with_free_stuck_and_slipping_nodes():
    case = loads_case(MIXED)
    prob = static_problem(case)
    sol = coulomb.solve(prob)
    assert {"free", "stuck", "slip+"} <= set(sol.labels) or {"free", "stuck", "slip-"} <= set(
        sol.labels)
    assert sol.iterations <= 15  # piecewise linear: ends once the active set is found
    assert sol.residual <= coulomb.TOL
    assert prob.equilibrium(sol.U, sol.X, sol.Y) <= 1e-12
    bad = coulomb.violations(sol.Un, sol.Ut, sol.X, sol.Y, prob.reference, 1.0, **_scales(sol))
    assert max(bad.values()) <= 1e-10, bad
    # the statuses mean what they say
    lab = np.array(sol.labels)
    assert np.all(sol.Un[lab == "free"] < 0) and np.all(sol.X[lab == "free"] == pytest.approx(0))
    stuck = lab == "stuck"
    assert np.all(np.abs(sol.Y[stuck]) < -1.0 * sol.X[stuck])
    assert np.allclose(sol.Ut[stuck], 0, atol=1e-12)
    # the same solution from another start, and again at once from the solution itself
    other = coulomb.solve(prob, start=np.concatenate([sol.Un * 0 + 0.01, sol.Ut * 0]))
    np.testing.assert_allclose(other.U, sol.U, atol=1e-10 * np.abs(sol.U).max())
    again = coulomb.solve(prob, start=np.concatenate([sol.Un, sol.Ut]))
    assert again.iterations == 0


def test_reference_displacement_shifts_the_stuck_nodes():
    text = MIXED.replace("friction = 1.0", "friction = 1.0\nreference = 0.001")
    prob = static_problem(loads_case(text))
    sol = coulomb.solve(prob)
    lab = np.array(sol.labels)
    assert (lab == "stuck").any()
    np.testing.assert_allclose(sol.Ut[lab == "stuck"], 0.001, rtol=1e-10)
    bad = coulomb.violations(sol.Un, sol.Ut, sol.X, sol.Y, prob.reference, 1.0, **_scales(sol))
    assert max(bad.values()) <= 1e-10


def test_non_convergence_is_a_solver_error():
    prob = static_problem(loads_case(MIXED))
    with pytest.raises(SolverError, match="did not converge in 1 iterations"):
        coulomb.solve(prob, maxiter=1)


def test_one_triangle_slip_solution():
    """Section 4.1: below the critical coefficient the only solution slips with
    U_t = 2 F1 / (lambda + G) and no contact force."""
    prob = static_problem(critfric.load_case(CASES / "one_triangle.toml"))
    lam, G = prob.lam, prob.G
    sol = coulomb.solve(prob, 1.0)
    assert sol.Ut[0] == pytest.approx(2 * 0.5 / (lam + G), rel=1e-12)
    assert abs(sol.X[0]) <= 1e-12 and abs(sol.Y[0]) <= 1e-12
