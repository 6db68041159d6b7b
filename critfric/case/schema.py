"""Case files: the TOML schema, strict validation, overrides and the shipped cases.

A case is a TOML file with the sections ``[geometry]``, ``[boundary]``, ``[material]``,
``[mesh]``, ``[solve]``, ``[output]`` and those of single commands (see ``SCHEMA``; the
manual's case-file reference is generated from it). Validation is strict: an unknown key, a
wrong type or an out-of-range value is a :class:`CaseError` that names the file, the dotted
key, the value and what is allowed.
"""

from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import tomli_w

from ..case import checks as c
from ..case import geometry3d as g3
from ..case.pathkeys import LOAD_KEYS, PARAMETERS, STARTS, check_loads
from ..errors import CaseError
from ..fem.contact3d import LAWS
from ..fem.elements import NAMES

MAX_CASE_BYTES = 16 << 20  # a case file (inline meshes included) up to this size
MAX_DEPTH = 8  # tables and arrays nested at most this deep (the schema needs 4)
NUMBER_RANGE = (1e-100, 1e100)  # magnitudes of nonzero numbers: squares stay finite
SHAPES = ("square", "rectangle", "parallelogram", "polygon", "mesh", "file") + g3.SHAPES_3D
METHODS = ("auto", "arpack", "dense")
BACKENDS = ("auto", "scipy", "pardiso")  # linear solvers: critfric.linsolve.BACKENDS


POSITIVE = c.number(0.0, lo_open=True)
MATERIAL = c.number(0.0, lo_open=True, magnitude=c.MATERIAL_RANGE)  # E, density: solved as 1

#: ``[mesh] grading`` of a sweep that extrapolates (3+ sizes) when the case sets none: the
#: singular points' share of the h -> 0 error shrinks with g (docs/validation.md: from 0.1
#: to 0.05, 18% more DOFs, inclined-body Q1 limits 2.1e-6 -> 9.0e-7 off the reference)
SWEEP_GRADING = 0.05
LOAD = {
    "friction": c.Key(c.number(0.0), None, "friction coefficient of the static problem (2.8)"),
    "traction": c.Key(c.table_of(c.vector, "[tx, ty]"), None,
                    "constant traction on traction-free edges {name = [tx, ty]}"),
    "body_force": c.Key(c.vector, None, "body force [fx, fy] (force per unit area)"),
    "points": c.Key(c.point_forces, None,
                  "point forces [{node = i or at = [x, y], force = [fx, fy]}, ...]"),
    "displacement": c.Key(c.table_of(c.displacement, "[ux, uy] or [[a0, ax, ay], [b0, bx, by]]"),
                        None, "prescribed displacement per Dirichlet edge (others: zero)"),
    "reference": c.Key(c.reference, 0.0, "reference tangential displacement u^r: one value or "
                     "one per contact node, sorted along t"),
}

