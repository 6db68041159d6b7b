"""Path files (``critfric path``): written atomically, read back exactly, validated before use,
listed by ``critfric table`` and drawn as the bifurcation diagram."""

from __future__ import annotations

import math
import shutil

import h5py
import numpy as np
import pytest
from helpers import square_case

from critfric.case.schema import loads_case
from critfric.errors import CaseError
from critfric.fem.mesh import Mesh
from critfric.files.catalog import summaries
from critfric.files.pathfile import (
    default_path_output,
    path_table,
    read_path,
    read_path_summary,
    write_path,
)
from critfric.multiplicity.pathresult import Curve, Event, PathPoint, PathResult, Piece
from critfric.plots.figures import plot_file

STICK, SLIP = ["stuck", "stuck"], ["slip+", "stuck"]


def _point(value: float, status: list[str], piece: int, k: int) -> PathPoint:
    """A point with contact values that are not short binary fractions (1/3, 1/7, ...)."""
    base = np.array([1.0, 2.0]) / (3.0 + k)
    return PathPoint(value, list(status), Un=-base / 7.0, Ut=base * value, X=-base,
                     Y=base * value / 11.0, piece=piece)


def _result(*, margins: bool = True, mesh: bool = True) -> PathResult:
    """Two contact nodes, two curves of 4 and 3 points: a kink at 0.5 on curve 0, a fold at
    1.6 on curve 1, a branch point at 1.8 (critical 1.8) where they meet, one isolated
    solution."""
    case = loads_case('title = "two nodes, by hand"\n' + square_case(size=0.5),
                      name="pathcase")
    m = (lambda v: v) if margins else (lambda v: None)
    c0 = Curve("start", [_point(0.0, STICK, 0, 0), _point(0.5, STICK, 0, 1),
                         _point(1.0, SLIP, 1, 2), _point(1.8, SLIP, 1, 3)],
               [Piece(STICK, 0.0, 0.5), Piece(SLIP, 0.5, 1.8, (1.8, -2.2), m(1.0))])
    c1 = Curve({"value": 1.8, "event": 2},
               [_point(1.8, ["slip+", "slip+"], 0, 4), _point(1.6, ["slip+", "slip+"], 0, 5),
                _point(1.7, ["slip+", "slip-"], 1, 6)],
               [Piece(["slip+", "slip+"], 1.8, 1.6, (2.5, None), m(2.5 / 1.8)),
                Piece(["slip+", "slip-"], 1.6, 1.7, (None, -0.9), None)])
    events = [Event("kink", 0.5, [0], None, [0], [STICK, SLIP]),
              Event("fold", 1.6, [], None, [1], [["slip+", "slip+"]]),
              Event("branch", 1.8, [1], 1.8, [0, 1], [SLIP, ["slip+", "slip+"]])]
    tiny = Mesh(np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]]),
                np.array([[0, 1, 2], [0, 2, 3]]), "P1",
                {"bottom": np.array([[0, 1]]), "top": np.array([[2, 3]])})
    return PathResult("friction", (0.0, 3.0), [c0, c1], events, n_dofs=8, n_contact=2,
                      seconds=0.25, friction=None, samples=np.linspace(0.0, 3.0, 7),
                      isolated=[(2.5, _point(2.5, ["free", "cone"], 0, 7))],
                      s=np.array([0.0, 1.0]), node=0, notes=["a note", "another"],
                      case=case, mesh=tiny if mesh else None,
                      contact_nodes=np.array([0, 1]))


@pytest.fixture
def written(tmp_path):
    result = _result()
    return result, write_path(result, tmp_path / "p.h5")


def _same(read, want, where="") -> None:
    """``want`` (to_json) within ``read``: floats to 1e-15, the rest equal."""
    if isinstance(want, dict):
        assert set(want) <= set(read), where
        for k, v in want.items():
            _same(read[k], v, f"{where}/{k}")
    elif isinstance(want, (list, tuple)):
        assert len(read) == len(want), where
        for i, (r, w) in enumerate(zip(read, want)):
            _same(r, w, f"{where}/{i}")
    elif isinstance(want, float):
        assert isinstance(read, float) and math.isclose(read, want, rel_tol=1e-15,
                                                        abs_tol=1e-15), where
    else:
        assert read == want and type(read) is type(want), where


def test_a_path_file_reads_back_as_its_json(written):
    result, path = written
    data = read_path(path)
    _same(data, result.to_json())
    for curve, back in zip(result.curves, data["curves"]):
        assert [q["piece"] for q in back["points"]] == [q.piece for q in curve.points]
        assert set(back["points"][0]) == {"value", "status", "Un", "Ut", "X", "Y", "piece"}
    assert set(data["isolated"][0]) == {"value", "status", "Un", "Ut", "X", "Y"}
    assert data["s"] == [0.0, 1.0] and data["samples"] == result.samples.tolist()
    assert data["case_name"] == "pathcase" and data["title"] == "two nodes, by hand"
    assert data["counts"] == result.counts()
    assert data["friction"] is None and data["events"][2]["critical"] == 1.8
    assert data["curves"][1]["pieces"][1]["margin"] is None
    assert data["mesh"].element == "P1" and data["mesh"].n_cells == 2
    assert data["contact_nodes"] == [0, 1]
    with h5py.File(path) as f:
        assert f.attrs["kind"] == "path" and f["curves/0/status"].dtype == np.int8
        assert "legend" in f["curves/0/pieces/state"].attrs
        assert f["curves/0/Un"].attrs["units"] == "length unit of the case"
        assert f.attrs["case_toml"] and int(f.attrs["schema_version"]) >= 1


