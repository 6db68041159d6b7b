"""critfric path: solution curves along the friction or the load, checked against the exact
enumeration, the Newton solver, the eigen stage and the closed forms of section 4.1."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from helpers import CASES, one_triangle_alpha

import critfric
from critfric.case.schema import from_dict, loads_case
from critfric.errors import CaseError, SolverError
from critfric.fem.assembly import lame
from critfric.multiplicity import arcs
from critfric.multiplicity import path as path_module
from critfric.multiplicity.enumeration import Enumerator
from critfric.multiplicity.path import follow, path_case
from critfric.multiplicity.states import Condensed
from critfric.multiplicity.verify import construction
from critfric.solve import prepare, solve_case
from critfric.solvers import coulomb
from critfric.solvers.coulomb import violations
from critfric.solvers.from_case import case_problem


def grid_case(*, nx, ny, height, skew, seed, parameter, span, friction=None):
    """A sheared grid of P1 triangles on y = 0 (nx + 1 contact nodes), clamped on top, with
    random tractions on its sides and a random displacement of its top (L0), and for a load
    path a second random displacement and traction (L1)."""
    rng = np.random.default_rng(seed)
    xs, ys = np.linspace(0, 1, nx + 1), np.linspace(0, height, ny + 1)
    nodes = [[float(x - skew * y), float(y)] for y in ys for x in xs]
    at = lambda i, j: j * (nx + 1) + i
    tris = [t for j in range(ny) for i in range(nx) for t in
            ([at(i, j), at(i + 1, j), at(i + 1, j + 1)], [at(i, j), at(i + 1, j + 1), at(i, j + 1)])]
    edges = {"bottom": [[at(i, 0), at(i + 1, 0)] for i in range(nx)],
             "top": [[at(i + 1, ny), at(i, ny)] for i in range(nx)],
             "left": [[at(0, j + 1), at(0, j)] for j in range(ny)],
             "right": [[at(nx, j), at(nx, j + 1)] for j in range(ny)]}
    normal = lambda s: float(rng.normal(0, s))
    load = {"displacement": {"top": [normal(0.01), -abs(normal(0.01))]},
            "traction": {"left": [normal(0.02), normal(0.02)],
                         "right": [normal(0.02), normal(0.02)]}}
    path = {"parameter": parameter, "range": list(span), "samples": 41}
    if parameter == "load":
        load["friction"] = friction
        path["load"] = {"displacement": {"top": [normal(0.02), normal(0.005)]},
                        "traction": {"left": [normal(0.02), 0.0]}}
    return from_dict({
        "geometry": {"shape": "mesh", "nodes": nodes, "triangles": tris, "edges": edges},
        "material": {"nu": float(rng.uniform(0.05, 0.45))}, "mesh": {"element": "P1"},
        "load": load, "path": path}, name=f"grid{seed}")


# (seed, nx, ny, height, skew, parameter, range, friction): folds, isolas, pairs born at folds
SMALL = [
    (1, 4, 2, 0.54, -1.87, "friction", (0.0, 4.0), None),
    (16, 3, 1, 1.61, -0.88, "friction", (0.0, 4.0), None),
    (338, 3, 1, 2.52, -2.05, "load", (0.0, 3.0), 1.96),
    (7, 4, 1, 1.0, -2.3, "load", (0.0, 3.0), 2.34),
    (3, 3, 2, 1.0, 0.0, "load", (0.0, 2.0), 0.5),
]


def enumerated(case, result):
    """Every solution at each sample value (scaled), by the exact enumeration."""
    prep = prepare(case)
    problem = case_problem(case, prep.system, friction=0.0)
    cond, u0 = coulomb.condense(problem)
    u0b = None
    if result.parameter == "load":
        second = case_problem(case, prep.system, load=case.path["load"])
        u0b = cond.solve(second.rhs)[cond.cdofs]
    cz = Condensed.of(problem, (cond, u0), extra=() if u0b is None else (u0b,))
    enum = Enumerator(None, cz)
    for t in result.samples:
        u0t = cz.u0 if u0b is None else cz.u0 + t * u0b
        enum.cz = dataclasses.replace(cz, u0=u0t)
        found = enum(t if result.parameter == "friction" else result.friction)
        zs = [np.concatenate([s.X, s.Y]) for s in found.solutions]
        zs += [np.concatenate([e.X, e.Y]) for b in found.branches for e in b.ends or [] if e]
        f = t if result.parameter == "friction" else result.friction
        exact = [z for z in zs if cz.consistent(z, f, u0t).any(axis=1).all()]
        yield t, cz, [cz.norm(z, u0t) for z in exact], found


def scaled(cz, pt):
    return np.concatenate([pt.X / cz.F, pt.Y / cz.F, pt.Un / cz.D, pt.Ut / cz.D])


@pytest.mark.parametrize("spec", SMALL, ids=[f"{s[5]}-{s[0]}-{s[1]}" for s in SMALL])
def test_small_paths_hold_every_solution_and_only_solutions(spec):
    seed, nx, ny, height, skew, parameter, span, friction = spec
    case = grid_case(nx=nx, ny=ny, height=height, skew=skew, seed=seed, parameter=parameter,
                     span=span, friction=friction)
    result = path_case(case)
    assert not result.isolated
    for t, cz, solutions, found in enumerated(case, result):
        f = t if parameter == "friction" else friction
        points = [pt for c in result.curves for pt in c.points if abs(pt.value - t) <= 1e-12]
        for pt in points:  # each point solves (2.9)-(2.11) to round-off
            bad = violations(pt.Un, pt.Ut, pt.X, pt.Y, cz.Ur, f, force_scale=cz.F,
                             disp_scale=cz.D)
            assert max(bad.values()) <= 1e-10, (t, bad)
        keys = [scaled(cz, pt) for pt in points]
        for s in solutions:  # every solution is on a curve
            assert any(np.abs(s - k).max() <= 1e-7 for k in keys), (t, s)
        if not found.branches:  # and every point is a solution
            for k in keys:
                assert any(np.abs(s - k).max() <= 1e-7 for s in solutions), (t, k)
    counts = lambda t: next(enumerated_at(case, result, t))
    for e in result.events:  # a fold is where the number of solutions changes
        if e.kind == "fold":
            step = 1e-6 * (span[1] - span[0])
            assert counts(e.value - step) != counts(e.value + step), e


def enumerated_at(case, result, t):
    one = dataclasses.replace(result, samples=np.array([t]))
    for _, _, solutions, _ in enumerated(case, one):
        yield len(solutions)


def test_small_paths_find_folds_isolas_and_pairs_born_away_from_the_start():
    """The cases above are chosen for what they hold: every kind of curve is exercised."""
    kinds = {}
    for seed, nx, ny, height, skew, parameter, span, friction in SMALL[:4]:
        r = path_case(grid_case(nx=nx, ny=ny, height=height, skew=skew, seed=seed,
                                parameter=parameter, span=span, friction=friction))
        kinds[(parameter, seed)] = r
    born = kinds[("friction", 16)]  # a pair of solutions born at a fold, away from the start
    (fold,) = born.events
    assert fold.kind == "fold" and fold.curves == [1]
    step = (4.0 - 0.0) / 40  # the first sample value past the fold seeds the pair
    assert born.curves[1].seed == {"value": pytest.approx(step * np.ceil(fold.value / step))}
    assert kinds[("load", 7)].counts()["folds"] >= 10
    folded = kinds[("load", 338)]
    loops = [c for c in folded.curves if isinstance(c.seed, dict) and "event" not in c.seed
             and len(c.pieces) > 1]
    assert loops, "a curve seeded away from the start (an isola or a pair born at a fold)"
    closed = [c for c in loops if np.isclose(c.points[0].value, c.points[-1].value)
              and np.allclose(c.points[0].Ut, c.points[-1].Ut)]
    assert closed, "an isola: a closed curve"


def test_one_triangle_fig_2_branch_at_3_minus_4_nu():
    """Section 4.1: the slip solution for every friction, the stuck one from 3 - 4 nu on,
    and the continuum between them at 3 - 4 nu: one branch point joining the curves."""
    case = critfric.load_case(CASES / "one_triangle.toml",
                              overrides={"path.range": [0.0, 3.0], "path.samples": 31})
    r = path_case(case)
    crit = one_triangle_alpha(0.3)
    lam, G = lame(1.0, 0.3)
    slip = 2 * 0.5 / (lam + G)
    (branch,) = [e for e in r.events if e.kind == "branch"]
    assert branch.critical == pytest.approx(crit, abs=1e-12)
    assert branch.value == pytest.approx(crit, abs=1e-12)
    assert branch.critical == pytest.approx(solve_case(case).critical, abs=1e-10)
    assert not branch.unbounded and len(branch.curves) == 2
    assert r.curves[0].seed == "start"
    for pt in (p for c in r.curves for p in c.points):
        assert pt.Ut[0] == pytest.approx(slip, abs=1e-12) or abs(pt.Ut[0]) < 1e-12
        if abs(pt.Ut[0]) < 1e-12:  # the stuck solution: only from 3 - 4 nu on
            assert pt.value >= crit - 1e-12 and pt.X[0] == pytest.approx(-0.5)
    # the slip solution runs over the whole range, the stuck one from the branch point
    values = lambda c, stuck: [p.value for p in c.points if (abs(p.Ut[0]) < 1e-12) == stuck]
    assert min(v for c in r.curves for v in values(c, False)) == 0.0
    assert max(v for c in r.curves for v in values(c, False)) == 3.0
    assert min(v for c in r.curves for v in values(c, True)) == pytest.approx(crit)
    # the slip solution has X = Y = 0, a free node's solution too: no fold where a curve
    # meets the end of the range, no piece walking the slip solution back as "free"
    assert [e.kind for e in r.events] == ["branch"]
    assert all(p.state != ["free"] for c in r.curves for p in c.pieces)
    assert sum(len(c.pieces) for c in r.curves) == 4  # slip, continuum, stuck; slip beyond
    data = r.to_json()
    assert data["parameter"] == "friction" and data["range"] == [0.0, 3.0]
    assert set(data["curves"][0]["points"][0]) == {"value", "status", "Un", "Ut", "X", "Y"}


def test_branch_point_of_section_5_is_the_critical_coefficient_of_its_state():
    """The loading of section 5 at friction alpha, fixed, followed along the friction: the
    curve meets the all-slipping continuum exactly at alpha, as `solve` computes it."""
    case = loads_case('[geometry]\nshape = "square"\n[mesh]\nelement = "P2"\nsize = 0.3\n')
    alpha = solve_case(case).critical
    system = prepare(case).system
    problem = construction(system, 1.0, 0.3, alpha, ["bottom"], ["top"]).problem
    r = follow(problem, "friction", (0.5 * alpha, 1.5 * alpha), samples=21, start="newton")
    (branch,) = [e for e in r.events if e.kind == "branch"]
    assert branch.critical == pytest.approx(alpha, abs=1e-10)
    assert branch.value == pytest.approx(alpha, abs=1e-10)
    assert branch.nodes == list(range(system.n_contact))  # every node slipping there
    continuum = [pc for c in r.curves for pc in c.pieces if pc.start == pc.end]
    assert continuum and all(s == "slip+" for s in continuum[0].state)
    # margins: each piece's lowest positive critical coefficient is that of its own state
    for pc in r.curves[0].pieces:
        if pc.state == continuum[0].state:
            assert pc.critical[0] == pytest.approx(alpha, abs=1e-10)


def test_below_every_critical_coefficient_one_curve_equal_to_newton():
    case = grid_case(nx=3, ny=2, height=1.0, skew=0.3, seed=4, parameter="friction",
                     span=(0.0, 0.9))
    r = path_case(case)
    assert len(r.curves) == 1 and r.counts()["folds"] == r.counts()["branches"] == 0
    assert all(pc.margin is None or pc.margin > 1 for pc in r.curves[0].pieces)
    problem = case_problem(case, prepare(case).system, friction=0.0)
    kinks = [e for e in r.events if e.kind == "kink"]
    assert kinks
    for e in kinks:
        newton = coulomb.solve(problem, e.value)
        (pt,) = [p for p in r.curves[0].points if p.value == e.value][:1]
        scale = np.abs(newton.X).max()
        assert np.abs(pt.X - newton.X).max() <= 1e-8 * scale
        assert np.abs(pt.Y - newton.Y).max() <= 1e-8 * scale


def test_a_positively_homogeneous_load_path_is_a_ray():
    """L0 = 0 and no reference displacement: z(t) = t z(1), one piece from the origin."""
    text = ('[geometry]\nshape = "square"\n[mesh]\nelement = "P1"\nsize = 0.25\n'
            '[load]\nfriction = 0.4\n'
            '[path]\nparameter = "load"\nrange = [0.0, 2.0]\n'
            'load = { displacement = { top = [0.02, -0.01] } }\n')
    r = path_case(loads_case(text))
    assert len(r.curves) == 1 and len(r.curves[0].pieces) == 1 and not r.events
    pts = r.curves[0].points
    last = pts[-1]
    for pt in pts[1:]:
        assert np.allclose(pt.X, pt.value / last.value * last.X, atol=1e-12 * np.abs(last.X).max())


@pytest.mark.parametrize("exact", [0, 1000], ids=["grid everywhere", "pencils everywhere"])
def test_pencil_and_grid_roots_agree(exact, monkeypatch):
    """The exact roots (pencils) and the bracketing grid of large states give one path: on a
    small sheared grid, and along the friction on the unit square (41 contact nodes, up to 40
    slipping: the grid by default), to 1e-13."""
    small = grid_case(nx=4, ny=2, height=0.54, skew=-1.87, seed=1, parameter="friction",
                      span=(0.0, 4.0))
    square = critfric.load_case("unit-square", overrides={
        "path.parameter": "friction", "path.range": [0.0, 0.12], "path.samples": 5,
        "path.start": "newton"})
    default = [path_case(small), path_case(square)]
    monkeypatch.setattr(arcs, "EXACT_SLIP", exact)
    for a, b in zip(default, [path_case(small), path_case(square)]):
        assert [e.kind for e in a.events] == [e.kind for e in b.events]
        assert np.allclose([e.value for e in a.events], [e.value for e in b.events], rtol=0,
                           atol=1e-13)
        assert a.counts() == b.counts()


@pytest.mark.parametrize("name, parameter, span", [
    ("unit-square", "friction", (0.0, 3.0)), ("unit-square", "load", (0.0, 1.0)),
    ("inclined-body", "friction", (0.0, 2.0))])
def test_paths_of_gmsh_bodies_are_exact_solutions(name, parameter, span):
    """41 and 57 contact nodes: every point solves (2.9)-(2.11) to 1e-10, and its residual
    on the Newton solver's complementarity functions is at most 1e-10."""
    over = {"path.parameter": parameter, "path.range": list(span), "path.samples": 11,
            "path.start": "newton"}
    if name == "inclined-body":  # pressed and sheared towards the lean
        over.update({"load.displacement": {"top": [-0.01, -0.01]}})
    case = critfric.load_case(name, overrides=over)
    r = path_case(case)
    assert r.counts()["pieces"] >= 10 and not any("incomplete" in n for n in r.notes)
    cz = Condensed.of(case_problem(case, prepare(case).system, friction=0.0))
    for c in r.curves:
        for pt in c.points:
            f = pt.value if parameter == "friction" else r.friction
            bad = violations(pt.Un, pt.Ut, pt.X, pt.Y, cz.Ur, f, force_scale=cz.F,
                             disp_scale=cz.D)
            assert max(bad.values()) <= 1e-10, (pt.value, bad)


