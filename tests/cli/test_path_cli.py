"""``critfric path`` and the ``[path]`` section: bad values fail in the schema with exit code 2
and the key named (no numerical core needed); the end-to-end runs skip until it exists."""

from __future__ import annotations

import json
import sys
import types

import numpy as np
import pytest
from helpers import CASES, run_cli

from critfric.case.schema import OVERRIDES, loads_case
from critfric.multiplicity.pathresult import Curve, Event, PathPoint, PathResult, Piece

# the shipped one triangle without its [path] section (each test adds its own)
TRIANGLE = (CASES / "one_triangle.toml").read_text().split("\n[path]")[0] + "\n"

# (what, [path] lines added to the one-triangle case, command-line options, words said)
BAD = [
    ("unknown parameter", "", ("--parameter", "temperature"), ("path.parameter", "'load'")),
    ("range reversed", "", ("--range", "3:1"), ("path.range", "a < b")),
    ("range empty", "", ("--range", "1:1"), ("path.range", "a < b")),
    ("range of one number", "", ("--range", "1"), ("--range", "A:B", "path.range")),
    ("range with a full-width digit", "", ("--range", "\uff11:3"), ("--range", "ASCII")),
    ("range not numbers", "", ("--range", "a:b"), ("--range", "'a:b'")),
    ("friction range below 0", "range = [-1.0, 2.0]", (), ("path.range", "0 <= a")),
    ("range of three numbers in the file", "range = [0, 1, 2]", (), ("path.range", "[a, b]")),
    ("samples 1", "", ("--samples", "1"), ("path.samples", "[2, 10001]")),
    ("node -1", "", ("--node", "-1"), ("path.node", "integer")),
    ("unknown start", 'start = "guess"', (), ("path.start", "'newton'")),
    ("max_pieces 0", "max_pieces = 0", (), ("path.max_pieces", "[1, 10000000]")),
    ("a load key [load] has but a load lacks", "load = { reference = 0.0 }", (),
     ("path.load.reference", "traction, body_force, points, displacement")),
    ("a misspelt load key", "load = { tracton = { free = [1.0, 0.0] } }", (),
     ("path.load.tracton", "traction")),
    ("a bad load value", "load = { body_force = [1.0] }", (), ("path.load.body_force", "[x, y]")),
    ("traction on the contact edge", "load = { traction = { contact = [1.0, 0.0] } }", (),
     ("path.load.traction", "'contact'", "traction-free edge (free)")),
    ("displacement on a free edge", "load = { displacement = { free = [0.1, 0.0] } }", (),
     ("path.load.displacement", "Dirichlet edge (clamped)")),
    ("a point force on no node", "load = { points = [{ node = 9, force = [1.0, 0.0] }] }", (),
     ("path.load.points.0", "node index < 3")),
    ("an empty load", "load = {}", (), ("path.load", "one or more")),
    ("a load path without L1", 'parameter = "load"', (), ("path.load", "second load L1")),
]


@pytest.mark.parametrize("what,lines,options,words", BAD, ids=[b[0] for b in BAD])
def test_bad_path_input_exits_2_naming_the_key(tmp_path, what, lines, options, words):
    case = tmp_path / "tri.toml"
    case.write_text(TRIANGLE + "\n[path]\n" + lines + "\n")
    res = run_cli("path", case, "-o", tmp_path / "p.h5", *options)
    assert res.exit_code == 2, res.output
    assert res.stdout == "" and "Traceback" not in res.output
    message = " ".join(res.stderr.split())
    assert message.startswith("critfric: error: ") and res.stderr.count("\n") == 1
    for word in words:
        assert word in message, (word, message)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["tri.toml"]


def test_path_section_defaults_overrides_and_load():
    case = loads_case(TRIANGLE)
    assert case.path == {"parameter": "friction", "range": None, "start": "auto",
                         "samples": 101, "node": None, "load": None, "max_pieces": 20000}
    assert {OVERRIDES[k] for k in ("parameter", "range", "start", "samples", "node")} == {
        "path.parameter", "path.range", "path.start", "path.samples", "path.node"}
    assert OVERRIDES["friction"] == "stability.friction"
    case = loads_case(TRIANGLE + '[path]\nparameter = "load"\nrange = [-1, 2]\n'
                      'load = { body_force = [0, 1] }\n')
    assert case.path["range"] == [-1.0, 2.0]  # a load factor may be negative
    assert case.path["load"] == {"traction": None, "body_force": [0.0, 1.0], "points": None,
                                 "displacement": None}
    assert loads_case(case.to_toml()).path == case.path


