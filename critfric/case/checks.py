"""Value checks for the case schema: each takes a TOML value and returns it normalized, or
raises :class:`Bad` whose text says what is allowed (the caller adds file, key and value)."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np


@dataclass(frozen=True)
class Key:
    """One key of the schema: its check, its default (``REQUIRED`` if none) and its meaning."""

    check: Callable[[Any], Any]
    default: Any
    doc: str


REQUIRED = object()


class Bad(ValueError):
    """Raised by a check: the text says what is allowed."""


class BadEntry(Bad):
    """Raised by the check of a table for one of its entries: ``key`` names the entry and
    ``value`` is what the message shows as given."""

    def __init__(self, allowed: str, key: str, value):
        super().__init__(allowed)
        self.key, self.value = key, value


def number(lo=-math.inf, hi=math.inf, *, lo_open=False, hi_open=False, magnitude=None):
    """A finite number in [lo, hi] (ends open as told); ``magnitude``: (least, largest) |value|
    too."""
    def check(value):
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise Bad("a number")
        value = float(value)
        low_ok = value > lo if lo_open else value >= lo
        high_ok = value < hi if hi_open else value <= hi
        sized = magnitude is None or magnitude[0] <= abs(value) <= magnitude[1]
        if not (math.isfinite(value) and low_ok and high_ok and sized):
            left = "(" if lo_open else "["
            right = ")" if hi_open else "]"
            size = "" if magnitude is None else (f" of magnitude in [{magnitude[0]:g}, "
                                                 f"{magnitude[1]:g}]")
            span = "" if lo == -math.inf and hi == math.inf else \
                f" in {left}{lo:g}, {hi:g}{right}"
            raise Bad(f"a finite number{span}{size}")
        return value

    return check


#: [material] E and density: the solvers work with E = density = 1 and scale their outputs,
#: so any magnitude up to the largest powers of ten a float holds is accepted (the case-wide
#: NUMBER_RANGE does not apply to these keys)
MATERIAL_RANGE = (1e-300, 1e300)
SCALED_KEYS = (".material.E", ".material.density")


def integer(lo, hi):
    def check(value):
        if isinstance(value, bool) or not isinstance(value, int) or not lo <= value <= hi:
            raise Bad(f"an integer in [{lo}, {hi}]")
        return value

    return check


def choice(*allowed):
    def check(value):
        if value not in allowed:
            raise Bad("one of " + ", ".join(repr(a) for a in allowed))
        return value

    return check


def boolean(value):
    if not isinstance(value, bool):
        raise Bad("true or false")
    return value


def _printable(value) -> bool:
    """A non-empty string of printable characters (no control character reaches a terminal)."""
    return isinstance(value, str) and bool(value) and value.isprintable()


def string(value):
    if not _printable(value):
        raise Bad("a non-empty string of printable characters (no control characters: they "
                  "would reach the terminal)")
    return value


def path(value):
    if not isinstance(value, str) or not value.strip() or "\x00" in value:
        raise Bad("a file path (a non-empty string without NUL characters)")
    return value


def case_output(section):
    """The ``[output]`` table as a case file gives it (before command-line overrides): its
    ``file`` a relative path inside the working directory (no absolute path, no '..', no
    '~') ending in .h5, so that a case from elsewhere cannot direct the result onto a file
    outside it."""
    if not isinstance(section, dict) or not isinstance(section.get("file"), str):
        return section  # the schema says what is wrong with it
    value = section["file"]
    try:
        path(value)
    except Bad as bad:
        raise BadEntry(str(bad), "file", value) from None
    parts = value.replace("\\", "/").split("/")
    if (value.startswith(("/", "~")) or ".." in parts or ":" in parts[0]
            or not value.lower().endswith(".h5") or not _printable(value)):
        raise BadEntry("a relative path ending in .h5, inside the working directory (no "
                       "absolute path, '..' or '~'; the command line's --output may go "
                       "anywhere)", "file", value)
    here = Path.cwd().resolve()
    folder = (here / value).parent.resolve()  # symbolic links on the way followed
    if folder != here and here not in folder.parents:
        raise BadEntry(f"a path inside the working directory (this one leads to {str(folder)!r} "
                       "through a symbolic link; the command line's --output may go anywhere)",
                       "file", value)
    return section


def portable(raw: dict) -> dict:
    """``raw`` without an ``[output] file`` that :func:`case_output` would refuse (one given
    on the command line), so that the TOML of the effective case can be run again."""
    try:
        case_output(raw.get("output"))
    except Bad:
        return {**raw, "output": {k: v for k, v in raw["output"].items() if k != "file"}}
    return raw


def names(value):
    if isinstance(value, str):
        value = [value]
    if not isinstance(value, list) or not value or not all(_printable(v) for v in value):
        raise Bad("a non-empty list of edge names (strings of printable characters)")
    if len(set(value)) != len(value):
        raise Bad("a list of distinct edge names")
    return list(value)


#: vertices of a polygon (and of a prism's base) at most: the check that it does not cross
#: itself compares every pair of edges (time and memory grow with the square of the count:
#: 1 s and 0.4 GB at 2000), and gmsh puts a node on every vertex, so a finely sampled curve
#: meshes far finer than mesh.size (a 1000-vertex circle: ~190 000 DOFs at size 0.2)
MAX_VERTICES = 1000
#: vertices of a prism's base at most: gmsh's 3D meshing slows sharply with many side faces
#: narrower than the mesh size (a unit circle's prism of depth 0.5 at size 0.2: 90 vertices
#: 3 s, 120 vertices 10 s, 200 vertices 84 s)
MAX_PRISM_VERTICES = 100
PRISM_LIMIT = (f"a prism's base has at most {MAX_PRISM_VERTICES} vertices (gmsh's 3D meshing "
               "slows sharply with many side faces narrower than the mesh size); sample the "
               "base coarser or mesh the body in gmsh (shape = \"file\")")


def points(value):
    if isinstance(value, list) and len(value) > MAX_VERTICES:
        raise Bad(f"at most {MAX_VERTICES} vertices (this list has {len(value)}: the "
                  "self-crossing check and the mesh grow with the square of the count); "
                  "sample the curve coarser or mesh it in gmsh (shape = \"file\")")
    ok = isinstance(value, list) and len(value) >= 3 and all(
        isinstance(p, list) and len(p) == 2
        and all(isinstance(c, (int, float)) and not isinstance(c, bool) and math.isfinite(c)
                for c in p)
        for p in value
    )
    if not ok:
        raise Bad("a list of at least 3 points [x, y] with finite numbers")
    return [[float(c) for c in p] for p in value]


def nodes(value):
    """Mesh nodes: at least 3 points [x, y] (2D) or 4 points [x, y, z] (3D)."""
    dim = len(value[0]) if isinstance(value, list) and value and isinstance(value[0], list) \
        else 0
    ok = dim in (2, 3) and len(value) >= dim + 1 and all(
        isinstance(p, list) and len(p) == dim and all(finite(c) for c in p) for p in value)
    if not ok:
        raise Bad("a list of at least 3 points [x, y] (2D) or at least 4 points [x, y, z] "
                  "(3D), all of one kind, with finite numbers")
    return [[float(c) for c in p] for p in value]


def triple(lo=None):
    """Three finite numbers [x, y, z], each above ``lo`` if given."""
    def check(value):
        if not (isinstance(value, list) and len(value) == 3 and all(finite(v) for v in value)
                and (lo is None or all(v > lo for v in value))):
            raise Bad("three finite numbers [x, y, z]"
                      + ("" if lo is None else f", each above {lo:g}"))
        return [float(v) for v in value]

    return check


def index_rows(width):
    def check(value):
        ok = isinstance(value, list) and len(value) >= 1 and all(
            isinstance(r, list) and len(r) in width
            and all(isinstance(i, int) and not isinstance(i, bool) and i >= 0 for i in r)
            for r in value
        )
        if not ok:
            sizes = " or ".join(str(w) for w in width)
            raise Bad(f"a non-empty list of rows of {sizes} node indices (integers >= 0)")
        return value

    return check


def edge_table(value):
    if not isinstance(value, dict) or not value:
        raise Bad("a table: edge name = [[node, node], ...]")
    out = {}
    for name, rows in value.items():
        if not _printable(name):
            raise Bad(f"edge names of printable characters, got {name!r}")
        try:
            out[name] = index_rows((2,))(rows)
        except Bad as bad:
            raise Bad(f"for edge {name!r}: {bad}") from None
    return out


def face_table(value):
    if not isinstance(value, dict) or not value:
        raise Bad("a table: face name = [[node, node, node], ...] (triangles) or "
                  "[[node, node, node, node], ...] (quadrilaterals)")
    out = {}
    for name, rows in value.items():
        if not _printable(name):
            raise Bad(f"face names of printable characters, got {name!r}")
        try:
            out[name] = index_rows((3, 4))(rows)
        except Bad as bad:
            raise Bad(f"for face {name!r}: {bad}") from None
    return out


def string_list(value):
    if not isinstance(value, list) or not all(_printable(v) for v in value):
        raise Bad("a list of non-empty strings of printable characters")
    return list(value)


def gamma(value):
    if isinstance(value, bool) or value not in (1, -1):
        raise Bad("1 or -1")
    return int(value)


def friction_range(value):
    if (not isinstance(value, list) or len(value) != 2
            or any(isinstance(v, bool) or not isinstance(v, (int, float)) for v in value)):
        raise Bad("two numbers [a, b]")
    a, b = (float(v) for v in value)
    if not (math.isfinite(a) and math.isfinite(b) and a <= 0.0 <= b and a < b):
        raise Bad("[a, b] with a <= 0 <= b and a < b (the branches are followed from "
                  "friction 0, where every mode is a free vibration)")
    return [a, b]


def interval(value):
    if not (isinstance(value, list) and len(value) == 2 and all(finite(v) for v in value)
            and value[0] < value[1]):
        raise Bad("two numbers [a, b] with a < b (finite)")
    return [float(v) for v in value]


def finite(c) -> bool:
    return isinstance(c, (int, float)) and not isinstance(c, bool) and math.isfinite(c)


def vector(value):
    if not (isinstance(value, list) and len(value) == 2 and all(finite(c) for c in value)):
        raise Bad("a vector [x, y] of 2 finite numbers")
    return [float(c) for c in value]


def table_of(check, what):
    def table(value):
        if not isinstance(value, dict) or not value:
            raise Bad(f"a table: edge name = {what}")
        out = {}
        for name, entry in value.items():
            try:
                out[name] = check(entry)
            except Bad as bad:
                raise Bad(f"for edge {name!r}: {bad}") from None
        return out

    return table


def displacement(value):
    """[ux, uy] (constant) or [[a0, ax, ay], [b0, bx, by]]: u = (a0 + ax x + ay y, b0 + ...)."""
    if isinstance(value, list) and len(value) == 2 and all(finite(c) for c in value):
        return [[float(value[0]), 0.0, 0.0], [float(value[1]), 0.0, 0.0]]
    if isinstance(value, list) and len(value) == 2 and all(
            isinstance(r, list) and len(r) == 3 and all(finite(c) for c in r) for r in value):
        return [[float(c) for c in r] for r in value]
    raise Bad("[ux, uy] (constant) or [[a0, ax, ay], [b0, bx, by]] (ux = a0 + ax x + ay y, "
               "uy = b0 + bx x + by y), finite numbers")


def point_forces(value):
    what = "a list of tables {node = i, force = [fx, fy]} or {at = [x, y], force = [fx, fy]}"
    if not isinstance(value, list) or not value:
        raise Bad(what)
    out = []
    for i, entry in enumerate(value):
        ok = isinstance(entry, dict) and set(entry) in ({"node", "force"}, {"at", "force"})
        try:
            if not ok:
                raise Bad(what)
            force = vector(entry["force"])
            if "node" in entry:
                node = entry["node"]
                if isinstance(node, bool) or not isinstance(node, int) or node < 0:
                    raise Bad("node: a node index (integer >= 0)")
                out.append({"node": node, "force": force})
            else:
                out.append({"at": vector(entry["at"]), "force": force})
        except Bad as bad:
            raise Bad(f"entry {i}: {bad}") from None
    return out


def reference(value):
    if finite(value):
        return float(value)
    if isinstance(value, list) and value and all(finite(c) for c in value):
        return [float(c) for c in value]
    raise Bad("a number or a non-empty list of numbers (one per contact node, along t)")


STATUSES = ("free", "stuck", "slip")


def contact_rules(value):
    what = ("a list of tables {from = s0, to = s1, status = 'free'|'stuck'|'slip'[, gamma = 1|-1]"
            "[, slip_angle = degrees]}, s0 and s1 numbers (2D) or pairs [s1, s2] (3D)")
    if not isinstance(value, list):
        raise Bad(what)
    out = []
    for i, rule in enumerate(value):
        try:
            if not isinstance(rule, dict) or not {"from", "to", "status"} <= set(rule) or not \
                    set(rule) <= {"from", "to", "status", "gamma", "slip_angle"}:
                raise Bad(what)
            lo, hi = _rule_end(rule["from"]), _rule_end(rule["to"])
            if np.shape(lo) != np.shape(hi):
                raise Bad("from and to both numbers (2D) or both pairs (3D)")
            if np.any(np.asarray(lo) > np.asarray(hi)):
                raise Bad(f"from <= to (got from = {lo}, to = {hi})")
            status = choice(*STATUSES)(rule["status"])
            for key in ("gamma", "slip_angle"):
                if key in rule and status != "slip":
                    raise Bad(f"{key} only in a rule with status = 'slip'")
            out.append({"from": lo, "to": hi, "status": status,
                        "gamma": gamma(rule.get("gamma", 1)),
                        "slip_angle": (number(-720.0, 720.0)(rule["slip_angle"])
                                       if "slip_angle" in rule else None)})
        except Bad as bad:
            raise Bad(f"rule {i}: {bad}") from None
    return out


def _rule_end(value):
    """An end of a [contact] rule: a number (2D arc length) or a pair of numbers (3D)."""
    if isinstance(value, list):
        if len(value) != 2:
            raise Bad(f"a pair [s1, s2] (got {len(value)} numbers)")
        return [number()(v) for v in value]
    return number()(value)


def subtable(checks: dict, what: str):
    """A non-empty table with some of the keys of ``checks``, each value checked by its check;
    returned with every key (None where absent). ``what``: the keys' meaning, for messages."""
    allowed = ", ".join(checks)

    def check(value):
        if not isinstance(value, dict) or not value:
            raise Bad(f"a table with one or more of {allowed} ({what})")
        out = dict.fromkeys(checks)
        for key, entry in value.items():
            if key not in checks:
                raise BadEntry(f"only the keys {allowed} ({what})", str(key), {key: entry})
            try:
                out[key] = checks[key](entry)
            except Bad as bad:
                raise BadEntry(str(bad), str(key), entry) from None
        return out

    return check
