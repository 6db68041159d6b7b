"""Property-based fuzzing of the case loader and the command line (hypothesis).

Property: whatever the case file or the command line, critfric either succeeds or raises a
:class:`critfric.errors.CritfricError` (the CLI: exits 0, 1 or 2 with one message, no
traceback). The suite runs a thousand derandomized examples (the same ones each run, as a
regression check); ``make fuzz`` runs thirty times as many random ones
(``CRITFRIC_FUZZ_SCALE`` multiplies the example counts).
"""

from __future__ import annotations

import os
import string

import pytest
import tomli_w
from helpers import run_cli
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

from critfric.case.schema import SCHEMA, from_dict, loads_case
from critfric.errors import CritfricError

pytestmark = pytest.mark.once  # the same on both installs: run by `make test` only

SCALE = float(os.environ.get("CRITFRIC_FUZZ_SCALE", "1"))
FULL = SCALE > 1  # make fuzz: random examples, no derandomization


def fuzz(n: int):
    return settings(max_examples=max(1, int(n * SCALE)), deadline=None, derandomize=not FULL,
                    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large,
                                           HealthCheck.filter_too_much])


BASES = {
    "square": {"geometry": {"shape": "square", "side": 1.0},
               "boundary": {"contact": ["bottom"], "dirichlet": ["top"]},
               "material": {"nu": 0.3}, "mesh": {"element": "P1", "size": 0.5}},
    "parallelogram": {"geometry": {"shape": "parallelogram", "base": 1.0, "height": 0.5,
                                   "offset": 0.3},
                      "mesh": {"element": "Q1", "size": 0.25, "structured": True}},
    "polygon": {"geometry": {"shape": "polygon", "vertices": [[0, 0], [2, 0], [2, 1], [1, 1],
                                                              [1, 2], [0, 2]]},
                "boundary": {"contact": "e0", "dirichlet": ["e4"]},
                "mesh": {"element": "P2", "size": 0.5, "grading": 0.5},
                "solve": {"method": "arpack", "count": 2}},
    "mesh": {"geometry": {"shape": "mesh", "nodes": [[0, 0], [1, 0], [1, 1], [0, 1]],
                          "quads": [[0, 1, 2, 3]],
                          "edges": {"bottom": [[0, 1]], "top": [[2, 3]]}},
             "mesh": {"element": "Q2"}, "solve": {"method": "dense", "gamma": -1}},
    "file": {"geometry": {"shape": "file", "file": "body.geo"}, "mesh": {"element": "P1"}},
}
SECTIONS = list(SCHEMA) + ["title", "extra"]
KEYS = [(s, k) for s, keys in SCHEMA.items() for k in keys]
WORDS = ["P1", "P2", "Q1", "Q2", "square", "rectangle", "polygon", "mesh", "file", "bottom",
         "top", "left", "right", "e0", "e4", "auto", "dense", "arpack", "body.geo", "body.msh",
         "nope.geo", "", "a\x00b.h5", "x" * 300, "/proc/x.h5"]

scalars = st.one_of(
    st.integers(min_value=-3, max_value=12), st.integers(min_value=-2**63, max_value=2**63 - 1),
    st.floats(allow_nan=True, allow_infinity=True), st.floats(-2.0, 2.0), st.booleans(),
    st.sampled_from(WORDS), st.text(max_size=8))
values = st.recursive(scalars, lambda inner: st.lists(inner, max_size=5)
                      | st.dictionaries(st.sampled_from(WORDS[:12]) | st.text(max_size=5),
                                        inner, max_size=3), max_leaves=10)
mutation = st.one_of(
    st.tuples(st.just("set"), st.sampled_from(KEYS), values),
    st.tuples(st.just("del"), st.sampled_from(KEYS), st.none()),
    st.tuples(st.just("section"), st.sampled_from(SECTIONS), values),
    st.tuples(st.just("key"), st.sampled_from(SECTIONS), st.text(string.ascii_lowercase,
                                                                 min_size=1, max_size=6)))

NAMES = ["bottom", "top", "left", "right", "e0", "e1", "e3", "e4"]
PLAUSIBLE = {  # values near and at the edges of what is allowed: these drive real solves
    ("material", "nu"): st.sampled_from([0.0, 1e-9, 0.1, 0.3, 0.45, 0.4999]),
    ("material", "E"): st.sampled_from([1e-6, 1.0, 2e11]),
    ("mesh", "element"): st.sampled_from(["P1", "P2", "Q1", "Q2"]),
    ("mesh", "size"): st.sampled_from([0.2, 0.25, 0.34, 0.5, 0.7, 1.0, 3.0, 1e3]),
    ("mesh", "structured"): st.booleans(),
    ("mesh", "grading"): st.sampled_from([1e-3, 0.1, 0.5, 1.0]),
    ("solve", "method"): st.sampled_from(["auto", "dense", "arpack"]),
    ("solve", "count"): st.integers(1, 6),
    ("solve", "shift"): st.sampled_from([0.0, -1.0, 0.5, 1.9, 3.0, 1e-12, 1e6, -1e6]),
    ("solve", "gamma"): st.sampled_from([1, -1]),
    ("solve", "tol"): st.sampled_from([0.0, 1e-12, 1e-6, 1e-2]),
    ("solve", "maxiter"): st.sampled_from([1, 2, 5, 50]),
    ("solve", "real_tol"): st.sampled_from([0.0, 1e-14, 1e-8, 1e-2]),
    ("output", "modes"): st.booleans(),
    ("boundary", "contact"): st.lists(st.sampled_from(NAMES), min_size=1, max_size=2),
    ("boundary", "dirichlet"): st.lists(st.sampled_from(NAMES), min_size=1, max_size=2),
    ("geometry", "side"): st.sampled_from([1e-3, 1.0, 50.0]),
    ("geometry", "height"): st.sampled_from([0.01, 0.5, 1.0, 100.0]),
    ("geometry", "offset"): st.sampled_from([-5.0, -0.5, 0.0, 0.5, 5.0]),
}
plausible = st.sampled_from(sorted(PLAUSIBLE)).flatmap(
    lambda key: st.tuples(st.just("set"), st.just(key), PLAUSIBLE[key]))


