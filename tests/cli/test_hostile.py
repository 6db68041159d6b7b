"""Hostile inputs (issue 12): case, mesh and script files from someone else. Each one gives
exit code 2 (1 for a numerical failure) with one `critfric: error:` line, no traceback, no
file created or changed, and no hang. The catalogue of merely wrong inputs is test_badinput."""

from __future__ import annotations

import time

import pytest
from helpers import SQUARE_GEO, run_cli

from critfric.meshing import geoscript, sandbox

CASE = """[geometry]
shape = "file"
file = "{file}"
[boundary]
contact = ["bottom"]
dirichlet = ["top"]
"""


def _files(tmp_path) -> dict:
    return {p.name: p.read_bytes() for p in tmp_path.iterdir()}


def _run_file(tmp_path, name: str, content: str | bytes, *more):
    path = tmp_path / name
    path.write_bytes(content.encode() if isinstance(content, str) else content)
    (tmp_path / "case.toml").write_text(CASE.format(file=name))
    before = _files(tmp_path)
    res = run_cli("solve", tmp_path / "case.toml", "-o", tmp_path / "out.h5", *more)
    return res, before


def _refused(res, tmp_path, before, *words, code=2):
    out = res.output
    assert res.exit_code == code, out
    assert out.count("critfric: error:") == 1 and "Traceback" not in out, out
    for w in words:
        assert w in out, (w, out)
    assert _files(tmp_path) == before  # nothing created, nothing changed


GEO_ATTACKS = {  # statement -> what the message names
    "field running a program": ('Field[1] = ExternalProcess; Field[1].CommandLine = "touch x";',
                                "ExternalProcess"),
    "log file anywhere": ('General.LogFileName = "{p}";', "General"),
    "field reading a file": ('Field[1] = Structured; Field[1].FileName = "/etc/passwd";',
                             "Structured"),
    "abort on error": ("General.AbortOnError = 2;", "General"),
    "terminal output": ("General.Terminal = 1;", "General"),
    "unknown option": ("Mesh.SaveAll = 1;", "Mesh.SaveAll"),
    "string to name": ('StringToName("SystemCall") "touch {p}";', "StringToName"),
    "printf to a file": ('Printf("x") > "{p}";', "Printf"),
    "include": ('Include "{p}";', "Include"),
    "unknown command": ("Geometry.OldNewReg = 1; Abort;", "Abort"),
}


@pytest.mark.parametrize("attack", sorted(GEO_ATTACKS))
def test_geo_statements_outside_the_allow_list_are_refused(tmp_path, attack):
    statement, word = GEO_ATTACKS[attack]
    p = tmp_path / "pwned"
    script = SQUARE_GEO + "// an innocent comment: SystemCall Include Merge\n" \
        + statement.format(p=p) + "\n"
    res, before = _run_file(tmp_path, "body.geo", script)
    _refused(res, tmp_path, before, "body.geo", "line 8", word, "--trust-geo")
    assert not p.exists()


def test_a_sidecar_option_file_is_never_read(tmp_path):
    """gmsh reads <script>.opt by itself: the script is meshed from a private copy, alone."""
    p = tmp_path / "pwned.log"
    (tmp_path / "body.geo.opt").write_text(f'General.LogFileName = "{p}";\n'
                                           f'SystemCall "touch {p}";\n')
    res, _ = _run_file(tmp_path, "body.geo", SQUARE_GEO)
    assert res.exit_code == 0, res.output
    assert not p.exists()


def test_an_endless_loop_is_stopped(tmp_path, monkeypatch):
    monkeypatch.setattr(sandbox, "CPU_SECONDS", 2)
    start = time.monotonic()
    res, before = _run_file(tmp_path, "body.geo", SQUARE_GEO + "For i In {1:1e15}\nEndFor\n")
    _refused(res, tmp_path, before, "body.geo", "CPU time")
    assert time.monotonic() - start < 30


def test_a_recursive_macro_is_stopped(tmp_path, monkeypatch):
    monkeypatch.setattr(sandbox, "CPU_SECONDS", 2)
    script = SQUARE_GEO + "Macro m\n  Call m;\nReturn\nCall m;\n"
    res, before = _run_file(tmp_path, "body.geo", script)
    _refused(res, tmp_path, before, "body.geo")


def test_the_check_is_linear_in_the_script(tmp_path):
    """200 000 comment lines and as many statements: checked in well under a second each."""
    for body in ("// comment\n" * 200_000, "a = 1;\n" * 200_000):
        start = time.perf_counter()
        assert geoscript.refusals(SQUARE_GEO + body) == []
        assert time.perf_counter() - start < 3


def test_a_byte_order_mark_is_not_a_statement(tmp_path):
    res, _ = _run_file(tmp_path, "body.geo", "\ufeff" + SQUARE_GEO)
    assert res.exit_code == 0, res.output