SCHEMA: dict[str, dict[str, c.Key]] = {
    "geometry": {
        "shape": c.Key(c.choice(*SHAPES), c.REQUIRED, "the body: " + ", ".join(SHAPES)),
        "side": c.Key(POSITIVE, 1.0, "square: side length"),
        "width": c.Key(POSITIVE, c.REQUIRED, "rectangle: width"),
        "height": c.Key(POSITIVE, c.REQUIRED, "rectangle, parallelogram: height H"),
        "base": c.Key(POSITIVE, c.REQUIRED, "parallelogram: base length L (the bottom edge)"),
        "offset": c.Key(c.number(), c.REQUIRED, "parallelogram: signed shift L' of the top edge"),
        "vertices": c.Key(c.points, c.REQUIRED, "polygon, prism: [[x, y], ...]"),
        "edge_names": c.Key(c.string_list, None, "polygon, prism: name of edge i (vertex i -> "
                            "i+1; of a prism: of the side face over it)"),
        "nodes": c.Key(c.nodes, c.REQUIRED, "mesh: node coordinates [[x, y], ...] or [[x, y, "
                       "z], ...]"),
        "triangles": c.Key(c.index_rows((3,)), None, "mesh: triangles [[a, b, c], ...]"),
        "quads": c.Key(c.index_rows((4,)), None, "mesh: quadrilaterals [[a, b, c, d], ...]"),
        "edges": c.Key(c.edge_table, None, "mesh (2D): named boundary edges {name = [[a, b], "
                       "...]}"),
        "file": c.Key(c.path, c.REQUIRED, "file: a gmsh .msh mesh or .geo script, relative to the "
                    "case file; boundary edges are its named physical curves"),
        "domain": c.Key(c.names, None, "file: physical surfaces (2D) or volumes (3D) of the body "
                        "[all of them]"),
        **g3.KEYS,
    },
    "boundary": {
        "contact": c.Key(c.names, ["bottom"], "edges of Gamma_C (one straight segment)"),
        "dirichlet": c.Key(c.names, ["top"], "clamped edges Gamma_D (at least one)"),
    },
    "material": {
        "E": c.Key(MATERIAL, 1.0, "Young modulus (no friction value depends on it)"),
        "nu": c.Key(c.number(0.0, 0.5, hi_open=True), 0.3, "Poisson ratio in [0, 0.5)"),
        "density": c.Key(MATERIAL, 1.0, "mass density rho (critfric stability: frequencies "
                         "scale as sqrt(E / rho); thresholds do not depend on it)"),
    },
    "mesh": {
        "element": c.Key(c.choice(*NAMES), "P1", "finite element: " + ", ".join(NAMES)),
        "size": c.Key(POSITIVE, c.REQUIRED, "target element size h (gmsh shapes)"),
        "structured": c.Key(c.boolean, False, "transfinite mesh (4-vertex shapes only)"),
        "grading": c.Key(c.number(0.0, 1.0, lo_open=True), None,
                       "size factor g in (0, 1] at every singular point (ends of Gamma_C, "
                       "state junctions, corners where the condition changes, re-entrant "
                       f"corners) [sweeps with 3+ sizes: {SWEEP_GRADING:g}]"),
    },
    "solve": {
        "method": c.Key(c.choice(*METHODS), "auto", "eigen solver: " + ", ".join(METHODS)),
        "backend": c.Key(c.choice(*BACKENDS), "auto",
                       "sparse linear solver: auto (the fastest available), scipy, pardiso"),
        "count": c.Key(c.integer(1, 1000), 1, "number of lowest positive critical coefficients"),
        "shift": c.Key(c.number(-1e6, 1e6), 0.0, "look for eigenvalues nearest this friction "
                     "value (|alpha| above 1e6 counts as infinite)"),
        "gamma": c.Key(c.gamma, 1, "slip sign of every contact node (+1 or -1)"),
        "tol": c.Key(c.number(0.0, 1e-2), 1e-12, "ARPACK relative tolerance of the Ritz "
                     "values (0: machine precision)"),  # 1e-12: the dense values to ~1e-14
        "maxiter": c.Key(c.integer(1, 10**7), None, "ARPACK iteration cap (default: ARPACK's)"),
        "real_tol": c.Key(c.number(0.0, 1e-2), 1e-8, "|Im a| <= real_tol |a| counts as real"),
        "slip_angle": c.Key(c.number(-720.0, 720.0), 0.0, "3D: slip direction, degrees from t1 "
                            "towards t2 in the contact plane"),
        "direction_law": c.Key(c.choice(*LAWS), "rate", "3D: the slip direction follows the "
                               "slip rate (rate) or is prescribed (frozen)"),
    },
    "load": LOAD,
    "contact": {
        "source": c.Key(c.choice("rules", "coulomb"), "rules", "contact state of the eigenproblem: "
                      "'rules' below, or 'coulomb': the state of the static solution of [load]"),
        "default": c.Key(c.choice(*c.STATUSES), "slip", "status of contact nodes no rule covers"),
        "rules": c.Key(c.contact_rules, None, "[{from = s0, to = s1, status, gamma, slip_angle}]: "
                     "status of the contact nodes at s in [s0, s1] (2D: arc length along t; "
                     "3D: [s1, s2] along t1, t2) (later rules win)"),
    },
    "stability": {
        "modes": c.Key(c.integer(1, 200), 10, "lowest-frequency mode pairs followed along friction"),
        "friction": c.Key(c.friction_range, None, "signed friction range [a, b], a <= 0 <= b, "
                          "followed from 0 both ways [default: 1.25 x the larger |static "
                          "coefficient|, else 10]"),
        "steps": c.Key(c.integer(10, 5000), 200, "friction steps each way that locate the "
                       "thresholds (then found exactly)"),
    },
    "path": {
        "parameter": c.Key(c.choice(*PARAMETERS), "friction", "the parameter followed: the "
                           "friction coefficient (load of [load] fixed), or the load factor t "
                           "of L0 + t L1 (friction of [load] fixed)"),
        "range": c.Key(c.interval, None, "parameter range [a, b], a < b (friction: a >= 0)"),
        "start": c.Key(c.choice(*STARTS), "auto", "the solutions the curves start from: auto "
                       "(every solution by enumeration when there are at most 8 contact nodes, "
                       "else the Newton solution), newton, enumerate"),
        "samples": c.Key(c.integer(2, 10001), 101, "parameter values, evenly spaced with the "
                         "ends, at which every curve holds a point and (small problems) every "
                         "solution is enumerated"),
        "node": c.Key(c.integer(0, 2**31), None, "contact node (index along t) whose tangential "
                      "displacement the diagram shows [the one that moves most]"),
        "load": c.Key(c.subtable({k: LOAD[k].check for k in LOAD_KEYS}, "those of [load] that "
                                 "describe a load"), None, "the second load L1 of a load path"),
        "max_pieces": c.Key(c.integer(1, 10**7), 20000, "refuse a path that would need more "
                            "pieces than this"),
    },
    "output": {
        "file": c.Key(c.path, None, "HDF5 result file (default: <case name>.h5)"),
        "modes": c.Key(c.boolean, True, "store the eigenfunctions of the critical eigenvalues"),
    },
}

