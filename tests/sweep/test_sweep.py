"""Sweeps: the grid, the closed form over nu, the resumable file, workers, h -> 0 limits."""

from __future__ import annotations

import math
import multiprocessing
import os
import signal
import subprocess
import sys
import time

import h5py
import numpy as np
import pytest
from helpers import CASES, REPO, four_triangles_alpha, resume_exactly_once, square_case

import critfric
from critfric.errors import CaseError
from critfric.files.sweepfile import read_sweep
from critfric.sweep.extrapolate import family_limit, limits_of, observed_order
from critfric.sweep.grid import Point, parse_nu
from critfric.sweep.runner import make_grid, run_sweep
from critfric.sweep.workers import THREAD_VARS, make_chunks, run_local


# ------------------------------------------------------------------------------ the grid
def test_nu_range_reaching_one_half_stops_short_of_it():
    values, notes = parse_nu("0:0.5")
    assert len(values) == 11 and values[0] == 0.0 and values[5] == 0.25
    assert 0.499 <= values[-1] < 0.5 and "0.5" in notes[0]
    values, notes = parse_nu("0.49:0.5:21")  # a fine step: the gap shrinks with it
    assert np.all(np.diff(values) > 0) and values[-1] < 0.5
    assert parse_nu("0.1:0.3:3") == ([0.1, 0.2, 0.3], [])
    assert parse_nu("0.3, 0.1,0.3") == ([0.1, 0.3], [])


@pytest.mark.parametrize("text", ["0.5", "0.6", "-0.1", "0:0.6", "0.3:0.1", "0:0.5:1",
                                  "a:b", "0:0.4:x", "", "nan", "0.1:0.2:3:4"])
def test_bad_nu_is_a_case_error(text):
    with pytest.raises(CaseError) as err:
        parse_nu(text)
    assert "--nu" in str(err.value)


def test_grid_is_validated_against_the_case():
    four = critfric.load_case(CASES / "four_triangles.toml")
    with pytest.raises(CaseError, match="mesh.size"):
        make_grid(four, nu="0.1,0.2", size="0.5")
    with pytest.raises(CaseError, match="mesh.element"):
        make_grid(four, element="Q1")
    with pytest.raises(CaseError, match="--size"):
        make_grid(critfric.loads_case(square_case()), size="0.1,-2")
    grid = make_grid(critfric.loads_case(square_case(size=0.5)), size="0.1,0.2,0.1",
                     element="P2,P1")
    assert grid.size == [0.2, 0.1] and grid.element == ["P2", "P1"] and grid.nu == [0.3]


# ------------------------------------------------------------------------------ closed form
def test_four_triangles_sweep_is_the_closed_form_at_every_nu(tmp_path):
    case = critfric.load_case(CASES / "four_triangles.toml")
    grid = make_grid(case, nu="0:0.5:11")
    sweep = run_sweep(case, grid, output=tmp_path / "four.h5", jobs=1)
    assert [r["nu"] for r in sweep.rows] == grid.nu and sweep.computed == 11
    first, rest = sweep.rows[0], sweep.rows[1:]
    assert first["nu"] == 0.0 and first["status"] == "no-real-eigenvalue"
    assert first["positive"] == [] and first["negative"] == []
    for r in rest:
        expected = four_triangles_alpha(r["nu"])
        assert r["status"] == "ok"
        np.testing.assert_allclose(r["positive"], [expected], rtol=1e-10)
        np.testing.assert_allclose(r["negative"], [-expected], rtol=1e-10)
    with h5py.File(tmp_path / "four.h5") as f:  # NaN-padded in the file
        assert np.isnan(f["points/positive"][0, 0])
        assert f["points/status"][0] == b"no-real-eigenvalue"
    assert sweep.limits == []  # one (inline) mesh: no h -> 0 limit
    assert sweep.summary()["points"][0]["positive"] == []


# ------------------------------------------------------------------------------ the file
def _interrupt_after(n):
    def on_point(row, done, total):
        if row is not None and done - on_point.start >= n:
            raise KeyboardInterrupt
        if row is None:
            on_point.start = done
    return on_point


