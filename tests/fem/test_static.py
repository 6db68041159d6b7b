"""[load] and [contact]: validation, the loads they build, and general contact states (3.2)."""

from __future__ import annotations

import numpy as np
import pytest
from helpers import square_case

import critfric
from critfric.case.schema import loads_case
from critfric.errors import CaseError
from critfric.fem.assembly import lame
from critfric.fem.contact import FREE, SLIP, STUCK
from critfric.fem.loads import body_force_load, traction_load
from critfric.multiplicity.problems import static_problem
from critfric.solve import prepare
from critfric.solvers import coulomb, eigen
from critfric.solvers.from_case import arc_length, contact_state

SQUARE = square_case(size=0.25)


@pytest.mark.parametrize("extra, key, text", [
    ("[load]\ntraction = { bottom = [1, 0] }", "load.traction", "traction-free edge"),
    ("[load]\ntraction = { right = [1] }", "load.traction", "[x, y]"),
    ("[load]\ntraction = { nowhere = [1, 0] }", "load.traction", "'nowhere'"),
    ("[load]\ndisplacement = { right = [0, 0] }", "load.displacement", "Dirichlet edge"),
    ("[load]\ndisplacement = { top = [[0, 1], [0, 0]] }", "load.displacement", "a0, ax, ay"),
    ("[load]\nbody_force = [0, 'down']", "load.body_force", "finite numbers"),
    ("[load]\npoints = [{ node = 3, force = [0, 1] }]", "load.points.0", "at = [x, y]"),
    ("[load]\npoints = [{ at = [0, 0] }]", "load.points", "force"),
    ("[load]\nreference = 'x'", "load.reference", "one per contact node"),
    ("[load]\nfriction = -0.1", "load.friction", "[0, inf]"),
    ("[contact]\ndefault = 'sliding'", "contact.default", "'slip'"),
    ("[contact]\nrules = [{ from = 0.5, to = 0.2, status = 'free' }]", "contact.rules",
     "from <= to"),
    ("[contact]\nrules = [{ from = 0, to = 1, status = 'free', gamma = -1 }]", "contact.rules",
     "gamma only"),
    ("[contact]\nrules = [{ from = 0, to = 1, status = 'slip', gamma = 2 }]", "contact.rules",
     "1 or -1"),
    ("[contact]\nsource = 'magic'", "contact.source", "'coulomb'"),
])
def test_bad_load_and_contact_name_file_key_and_allowed(extra, key, text):
    with pytest.raises(CaseError) as err:
        loads_case(SQUARE + extra, source="bad.toml")
    assert err.value.key == key and err.value.file == "bad.toml"
    assert text in str(err.value) and "allowed" in str(err.value)


def test_load_round_trips_and_defaults():
    case = loads_case(SQUARE)
    assert case.load["friction"] is None and case.load["reference"] == 0.0
    assert case.contact == {"source": "rules", "default": "slip", "rules": None}
    text = SQUARE + ("[load]\nfriction = 0.4\ntraction = { right = [1, 2] }\n"
                     "points = [{ at = [0, 1], force = [1, 0] }]\n"
                     "[contact]\nrules = [{ from = 0, to = 0.5, status = 'stuck' }]\n")
    case = loads_case(text)
    again = loads_case(case.to_toml())
    assert again.load == case.load and again.contact == case.contact


def test_errors_found_at_mesh_time_name_the_key():
    cases = [("[load]\npoints = [{ at = [0.3, 0.3], force = [0, 1] }]", "load.points.0",
              "no mesh node"),
             ("[load]\npoints = [{ at = [0, 1], force = [0, 1] }]", "load.points.0",
              "Dirichlet"),
             ("[load]\nreference = [0.0, 1.0]", "load.reference", "5 contact nodes"),
             ("[load]\ndisplacement = { top = [0.0, 1.0], right = [0.0, 0.0] }\n"
              "[boundary]\ndirichlet = ['top', 'right']", "load.displacement", "two different")]
    for extra, key, text in cases:
        case = loads_case(SQUARE + extra, source="c.toml")
        with pytest.raises(CaseError) as err:
            static_problem(case)
        assert err.value.key == key and text in str(err.value), str(err.value)


def test_loads_reach_the_right_dofs():
    """Point force at a contact node in the n/t basis; body force and tractions sum to the
    force they integrate; the affine Dirichlet field is reproduced at the Dirichlet nodes."""
    text = SQUARE + ("[load]\nbody_force = [0.5, -2.0]\ntraction = { right = [3.0, 1.0] }\n"
                     "points = [{ at = [0.5, 0.0], force = [0.25, -1.0] }]\n"
                     "displacement = { top = [[0.1, 0.2, 0.0], [-0.3, 0.0, 0.0]] }\n")
    case = loads_case(text)
    prep = prepare(case)
    s = prep.system
    prob = static_problem(case, prep)
    total = s.to_xy(prob.load).sum(axis=0)  # free DOFs only: the top row is Dirichlet
    top = prep.mesh.edge_nodes(["top"])
    full = body_force_load(prep.mesh, [0.5, -2.0]).reshape(-1, 2)
    full += traction_load(prep.mesh, "right", [3.0, 1.0]).reshape(-1, 2)
    expected = full.sum(axis=0) - full[top].sum(axis=0) + [0.25, -1.0]
    np.testing.assert_allclose(total, expected, rtol=1e-13)
    i = int(np.flatnonzero(np.all(np.isclose(prep.mesh.points[s.nodes], [0.5, 0.0]), axis=1))[0])
    body = s.from_xy(body_force_load(prep.mesh, [0.5, -2.0]))
    assert prob.load[s.cn[i]] - body[s.cn[i]] == pytest.approx(1.0)  # n = (0, -1)
    assert prob.load[s.ct[i]] - body[s.ct[i]] == pytest.approx(0.25)
    u = prob.displacement(np.zeros(s.n_dofs))
    x = prep.mesh.points[top]
    np.testing.assert_allclose(u[top], np.column_stack([0.1 + 0.2 * x[:, 0], -0.3 + 0 * x[:, 0]]))


