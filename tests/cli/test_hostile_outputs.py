"""Hostile outputs and small inputs: figures and exports into places that cannot be written or
where a symbolic link stands, plots of sweeps without values, numbers that only look like
numbers, polygons with thousands of vertices. Each gives exit code 2 (1 for a failed write)
and one `critfric: error:` line naming the path or the option, never a traceback, never a
file written through a link or left half-written."""

from __future__ import annotations

import errno
import os
import time

import numpy as np
import pytest
from helpers import run_cli

import critfric
from critfric.files import sweepfile
from critfric.sweep.extrapolate import limits_of
from critfric.sweep.grid import empty_row
from critfric.sweep.runner import make_grid

pytestmark = pytest.mark.once  # the same on both installs: run by `make test` only


def _refused(res, *words, code=2):
    out = res.output
    assert res.exit_code == code, out
    assert out.count("critfric: error:") == 1 and "Traceback" not in out, out
    for w in words:
        assert w in out, (w, out)


def _files(folder) -> dict:
    return {p.name: (p.is_symlink(), p.read_bytes() if p.is_file() else None)
            for p in folder.iterdir()}


@pytest.fixture(scope="module")
def solved(tmp_path_factory):
    """A solve file of the one-triangle case (2D, with modes) in its own folder."""
    folder = tmp_path_factory.mktemp("solved")
    assert run_cli("solve", "one-triangle", "-o", folder / "r.h5").exit_code == 0
    return (folder / "r.h5").read_bytes()


def _solve_file(tmp_path, solved, name="r.h5"):
    path = tmp_path / name
    path.write_bytes(solved)
    return path


# --------------------------------------------------------------------- links and paths
def test_plot_refuses_a_link_at_a_figure_and_writes_none(tmp_path, solved):
    r = _solve_file(tmp_path, solved)
    victim = tmp_path / "victim.txt"
    victim.write_text("precious")
    (tmp_path / "r_spectrum.png").symlink_to(victim)
    before = _files(tmp_path)
    _refused(run_cli("plot", r), "r_spectrum.png", "symbolic link")
    assert victim.read_text() == "precious" and (tmp_path / "r_spectrum.png").is_symlink()
    assert _files(tmp_path) == before  # no other figure, no temporary directory


def test_export_refuses_a_link_at_the_export_or_its_companion(tmp_path, solved):
    r = _solve_file(tmp_path, solved)
    victim = tmp_path / "victim.txt"
    victim.write_text("precious")
    for name, extra in (("r_modes.xdmf", ()), ("r_modes.h5", ()),
                        ("m.vtu", ("--format", "vtu", "-o", tmp_path / "m.vtu"))):
        (tmp_path / name).symlink_to(victim)
        before = _files(tmp_path)
        _refused(run_cli("export", r, "--force", *extra), name, "symbolic link")
        assert _files(tmp_path) == before and victim.read_text() == "precious"
        (tmp_path / name).unlink()


def test_a_result_is_never_written_over_a_link(tmp_path):
    victim = tmp_path / "victim.txt"
    victim.write_text("precious")
    for name, target in (("r.h5", victim), ("dangling.h5", tmp_path / "nowhere.h5")):
        (tmp_path / name).symlink_to(target)
        before = _files(tmp_path)
        _refused(run_cli("solve", "one-triangle", "-o", tmp_path / name, "--force"), name,
                 "symbolic link")
        assert _files(tmp_path) == before


def test_a_result_never_replaces_a_pipe_or_a_device(tmp_path):
    import os
    import stat

    os.mkfifo(tmp_path / "pipe.h5")
    targets = ["pipe.h5"]
    if os.geteuid() == 0:  # a copy of /dev/null: --force must not turn it into a file
        os.mknod(tmp_path / "null.h5", stat.S_IFCHR | 0o666, os.makedev(1, 3))
        targets.append("null.h5")
    for name in targets:
        _refused(run_cli("solve", "one-triangle", "-o", tmp_path / name, "--force"), name,
                 "not a regular file")
        assert not (tmp_path / name).is_file()


