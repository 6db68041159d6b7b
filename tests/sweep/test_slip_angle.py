"""Sweeps over the slip angle of a 3D body: values equal to single solves, the mirror identity
alpha(angle + 180) = -alpha(angle), the body's coefficient (the minimum over directions)
located between samples, resuming, and the parsing of --slip-angle."""

from __future__ import annotations

import math

import numpy as np
import pytest
from helpers import box_case

import critfric
from critfric.errors import CaseError
from critfric.files.sweepfile import read_sweep
from critfric.solve import prepare, solve_prepared
from critfric.sweep.directions import bracket, circle_samples, locate
from critfric.sweep.grid import parse_slip_angles
from critfric.sweep.runner import make_grid, run_sweep

BOX = box_case(extra="[solve]\ncount = 2")


@pytest.fixture(scope="module")
def box():
    return critfric.loads_case(BOX)


def _solve(case, angle, **overrides):
    return critfric.solve_case(case, overrides={"solve.slip_angle": angle, **overrides})


# ------------------------------------------------------------------------------ parsing
def test_slip_angles_parse_like_nu_within_what_the_case_accepts():
    values, notes = parse_slip_angles("0:360:13")
    assert values == [30.0 * k for k in range(13)]
    assert "7 of the 13" in notes[0]  # 180 ... 360 repeat 0 ... 180 (reversed)
    assert parse_slip_angles("0:150:6") == ([0.0, 30.0, 60.0, 90.0, 120.0, 150.0], [])
    assert parse_slip_angles("45, -30,45") == ([-30.0, 45.0], [])
    assert len(parse_slip_angles("0:180")[0]) == 13


@pytest.mark.parametrize("text", ["0:800", "-721,0", "800", "90:0", "0:90:1", "a:b", "",
                                  "nan", "0:90:x", "0:90:3:4", "inf"])
def test_bad_slip_angles_are_case_errors_naming_the_option(text):
    with pytest.raises(CaseError) as err:
        parse_slip_angles(text)
    assert "--slip-angle" in str(err.value)


def test_the_grid_refuses_slip_angles_a_case_cannot_take(box):
    square = critfric.load_case("unit-square")
    with pytest.raises(CaseError, match="--slip-angle.*3D bodies"):
        make_grid(square, slip_angle="0:90:3")
    with pytest.raises(CaseError, match="--slip-angle.*quantity critical"):
        make_grid(box, slip_angle="0:90:3", quantity="flutter")
    ruled = box.with_overrides({"contact.rules": [
        {"from": [0.0, 0.0], "to": [0.5, 1.0], "status": "slip", "slip_angle": 30.0}]})
    with pytest.raises(CaseError, match="contact.rules"):
        make_grid(ruled, slip_angle="0:90:3")
    grid = make_grid(box, slip_angle="0,180")  # one direction and its reverse: no minimum
    assert grid.directions == 1 and any("no minimum" in n for n in grid.notes)
    grid = make_grid(box, nu="0.2,0.3", slip_angle="0:90:4")
    assert len(grid.points()) == 8 and grid.to_json()["slip_angle"] == [0.0, 30.0, 60.0, 90.0]
    assert "slip_angle" not in make_grid(box).to_json()  # 2D-style identity unchanged


