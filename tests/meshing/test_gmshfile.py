"""User geometries from gmsh files: .msh meshes (meshio) and .geo scripts (gmsh), and the
refusal of scripts that can run programs or touch other files."""

from __future__ import annotations

import time

import numpy as np
import pytest
from helpers import SQUARE_GEO

from critfric import loads_case, solve_case
from critfric.errors import CaseError
from critfric.meshing.geometry import rectangle
from critfric.meshing.geoscript import refusals
from critfric.meshing.mesh import build_mesh

pytestmark = pytest.mark.once  # the same on both installs: run by `make test` only


def file_case(path, *, element="P1", extra="", contact="bottom", dirichlet="top"):
    return loads_case(f"""
[geometry]
shape = "file"
file = "{path}"
{extra}
[boundary]
contact = ["{contact}"]
dirichlet = ["{dirichlet}"]
[mesh]
element = "{element}"
""", source=str(path.parent / "case.toml"))


# ------------------------------------------------------------------------ refused scripts
# statement templates: each would create the file {p} (checked after gmsh ran, or not)
HAZARDS = {
    "SystemCall": 'SystemCall "touch {p}";',
    "System": 'System "touch {p}";',
    "NonBlockingSystemCall": 'NonBlockingSystemCall "touch {p}";',
    "StringToName": 'StringToName["SystemCall"] "touch {p}";',
    "S2N": 'S2N[StrCat("System", "Call")] "touch {p}";',
    "Printf": 'Printf("owned") /* > */\n// ) >\n>> "{p}";',
    "Save": 'Save "{p}.msh";',
    "CreateDir": 'CreateDir "{p}";',
    "Include": 'Include "{inc}";',
    "Merge": 'Merge "{inc}";',
    "OnelabRun": 'OnelabRun("client", "touch {p}");',
}


def _script(tmp_path, word: str):
    p = tmp_path / "pwned"
    inc = tmp_path / "inner.geo"
    inc.write_text(f'SystemCall "touch {p}";\n')
    geo = tmp_path / "body.geo"
    geo.write_text(SQUARE_GEO + "// the next line reaches outside\n"
                   + HAZARDS[word].format(p=p, inc=inc) + "\n")
    return geo, p


def _created(p) -> bool:
    return any(p.parent.glob(p.name + "*"))


@pytest.mark.parametrize("word", sorted(HAZARDS))
def test_a_script_that_reaches_outside_is_refused_and_creates_nothing(tmp_path, word):
    geo, p = _script(tmp_path, word)
    with pytest.raises(CaseError) as err:
        solve_case(file_case(geo))
    message = str(err.value)
    assert "body.geo" in message and "line 8" in message and word in message
    assert "--trust-geo" in message
    time.sleep(0.05)  # NonBlockingSystemCall would run in the background
    assert not _created(p)


@pytest.mark.parametrize("word", ["SystemCall", "StringToName", "S2N", "Printf", "Include"])
def test_the_refused_scripts_are_real_threats(tmp_path, word):
    """With --trust-geo the same scripts do create the file: the refusal is what stops them."""
    geo, p = _script(tmp_path, word)
    result = solve_case(file_case(geo), trust_geo=True)
    assert result.critical > 0
    assert _created(p)


def test_a_clean_script_is_not_refused():
    text = SQUARE_GEO + """
lc = 0.1; // Mesh.MeshSizeMax below
Mesh.Algorithm = 6; Mesh.MeshSizeMax = lc;
For i In {1:3}
  x~{i} = i * 1.5e-3;
EndFor
Transfinite Curve{1} = 11; Recombine Surface{1};
If (lc > 0.05) Recombine Surface{1}; EndIf
"""
    assert refusals(text) == []


@pytest.mark.parametrize("statement", ['Printf("%900.3g", 1);', 'Printf("%f", 1e300);',
                                       'Printf("%g' + "A" * 900 + '", 1);', 'Printf("plain");'])
def test_printf_is_refused(statement):
    """gmsh formats Printf into 256-byte stack buffers, unchecked (a long format crashed the
    meshing child with the script's bytes as the return address), and critfric shows none of
    its output."""
    assert "Printf" in [w for _, w, _ in refusals(SQUARE_GEO + statement)]


