"""The catalogue of bad inputs: every row is a malformed or meaningless case file or command
line, the exit code it must give (2 bad input, 1 numerical failure) and words its message
must contain. Every row must also give one message on stderr, no traceback, and leave the
directory exactly as it was (no result file, no temporary file, no lock file).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import h5py
import pytest
from helpers import SQUARE_GEO
from typer.testing import CliRunner

from critfric.cli.app import app
from critfric.cli.common import number_options

pytestmark = pytest.mark.once  # the same on both installs: run by `make test` only

runner = CliRunner()

SQUARE = """\
[geometry]
shape = "square"
[boundary]
contact = ["bottom"]
dirichlet = ["top"]
[material]
nu = 0.3
[mesh]
element = "P1"
size = 0.5
"""

FOUR = """\
[geometry]
shape = "mesh"
nodes = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0], [0.5, 0.5]]
triangles = [[0, 1, 4], [1, 2, 4], [2, 3, 4], [3, 0, 4]]
[geometry.edges]
bottom = [[0, 1]]
right = [[1, 2]]
top = [[2, 3]]
left = [[3, 0]]
"""

POLYGON = """\
[geometry]
shape = "polygon"
vertices = {vertices}
[boundary]
contact = ["e0"]
dirichlet = ["e2"]
[mesh]
size = 0.25
"""

BOX = """\
[geometry]
shape = "box"
size = [1.0, 1.0, 1.0]
[boundary]
contact = ["z0"]
dirichlet = ["z1"]
[mesh]
size = 0.5
"""

TETRAHEDRON = """\
[geometry]
shape = "mesh"
nodes = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]
tetrahedra = [[0, 1, 2, 3]]
[geometry.faces]
bottom = [[0, 1, 2]]
side = [[0, 1, 3]]
[boundary]
contact = ["bottom"]
dirichlet = ["side"]
"""

# one wedge (a 6-node prism) in a physical volume: a 3D cell critfric does not mesh with
WEDGE_MSH = """\
$MeshFormat
2.2 0 8
$EndMeshFormat
$PhysicalNames
1
3 1 "body"
$EndPhysicalNames
$Nodes
6
1 0 0 0
2 1 0 0
3 0 1 0
4 0 0 1
5 1 0 1
6 0 1 1
$EndNodes
$Elements
1
1 6 2 1 1 1 2 3 4 5 6
$EndElements
"""

FILE_CASE = """\
[geometry]
shape = "file"
file = "{file}"
{extra}
[boundary]
contact = ["bottom"]
dirichlet = ["top"]
"""


def edit(old: str, new: str, text: str = SQUARE) -> str:
    assert old in text, old
    return text.replace(old, new, 1)


@dataclass(frozen=True)
class Bad:
    """One bad input: files written in a fresh directory, the command line, the exit code and
    the words the one-line message must contain."""

    what: str
    files: dict = field(default_factory=dict)
    args: tuple = ("solve", "case.toml")
    code: int = 2
    words: tuple = ()


def case(what, text, *words, code=2, more=None, named="case.toml"):
    return Bad(what, {"case.toml": text, **(more or {})}, ("solve", "case.toml"), code,
               (named,) + words)


def option(what, *extra, words=()):
    return Bad(what, {"case.toml": SQUARE}, ("solve", "case.toml", *extra), 2, words)


def path(what, lines, *words, options=()):
    """critfric path on the square with ``lines`` in its [path] section."""
    return Bad(what, {"case.toml": SQUARE + "[path]\n" + lines + "\n"},
               ("path", "case.toml", *options), 2, words)


CATALOGUE = [
    # --- the TOML file itself
    case("TOML syntax error", edit("size = 0.5", "size = = 0.5"), "TOML syntax error", "line"),
    Bad("case file not UTF-8", {"case.toml": b"[geometry]\nshape = \"\xff\xfe\"\n"},
        words=("case.toml", "cannot read")),
    case("empty case file", "", "[geometry]", "missing section"),
    case("unknown section", SQUARE + "[solver]\nmethod = 'dense'\n", "'solver'", "allowed"),
    case("unknown key", edit("[mesh]", "[mesh]\nsmoothness = 3"), "mesh.smoothness", "allowed"),
    case("section given as a value", "mesh = 3\n" + edit("[mesh]\nelement = \"P1\"\nsize = 0.5",
                                                         ""), "[mesh]", "must be a table"),
    case("missing geometry.shape", edit('shape = "square"', 'side = 1.0'), "geometry.shape"),
    case("unknown shape", edit('"square"', '"circle"'), "geometry.shape", "'circle'", "square"),
    # --- wrong types
    case("nu given as a string", edit("nu = 0.3", 'nu = "0.3"'), "material.nu", "a number"),
    case("count not an integer", SQUARE + "[solve]\ncount = 1.5\n", "solve.count", "integer"),
    case("structured not a boolean", edit("size = 0.5", "size = 0.5\nstructured = \"yes\""),
         "mesh.structured", "true or false"),
    case("title not a string", "title = 5\n" + SQUARE, "[title]", "string"),
    case("contact not a list of names", edit('contact = ["bottom"]', "contact = 3"),
         "boundary.contact", "edge names"),
    # --- values out of range
    case("nu = 0.5", edit("nu = 0.3", "nu = 0.5"), "material.nu", "[0, 0.5)"),
    case("nu < 0", edit("nu = 0.3", "nu = -0.1"), "material.nu", "[0, 0.5)"),
    case("nu = nan", edit("nu = 0.3", "nu = nan"), "material.nu", "finite"),
    case("E = 0", edit("nu = 0.3", "nu = 0.3\nE = 0"), "material.E", "(0, inf]"),
    case("E < 0", edit("nu = 0.3", "nu = 0.3\nE = -1e3"), "material.E", "-1000"),
    case("size = 0", edit("size = 0.5", "size = 0"), "mesh.size", "(0, inf]"),
    case("size < 0", edit("size = 0.5", "size = -1.0"), "mesh.size", "-1.0"),
    case("size = inf", edit("size = 0.5", "size = inf"), "mesh.size", "finite"),
    case("size absurdly small", edit("size = 0.5", "size = 1e-9"), "mesh.size", "DOFs",
         "memory", "finest mesh size", "--max-dofs"),
    case("size missing", edit("size = 0.5", ""), "mesh.size", "missing"),
    case("count = 0", SQUARE + "[solve]\ncount = 0\n", "solve.count", "[1, 1000]"),
    case("count < 0", SQUARE + "[solve]\ncount = -3\n", "solve.count", "-3"),
    case("gamma = 2", SQUARE + "[solve]\ngamma = 2\n", "solve.gamma", "1 or -1"),
    case("grading = 0", edit("size = 0.5", "size = 0.5\ngrading = 0"), "mesh.grading", "(0, 1]"),
    case("empty output file name", SQUARE + "[output]\nfile = \"\"\n", "output.file", "string"),
    case("unknown element", edit('"P1"', '"P3"'), "mesh.element", "'P3'", "Q2"),
    case("NUL character in the output path", SQUARE + '[output]\nfile = "a\\u0000b.h5"\n',
         "output.file", "NUL"),
    # --- meaningless geometry
    case("self-intersecting polygon", POLYGON.format(vertices="[[0,0],[1,1],[1,0],[0,1]]"),
         "geometry.vertices", "intersects itself"),
    case("repeated polygon vertex", POLYGON.format(vertices="[[0,0],[1,0],[1,0],[1,1],[0,1]]"),
         "geometry.vertices", "coincide"),
    case("polygon with two vertices", POLYGON.format(vertices="[[0,0],[1,0]]"),
         "geometry.vertices", "at least 3 points"),
    case("polygon on one line", POLYGON.format(vertices="[[0,0],[1,0],[2,0]]"),
         "geometry.vertices", "one line"),
    case("edge_names count mismatch",
         POLYGON.format(vertices="[[0,0],[1,0],[1,1],[0,1]]").replace(
             "[boundary]", 'edge_names = ["a", "b"]\n[boundary]'),
         "geometry.edge_names", "one name"),
    case("structured 5-vertex polygon",
         POLYGON.format(vertices="[[0,0],[1,0],[1,1],[0.5,1.5],[0,1]]") + "structured = true\n",
         "mesh.structured", "4-vertex"),
    case("contact edge not straight", edit('contact = ["bottom"]', 'contact = ["bottom", "left"]'),
         "boundary.contact", "straight"),
    case("contact edge with no free node",
         FOUR + '[boundary]\ncontact = ["bottom"]\ndirichlet = ["left", "right"]\n',
         "boundary.contact", "at least one free node"),
    case("no Dirichlet edge", edit('dirichlet = ["top"]', "dirichlet = []"),
         "boundary.dirichlet", "edge names"),
    case("edge both contact and Dirichlet", edit('dirichlet = ["top"]', 'dirichlet = ["bottom"]'),
         "boundary.dirichlet", "both contact and Dirichlet"),
    case("unknown edge name", edit('contact = ["bottom"]', 'contact = ["floor"]'),
         "boundary.contact", "'floor'", "bottom"),
    case("Q1 element on a triangle mesh", FOUR + '[mesh]\nelement = "Q1"\n', "mesh.element",
         "P1 or P2"),
    case("inline node index out of range", edit("[3, 0, 4]", "[3, 0, 9]", FOUR),
         "geometry.triangles", "0..4"),
    case("inline degenerate triangle",
         edit("[0.5, 0.5]]", "[0.5, 0.5], [2.0, 0.0]]", edit("[3, 0, 4]]", "[3, 0, 4], [0, 1, 5]]",
                                                               FOUR)), "degenerate"),
    case("interior edge named as boundary", edit("left = [[3, 0]]", "left = [[3, 0]]\nx = [[0, 4]]",
                                                 FOUR), "geometry.edges.x", "interior edge"),
    case("a piece of the body floats free",
         edit("[0.5, 0.5]]", "[0.5, 0.5], [3, 0], [4, 0], [3.5, 0.5]]",
              edit("[3, 0, 4]]", "[3, 0, 4], [5, 6, 7]]", FOUR))
         + '[boundary]\ncontact = ["bottom"]\ndirichlet = ["top"]\n',
         "boundary.dirichlet", "float"),
    # --- 3D bodies
    case("box size with a zero edge", edit("[1.0, 1.0, 1.0]", "[1.0, 0.0, 1.0]", BOX),
         "geometry.size", "each above 0"),
    case("box size of two numbers", edit("[1.0, 1.0, 1.0]", "[1.0, 1.0]", BOX), "geometry.size",
         "[x, y, z]"),
    case("box origin not finite", edit("[boundary]", "origin = [0, inf, 0]\n[boundary]", BOX),
         "geometry.origin", "finite"),
    case("box with the 2D default boundary", edit('contact = ["z0"]\ndirichlet = ["z1"]\n', "",
                                                   BOX), "boundary.contact",
         "unknown face 'bottom'", "x0, x1, y0, y1, z0, z1"),
    case("box mesh graded", edit("size = 0.5", "size = 0.5\ngrading = 0.1", BOX), "mesh.grading",
         "3D"),
    case("prism depth 0", POLYGON.format(vertices="[[0,0],[1,0],[0,1]]").replace(
        "[boundary]", "depth = 0\n[boundary]").replace('"polygon"', '"prism"'), "geometry.depth",
         "(0, inf]"),
    case("prism edge named like an end face",
         POLYGON.format(vertices="[[0,0],[1,0],[0,1]]").replace('"polygon"', '"prism"').replace(
             "[boundary]", 'edge_names = ["e0", "e1", "z1"]\n[boundary]'),
         "geometry.edge_names", "'z1'", "end face"),
    case("inline tetrahedra without faces", TETRAHEDRON.split("[geometry.faces]")[0],
         "geometry.faces", "missing"),
    case("inline tetrahedra with 2D nodes",
         edit("[0.0, 0.0, 1.0]]", "[1.0, 1.0]]", edit("[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], "
                                                      "[0.0, 1.0, 0.0]", "[[0.0, 0.0], [1.0, "
                                                      "0.0], [0.0, 1.0]", TETRAHEDRON)),
         "geometry.nodes", "[x, y, z]"),
    case("inline tetrahedra named by edges",
         TETRAHEDRON.split("[geometry.faces]")[0] + "[geometry.edges]\nbottom = [[0, 1]]\n",
         "geometry.edges", "mesh of tetrahedra", "[geometry.faces]"),
    case("Q1 element on a tetrahedron mesh", TETRAHEDRON + '[mesh]\nelement = "Q1"\n',
         "mesh.element", "P1 or P2"),
    case("3D .msh with a wedge", FILE_CASE.format(file="body.msh", extra=""), "wedge",
         "tetrahedra only or hexahedra only", named="body.msh", more={"body.msh": WEDGE_MSH}),
    # --- user geometry files
    case("geometry file missing", FILE_CASE.format(file="body.msh", extra=""), "body.msh",
         "no such file"),
    case("geometry file of unknown kind", FILE_CASE.format(file="body.stl", extra=""),
         "geometry.file", ".msh"),
    case("garbage .msh file", FILE_CASE.format(file="body.msh", extra=""),
         "cannot read this gmsh mesh", named="body.msh", more={"body.msh": "$MeshFormat\nfour\n"}),
    case(".geo with a syntax error", FILE_CASE.format(file="body.geo", extra=""),
         "gmsh cannot read", "line 1", named="body.geo", more={"body.geo": "Point(1) = {0, 0;\n"}),
    case(".geo running a shell command", FILE_CASE.format(file="body.geo", extra=""),
         "SystemCall", "shell command", "--trust-geo", named="body.geo",
         more={"body.geo": SQUARE_GEO + 'SystemCall "touch pwned";\n'}),
    case(".geo without the contact group", edit('"bottom"]', '"floor"]',
                                                FILE_CASE.format(file="body.geo", extra="")),
         "boundary.contact", "'floor'", "bottom", more={"body.geo": SQUARE_GEO}),
    case(".geo with an unknown domain", FILE_CASE.format(file="body.geo", extra='domain = "x"'),
         "geometry.domain", "'x'", "domain", named="body.geo", more={"body.geo": SQUARE_GEO}),
    case("mesh size given for a .msh", FILE_CASE.format(file="b.msh", extra="") + "[mesh]\n"
         "size = 0.1\n", "mesh.size", "does not apply"),
    # --- a numerical failure (exit 1): nu so close to 1/2 that the solve loses all accuracy
    case("nu = 0.5 - 1e-14", edit("nu = 0.3", "nu = 0.49999999999999"), "residual",
         "ill-conditioned", "try method = 'arpack'", code=1, named="eigenvector"),
    # --- command lines
    Bad("missing case file", {}, ("solve", "nope.toml"), 2, ("nope.toml", "no such case file")),
    Bad("case path is a directory", {"dir/x": "x"}, ("solve", "dir"), 2, ("dir", "not a file")),
    option("--nu out of range", "--nu", "0.7", words=("case.toml", "material.nu", "0.7")),
    option("--nu not a number", "--nu", "abc", words=("--nu", "'abc'", "finite plain number")),
    option("--element unknown", "--element", "P9", words=("mesh.element", "P9")),
    option("--count 0", "--count", "0", words=("solve.count",)),
    option("--size negative", "--size", "-1", words=("mesh.size",)),
    option("--method unknown", "--method", "lanczos", words=("solve.method", "lanczos")),
    option("unknown option", "--frobnicate", words=("--frobnicate",)),
    Bad("missing case argument", {}, ("solve",), 2, ("Missing argument", "case")),
    option("--max-dofs 0", "--max-dofs", "0", words=("--max-dofs",)),
    option("--max-dofs too small", "--max-dofs", "10", words=("DOFs", "--max-dofs 10",
                                                               "finest mesh size")),
    option("output is a directory", "-o", "out", words=("out", "is a directory")),
    option("output directory missing", "-o", "nowhere/r.h5", words=("nowhere", "does not exist")),
    option("output under a regular file", "-o", "case.toml/r.h5",
           words=("case.toml/r.h5", "Not a directory")),
    option("output in an unwritable directory", "-o", "/proc/critfric-test.h5",
           words=("/proc", "cannot write")),
    option("output file name too long", "-o", "r" * 300 + ".h5", words=("cannot write",
                                                                       "too long")),
    Bad("existing output without --force", {"case.toml": SQUARE, "old.h5": "keep"},
        ("solve", "case.toml", "-o", "old.h5"), 2, ("old.h5", "--force")),
    Bad("table of a missing file", {}, ("table", "none.h5"), 2, ("none.h5", "cannot read")),
    Bad("table of a text file", {"r.h5": "not hdf5"}, ("table", "r.h5"), 2,
        ("r.h5", "cannot read")),
    Bad("table of a truncated result", {"r.h5": "@truncated"}, ("table", "r.h5"), 2,
        ("r.h5", "cannot read")),
    Bad("table of a foreign HDF5 file", {"r.h5": "@foreign"}, ("table", "r.h5"), 2,
        ("r.h5", "not a critfric")),
    # --- critfric path and [path]: all refused by the schema, before any computation
    path("path: unknown parameter", 'parameter = "temperature"', "case.toml", "path.parameter",
         "'friction'", "'load'"),
    path("path: range reversed", "", "path.range", "a < b", options=("--range", "3:1")),
    path("path: range empty", "range = [1.0, 1.0]", "path.range", "a < b"),
    path("path: range of one number", "", "--range", "A:B", options=("--range", "2")),
    path("path: range with a full-width digit", "", "--range", "ASCII",
         options=("--range", "0:\uff13")),
    path("path: range not a list", 'range = "0:3"', "path.range", "two numbers"),
    path("path: friction range below 0", "range = [-0.5, 2.0]", "path.range", "0 <= a"),
    path("path: samples 1", "samples = 1", "path.samples", "[2, 10001]"),
    path("path: samples not an integer", "samples = 10.5", "path.samples", "integer"),
    path("path: node -1", "", "path.node", "integer", options=("--node", "-1")),
    path("path: unknown start", 'start = "guess"', "path.start", "'enumerate'"),
    path("path: max_pieces 0", "max_pieces = 0", "path.max_pieces", "[1, 10000000]"),
    path("path: unknown key", "steps = 10", "path.steps", "allowed", "samples"),
    path("path: load not a table", "load = 3", "path.load", "a table"),
    path("path: load key [load] has but a load lacks", "load = { reference = 0.0 }",
         "path.load.reference", "traction, body_force, points, displacement"),
    path("path: load friction", "load = { friction = 1.0 }", "path.load.friction",
         "only the keys"),
    path("path: bad load value", "load = { body_force = [1.0, nan] }", "path.load.body_force",
         "finite"),
    path("path: load traction on the contact edge", "load = { traction = { bottom = [1, 0] } }",
         "path.load.traction", "'bottom'", "traction-free"),
    path("path: load displacement on a free edge", "load = { displacement = { left = [1, 0] } }",
         "path.load.displacement", "'left'", "Dirichlet edge (top)"),
    path("path: load point by node on a gmsh mesh",
         "load = { points = [{ node = 0, force = [1, 0] }] }", "path.load.points.0", "at = [x, y]"),
    path("path: load path without L1", 'parameter = "load"\nrange = [0.0, 1.0]', "path.load",
         "second load L1"),
    # --- sweeps, plots and exports
    Bad("sweep nu outside [0, 0.5)", {}, ("sweep", "--nu", "0.7"), 2, ("--nu", "0.7", "0.5")),
    Bad("sweep nu list with an empty item", {}, ("sweep", "--nu", "0.1,,0.2"), 2,
        ("--nu", "empty item")),
    Bad("sweep size list ending in a comma", {}, ("sweep", "--size", "0.1,"), 2,
        ("--size", "empty item")),
    Bad("sweep nu range past 0.5", {}, ("sweep", "--nu", "0.6:0.8"), 2, ("--nu", "0.6:0.8")),
    Bad("sweep nu range not numbers", {}, ("sweep", "--nu", "a:b"), 2, ("--nu", "'a'")),
    Bad("sweep nu range of one point", {}, ("sweep", "--nu", "0.1:0.3:1"), 2, ("--nu", ">= 2")),
    Bad("sweep negative size", {}, ("sweep", "--size", "0.1,-1"), 2, ("--size", "positive")),
    Bad("sweep size not a number", {}, ("sweep", "--size", "x"), 2, ("--size", "'x'")),
    Bad("sweep unknown element", {}, ("sweep", "--element", "P1,P7"), 2, ("--element", "P7")),
    Bad("sweep --jobs 0", {}, ("sweep", "--jobs", "0"), 2, ("--jobs",)),
    Bad("sweep with a size too fine for memory", {"case.toml": SQUARE},
        ("sweep", "case.toml", "--nu", "0.3", "--size", "0.1,1e-9"), 2,
        ("case.toml", "mesh.size", "1e-09", "--max-dofs")),
    Bad("sweep over a .geo that runs a command",
        {"case.toml": FILE_CASE.format(file="body.geo", extra=""),
         "body.geo": SQUARE_GEO + 'SystemCall "touch pwned";\n'},
        ("sweep", "case.toml", "--nu", "0.3"), 2, ("body.geo", "SystemCall", "--trust-geo")),
    Bad("sweep output is a directory", {"out/x": "x"}, ("sweep", "--nu", "0.1", "-o", "out"),
        2, ("out", "directory")),
    Bad("sweep output is a solve file", {"r.h5": "@solve"},
        ("sweep", "--nu", "0.1", "-o", "r.h5"), 2, ("r.h5", "--force")),
    Bad("plot of a truncated result", {"r.h5": "@truncated"}, ("plot", "r.h5"), 2,
        ("r.h5", "cannot read")),
    Bad("plot of a foreign HDF5 file", {"r.h5": "@foreign"}, ("plot", "r.h5"), 2,
        ("r.h5", "critfric")),
    Bad("plot of a text file", {"r.h5": "not hdf5"}, ("plot", "r.h5"), 2, ("r.h5", "cannot read")),
    Bad("export of a truncated result", {"r.h5": "@truncated"}, ("export", "r.h5"), 2,
        ("r.h5", "cannot read")),
    Bad("export of a foreign HDF5 file", {"r.h5": "@foreign"}, ("export", "r.h5"), 2,
        ("r.h5", "not a critfric")),
    Bad("export to an unknown format", {"r.h5": "@foreign"}, ("export", "r.h5", "--format",
                                                              "stl"), 2, ("--format", "stl")),
]


def _write(tmp_path, name: str, content) -> None:
    path = tmp_path / name
    path.parent.mkdir(parents=True, exist_ok=True)
    if content == "@foreign":
        with h5py.File(path, "w") as f:
            f["data"] = [1.0, 2.0]
    elif content in ("@truncated", "@solve"):
        res = runner.invoke(app, ["solve", "one-triangle", "-o", str(path)])
        assert res.exit_code == 0, res.output
        if content == "@truncated":
            data = path.read_bytes()
            path.write_bytes(data[: len(data) // 2])
    elif isinstance(content, bytes):
        path.write_bytes(content)
    else:
        path.write_text(content)


def _listing(tmp_path) -> dict:
    return {p.relative_to(tmp_path): p.stat().st_size for p in tmp_path.rglob("*")}


@pytest.mark.parametrize("bad", CATALOGUE, ids=[b.what for b in CATALOGUE])
def test_bad_input(tmp_path, monkeypatch, bad):
    monkeypatch.chdir(tmp_path)
    for name, content in bad.files.items():
        _write(tmp_path, name, content)
    if "out" in bad.args:
        (tmp_path / "out").mkdir(exist_ok=True)
    before = _listing(tmp_path)
    res = runner.invoke(app, list(bad.args))
    assert res.exit_code == bad.code, (res.exit_code, res.output)
    assert res.exception is None or isinstance(res.exception, SystemExit), res.exception
    assert "Traceback" not in res.output and res.stdout == ""
    message = " ".join(res.stderr.split())
    assert message.startswith("critfric: error: "), res.stderr  # the parser's errors too
    assert res.stderr.count("\n") == 1, res.stderr  # one line
    for word in bad.words:
        assert word in message, (word, message)
    assert _listing(tmp_path) == before  # nothing written, nothing left behind
    assert not (tmp_path / "pwned").exists()


def test_the_catalogue_is_large_and_distinct():
    assert len(CATALOGUE) >= 30
    assert len({b.what for b in CATALOGUE}) == len(CATALOGUE)


# values Python's int()/float() take that are no plain ASCII number, and what names them
NOT_PLAIN = [("1_0", "'1_0'"), ("\uff11\uff10", "U+FF11 FULLWIDTH DIGIT ONE"),
             ("\u0663", "U+0663 ARABIC-INDIC DIGIT THREE"), ("nan", "'nan'"),
             ("-inf", "'-inf'"), (" 3 ", "' 3 '"), ("1\x1b[2J", "'1\\x1b[2J'")]


@pytest.mark.parametrize("command", [("solve", "x", "--nu"), ("solve", "x", "--count"),
                                     ("stability", "x", "--steps"), ("sweep", "--grading"),
                                     ("sweep", "--jobs"), ("path", "x", "--samples"),
                                     ("verify", "x", "--off")])
@pytest.mark.parametrize("value,named", NOT_PLAIN, ids=[v for v, _ in NOT_PLAIN])
def test_numeric_options_take_plain_ascii_numbers_only(command, value, named):
    res = runner.invoke(app, [*command, value])
    message = " ".join(res.stderr.split())
    assert res.exit_code == 2 and res.stdout == "", res.output
    assert "Traceback" not in res.output and "\x1b" not in res.stderr
    for word in (command[-1], named, "allowed: a "):
        assert word in message, (word, message)


def test_every_numeric_option_of_every_command_is_plain():
    """A later int or float option gets the plain parser too: each refuses a full-width
    digit, naming itself and the character."""
    options = number_options(app)
    assert {"--nu", "--count", "--max-dofs", "--jobs", "--off", "--node"} <= {
        o for _, o in options} and len(options) >= 20
    for command, option in options:
        res = runner.invoke(app, [command, "x", option, "\uff13"])
        message = " ".join(res.stderr.split())
        assert res.exit_code == 2 and option in message and "U+FF13" in message, (
            command, option, res.output)


def test_plain_numeric_options_still_read_plain_numbers_and_bounds():
    res = runner.invoke(app, ["solve", "one-triangle", "--json", "--nu", "+0.25", "--count",
                              "1", "-o", "/dev/null/x.h5"])
    assert res.exit_code == 2 and "/dev/null" in res.stderr, res.output  # parsed, then refused
    res = runner.invoke(app, ["sweep", "--jobs", "0"])
    assert res.exit_code == 2 and "'0'" in res.stderr and ">= 1" in res.stderr, res.output