def test_a_case_file_cannot_send_its_result_out_of_the_working_directory(tmp_path):
    for target in ("/tmp/critfric-escape.h5", "../escape.h5", "~/escape.h5", "a/../../x.h5",
                   "notes.txt"):
        case = tmp_path / "case.toml"
        case.write_text(f'[geometry]\nshape = "square"\n[output]\nfile = "{target}"\n')
        _refused(run_cli("solve", case, "--force"), "output.file", "relative path")
    # the command line may, and the result's TOML runs again (without that output)
    out = tmp_path / "elsewhere.h5"
    assert run_cli("solve", "one-triangle", "-o", out).exit_code == 0
    import h5py

    from critfric.case.schema import loads_case
    with h5py.File(out) as f:
        assert loads_case(f.attrs["case_toml"]).output["file"] is None


def test_a_case_file_cannot_send_its_result_through_a_linked_folder(tmp_path):
    """``sub/r.h5`` where sub links to a folder elsewhere: refused, the file there kept."""
    work, elsewhere = tmp_path / "work", tmp_path / "elsewhere"
    work.mkdir()
    elsewhere.mkdir()
    (elsewhere / "r.h5").write_bytes(b"precious")
    (work / "sub").symlink_to(elsewhere)
    (work / "inside").mkdir()
    (work / "case.toml").write_text('[geometry]\nshape = "square"\n[boundary]\ncontact = '
                                    '["bottom"]\ndirichlet = ["top"]\n[mesh]\nsize = 0.5\n'
                                    '[output]\nfile = "sub/r.h5"\n')
    for force in ((), ("--force",)):
        _refused(run_cli("solve", "case.toml", *force, cwd=work), "output.file",
                 "inside the working directory", "symbolic link")
    assert (elsewhere / "r.h5").read_bytes() == b"precious" and os.listdir(elsewhere) == ["r.h5"]
    (work / "case.toml").write_text((work / "case.toml").read_text().replace("sub/", "inside/"))
    assert run_cli("solve", "case.toml", cwd=work).exit_code == 0  # a real folder inside
    assert (work / "inside" / "r.h5").is_file()


def test_figures_into_an_unwritable_place_name_it(tmp_path, solved):
    _refused(run_cli("solutions", "one-triangle", "--friction", "1", "--plot",
                     "/proc/critfric.png"), "/proc/critfric.png", "--plot", "cannot write")
    _refused(run_cli("export", _solve_file(tmp_path, solved), "--format", "vtu", "-o",
                     "/proc/critfric.vtu"), "/proc/critfric.vtu", "cannot write")
    _refused(run_cli("solutions", "one-triangle", "--friction", "1", "--plot",
                     tmp_path / "b.txt"), "b.txt", ".png")
    assert not (tmp_path / "b.txt").exists()


@pytest.mark.skipif(os.geteuid() == 0, reason="root writes into a read-only directory")
def test_plot_into_a_read_only_directory_names_it(tmp_path, solved):
    r = _solve_file(tmp_path, solved)
    tmp_path.chmod(0o555)
    try:
        _refused(run_cli("plot", r), "not writable", str(tmp_path))
    finally:
        tmp_path.chmod(0o755)


def test_a_figure_write_that_fails_leaves_the_old_figures(tmp_path, solved, monkeypatch):
    from matplotlib.figure import Figure

    r = _solve_file(tmp_path, solved)
    assert run_cli("plot", r).exit_code == 0
    before = _files(tmp_path)
    calls = []

    def full_disk(self, target, **kw):  # the second figure finds the disk full, half-way
        calls.append(target)
        with open(target, "wb") as f:
            f.write(b"\x89PNG half")
        if len(calls) == 2:
            raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(Figure, "savefig", full_disk)
    _refused(run_cli("plot", r), "No space left", "nothing was changed", code=1)
    assert _files(tmp_path) == before  # every old figure whole, nothing new left behind


def test_figure_names_keep_the_dots_of_the_file_name(tmp_path, solved):
    r = _solve_file(tmp_path, solved, "run.v2.h5")
    res = run_cli("plot", r, "--format", "png,svg")
    assert res.exit_code == 0, res.output
    written = sorted(p.name for p in tmp_path.iterdir() if p.suffix in (".png", ".svg"))
    assert len(written) == 8 and all(n.startswith("run.v2_") for n in written), written