def test_path_refuses_what_it_cannot_do(monkeypatch):
    case = critfric.load_case(CASES / "one_triangle.toml", overrides={"path.range": [0, 3]})
    monkeypatch.setattr(path_module, "MAX_SECONDS", 0)  # as if the mesh were too fine
    with pytest.raises(CaseError, match="minutes") as err:
        path_case(case)
    assert err.value.key == "mesh.size"
    monkeypatch.undo()
    with pytest.raises(CaseError, match="1e\\+06") as err:  # beyond 1e6: infinite
        path_case(case.with_overrides({"path.range": [0.0, 1e7]}))
    assert err.value.key == "path.range"
    eight = grid_case(nx=7, ny=1, height=1.0, skew=0.0, seed=0, parameter="friction",
                      span=(0.0, 1.0))  # 8 contact nodes: 4^8 states at each sample
    with pytest.raises(CaseError, match="at most 457 samples") as err:
        path_case(eight.with_overrides({"path.samples": 1000}))
    assert err.value.key == "path.samples"
    with pytest.raises(CaseError, match="path.node|contact node"):
        path_case(case.with_overrides({"path.node": 3}))
    text = (CASES / "one_triangle.toml").read_text().split("\n[path]")[0]
    with pytest.raises(CaseError) as err:
        path_case(loads_case(text))
    assert err.value.key == "path.range"
    with pytest.raises(SolverError, match="max_pieces"):
        path_case(grid_case(nx=3, ny=2, height=1.0, skew=0.0, seed=3, parameter="load",
                            span=(0.0, 2.0), friction=0.5).with_overrides(
            {"path.max_pieces": 1}))


def test_without_a_load_the_zero_solution_has_no_events():
    """Four triangles, no load: at 1.3111, 1.8359 and 2.4222 a state is singular, but its
    null vectors break X <= 0 or Y w <= 0 both ways (no continuum: `solutions` finds U = 0
    alone there), and the zero solution holds every status at once (no kink)."""
    case = critfric.load_case("four-triangles")
    r = path_case(case.with_overrides({"path.range": [1.0, 3.0]}))
    assert r.events == [] and len(r.curves) == 1
    enum = Enumerator(case_problem(case, prepare(case).system, friction=0.0))
    for f in (1.3111111111111113, 1.8358568490953673, 2.4222222222222223):
        e = enum(f)
        assert e.count == 1 and not e.branch
        assert np.abs(e.solutions[0].Ut).max() == 0.0 and np.abs(e.solutions[0].X).max() == 0.0