TOP_LEVEL = {"title": c.Key(c.string, None, "a title for tables and plots")}

SHAPE_KEYS = {
    "square": {"side"},
    "rectangle": {"width", "height"},
    "parallelogram": {"base", "height", "offset"},
    "polygon": {"vertices", "edge_names"},
    "mesh": {"nodes", "triangles", "quads", "edges"} | g3.MESH_KEYS,
    "file": {"file", "domain"},
    **g3.SHAPE_KEYS,
}

# CLI override name -> dotted key
OVERRIDES = {
    "nu": "material.nu",
    "element": "mesh.element",
    "size": "mesh.size",
    "count": "solve.count",
    "shift": "solve.shift",
    "method": "solve.method",
    "backend": "solve.backend",
    "slip_angle": "solve.slip_angle",
    "direction_law": "solve.direction_law",
    "output": "output.file",
    "modes": "stability.modes",
    "friction": "stability.friction",
    "steps": "stability.steps",
    **{k: f"path.{k}" for k in ("parameter", "range", "start", "samples", "node")},
}


# ----------------------------------------------------------------------------- the case
@dataclass(frozen=True)
class Case:
    """A validated case: one plain dict per section, every default filled in."""

    name: str
    source: str
    geometry: dict
    boundary: dict
    material: dict
    mesh: dict
    solve: dict
    output: dict
    title: str | None = None
    text: str = ""
    raw: dict = field(default_factory=dict, repr=False)
    load: dict = field(default_factory=dict)
    contact: dict = field(default_factory=dict)
    stability: dict = field(default_factory=dict)
    path: dict = field(default_factory=dict)

    def to_toml(self) -> str:
        """The effective case (overrides applied) as TOML: re-running it gives the same run
        (an --output outside the working directory left out: the re-run writes its default)."""
        return tomli_w.dumps(c.portable(self.raw))

    def inputs(self) -> list[Path]:
        """The files this case reads: the case file itself and its gmsh file, if any."""
        files = [Path(self.source)] if Path(self.source).is_file() else []
        return files + ([geometry_file(self)] if self.geometry.get("shape") == "file" else [])

    def with_overrides(self, overrides: dict[str, Any] | None) -> Case:
        """A new validated case with dotted-key ``overrides`` applied."""
        return from_dict(self.raw, source=self.source, name=self.name, text=self.text,
                         overrides=overrides)