@pytest.mark.once
@pytest.mark.parametrize("jobs", [1, 2])
def test_ctrl_c_keeps_every_finished_point_and_a_rerun_computes_only_the_rest(tmp_path, jobs):
    case = critfric.load_case(CASES / "four_triangles.toml")
    grid = make_grid(case, nu="0.05:0.45:9")
    out = tmp_path / "s.h5"
    with pytest.raises(KeyboardInterrupt):
        run_sweep(case, grid, output=out, jobs=jobs, on_point=_interrupt_after(4))
    assert multiprocessing.active_children() == []  # the workers were stopped
    assert len({r["nu"] for r in read_sweep(out)["rows"]}) == 4
    again = run_sweep(case, grid, output=out, jobs=1)
    assert again.computed == 5
    rows = read_sweep(out)["rows"]
    assert sorted(r["nu"] for r in rows) == grid.nu  # each point exactly once
    whole = run_sweep(case, grid, output=tmp_path / "whole.h5", jobs=1)
    assert [r["positive"] for r in again.rows] == [r["positive"] for r in whole.rows]
    assert run_sweep(case, grid, output=out, jobs=1).computed == 0


def test_a_changed_case_or_grid_is_refused_unless_forced(tmp_path):
    case = critfric.load_case(CASES / "four_triangles.toml")
    out = tmp_path / "s.h5"
    run_sweep(case, make_grid(case, nu="0.1,0.2"), output=out, jobs=1)
    with pytest.raises(CaseError, match="--force"):
        run_sweep(case, make_grid(case, nu="0.1,0.3"), output=out, jobs=1)
    other = case.with_overrides({"solve.count": 2})
    with pytest.raises(CaseError, match="another case or grid"):
        run_sweep(other, make_grid(other, nu="0.1,0.2"), output=out, jobs=1)
    forced = run_sweep(case, make_grid(case, nu="0.1,0.3"), output=out, jobs=1, force=True)
    assert forced.computed == 2 and [r["nu"] for r in read_sweep(out)["rows"]] == [0.1, 0.3]
    solve_file = tmp_path / "r.h5"
    critfric.write_result(critfric.solve_case(case), solve_file)
    with pytest.raises(CaseError, match="not a sweep file"):
        run_sweep(case, make_grid(case), output=solve_file, jobs=1)


SWEEP_ARGS = ["sweep", "unit-square", "--nu", "0.02:0.47:16", "--size", "0.025",
              "--element", "P1", "--jobs", "2", "--json"]


def _rows_or_none(path):
    try:
        return read_sweep(path)["rows"]
    except (CaseError, OSError):
        return None