def test_case_loads_reproduce_the_linear_solution():
    """Section 5's field written as a case: affine Dirichlet data on top, sigma n on the sides.
    The Newton solver returns it at every node (u linear is in the finite element space)."""
    nu, friction, a0 = 0.3, 0.7, 0.01
    lam, G = lame(1.0, nu)
    kappa = 2 * friction * (1 - nu) / (1 - 2 * nu)
    sxx, sxy = -lam, friction * (lam + 2 * G)
    text = square_case(size=0.2, element="P2") + (
        f"[load]\nfriction = {friction}\n"
        f"displacement = {{ top = [[{a0}, 0.0, {kappa}], [0.0, 0.0, -1.0]] }}\n"
        f"traction = {{ right = [{sxx}, {sxy}], left = [{-sxx}, {-sxy}] }}\n")
    case = loads_case(text)
    sol = coulomb.solve(static_problem(case))
    x = prepare(case).mesh.points
    exact = np.column_stack([a0 + kappa * x[:, 1], -x[:, 1]])
    np.testing.assert_allclose(sol.u, exact, atol=1e-12 * np.abs(exact).max())
    assert set(sol.labels) == {"slip+"}
    np.testing.assert_allclose(sol.Y, friction * sol.X, rtol=1e-10)


MIXED = square_case(size=0.05) + """
[contact]
rules = [{ from = 0.0, to = 0.2, status = "stuck" },
         { from = 0.2, to = 0.45, status = "slip", gamma = -1 },
         { from = 0.5, to = 0.7, status = "free" }]
"""


def test_contact_rules_give_the_state_by_arc_length():
    case = loads_case(MIXED)
    prep = prepare(case)
    state = contact_state(case, prep.system)
    s = arc_length(prep.system, ["bottom"])
    np.testing.assert_allclose(s, prep.mesh.points[prep.system.nodes, 0])
    x = np.round(s, 9)  # later rules win where intervals share a node (s = 0.2)
    expect = np.select([(x >= 0.5) & (x <= 0.7), (x >= 0.2) & (x <= 0.45), x <= 0.2],
                       [FREE, SLIP, STUCK], SLIP)
    np.testing.assert_array_equal(state.status, expect)
    gamma = np.where((x >= 0.2) & (x <= 0.45), -1.0, 1.0)
    np.testing.assert_array_equal(state.gamma[expect == SLIP], gamma[expect == SLIP])
    with pytest.raises(CaseError, match="no contact node is slipping") as err:
        contact_state(loads_case(square_case(size=0.25) + "[contact]\ndefault = 'stuck'"),
                             prepare(loads_case(square_case(size=0.25))).system)
    assert err.value.key == "contact.rules"


def test_mixed_state_dense_and_arpack_agree_and_count_is_p0():
    """Stuck, free and slipping nodes with both slip signs: Proposition 3.1 on the dense path,
    and the same critical coefficients from ARPACK (through `critfric solve`'s pipeline)."""
    case = loads_case(MIXED)
    prep = prepare(case)
    state = contact_state(case, prep.system)
    assert {FREE, STUCK, SLIP} <= set(state.status.tolist())
    assert set(state.gamma[state.status == SLIP].tolist()) == {-1.0, 1.0}
    K = prep.system.stiffness(*lame(1.0, 0.3))
    dense = eigen.solve(K, prep.system, state, method="dense", count=2)
    arpack = eigen.solve(K, prep.system, state, method="arpack", count=2)
    assert len(dense.alpha) + dense.n_infinite == state.n_slip
    assert len(dense.positive) >= 2
    np.testing.assert_allclose(arpack.positive[:2], dense.positive[:2], rtol=1e-9)
    np.testing.assert_allclose(arpack.negative[:2], dense.negative[:2], rtol=1e-9)
    for method in ("dense", "arpack"):
        r = critfric.solve_case(case, overrides={"solve.method": method})
        np.testing.assert_allclose(r.positive[0], dense.positive[0], rtol=1e-9)
    plain = critfric.solve_case(loads_case(square_case(size=0.05)))
    assert abs(plain.positive[0] - dense.positive[0]) > 1e-3  # the state matters


@pytest.mark.parametrize("E", [1.0, 210e9])
def test_state_from_the_coulomb_solution(E):
    """[contact] source = 'coulomb': the eigenproblem of the state of the static solution
    (solve_case's stiffness, assembled at the case's nu alone, serves the static problem at
    the case's E)."""
    text = square_case(size=0.05) + """
[load]
friction = 1.0
displacement = { top = [[-0.002, 0.0, 0.0], [-0.03, 0.045, 0.0]] }
[contact]
source = "coulomb"
"""
    case = loads_case(text).with_overrides({"material.E": E})
    prep = prepare(case)
    sol = coulomb.solve(static_problem(case, prep))
    state = contact_state(case, prep.system)
    np.testing.assert_array_equal(state.status, sol.state.status)
    r = critfric.solve_case(case, overrides={"solve.method": "dense"})
    K = prep.system.stiffness(*lame(1.0, 0.3))
    ref = eigen.solve(K, prep.system, sol.state, method="dense")
    np.testing.assert_allclose(r.alpha, ref.alpha, rtol=1e-12)
    assert len(ref.alpha) + ref.n_infinite == sol.state.n_slip