def mutate(base: dict, edits) -> dict:
    raw = {k: dict(v) if isinstance(v, dict) else v for k, v in base.items()}
    for op, where, value in edits:
        if op == "set":
            section, key = where
            if not isinstance(raw.get(section, {}), dict):
                raw[section] = {}
            raw.setdefault(section, {})[key] = value
        elif op == "del":
            section, key = where
            if isinstance(raw.get(section), dict):
                raw[section].pop(key, None)
        elif op == "section":
            raw[where] = value
        else:
            if not isinstance(raw.get(where, {}), dict):
                raw[where] = {}
            raw.setdefault(where, {})[value] = 1
    return raw


def _only_ours(call) -> None:
    try:
        call()
    except CritfricError:
        pass


@fuzz(500)
@given(st.text(max_size=300))
def test_random_text_is_a_case_or_a_case_error(text):
    _only_ours(lambda: loads_case(text, source="fuzz.toml"))


@pytest.mark.slow
@fuzz(500)
@given(st.sampled_from(sorted(BASES)), st.lists(mutation, min_size=1, max_size=4))
def test_mutated_cases_load_or_fail_cleanly(base, edits):
    raw = mutate(BASES[base], edits)
    _only_ours(lambda: from_dict(raw, source="fuzz.toml"))
    try:
        text = tomli_w.dumps(raw)
    except (TypeError, ValueError):  # not representable in TOML (e.g. a None): nothing to load
        return
    _only_ours(lambda: loads_case(text, source="fuzz.toml"))


# ------------------------------------------------------------------------ the command line
GEO = """Point(1) = {0, 0, 0, 0.5}; Point(2) = {1, 0, 0, 0.5};
Point(3) = {1, 1, 0, 0.5}; Point(4) = {0, 1, 0, 0.5};
Line(1) = {1, 2}; Line(2) = {2, 3}; Line(3) = {3, 4}; Line(4) = {4, 1};
Curve Loop(1) = {1, 2, 3, 4}; Plane Surface(1) = {1};
Physical Curve("bottom") = {1}; Physical Curve("top") = {3};
Physical Surface("domain") = {1};
"""
OPTIONS = {
    "--nu": st.floats(allow_nan=True, allow_infinity=True).map(repr) | st.sampled_from(
        ["0", "0.25", "0.4999", "abc", "", "-0"]),
    "--element": st.sampled_from(["P1", "P2", "Q1", "Q2", "p1", "Q3", ""]),
    "--size": st.sampled_from(["0.5", "0.34", "1", "1e9", "0", "-1", "1e-300", "nan", "x"]),
    "--count": st.sampled_from(["1", "2", "3", "0", "-1", "1001", "1.5"]),
    "--shift": st.floats(allow_nan=True, allow_infinity=True).map(repr),
    "--method": st.sampled_from(["auto", "dense", "arpack", "lanczos"]),
    "-o": st.sampled_from(["out.h5", "sub/out.h5", ".", "", "case.toml/x.h5", "x" * 300,
                           "/proc/x.h5", " "]),
    "--force": st.none(), "--json": st.none(), "--trust-geo": st.none(),
    "--bogus": st.none(),
}


@pytest.fixture(scope="module")
def workdir(tmp_path_factory):
    d = tmp_path_factory.mktemp("fuzz")
    (d / "body.geo").write_text(GEO)
    return d


@st.composite
def command_lines(draw):
    base = draw(st.sampled_from(sorted(BASES)))
    edits = st.lists(plausible, max_size=4) if draw(st.integers(0, 9)) < 7 else \
        st.lists(mutation, max_size=2)
    raw = mutate(BASES[base], draw(edits))
    try:
        text = tomli_w.dumps(raw)
    except (TypeError, ValueError):
        text = ""
    if draw(st.integers(0, 9)) < 3:  # a text-level edit: drop, duplicate or cut a line
        lines = text.splitlines() or [""]
        i = draw(st.integers(0, len(lines) - 1))
        how = draw(st.sampled_from(["drop", "dup", "cut"]))
        cut = lines[i][: draw(st.integers(0, len(lines[i])))]
        lines[i:i + 1] = {"drop": [], "dup": [lines[i]] * 2, "cut": [cut]}[how]
        text = "\n".join(lines)
    args = ["solve", "case.toml", "-o", "fuzz-out.h5", "--force"]
    for name in draw(st.lists(st.sampled_from(sorted(OPTIONS)), max_size=4, unique=True)):
        value = draw(OPTIONS[name])
        args += [name] if value is None else [name, value]
    return text, args + ["--max-dofs", "3000"]  # last: bounds the work of every example


@pytest.mark.slow
@fuzz(100)
@given(command_lines())
def test_command_line_exits_cleanly(workdir, command):
    text, args = command
    (workdir / "case.toml").write_text(text)
    res = run_cli(*args, cwd=workdir)
    assert res.exception is None or isinstance(res.exception, SystemExit), (args, text)
    assert res.exit_code in (0, 1, 2), (res.exit_code, args, res.output)
    event(f"exit {res.exit_code}")
    assert "Traceback" not in res.output
    if res.exit_code:
        assert "rror" in res.stderr, res.output
    leftovers = [p.name for p in workdir.iterdir() if p.name.endswith((".tmp", ".lock"))]
    assert not leftovers