def test_path_help_has_the_examples():
    res = run_cli("path", "--help")
    assert res.exit_code == 0
    assert "critfric path one-triangle --range 0:3 --plot" in res.output
    assert "--parameter load --range 0:1 --json" in res.output


def _fake_path_case(case, *, max_dofs=None, trust_geo=False):
    """A made-up result of the shape of one-triangle's friction path (for the command alone)."""
    one = lambda v: PathPoint(v, ["slip+"], np.zeros(1), np.ones(1), np.zeros(1), np.zeros(1))
    curves = [Curve("start", [one(0.0), one(3.0)], [Piece(["slip+"], 0.0, 3.0, (1.8, None))]),
              Curve({"value": 1.8, "event": 0}, [one(1.8)], [Piece(["stuck"], 1.8, 3.0)])]
    events = [Event("branch", 1.8, [0], 1.8, [0, 1], [["slip+"], ["stuck"]])]
    return PathResult("friction", tuple(case.path["range"]), curves, events, n_dofs=6,
                      n_contact=1, seconds=0.01, samples=np.linspace(0.0, 3.0, 4),
                      s=np.zeros(1), case=case, notes=["a made-up result"])


def test_the_summary_says_the_events_and_the_curves(tmp_path, monkeypatch):
    fake = types.ModuleType("critfric.multiplicity.path")
    fake.path_case = _fake_path_case
    monkeypatch.setitem(sys.modules, "critfric.multiplicity.path", fake)
    out = tmp_path / "p.h5"
    res = run_cli("path", "one-triangle", "--range", "0:3", "-o", out)
    assert res.exit_code == 0, res.output
    lines = res.stdout.splitlines()
    assert lines[2] == "parameter  friction over [0, 3]"
    assert lines[3] == "found      2 curves, 2 pieces, 0 kinks, 0 folds, 1 branches"
    assert lines[4].split() == ["branch", "at", "1.8", "nodes", "0", "critical", "1.8"]
    assert lines[6] == "curve 1    from event 0 at 1.8: 1 pieces, friction 1.8 .. 3"
    assert "critfric: note: a made-up result" in res.stderr and f"wrote {out}" in res.stderr
    again = run_cli("path", "one-triangle", "--range", "0:3", "-o", out, "--json")
    assert again.exit_code == 2 and "--force" in again.stderr  # an existing file is kept
    res = run_cli("path", "one-triangle", "--range", "0:3", "-o", out, "--json", "--force")
    assert json.loads(res.stdout)["events"][0]["critical"] == 1.8


def test_friction_path_of_one_triangle_finds_the_branch_point(tmp_path):
    pytest.importorskip("critfric.multiplicity.path")
    out = tmp_path / "p.h5"
    res = run_cli("path", "one-triangle", "--range", "0:3", "--json", "-o", out)
    assert res.exit_code == 0, res.output
    data = json.loads(res.stdout)
    assert data["parameter"] == "friction" and data["range"] == [0, 3]
    assert any(c["seed"] == "start" for c in data["curves"])
    assert any(e["kind"] == "branch" and e["critical"] is not None
               and abs(e["critical"] - 1.8) < 1e-9 for e in data["events"]), data["events"]
    assert out.is_file()
    human = run_cli("path", "one-triangle", "--range", "0:3", "-o", out, "--force")
    assert human.exit_code == 0, human.output
    assert "friction over [0, 3]" in human.stdout and "critical 1.8" in human.stdout


def test_node_beyond_the_contact_nodes_exits_2(tmp_path):
    pytest.importorskip("critfric.multiplicity.path")
    res = run_cli("path", "one-triangle", "--range", "0:3", "--node", 5, "-o", tmp_path / "p.h5")
    assert res.exit_code == 2, res.output
    assert "path.node" in res.stderr and "Traceback" not in res.output
    assert list(tmp_path.iterdir()) == []
