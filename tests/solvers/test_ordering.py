"""The nested dissection made beside the assembly: the same order, made once, and no thread
left running by ``prepare``."""

from __future__ import annotations

import threading

import numpy as np
import pytest

from critfric.case.schema import load_case
from critfric.solve import make_mesh, prepare
from critfric.solvers import ordering


def _dissection_threads() -> list[threading.Thread]:
    return [t for t in threading.enumerate() if t.name == "critfric-dissection"]


def test_a_dissection_under_way_is_waited_for_not_repeated(monkeypatch):
    mesh = make_mesh(load_case("unit-square", overrides={"mesh.size": 0.02}))
    expected = ordering._dissect(mesh.points, mesh.cells)
    started, release, calls = threading.Event(), threading.Event(), []
    dissect = ordering._dissect

    def slow(*args, **kwargs):  # the thread's dissection holds until the caller waits on it
        calls.append(threading.current_thread().name)
        started.set()
        release.wait(10)
        return dissect(*args, **kwargs)

    monkeypatch.setattr(ordering, "_dissect", slow)
    thread = ordering.dissect_beside(mesh)
    assert started.wait(10)
    box = {}
    caller = threading.Thread(target=lambda: box.update(rank=ordering.mesh_rank(mesh)))
    caller.start()
    release.set()
    caller.join(10)
    thread.join(10)
    assert calls == ["critfric-dissection"]  # made once, in the thread
    np.testing.assert_array_equal(box["rank"], expected[0])


@pytest.mark.parametrize("backend, started", [("scipy", True), ("pardiso", False)])
def test_prepare_dissects_for_scipy_alone_and_joins(backend, started, monkeypatch):
    from critfric import solve

    made = []
    beside = ordering.dissect_beside

    def spy(mesh):
        made.append(mesh)
        return beside(mesh)

    monkeypatch.setattr(solve, "dissect_beside", spy)
    monkeypatch.setattr(solve, "resolve_backend", lambda name: name)  # any install
    case = load_case("unit-square", overrides={"mesh.size": 0.01, "solve.backend": backend})
    prep = prepare(case)
    assert bool(made) == started
    assert not _dissection_threads()
    if started:  # the order read from the mesh's dissection made in prepare
        key = (id(prep.mesh), ordering.MAX_LEVELS)
        assert ordering._RANKS[key][0]() is prep.mesh


def test_small_and_order_2_meshes_are_not_dissected():
    small = make_mesh(load_case("unit-square", overrides={"mesh.size": 0.1}))
    p2 = make_mesh(load_case("unit-square", overrides={"mesh.size": 0.02,
                                                       "mesh.element": "P2"}))
    large = make_mesh(load_case("unit-square", overrides={"mesh.size": 0.01}))
    assert not ordering.dissects(small) and not ordering.dissects(p2)
    assert ordering.dissects(large)