# ------------------------------------------------------------------------------ values
def test_sweep_values_are_single_solves_and_obey_the_mirror_identity(box, tmp_path):
    grid = make_grid(box, slip_angle="-30:150:7")
    sweep = run_sweep(box, grid, output=tmp_path / "a.h5", jobs=1)
    assert [r["slip_angle"] for r in sweep.rows] == grid.slip_angle
    by_angle = {r["slip_angle"]: r for r in sweep.rows}
    for r in sweep.rows:
        alone = _solve(box, r["slip_angle"])
        assert r["status"] == "ok" and r["n_dofs"] == alone.n_dofs
        np.testing.assert_allclose(r["positive"], alone.positive[:2], rtol=1e-10, atol=0)
        np.testing.assert_allclose(r["negative"], alone.negative[:2], rtol=1e-10, atol=0)
        np.testing.assert_allclose(r["r_positive"], alone.r_of(alone.positive[:2]), atol=1e-10)
        reverse = _solve(box, r["slip_angle"] + 180.0)  # every eigenvalue flips sign
        assert reverse.positive[0] == pytest.approx(-r["negative"][0], rel=1e-10, abs=0)
        assert reverse.negative[0] == pytest.approx(-r["positive"][0], rel=1e-10, abs=0)
    assert by_angle[150.0]["positive"][0] == pytest.approx(-by_angle[-30.0]["negative"][0],
                                                           rel=1e-10, abs=0)
    stored = read_sweep(tmp_path / "a.h5")
    assert [r["slip_angle"] for r in stored["rows"]] == grid.slip_angle
    assert len(stored["minima"]) == len(sweep.minima) == 1


def test_the_minimum_over_directions_is_located_exactly_between_samples(box, tmp_path):
    grid = make_grid(box, slip_angle="0:150:6")
    sweep = run_sweep(box, grid, output=tmp_path / "m.h5", jobs=1)
    (m,) = sweep.minima
    assert m["status"] == "ok" and 0 < m["evaluations"] <= 60 and 0 <= m["slip_angle"] < 360
    angles, values, _ = circle_samples(sweep.rows)
    assert len(angles) == 12 and np.all(m["positive"] <= values)
    assert m["positive"] < values.min() - 1e-6  # strictly between samples, not a sample
    lo, hi = m["bracket_lo"], m["bracket_hi"]
    assert lo < m["slip_angle"] < hi or lo < m["slip_angle"] - 360 < hi
    direct = _solve(box, m["slip_angle"])
    assert direct.positive[0] == pytest.approx(m["positive"], rel=1e-10, abs=0)
    assert direct.r_of(direct.positive[:1])[0] == pytest.approx(m["r_positive"], abs=1e-10)
    # an independent scan: the whole bracket every degree, then +-0.01 degree finely
    prep = prepare(box)
    scan = np.r_[np.arange(lo, hi, 1.0), m["slip_angle"] + np.linspace(-1e-2, 1e-2, 21)]
    found = [solve_prepared(prep, box.with_overrides({"solve.slip_angle": float(a)}))
             .positive[0] for a in scan]
    assert min(found) >= m["positive"] * (1 - 1e-9)
    fine = np.array(found[-21:]) - m["positive"]  # a parabola through the fine scan
    a2, a1, _ = np.polyfit(scan[-21:] - m["slip_angle"], fine, 2)
    # its vertex: the angle, to 1e-4 degree (the value is flat to round-off within a few
    # 1e-6 degree of it: sqrt(eps / curvature))
    assert a2 > 0 and abs(a1 / (2 * a2)) < 1e-4
    (stored,) = read_sweep(tmp_path / "m.h5")["minima"]  # the file holds what was reported
    assert {k: stored[k] for k in m} == m
    assert sweep.summary()["minima"][0]["positive"] == m["positive"]


def test_brent_on_a_known_curve_with_a_gap_of_infinite_values():
    calls = []

    def curve(angle):
        calls.append(angle)
        if 92.0 < angle < 200.0:  # no positive eigenvalue in these directions
            return math.inf, math.nan
        return 2.0 + 0.1 * (1.0 - math.cos(math.radians(angle - 77.3))), 0.25

    angles = np.arange(0.0, 360.0, 30.0)
    values = np.array([curve(a)[0] for a in angles])
    calls.clear()
    found = locate(curve, angles, values)
    assert found["status"] == "ok" and abs(found["slip_angle"] - 77.3) < 1e-5
    assert found["positive"] == pytest.approx(2.0, abs=1e-12) and found["r_positive"] == 0.25
    assert (found["bracket_lo"], found["bracket_hi"]) == (60.0, 120.0)  # 120: infinite
    assert any(92 < a < 120 for a in calls) and found["evaluations"] == len(calls) < 60
    wrapped = locate(lambda a: curve((a + 90.0) % 360), angles, np.roll(values, -3))
    assert abs(wrapped["slip_angle"] - 347.3) < 1e-5  # reported in [0, 360)
    assert (wrapped["bracket_lo"], wrapped["bracket_hi"]) == (-30.0, 30.0)  # around 0
    none = locate(curve, angles, np.full(len(angles), math.inf))
    assert none["status"] == "no-positive-alpha" and none["positive"] == math.inf
    assert none["evaluations"] == 0 and math.isnan(none["slip_angle"])