# ------------------------------------------------------------- sweeps without values
def _sweep_file(path, mode: str, sizes: str = "0.5,0.25,0.125"):
    """A unit-square sweep file of 2 nu x 3 sizes written through the sweep file API: every
    point failed ("failed"), every other one ("mixed"), no real eigenvalue ("none"), the
    same value at every size ("constant": the limit equals every value), or no point yet
    ("empty")."""
    case = critfric.load_case("unit-square")
    grid = make_grid(case, nu="0.1,0.3", size=sizes, element="P1")
    sweepfile.open_sweep(path, case=case, grid=grid, force=True)
    if mode == "empty":
        return path
    rows = []
    for i, p in enumerate(grid.points()):
        if mode == "failed" or (mode == "mixed" and i % 2 == 0):
            row = empty_row(p, "failed: RuntimeError: no convergence")
        elif mode == "none":
            row = {**empty_row(p, "no-real-eigenvalue"), "h": p.size, "n_dofs": 10,
                   "n_contact": 3, "complex_count": 4}
        else:
            alpha = 1.5 if mode == "constant" else 1.5 + p.size ** 2
            row = {**empty_row(p, "ok"), "h": p.size, "n_dofs": 10, "n_contact": 3,
                   "complex_count": 0, "positive": [alpha], "negative": [-alpha],
                   "r_positive": [0.0]}
        sweepfile.append_point(path, row)
        rows.append(row)
    sweepfile.write_limits(path, limits_of(rows, []), grid, rows)
    return path


@pytest.mark.parametrize("mode, words", [
    ("failed", ("no value to draw", "6 failed", "RuntimeError")),
    ("none", ("no value to draw", "6 have no real value")),
    ("empty", ("no finished point", "nothing to draw")),
])
def test_plot_of_a_sweep_without_values_says_so(tmp_path, mode, words):
    path = _sweep_file(tmp_path / "s.h5", mode)
    before = _files(tmp_path)
    _refused(run_cli("plot", path), "s.h5", *words)
    assert _files(tmp_path) == before


def test_sweep_plot_with_every_point_failed_is_a_note_after_the_report(tmp_path):
    from critfric.sweep.runner import sweep_case

    case = critfric.load_case("unit-square")
    grid = make_grid(case, nu="0.1,0.3", size="0.5,0.25,0.125", element="P1")
    out = tmp_path / "s.h5"
    sweepfile.open_sweep(out, case=sweep_case(case, grid.size)[0], grid=grid, force=True)
    for p in grid.points():  # every point done and failed: the sweep only reports
        sweepfile.append_point(out, empty_row(p, "failed: RuntimeError: no convergence"))
    res = run_cli("sweep", "unit-square", "--nu", "0.1,0.3", "--size", "0.5,0.25,0.125",
                  "--element", "P1", "-o", out, "--plot", "-j", "1")
    assert res.exit_code == 1 and "Traceback" not in res.output, res.output  # for batch jobs
    assert "not converged" in res.output and "note: no figure" in res.output
    assert "critfric: error: 6 of 6 points failed" in res.output
    assert not list(tmp_path.glob("*.png"))


def test_plot_of_a_sweep_whose_values_equal_their_limits_draws(tmp_path):
    path = _sweep_file(tmp_path / "s.h5", "constant")  # no distance to put on a log axis
    res = run_cli("plot", path)
    assert res.exit_code == 0 and "Traceback" not in res.output, res.output
    assert {"s_critical.png", "s_convergence.png"} <= {p.name for p in tmp_path.iterdir()}


def test_plot_of_a_sweep_with_failed_points_notes_them(tmp_path):
    from critfric.plots.figures import figures

    drawn = figures(_sweep_file(tmp_path / "s.h5", "mixed"))
    notes = [t.get_text() for ax in drawn["critical"].axes for t in ax.texts]
    assert any("3 of 6 points failed" in n for n in notes), notes