def test_a_path_without_mesh_events_or_curves_is_a_file_too(tmp_path):
    result = _result(mesh=False)
    result.curves, result.events, result.isolated = [], [], []
    data = read_path(write_path(result, tmp_path / "empty.h5"))
    _same(data, result.to_json())
    assert data["mesh"] is None and data["contact_nodes"] is None
    assert plot_file(tmp_path / "empty.h5") == [tmp_path / "empty_diagram.png"]


def test_the_default_output_is_named_after_the_case():
    assert str(default_path_output(_result().case)) == "pathcase_path.h5"


def test_table_rows_of_a_path_file(written, tmp_path):
    _, path = written
    rows, skipped = summaries([path])
    assert skipped == [] and len(rows) == 1
    row = rows[0]
    assert row["kind"] == "path" and row["file"] == str(path) and row["case"] == "pathcase"
    assert row["counts"] == {"curves": 2, "pieces": 4, "kinks": 1, "folds": 1, "branches": 1}
    assert row["branch_points"] == [{"value": 1.8, "critical": 1.8, "unbounded": False}]
    assert row["parameter"] == "friction" and row["range"] == [0.0, 3.0]
    assert row["friction"] is None and row["isolated"] == 1 and row["n_contact"] == 2
    assert row == {**read_path_summary(path), "file": str(path), "kind": "path"}
    text = path_table(rows)
    assert "pathcase" in text and "1.8" in text and len(text.splitlines()) == 3


def test_writing_over_a_file_needs_force(written):
    result, path = written
    before = path.read_bytes()
    with pytest.raises(CaseError, match="exists already"):
        write_path(result, path)
    assert path.read_bytes() == before
    write_path(result, path, force=True)


def _replace(f, key, value):
    attrs = dict(f[key].attrs)
    del f[key]
    f[key] = value
    f[key].attrs.update(attrs)


EDITS = {
    "curves/1/Un": lambda f: _replace(f, "curves/1/Un", np.zeros((3, 3))),
    "curves/0/value": lambda f: f["curves/0/value"].__setitem__(1, np.nan),
    "kind": lambda f: f.attrs.__setitem__("kind", "nonsense"),
    "curves/0/status": lambda f: f["curves/0/status"].__setitem__((0, 0), 9),
    "curves/0/piece": lambda f: _replace(f, "curves/0/piece", np.array([0, 0, 1, 5])),
    "curves/1/pieces/margin": lambda f: _replace(f, "curves/1/pieces/margin",
                                                 np.zeros(3)),
    "events/nodes": lambda f: _replace(f, "events/nodes",
                                       np.array([b"[0]", b"[7]", b"{"], dtype=object)),
    "events/critical": lambda f: f.__delitem__("events/critical"),
    "contact/s": lambda f: _replace(f, "contact/s", np.zeros(3)),
    "isolated/Ut": lambda f: _replace(f, "isolated/Ut", np.array([[np.inf, 0.0]])),
    "mesh/contact_nodes": lambda f: _replace(f, "mesh/contact_nodes", np.array([0, 1, 2])),
    "'node'": lambda f: f.attrs.__setitem__("node", 2),
    "'range'": lambda f: f.attrs.__setitem__("range", np.array([0.0])),
}


@pytest.mark.parametrize("name", sorted(EDITS))
def test_a_malformed_path_file_is_refused_naming_the_dataset(written, tmp_path, name):
    _, good = written
    bad = tmp_path / "bad.h5"
    shutil.copy(good, bad)
    with h5py.File(bad, "r+") as f:
        EDITS[name](f)
    for read in (read_path, read_path_summary, plot_file):
        with pytest.raises(CaseError) as err:
            read(bad)
        assert "bad.h5" in str(err.value)
        assert name in str(err.value) or name == "kind" and "is not a" in str(err.value)
    rows, skipped = summaries([bad])
    assert rows == [] and skipped[0][0] == bad
    assert not list(tmp_path.glob("bad_*.png"))


@pytest.mark.parametrize("margins", [True, False])
def test_the_diagram_is_written(tmp_path, margins):
    path = write_path(_result(margins=margins), tmp_path / "p.h5")
    out = plot_file(path)
    assert out == [tmp_path / "p_diagram.png"]
    assert out[0].read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and out[0].stat().st_size > 10_000