# ------------------------------------------------------------------------------ resuming
@pytest.mark.once
def test_an_interrupted_angle_sweep_resumes_with_only_what_is_missing(box, tmp_path):
    """Interrupted after three points (on two workers), then at the first minimum: each
    re-run computes only the missing points and minima, and the file ends as a fresh one."""
    grid = make_grid(box, nu="0.2,0.3", slip_angle="0:120:3")
    out = tmp_path / "r.h5"

    def stop_at(step):
        def on_point(row, done, total):
            assert total == 8  # 6 points and 2 minima
            if row is not None and done == step:
                raise KeyboardInterrupt
        return on_point

    with pytest.raises(KeyboardInterrupt):
        run_sweep(box, grid, output=out, jobs=2, on_point=stop_at(3))
    kept = read_sweep(out)
    assert len(kept["rows"]) == 3 and kept["minima"] == []
    with pytest.raises(KeyboardInterrupt):
        run_sweep(box, grid, output=out, jobs=2, on_point=stop_at(7))
    kept = read_sweep(out)
    assert len(kept["rows"]) == 6 and len(kept["minima"]) == 1
    resumed = run_sweep(box, grid, output=out, jobs=1)
    assert resumed.computed == 0 and resumed.located == 1 and len(resumed.minima) == 2
    again = run_sweep(box, grid, output=out, jobs=1)
    assert again.computed == 0 and again.located == 0
    fresh = run_sweep(box, grid, output=tmp_path / "fresh.h5", jobs=1)
    keys = [(r["nu"], r["slip_angle"]) for r in resumed.rows]
    assert keys == [(r["nu"], r["slip_angle"]) for r in fresh.rows] and len(set(keys)) == 6
    for a, b in zip(resumed.rows, fresh.rows):
        np.testing.assert_allclose(a["positive"], b["positive"], rtol=1e-10)
        np.testing.assert_allclose(a["negative"], b["negative"], rtol=1e-10)
    for a, b in zip(resumed.minima, fresh.minima):
        assert (a["nu"], a["status"]) == (b["nu"], b["status"]) == (a["nu"], "ok")
        assert a["positive"] == pytest.approx(b["positive"], rel=1e-10, abs=0)
        assert a["slip_angle"] == pytest.approx(b["slip_angle"], abs=1e-5)


def test_samples_tied_by_symmetry_bracket_the_first_angle():
    """Minima equal but for rounding (a symmetric body) are the same minimum on every
    install: the first angle's bracket is taken, whichever rounds lower (the two installs
    had located 135 and 225 degrees)."""
    angles = np.arange(0.0, 360.0, 30.0)
    values = 2.0 + np.abs(angles - 180) * 1e-3
    values[[4, 7]] = 1.9092791928, 1.9092791928 * (1 - 3e-16)
    assert bracket(angles, values) == (90.0, 120.0, 150.0)
    values[[4, 7]] = values[[7, 4]]
    assert bracket(angles, values) == (90.0, 120.0, 150.0)
    values[7] = 1.9092791928 * (1 - 1e-6)  # a real difference wins
    assert bracket(angles, values) == (180.0, 210.0, 240.0)