# --------------------------------------------------------- numbers that only look like them
UNICODE = [
    ("sweep", "--nu", "0:0.4:\u00b3", "SUPERSCRIPT THREE"),
    ("sweep", "--nu", "\uff10.\uff13", "FULLWIDTH DIGIT ZERO"),
    ("sweep", "--nu", "\u22120.1:0.3", "MINUS SIGN"),
    ("sweep", "--nu", "\u0660.\u0661,0.2", "ARABIC-INDIC DIGIT ZERO"),
    ("sweep", "--nu", "0.1:0.3:\uff13", "FULLWIDTH DIGIT THREE"),
    ("sweep", "--nu", "nan", "'nan'"),
    ("sweep", "--nu", "0.1:inf", "'inf'"),
    ("sweep", "--nu", "1_0", "'1_0'"),
    ("sweep", "--size", "0.1,1e999", "'1e999'"),
    ("sweep", "--slip-angle", "0:\uff19\uff10", "FULLWIDTH DIGIT NINE"),
    ("stability", "--friction", "\u22121:1", "MINUS SIGN"),
    ("path", "--range", "0:nan", "'nan'"),
    ("solutions", "--friction", "1:2:\uff13", "FULLWIDTH DIGIT THREE"),
    ("solutions", "--friction", "\u00b9", "SUPERSCRIPT ONE"),
]


@pytest.mark.parametrize("command, option, value, named", UNICODE)
def test_numbers_in_plain_ascii_only(tmp_path, command, option, value, named):
    case = "unit-square" if command != "solutions" else "one-triangle"
    res = run_cli(command, case, option, value, "-o" if command == "sweep" else "--json",
                  *((tmp_path / "s.h5",) if command == "sweep" else ()))
    _refused(res, option, named, "allowed", "ASCII")
    assert not any(tmp_path.iterdir())


# ------------------------------------------------------------------ huge polygons
@pytest.mark.parametrize("shape", ["polygon", "prism"])
def test_a_polygon_of_8000_vertices_is_refused_at_once(tmp_path, shape):
    t = np.linspace(0.0, 2.0 * np.pi, 8000, endpoint=False)
    vertices = ", ".join(f"[{x:.12g}, {y:.12g}]" for x, y in zip(np.cos(t), np.sin(t)))
    (tmp_path / "c.toml").write_text(
        f'[geometry]\nshape = "{shape}"\nvertices = [{vertices}]\n'
        + ("depth = 0.5\n" if shape == "prism" else "")
        + '[boundary]\ncontact = ["e0"]\ndirichlet = ["e4000"]\n[mesh]\nsize = 0.2\n')
    start = time.monotonic()
    res = run_cli("solve", tmp_path / "c.toml", "-o", tmp_path / "c.h5")
    _refused(res, "geometry.vertices", "at most 1000 vertices", "8000")
    assert time.monotonic() - start < 10  # a bound, asserted as one: no meshing began
    assert not (tmp_path / "c.h5").exists()


def test_a_prism_base_of_150_vertices_is_refused_with_the_limit(tmp_path):
    t = np.linspace(0.0, 2.0 * np.pi, 150, endpoint=False)
    vertices = ", ".join(f"[{x:.12g}, {y:.12g}]" for x, y in zip(np.cos(t), np.sin(t)))
    (tmp_path / "c.toml").write_text(
        f'[geometry]\nshape = "prism"\nvertices = [{vertices}]\ndepth = 0.5\n'
        '[boundary]\ncontact = ["e0"]\ndirichlet = ["e75"]\n[mesh]\nsize = 0.2\n')
    _refused(run_cli("solve", tmp_path / "c.toml", "-o", tmp_path / "c.h5"),
             "geometry.vertices", "at most 100 vertices", "150")


def test_the_polygon_api_states_the_limits():
    from critfric.errors import CaseError
    from critfric.meshing.geometry import polygon
    from critfric.meshing.solid import prism_polygon

    t = np.linspace(0.0, 2.0 * np.pi, 1001, endpoint=False)
    with pytest.raises(CaseError, match="at most 1000 vertices"):
        polygon(np.c_[np.cos(t), np.sin(t)])
    with pytest.raises(CaseError, match="at most 100 vertices"):
        prism_polygon(np.c_[np.cos(t[::5]), np.sin(t[::5])])


def test_running_out_of_memory_is_a_message_not_a_traceback(capsys):
    """Past the memory guard's estimate (another job took the memory): exit 1, one line that
    says what to do, and what was (not) written."""
    import typer

    from critfric.cli.failures import reported

    with pytest.raises(typer.Exit) as ended, reported("nothing was written"):
        raise MemoryError
    err = capsys.readouterr().err
    assert ended.value.exit_code == 1 and "Traceback" not in err
    assert "out of memory (nothing was written)" in err and "coarser mesh" in err
