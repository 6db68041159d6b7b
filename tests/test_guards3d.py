"""The resource guard of 3D bodies: the memory model against its measurements, a huge box
refused before meshing, a small one solved."""

from __future__ import annotations

import csv
import math
import time
from pathlib import Path

import pytest
from helpers import box_case

from critfric import guards, prepare
from critfric.case.schema import loads_case
from critfric.errors import CaseError
from critfric.guards import check_dofs, dofs_that_fit, memory_estimate
from critfric.meshing.solid import SolidFootprint
from critfric.solvers import eigen

MEASURED = Path(__file__).resolve().parent.parent / "benchmarks" / "box3d_memory.csv"


def test_the_model_covers_every_measured_peak_closely():
    with MEASURED.open() as f:
        rows = list(csv.DictReader(f))
    assert {(r["backend"], r["element"]) for r in rows} >= {
        (b, e) for b in ("pardiso", "scipy") for e in ("P1", "P2", "Q1")}
    for r in rows:
        estimate = memory_estimate(float(r["n_dofs"]), float(r["n_contact"]), dim=3,
                                   element=r["element"], backend=r["backend"])
        peak = float(r["peak_mb"]) * 1e6
        assert peak <= estimate <= 1.6 * peak, r  # never below a peak, not far above


def test_the_3d_model_grows_and_inverts():
    for backend in ("pardiso", "scipy"):
        model = {"dim": 3, "element": "P1", "backend": backend}
        small, large = (memory_estimate(n, **model) for n in (1e5, 1e6))
        assert 10 < large / small < 40  # the factor's fill ~ n^1.43, more than the 2D model
        assert memory_estimate(dofs_that_fit(16e9, **model), **model) == pytest.approx(
            16e9, rel=1e-6)
        assert memory_estimate(math.inf, **model) == math.inf
    # the 3p x 3p Schur complement counts only where the dense path forms it
    rows = guards.DENSE_MAX_ROWS
    assert rows == 2 * eigen.SCHUR_MAX_CONTACT
    p = rows / 3
    with_dense = memory_estimate(3e5, p, dim=3, backend="pardiso")
    assert with_dense > memory_estimate(3e5, 0, dim=3, backend="pardiso")
    assert memory_estimate(3e5, p + 1, dim=3, backend="pardiso") < with_dense
    # 3D needs more than 2D at the same size; SciPy more than PARDISO
    assert memory_estimate(3e5, dim=3, backend="pardiso") > memory_estimate(3e5)
    assert (memory_estimate(3e5, dim=3, backend="scipy")
            > memory_estimate(3e5, dim=3, backend="pardiso"))


def test_a_solid_footprint_selects_the_3d_model(monkeypatch):
    monkeypatch.setattr(guards, "available_memory", lambda *a: 8e9)
    footprint = SolidFootprint(0.5, 4.0, 10.0, 8)  # the box 1 x 0.5 x 1
    h = 0.01  # ~1.1 M DOFs: below 8 GB in 2D's model, far above in 3D's
    n = footprint.dofs(h, "P1")
    assert memory_estimate(n) < 8e9 < memory_estimate(n, dim=3, backend="pardiso")
    with pytest.raises(CaseError) as err:
        check_dofs(n, element="P1", what=f"mesh.size = {h:g}", source="b.toml",
                   footprint=footprint, backend="pardiso")
    message = str(err.value)
    assert "mesh.size = 0.01" in message and "DOFs (P1)" in message and "GB" in message
    finest = float(message.split("finest mesh size that fits is about ")[1].split()[0])
    assert finest > h
    fits = footprint.dofs(finest * 1.001, "P1")
    assert memory_estimate(fits, dim=3, backend="pardiso") <= 8e9
    check_dofs(fits, element="P1", what="x", source=None, footprint=footprint,
               backend="pardiso")  # what the message suggests is accepted


def test_prepare_refuses_a_huge_box_before_meshing_and_accepts_a_small_one():
    case = loads_case(box_case(size=1e-3), source="box.toml")
    start = time.perf_counter()
    with pytest.raises(CaseError, match=r"box\.toml.*mesh\.size = 0\.001 gives about "
                                        r"[0-9.]+e\+0[89] DOFs \(P1\), needing about .* of memory"):
        prepare(case)
    assert time.perf_counter() - start < 30  # 10^9 tetrahedra were never meshed
    small = prepare(case.with_overrides({"mesh.size": 0.25}))
    assert small.mesh.dim == 3 and 0 < small.system.n_dofs < 2000