def _shipped_dir() -> Path:
    installed = Path(__file__).parent / "shipped"  # a wheel: pyproject.toml puts cases/ here
    return installed if installed.is_dir() else Path(__file__).parents[2] / "cases"


def shipped_cases() -> dict[str, Path]:
    """Built-in case names (``inclined-body``) -> shipped TOML files."""
    return {p.stem.replace("_", "-"): p for p in sorted(_shipped_dir().glob("*.toml"))}


def resolve(case: str | Path) -> Path:
    """A path to an existing case file, or the file of a shipped case name."""
    path = Path(case)
    if path.is_file():
        return path
    shipped = shipped_cases()
    key = str(case).replace("_", "-").removesuffix(".toml")
    if key in shipped and not path.exists():
        return shipped[key]
    if path.exists():
        raise CaseError("is not a file", file=str(path))
    names = ", ".join(shipped)
    raise CaseError(f"no such case file, and not a shipped case name ({names})", file=str(path))


def load_case(case: str | Path, *, overrides: dict[str, Any] | None = None) -> Case:
    """Read and validate a case file (or a shipped case name), with dotted-key overrides."""
    path = resolve(case)
    try:
        if path.stat().st_size > MAX_CASE_BYTES:
            raise CaseError(f"is {path.stat().st_size >> 20} MB; allowed: case files up to "
                            f"{MAX_CASE_BYTES >> 20} MB (a larger mesh belongs in a .msh file)",
                            file=str(path))
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise CaseError(f"cannot read the case file: {exc}", file=str(path)) from None
    return loads_case(text, source=str(path), name=path.stem, overrides=overrides)


def as_case(case: Case | dict | str | Path, *, overrides: dict[str, Any] | None = None
            ) -> Case:
    """A :class:`Case` from a case, a dict of sections, a case file path or a shipped name,
    with dotted-key ``overrides`` applied."""
    if isinstance(case, dict):
        return from_dict(case, overrides=overrides)
    if not isinstance(case, Case):
        return load_case(case, overrides=overrides)
    return case.with_overrides(overrides) if overrides else case


def loads_case(text: str, *, source: str = "<string>", name: str = "case",
               overrides: dict[str, Any] | None = None) -> Case:
    """Parse and validate TOML text."""
    if len(text) > MAX_CASE_BYTES:
        raise CaseError(f"has {len(text)} characters; allowed: up to {MAX_CASE_BYTES}",
                        file=source)
    try:
        raw = tomllib.loads(text.removeprefix("\ufeff"))
    except tomllib.TOMLDecodeError as exc:
        raise CaseError(f"TOML syntax error: {exc}", file=source) from None
    except RecursionError:
        raise CaseError("arrays or tables nested too deeply; allowed: the nesting of the case "
                        "schema (a few levels)", file=source) from None
    return from_dict(raw, source=source, name=name, text=text, overrides=overrides)


def _short(value) -> str:
    """repr(value), cut to 80 characters for a message."""
    text = repr(value)
    return text if len(text) <= 80 else text[:60] + f"... ({len(text)} characters)"