@pytest.mark.once
def test_sigkill_half_way_then_rerun_gives_every_point_once(tmp_path):
    out = tmp_path / "killed.h5"
    env = dict(os.environ, PYTHONPATH=str(REPO) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    proc = subprocess.Popen([sys.executable, "-m", "critfric", *SWEEP_ARGS, "-o", str(out)],
                            env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    deadline = time.monotonic() + 60
    rows = None
    while time.monotonic() < deadline and proc.poll() is None:
        rows = _rows_or_none(out) if out.exists() else None
        if rows is not None and len(rows) >= 2:
            break
        time.sleep(0.02)
    assert proc.poll() is None, "the sweep ended before it could be killed: " + \
        proc.stderr.read().decode()
    proc.send_signal(signal.SIGKILL)
    proc.wait(10)
    proc.stderr.close()
    kept = read_sweep(out)["rows"]
    assert 2 <= len(kept) < 16
    case, grid, resumed, _ = resume_exactly_once(out, "0.02:0.47:16", 16, len(kept))
    whole = run_sweep(case, grid, output=tmp_path / "whole.h5", jobs=1)
    for a, b in zip(resumed.rows, whole.rows):
        assert a["status"] == b["status"] == "ok" and a["n_dofs"] == b["n_dofs"]
        np.testing.assert_allclose(a["positive"], b["positive"], rtol=1e-10)
        np.testing.assert_allclose(a["negative"], b["negative"], rtol=1e-10)


# ------------------------------------------------------------------------------ workers
def test_chunks_keep_groups_together_and_split_only_to_balance():
    pts = [Point(nu, s, el) for el in ("P1", "P2") for s in (0.2, 0.1) for nu in (0.1, 0.2, 0.3)]
    for jobs in (1, 2, 3, 4, 8):
        chunks = make_chunks(pts, jobs)
        flat = [p for c in chunks for p in c]
        assert sorted(flat, key=lambda p: p.key) == sorted(pts, key=lambda p: p.key)
        assert all(len({p.group for p in c}) == 1 for c in chunks)
    # equal-cost groups, jobs <= groups: one chunk per group (each mesh built once)
    same = [Point(nu, 0.1, el) for el in ("P1", "Q1") for nu in (0.1, 0.2, 0.3)]
    assert sorted(len(c) for c in make_chunks(same, 2)) == [3, 3]
    # one group and two jobs: split in two
    assert [len(c) for c in make_chunks(pts[:3], 2)] == [2, 1]


def _probe(spec, point):
    """A worker task for the tests: the worker's thread variables, or a hard crash."""
    if point.nu == spec["crash_at"]:
        os._exit(3)
    return {"nu": point.nu, "env": {k: os.environ.get(k) for k in THREAD_VARS},
            "pid": os.getpid()}


@pytest.mark.once
def test_workers_pin_threads_and_survive_a_crashed_worker():
    before = {k: os.environ.get(k) for k in THREAD_VARS}
    points = [Point(nu, 0.1, "P1") for nu in (0.1, 0.2, 0.3, 0.4)]
    got = dict(run_local(2, _probe, {"crash_at": 0.2}, points))
    assert set(got) == set(points)
    crashed = got.pop(points[1])
    assert crashed["status"] == "failed: the worker process died (exit code 3)"
    for row in got.values():
        assert all(v == "1" for v in row["env"].values()), row
    assert {k: os.environ.get(k) for k in THREAD_VARS} == before


def test_worker_processes_give_the_in_process_values(tmp_path):
    case = critfric.loads_case(square_case(size=0.2))
    grid = make_grid(case, nu="0.1,0.3,0.45", size="0.2,0.1", element="P1,Q2")
    local = run_sweep(case, grid, output=tmp_path / "a.h5", jobs=1)
    pooled = run_sweep(case, grid, output=tmp_path / "b.h5", jobs=2)
    assert len(pooled.rows) == 12
    for a, b in zip(local.rows, pooled.rows):
        assert (a["nu"], a["size"], a["element"]) == (b["nu"], b["size"], b["element"])
        np.testing.assert_allclose(a["positive"], b["positive"], rtol=1e-10)
        np.testing.assert_allclose(a["negative"], b["negative"], rtol=1e-10)


# ------------------------------------------------------------------------------ limits
@pytest.mark.parametrize("h", [[0.4, 0.2, 0.1, 0.05], [0.3, 0.2, 0.13, 0.07]])
def test_richardson_recovers_limit_and_order_of_a_power_law(h):
    f = [2.0 + 0.3 * x**1.5 - 0.01 * x**4 for x in h]
    limit, order, error, status = family_limit(h, f)
    assert status == "ok"
    assert abs(order - 1.5) < 0.02 and abs(limit - 2.0) < 1e-4
    # honest, and not much above the correction
    assert abs(limit - 2.0) <= error <= 1.5 * abs(f[-1] - limit)
    exact = [2.0 + 0.3 * x**1.5 for x in h[:3]]
    assert observed_order(h[:3], exact) == pytest.approx(1.5, rel=1e-9)


@pytest.mark.parametrize("f,why", [
    ([1.0, 1.1, 1.05, 1.08], "change by"),  # oscillating by 3-5%
    ([1.0, 1.1, 1.2, 1.3], "order below 0.5"),  # drifting
    ([1.0, 1.1, 1.1 + 0.1 / 1.2, 1.1 + 0.1 / 1.2 + 0.1 / 1.44], "change by"),  # order 0.26
    ([1.0, math.nan, math.nan, 1.011], "only 2"),
    ([5.0, 3.0, 2.0, 1.8], "change by"),  # 10% at the finest sizes
])
def test_not_converged_families_get_no_limit(f, why):
    limit, order, error, status = family_limit([0.1, 0.05, 0.025, 0.0125], f)
    assert math.isnan(limit) and status.startswith("not converged") and why in status, status


def test_noisy_families_that_converge_keep_a_limit_with_an_honest_error():
    """Mesh noise on a converging family (P1 on graded unit squares, measured: the finest
    values 1.944490, 1.944775, 1.944739 for a limit 1.9447114) is not a reason to refuse."""
    h = [0.1, 0.05, 0.025, 0.0125]
    limit, order, error, status = family_limit(h, [1.945276, 1.944490, 1.944775, 1.944739],
                                               "P1")
    assert status == "ok" and abs(limit - 1.9447114) <= error < 2e-3
    # measured P1 negative family of a slip | free | slip base (graded 0.05): a step back,
    # then steps forward; P2 and Q2 converge to 1.81295 (order ~1)
    limit, order, error, status = family_limit(h, [1.812848, 1.812808, 1.812836, 1.812880],
                                               "P1")
    assert status == "ok" and math.isnan(order) and abs(limit - 1.81295) <= error < 3e-4
    # measured inclined-body P2 values (graded 0.1): the old estimate missed the reference
    f = [0.585033730, 0.585022737, 0.585019227, 0.585018007]
    limit, order, error, status = family_limit(h, f, "P2")
    assert status == "ok" and abs(limit - 0.5850169) <= error < 2e-6 and 1.2 < order < 2


def test_orders_above_what_the_element_reaches_widen_the_error():
    h = [0.1, 0.05, 0.025, 0.0125]
    f = [2.0 + 0.1 * x**6 for x in h]  # "order 6" for P1: capped at 3
    _, order, error, status = family_limit(h, f, "P1")
    assert status == "ok" and order == pytest.approx(3.0) and error >= 3 * np.ptp(f[-3:])


def _rows(element, values, nu=0.3):
    h = [0.1, 0.05, 0.025, 0.0125]
    return [{"nu": nu, "size": s, "element": element, "status": "ok", "positive": [v],
             "negative": []} for s, v in zip(h, values)]


def test_elements_that_disagree_are_not_converged():
    h = np.array([0.1, 0.05, 0.025, 0.0125])
    p1 = _rows("P1", 1.9 + 0.1 * h**1.3)
    p2 = _rows("P2", 1.9 + 0.02 * h**1.3)
    agree = [lim for lim in limits_of(p1 + p2) if lim.family == "positive"]
    assert [lim.status for lim in agree] == ["ok", "ok"]
    assert all(abs(lim.limit - 1.9) < 1e-9 for lim in agree)
    off = _rows("P2", 1.91 + 0.02 * h**1.3)
    apart = [lim for lim in limits_of(p1 + off) if lim.family == "positive"]
    assert all("elements disagree" in lim.status and math.isnan(lim.limit) for lim in apart)
    negative = [lim for lim in limits_of(p1) if lim.family == "negative"]
    assert negative[0].status.startswith("not converged")


def test_unit_square_limits_of_p1_and_p2_match_a_much_finer_solve(tmp_path):
    """Done-when check at CI sizes: nu = 0.3, four sizes of P1 and three of P2 (at 0.2, P2 is
    not yet asymptotic on the default grading) on the sweeps' default graded meshes; the
    reference 1.94471145 is from radially graded P2 and Q2 (make validate)."""
    case = critfric.load_case("unit-square")
    limits = {}
    for element, sizes in (("P1", "0.1,0.05,0.025,0.0125"), ("P2", "0.1,0.05,0.025")):
        grid = make_grid(case, nu="0.3", size=sizes, element=element)
        sweep = run_sweep(case, grid, output=tmp_path / f"{element}.h5", jobs=1)
        for lim in sweep.limits:
            assert lim.status == "ok", lim
            assert abs(abs(lim.limit) - 1.94471145) <= lim.error, lim  # the error bar holds
        limits[element] = next(m for m in sweep.limits if m.family == "positive")
    assert 1.2 < limits["P2"].order < 1.7 and limits["P2"].error < 2e-5
    fine = critfric.solve_case(case, overrides={"mesh.element": "Q2", "mesh.size": 0.0125})
    assert abs(fine.critical - 1.94472) < 5e-5


def test_sweeps_that_extrapolate_grade_their_meshes_by_default(tmp_path):
    from critfric.sweep.runner import SWEEP_GRADING

    case = critfric.load_case("unit-square")
    grid = make_grid(case, nu="0.3", size="0.4,0.3,0.2", element="P1")
    assert any("graded" in n and "4 singular points" in n for n in grid.notes), grid.notes
    assert not any("graded" in n for n in make_grid(case, nu="0.3", size="0.4,0.2").notes)
    uniform = case.with_overrides({"mesh.grading": 1.0})
    assert not any("graded" in n for n in make_grid(uniform, nu="0.3", size="0.4,0.3,0.2").notes)
    sweep = run_sweep(case, grid, output=tmp_path / "g.h5", jobs=1)
    graded = critfric.solve_case(case, overrides={"mesh.size": 0.2, "mesh.grading": SWEEP_GRADING})
    assert sweep.rows[-1]["positive"][0] == pytest.approx(graded.critical, abs=1e-12)
    assert sweep.rows[-1]["n_dofs"] == graded.n_dofs


def test_a_family_one_element_finds_erratic_gets_no_limit_from_another():
    """Mixed-state base, positive family: nested Q1 meshes converge smoothly (8.58, 8.46,
    8.39, 8.34) where P2 jumps (17.0, 13.2, 11.6, 19.6): mesh-dependent, no limit."""
    q1 = _rows("Q1", [8.5824373828, 8.4576224507, 8.3868979629, 8.3422030520])
    p2 = _rows("P2", [17.0194824805, 13.1977468335, 11.6234375959, 19.6042972313])
    alone = [lim for lim in limits_of(q1) if lim.family == "positive"]
    assert alone[0].status == "ok"  # by itself the Q1 family looks converged
    both = [lim for lim in limits_of(q1 + p2) if lim.family == "positive"]
    assert all(lim.status.startswith("not converged") and math.isnan(lim.limit) for lim in both)
    q1_limit = next(lim for lim in both if lim.element == "Q1")
    assert "P2 swings by 41%" in q1_limit.status, q1_limit.status
    # a pre-asymptotic but steady element (changes of 1e-4) does not invalidate another
    p1 = _rows("P1", [8.345, 8.3434, 8.3428, 8.3426])
    steady = [lim for lim in limits_of(q1 + p1) if lim.family == "positive"]
    assert next(lim for lim in steady if lim.element == "Q1").status == "ok"


def test_eigenvalues_of_strong_grading_below_a_family_are_left_out():
    """Measured: unit square, Q2, nested meshes graded as h (1e-4 + (d/R)^(3/4)): from
    h = 0.025 on, eigenvalues of the slip | free corner (1.9315, 1.8908, falling towards
    1.5686 with each halving) come below the body's 1.9447114, which converges."""
    h = [0.1, 0.05, 0.025, 0.0125]
    values = [[1.94470978683, 2.02821373219, 2.14431075747],
              [1.94471132284, 2.01415587299, 2.01568514844],
              [1.93150035833, 1.94471143655, 2.0009256652],
              [1.89078430106, 1.94471144227, 1.95118084973]]
    rows = [{"nu": 0.3, "size": s, "element": "Q2", "status": "ok", "positive": v,
             "negative": []} for s, v in zip(h, values)]
    (lim,) = [lim for lim in limits_of(rows) if lim.family == "positive"]
    assert lim.status == "ok" and abs(lim.limit - 1.94471145) <= lim.error + 3e-8 < 1e-7
    assert "1.89078" in lim.note and "1.9315" in lim.note and "note" in lim.to_json()
    # the lowest values alone do not converge; with one value a size, nothing is followed
    lowest = [{**r, "positive": r["positive"][:1]} for r in rows]
    (alone,) = [lim for lim in limits_of(lowest) if lim.family == "positive"]
    assert alone.status.startswith("not converged") and alone.note == ""