def test_the_bytes_checked_are_the_bytes_meshed(tmp_path):
    """No window between the check and gmsh's read: the child gets a copy of the bytes."""
    from pathlib import Path

    evil = tmp_path / "body.geo"
    evil.write_text(SQUARE_GEO + f'SystemCall "touch {tmp_path / "pwned"}";\n')
    job = {"kind": "geo", "element": "P1", "size": None, "domain": None, "max_dofs": None,
           "trust": False}
    mesh = sandbox.run_in_child(Path(evil), SQUARE_GEO.encode(), job,
                                entry="critfric.meshing.gmshfile:child_mesh", source=None)
    assert mesh.n_nodes > 3 and not (tmp_path / "pwned").exists()


SPARSE_MSH = """$MeshFormat
4.1 0 8
$EndMeshFormat
$Nodes
1 3 1 1000000000
2 1 0 3
999999998
999999999
1000000000
0 0 0
1 0 0
0 1 0
$EndNodes
$Elements
1 1 1 1
2 1 2 1
1 999999998 999999999 1000000000
$EndElements
"""


def test_a_small_msh_declaring_huge_tags_is_refused_without_the_memory(tmp_path):
    start = time.monotonic()
    res, before = _run_file(tmp_path, "body.msh", SPARSE_MSH)
    _refused(res, tmp_path, before, "body.msh", "memory")
    assert time.monotonic() - start < 30


@pytest.mark.parametrize("content", [b"\x00" * 4096, b"$MeshFormat\n4.1 0 8\n$EndMeshFormat\n"
                                     b"$Nodes\n1 1 1 1\n", "$Nodes\n" + "9" * 5000 + "\n"])
def test_garbage_msh_is_a_message(tmp_path, content):
    res, before = _run_file(tmp_path, "body.msh", content)
    _refused(res, tmp_path, before, "body.msh")


# ------------------------------------------------------------------------- files at risk
def test_an_output_that_is_an_input_is_refused(tmp_path):
    case = tmp_path / "case.toml"
    case.write_text('[geometry]\nshape = "square"\n[mesh]\nsize = 0.5\n')
    before = _files(tmp_path)
    for out in (case, tmp_path / "." / "case.toml"):
        res = run_cli("solve", case, "-o", out, "--force")
        _refused(res, tmp_path, before, "is an input")
    link = tmp_path / "link.h5"
    link.symlink_to(case)
    before = _files(tmp_path)
    _refused(run_cli("solve", case, "-o", link, "--force"), tmp_path, before, "is an input")
    _refused(run_cli("sweep", case, "-o", case, "-j", "1"), tmp_path, before, "is an input")


def test_a_planted_lock_symlink_is_not_followed(tmp_path):
    victim = tmp_path / "victim.txt"
    victim.write_text("precious")
    (tmp_path / ".r.h5.lock").symlink_to(victim)
    res = run_cli("solve", "one-triangle", "-o", tmp_path / "r.h5")
    assert res.exit_code == 2 and "Traceback" not in res.output, res.output
    assert victim.read_text() == "precious" and not (tmp_path / "r.h5").exists()


def test_results_get_the_umask_permissions(tmp_path):
    import os

    old = os.umask(0o027)
    try:
        assert run_cli("solve", "one-triangle", "-o", tmp_path / "r.h5").exit_code == 0
        assert (tmp_path / "r.h5").stat().st_mode & 0o777 == 0o640
    finally:
        os.umask(old)


def test_export_never_clobbers_its_companion(tmp_path):
    assert run_cli("solve", "one-triangle", "-o", tmp_path / "r.h5").exit_code == 0
    companion = tmp_path / "r_modes.h5"
    companion.write_text("someone's data")
    before = _files(tmp_path)
    _refused(run_cli("export", tmp_path / "r.h5"), tmp_path, before, "r_modes.h5", "--force")
    assert run_cli("export", tmp_path / "r.h5", "--force").exit_code == 0
    assert companion.read_bytes()[:4] == b"\x89HDF"


def test_a_full_disk_is_exit_1_and_leaves_the_old_file(tmp_path):
    """The file-size limit stands in for a full disk: writing fails with EFBIG."""
    import signal
    import subprocess
    import sys

    from helpers import REPO

    out = tmp_path / "r.h5"
    out.write_bytes(b"old result")

    def small_files():
        import resource

        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        resource.setrlimit(resource.RLIMIT_FSIZE, (20_000, 20_000))

    proc = subprocess.run([sys.executable, "-m", "critfric", "solve", "unit-square", "-o", out,
                           "--force"], cwd=tmp_path, capture_output=True, text=True,
                          env={**__import__("os").environ, "PYTHONPATH": str(REPO)},
                          preexec_fn=small_files, timeout=120)
    assert proc.returncode == 1, proc.stderr
    assert proc.stderr.count("critfric: error:") == 1 and "Traceback" not in proc.stderr
    assert "nothing was changed" in proc.stderr
    assert out.read_bytes() == b"old result"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["r.h5"]