def test_long_names_are_refused():
    """gmsh writes "Unknown variable '<name>'" into a 1024-byte stack buffer, unchecked: a
    long name, or one built of many ~{} indices, overwrote the child's return addresses."""
    name = "v" * 3000
    found = refusals(SQUARE_GEO + f"If (0)\n{name} = 1;\nEndIf\nx = {name};\n")
    assert found and all("more than 128 characters" in why for _, _, why in found)
    built = "a = 1;\nb = a" + "~{1000000000}" * 120 + ";\n"
    assert [w for _, w, _ in refusals(SQUARE_GEO + built)] == ["a~{...}"]
    assert refusals(SQUARE_GEO + "For i In {1:2}\n  x~{i}~{i} = i;\nEndFor\n") == []


def test_refusals_are_found_anywhere_with_their_line():
    """Code is checked wherever it stands; a comment is not code (gmsh skips it too)."""
    text = ('a = 1e5;\nb = 1e5SystemCall "x";\n/* Include "y"; */ Include "z";\n'
            'Printf("a") >> "f";\n// SystemCall "harmless in a comment";\n')
    assert [(line, word) for line, word, _ in refusals(text)] == [
        (2, "SystemCall"), (3, "Include"), (4, "Printf")]


# ------------------------------------------------------------------------ .geo scripts
@pytest.mark.parametrize("element", ["P1", "P2", "Q1", "Q2"])
def test_geo_square_matches_the_builtin_square(tmp_path, element):
    geo = tmp_path / "body.geo"
    geo.write_text(SQUARE_GEO.replace("0.5}", "0.25}"))
    from_file = solve_case(file_case(geo, element=element))
    assert from_file.element == element and from_file.n_contact >= 3
    builtin = solve_case("unit-square", overrides={"mesh.element": element, "mesh.size": 0.25})
    assert from_file.critical == pytest.approx(builtin.critical, rel=0.02)


def test_geo_with_quads_for_a_triangle_element_is_refused(tmp_path):
    geo = tmp_path / "body.geo"
    geo.write_text(SQUARE_GEO + "Recombine Surface{1};\n")
    with pytest.raises(CaseError, match=r"mesh\.element.*quadrangles"):
        solve_case(file_case(geo, element="P1"))


def test_geo_with_a_curved_edge(tmp_path):
    """A half disk in contact along its diameter, clamped on the arc."""
    geo = tmp_path / "half.geo"
    geo.write_text("""
Point(1) = {-1, 0, 0, 0.2}; Point(2) = {0, 0, 0, 0.2}; Point(3) = {1, 0, 0, 0.2};
Line(1) = {1, 3}; Circle(2) = {3, 2, 1};
Curve Loop(1) = {1, 2}; Plane Surface(1) = {1};
Physical Curve("flat") = {1}; Physical Curve("arc") = {2}; Physical Surface("disk") = {1};
""")
    r = solve_case(file_case(geo, element="P2", contact="flat", dirichlet="arc",
                             extra='domain = "disk"'))
    assert r.n_contact > 5 and np.all(np.abs(r.mesh.points[r.contact_nodes, 1]) < 1e-12)


def test_geo_too_fine_is_refused_before_meshing(tmp_path):
    geo = tmp_path / "body.geo"
    geo.write_text(SQUARE_GEO.replace("0.5}", "1e-5}"))
    start = time.perf_counter()
    with pytest.raises(CaseError, match="finest mesh size that fits is about"):
        solve_case(file_case(geo), max_dofs=10_000)
    assert time.perf_counter() - start < 60  # refused, not meshed (10^10 cells: never ends)


