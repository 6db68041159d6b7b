"""The command line, in-process: exit codes, JSON on stdout, the result file."""

from __future__ import annotations

import json

import h5py
import numpy as np
import pytest
from helpers import CASES, four_triangles_alpha, one_triangle_alpha, run_cli, square_case


@pytest.mark.parametrize("nu", [0.1, 0.3, 0.45])
def test_solve_one_triangle_json(tmp_path, nu):
    out = tmp_path / "r.h5"
    res = run_cli("solve", CASES / "one_triangle.toml", "--nu", nu, "-o", out, "--json")
    assert res.exit_code == 0, res.output
    summary = json.loads(res.stdout)
    assert summary["positive"] == pytest.approx([one_triangle_alpha(nu)], rel=1e-12)
    assert set(summary) >= {"positive", "negative", "complex_count", "n_dofs", "n_contact",
                            "element", "nu", "h", "seconds"}
    assert out.exists()


def test_solve_by_shipped_name_writes_a_self_describing_file(tmp_path):
    out = tmp_path / "four.h5"
    res = run_cli("solve", "four-triangles", "--nu", 0.25, "--output", out, "--json")
    assert res.exit_code == 0, res.output
    with h5py.File(out) as f:
        a = f.attrs
        assert a["kind"] == "solve" and a["nu"] == 0.25 and a["n_contact"] == 2
        assert "nu = 0.25" in a["case_toml"] and "Fig. 3" in a["case_text"]
        pos = f["critical/positive"][()]
        np.testing.assert_allclose(pos, [four_triangles_alpha(0.25)], rtol=1e-10)
        np.testing.assert_allclose(f["critical/negative"][()], -pos, rtol=1e-10)
        assert f["eigen/alpha"].dtype == np.complex128
        mode = f["modes/positive_0"]
        assert mode["phi"].shape == (5, 2) and mode["theta_n"].shape == (2,)
        assert mode.attrs["alpha"] == pytest.approx(pos[0])
        assert f["mesh/points"].shape == (5, 2) and f["mesh/cells"].shape == (4, 3)
        np.testing.assert_array_equal(f["mesh/contact_nodes"][()], [0, 1])
    table = run_cli("table", out)
    assert table.exit_code == 0 and "four_triangles" in table.stdout


def test_overrides_reach_the_solver(tmp_path):
    case = tmp_path / "sq.toml"
    case.write_text(square_case(size=0.5))
    res = run_cli("solve", case, "--element", "Q2", "--size", 0.25, "--method", "arpack",
              "--count", 2, "-o", tmp_path / "o.h5", "--json")
    assert res.exit_code == 0, res.output
    s = json.loads(res.stdout)
    assert s["element"] == "Q2" and s["method"].startswith("arpack")
    assert len(s["positive"]) >= 2


def test_existing_output_needs_force(tmp_path):
    out = tmp_path / "r.h5"
    assert run_cli("solve", "one-triangle", "-o", out).exit_code == 0
    again = run_cli("solve", "one-triangle", "-o", out)
    assert again.exit_code == 2 and "--force" in again.stderr
    assert run_cli("solve", "one-triangle", "-o", out, "--force").exit_code == 0


BAD_EDITS = {
    "syntax": ("size = 0.5", "size = = 0.5", "TOML syntax error"),
    "unknown key": ("[mesh]", "[mesh]\nsmoothness = 3", "mesh.smoothness"),
    "nu = 0.5": ("nu = 0.3", "nu = 0.5", "material.nu"),
    "negative size": ("size = 0.5", "size = -1.0", "mesh.size"),
    "unknown element": ('element = "P1"', 'element = "P7"', "mesh.element"),
    "no dirichlet": ("[solve]", "[boundary]\ndirichlet = []\n[solve]", "boundary.dirichlet"),
    "not straight": ("[solve]", "[boundary]\ncontact = ['bottom', 'left']\n[solve]",
                     "boundary.contact"),
}


@pytest.mark.parametrize("name", sorted(BAD_EDITS))
def test_bad_case_files_exit_2_and_write_nothing(tmp_path, name):
    old, new, key = BAD_EDITS[name]
    text = square_case(size=0.5)
    assert old in text
    case = tmp_path / "bad.toml"
    case.write_text(text.replace(old, new, 1))
    out = tmp_path / "out.h5"
    res = run_cli("solve", case, "-o", out)
    assert res.exit_code == 2, res.output
    assert key in res.stderr and "bad.toml" in res.stderr
    assert "Traceback" not in res.output
    assert list(tmp_path.iterdir()) == [case]


def test_cases_lists_shipped_names():
    res = run_cli("cases")
    assert res.exit_code == 0 and "inclined-body" in res.stdout


@pytest.mark.parametrize("command", ["solve", "cases", "table", "sweep", "plot", "export",
                                     "solutions", "verify"])
def test_help_is_plain_text_with_literal_brackets_and_examples(command):
    res = run_cli(command, "--help")
    assert res.exit_code == 0
    text = res.output
    assert "Examples:" in text and f"critfric {command}" in text
    assert not set("╭╮╰╯│─") & set(text)  # no boxes: readable in a log or a dumb terminal
    if command == "solve":
        assert "[material] nu" in text and "[default: what" in text


def test_a_sweep_logged_to_a_file_says_each_point(tmp_path):
    res = run_cli("sweep", "four-triangles", "--nu", "0.1:0.3:3", "-o", tmp_path / "s.h5",
                  "-j", "1")
    assert res.exit_code == 0
    lines = [line for line in res.stderr.splitlines() if "critfric: sweep: point" in line]
    assert len(lines) == 3 and "3/3" in lines[-1] and "elapsed" in lines[-1]


def test_quiet_and_verbose(tmp_path):
    loud = run_cli("-v", "solve", "one-triangle", "-o", tmp_path / "a.h5")
    assert loud.exit_code == 0 and "critfric: stages: mesh" in loud.stderr
    quiet = run_cli("-q", "solve", "one-triangle", "-o", tmp_path / "b.h5")
    assert quiet.exit_code == 0 and quiet.stderr == "" and "1.8" in quiet.stdout
    error = run_cli("-q", "solve", "no-such-case")
    assert error.exit_code == 2 and error.stderr.startswith("critfric: error:")
    normal = run_cli("solve", "one-triangle", "-o", tmp_path / "c.h5")
    assert "wrote" in normal.stderr and "stages" not in normal.stderr


@pytest.mark.once
def test_plots_in_every_format_and_exports_with_tags_and_coefficients(tmp_path):
    import meshio

    out = tmp_path / "r.h5"
    assert run_cli("solve", "unit-square", "-o", out).exit_code == 0
    res = run_cli("plot", out, "--format", "png,pdf,svg")
    assert res.exit_code == 0
    made = {p.suffix for p in tmp_path.glob("r_*")}
    assert {".png", ".pdf", ".svg"} <= made
    assert run_cli("plot", out, "--format", "gif").exit_code == 2
    assert run_cli("export", out, "--format", "vtu").exit_code == 0
    vtu = (tmp_path / "r_modes.vtu").read_text(errors="replace")
    assert "<FieldData>" in vtu and 'Name="critical_positive"' in vtu
    mesh = meshio.read(tmp_path / "r_modes.vtu")
    assert [c.type for c in mesh.cells] == ["triangle", "line"]
    tags = mesh.cell_data["boundary_tag"][1]
    assert set(tags) == {1, 2, 3, 4}  # bottom, left, right, top