def _check_numbers(value, source: str, key: str, depth: int = 0) -> None:
    """Every number of a case within what critfric computes with (no overflow when squared,
    no integer beyond 64 bits), every nesting within MAX_DEPTH."""
    if depth > MAX_DEPTH:
        raise CaseError(f"nested more than {MAX_DEPTH} levels deep; allowed: the nesting of "
                        "the case schema", file=source, key=key.lstrip(".") or None)
    if isinstance(value, dict):
        for k, v in value.items():
            _check_numbers(v, source, f"{key}.{k}", depth + 1)
    elif isinstance(value, list):
        for i, v in enumerate(value):
            _check_numbers(v, source, f"{key}.{i}", depth + 1)
    elif isinstance(value, bool):
        return
    elif isinstance(value, int) and abs(value) >= 2**63:
        raise CaseError(f"got an integer of {len(str(abs(value)))} digits; allowed: integers "
                        "below 2^63", file=source, key=key.lstrip("."))
    elif isinstance(value, float) and value != 0 and key not in c.SCALED_KEYS and not (
            NUMBER_RANGE[0] <= abs(value) <= NUMBER_RANGE[1] or not math.isfinite(value)):
        raise CaseError(f"got {value:g}; allowed: numbers of magnitude in [{NUMBER_RANGE[0]:g}, "
                        f"{NUMBER_RANGE[1]:g}] (or 0)", file=source, key=key.lstrip("."))


def _apply_overrides(raw: dict, overrides: dict[str, Any], source: str) -> dict:
    merged = {k: dict(v) if isinstance(v, dict) else v for k, v in raw.items()}
    for dotted, value in overrides.items():
        if value is None:
            continue
        section, _, key = dotted.partition(".")
        if section not in SCHEMA or key not in SCHEMA[section]:
            raise CaseError(f"unknown override key {dotted!r}", file=source, key=dotted)
        if not isinstance(merged.get(section, {}), dict):
            raise CaseError("must be a table", file=source, key=section)
        merged.setdefault(section, {})[key] = value
    return merged


def from_dict(raw: dict, *, source: str = "<dict>", name: str = "case", text: str = "",
              overrides: dict[str, Any] | None = None) -> Case:
    """Validate a parsed case dict; return a :class:`Case` with all defaults filled."""
    if not isinstance(raw, dict):
        raise CaseError(f"got a {type(raw).__name__}; allowed: a table of sections", file=source)
    _check(c.Key(c.case_output, None, ""), raw.get("output"), source, "output")
    if overrides:  # (--output may go anywhere; the case file's own [output] file may not)
        raw = _apply_overrides(raw, overrides, source)
    _check_numbers(raw, source, "")
    for key in raw:
        if key not in SCHEMA and key not in TOP_LEVEL:
            allowed = ", ".join(f"[{s}]" for s in SCHEMA) + ", " + ", ".join(TOP_LEVEL)
            raise CaseError(f"unknown section or key {key!r}; allowed: {allowed}",
                            file=source, key=key)
    title = _check(TOP_LEVEL["title"], raw["title"], source, "title") if "title" in raw else None
    if not isinstance(raw.get("geometry"), dict):
        raise CaseError("missing section [geometry] (a table with at least 'shape')",
                        file=source, key="geometry")
    sections = {}
    for section, keys in SCHEMA.items():
        given = raw.get(section, {})
        if not isinstance(given, dict):
            raise CaseError("must be a table", file=source, key=section)
        active = _active_keys(section, given, source)
        values = {}
        for key in given:
            if key not in keys or key not in active:
                allowed = ", ".join(sorted(active))
                raise CaseError(f"unknown key {key!r} here; allowed: {allowed}",
                                file=source, key=f"{section}.{key}")
        for key in sorted(active):
            spec = keys[key]
            dotted = f"{section}.{key}"
            if key in given:
                values[key] = _check(spec, given[key], source, dotted)
            elif spec.default is c.REQUIRED:
                raise CaseError(f"missing key ({spec.doc})", file=source, key=dotted)
            else:
                values[key] = spec.default
        sections[section] = values
    _check_consistency(sections, source)
    return Case(name=name, source=source, title=title, text=text, raw=raw, **sections)