# ------------------------------------------------------------------------ .msh meshes
def _write_msh(path, surfaces: dict, curves: dict, *, version=4.1, binary=False):
    """Write a gmsh file with gmsh itself: ``surfaces`` {name: (points, cells)} (discrete
    surfaces, first-order cells), ``curves`` {name: (surface name, node pairs)} (a name may
    repeat a curve of another name: one curve in two physical groups)."""
    import gmsh

    gmsh.initialize(readConfigFiles=False, interruptible=False)  # keep Python's Ctrl-C
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.model.add("written")
        offsets, curve_of = {}, {}
        start = 1
        for tag, (name, (points, cells)) in enumerate(surfaces.items(), start=1):
            gmsh.model.addDiscreteEntity(2, tag)
            nodes = np.arange(start, start + len(points))
            gmsh.model.mesh.addNodes(2, tag, nodes, np.column_stack(
                [points, np.zeros(len(points))]).ravel())
            gmsh.model.mesh.addElementsByType(tag, 2 if cells.shape[1] == 3 else 3, [],
                                              (cells + start).ravel())
            gmsh.model.addPhysicalGroup(2, [tag], name=name)
            offsets[name], start = start, start + len(points)
        for name, (surface, pairs) in curves.items():
            key = pairs.tobytes()
            if key not in curve_of:
                curve_of[key] = len(curve_of) + 1
                gmsh.model.addDiscreteEntity(1, curve_of[key])
                gmsh.model.mesh.addElementsByType(curve_of[key], 1, [],
                                                  (pairs + offsets[surface]).ravel())
            gmsh.model.addPhysicalGroup(1, [curve_of[key]], name=name)
        gmsh.option.setNumber("Mesh.MshFileVersion", version)
        gmsh.option.setNumber("Mesh.Binary", int(binary))
        gmsh.write(str(path))
    finally:
        gmsh.finalize()


@pytest.mark.parametrize("element,version,binary", [("P1", 4.1, False), ("P2", 2.2, False),
                                                    ("Q1", 4.1, True), ("Q2", 2.2, True)])
def test_msh_gives_the_same_eigenvalues_as_the_same_mesh_inline(tmp_path, element, version,
                                                               binary):
    first = "P1" if element[0] == "P" else "Q1"
    mesh = build_mesh(rectangle(1.0, 1.0), size=0.25, element=first, structured=True)
    msh = tmp_path / "body.msh"
    curves = {n: ("domain", f[:, :2]) for n, f in mesh.edges.items()}
    curves["contact"] = curves["bottom"]  # the same curve in two physical groups
    _write_msh(msh, {"domain": (mesh.points, mesh.cells)}, curves, version=version,
               binary=binary)
    from_file = solve_case(file_case(msh, element=element, contact="contact"))
    cells = "triangles" if first == "P1" else "quads"
    edges = "\n".join(f"{n} = {f[:, :2].tolist()}" for n, f in mesh.edges.items())
    inline = solve_case(loads_case(f"""
[geometry]
shape = "mesh"
nodes = {mesh.points.tolist()}
{cells} = {mesh.cells.tolist()}
[geometry.edges]
{edges}
[mesh]
element = "{element}"
"""))
    assert from_file.n_dofs == inline.n_dofs
    np.testing.assert_allclose(from_file.positive, inline.positive, rtol=1e-12)


def test_msh_domain_picks_one_surface(tmp_path):
    mesh = build_mesh(rectangle(1.0, 1.0), size=0.5, element="P1", structured=True)
    msh = tmp_path / "two.msh"
    far = mesh.points + [5.0, 0.0]  # a second, disjoint square
    _write_msh(msh, {"body": (mesh.points, mesh.cells), "other": (far, mesh.cells)},
               {n: ("body", mesh.edges[n]) for n in ("bottom", "top")})
    body = solve_case(file_case(msh, extra='domain = "body"'))
    assert body.mesh.n_nodes == len(mesh.points)
    with pytest.raises(CaseError, match="float"):  # both squares: the far one is not held
        solve_case(file_case(msh))
    with pytest.raises(CaseError, match=r"geometry\.domain.*'bdy'.*allowed: body, other"):
        solve_case(file_case(msh, extra='domain = "bdy"'))


def test_geo_whose_mesh_is_too_large_is_refused_from_its_curves(tmp_path):
    """Transfinite counts: refused from the curves' mesh, before the surface is meshed."""
    geo = tmp_path / "body.geo"
    geo.write_text(SQUARE_GEO + "Transfinite Curve{1, 3} = 40; Transfinite Curve{2, 4} = 40;\n"
                   "Transfinite Surface{1};\n")
    with pytest.raises(CaseError, match=r"body\.geo.*segments up to 0\.0256.*gives about "
                       r"3\.68e\+03 DOFs"):
        solve_case(file_case(geo), max_dofs=1000)
    assert solve_case(file_case(geo), max_dofs=4000).n_dofs > 2000