def _active_keys(section: str, given: dict, source: str) -> set[str]:
    keys = set(SCHEMA[section])
    if section == "geometry":
        shape = _check(SCHEMA["geometry"]["shape"], given.get("shape"), source, "geometry.shape")
        return {"shape"} | SHAPE_KEYS[shape]
    if section == "mesh" and given.get("size") is None:
        keys.discard("size")  # made required again below for gmsh shapes
    return keys


def _check(spec: c.Key, value, source: str, dotted: str):
    try:
        return spec.check(value)
    except c.Bad as bad:  # a BadEntry names an entry of a table (path.load.traction)
        entry = isinstance(bad, c.BadEntry)
        raise CaseError(f"got {_short(bad.value if entry else value)}; allowed: {bad}",
                        file=source, key=f"{dotted}.{bad.key}" if entry else dotted) from None


def _check_consistency(s: dict, source: str) -> None:
    geo, mesh, bnd = s["geometry"], s["mesh"], s["boundary"]
    shape = geo["shape"]
    if shape == "mesh":
        names = g3.inline_names(geo, mesh, source)
    elif shape in g3.SHAPES_3D:
        names = g3.solid_names(geo, mesh, source)
    elif shape == "file":
        _check_file_shape(geo, mesh, source)
        names = None  # the file's physical groups: checked when it is read
    else:
        if mesh.get("size") is None:
            raise CaseError("missing key (target element size h, a positive number)",
                            file=source, key="mesh.size")
        if shape == "polygon":
            n = len(geo["vertices"])
            names = set(geo["edge_names"] or [f"e{i}" for i in range(n)])
            if geo["edge_names"] is not None and len(geo["edge_names"]) != n:
                raise CaseError(f"got {len(geo['edge_names'])} names for {n} edges; allowed: "
                                "one name per edge", file=source, key="geometry.edge_names")
        else:
            names = {"bottom", "right", "top", "left"}
    for key in ("contact", "dirichlet"):
        unknown = [e for e in bnd[key] if names is not None and e not in names]
        if unknown:
            what = "face" if g3.is_solid(geo) else "edge"
            raise CaseError(f"unknown {what} {unknown[0]!r}; allowed: "
                            + ", ".join(sorted(names)), file=source, key=f"boundary.{key}")
    both = set(bnd["contact"]) & set(bnd["dirichlet"])
    if both:
        raise CaseError(f"edge {sorted(both)[0]!r} is both contact and Dirichlet; an edge has "
                        "one condition", file=source, key="boundary.dirichlet")
    mesh.setdefault("size", None)
    check_loads(s, names, source)


GMSH_SUFFIXES = (".msh", ".geo")


def _check_file_shape(geo: dict, mesh: dict, source: str) -> None:
    suffix = Path(geo["file"]).suffix.lower()
    if suffix not in GMSH_SUFFIXES:
        raise CaseError(f"got {geo['file']!r}; allowed: a gmsh mesh (.msh) or script (.geo)",
                        file=source, key="geometry.file")
    for key in ("structured", "grading") + (("size",) if suffix == ".msh" else ()):
        if mesh.get(key) not in (None, False):
            raise CaseError(f"does not apply to a {suffix} file (shape = 'file')",
                            file=source, key=f"mesh.{key}")


def geometry_file(case: Case) -> Path:
    """The gmsh file of a ``shape = "file"`` case; a relative path is relative to the case file
    (to the current directory for a case given as text)."""
    path = Path(case.geometry["file"]).expanduser()
    base = Path(case.source).parent if Path(case.source).is_file() else Path(".")
    return path if path.is_absolute() else base / path
