"""`critfric sweep`, `plot` and `export` on the command line; the figures and the export."""

from __future__ import annotations

import json

import h5py
import meshio
import numpy as np
import pytest
from helpers import CASES, four_triangles_alpha, run_cli, square_case
from matplotlib.image import imread

import critfric
from critfric.fem.assembly import cell_stress, lame, von_mises
from critfric.files.export import read_solve

pytestmark = pytest.mark.once  # the same on both installs: run by `make test` only


def assert_png(path):
    assert path.exists() and path.stat().st_size > 1000
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    image = imread(path)
    assert image.ndim == 3 and image.shape[0] > 200 and image.shape[1] > 200
    assert np.ptp(image[..., :3]) > 0.5  # not a blank canvas


def test_sweep_as_written_sweeps_the_unit_square(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    res = run_cli("sweep", "--nu", "0:0.5")
    assert res.exit_code == 0, res.output
    assert "0.499" in res.stderr and "never at 0.5" in res.stderr
    (out,) = tmp_path.glob("unit_square_sweep_*.h5")  # named after the case and the grid
    assert f"wrote {out.name}" in res.stderr
    with h5py.File(out) as f:
        assert f.attrs["kind"] == "sweep" and len(f["points/status"]) == 11
        nu = f["points/nu"][()]
        assert sorted(nu)[-1] == 0.499 and f["points/element"][0] == b"P1"
        assert f["points/size"][0] == 0.025 and "limits" in f
        status = [s.decode() for s in f["points/status"][()]]
    assert status.count("ok") >= 10  # nu = 0 has no real eigenvalue on this mesh
    assert "0.3" in res.stdout and "1.9469250" in res.stdout
    assert "need at least three sizes" in res.stdout
    again = run_cli("sweep", "--nu", "0:0.5")  # the same command resumes the same file
    assert again.exit_code == 0 and list(tmp_path.glob("unit_square_sweep_*.h5")) == [out]
    other = run_cli("sweep", "--nu", "0.1,0.2")  # another grid: another file, no clash
    assert other.exit_code == 0 and len(list(tmp_path.glob("unit_square_sweep_*.h5"))) == 2


def test_sweep_json_prints_points_and_limits_only(tmp_path):
    out = tmp_path / "s.h5"
    case = tmp_path / "sq.toml"
    case.write_text(square_case(size=0.5))
    res = run_cli("sweep", case, "--nu", "0.3", "--size", "0.2,0.1,0.05", "--element", "P1,P2",
              "--jobs", "1", "-o", out, "--json")
    assert res.exit_code == 0, res.output
    data = json.loads(res.stdout)
    assert set(data) == {"points", "limits"} and len(data["points"]) == 6
    p = data["points"][0]
    assert {"nu", "size", "element", "n_dofs", "positive", "negative", "status",
            "seconds"} <= set(p)
    assert {(lim["element"], lim["family"]) for lim in data["limits"]} == {
        ("P1", "positive"), ("P1", "negative"), ("P2", "positive"), ("P2", "negative")}
    assert {"nu", "element", "limit", "order", "error"} <= set(data["limits"][0])
    again = run_cli("sweep", case, "--nu", "0.3", "--size", "0.2,0.1,0.05", "--element", "P1,P2",
                "--jobs", "1", "-o", out, "--json")
    assert json.loads(again.stdout) == data  # resumed: nothing computed, same file


@pytest.mark.parametrize("args,key", [
    (["--nu", "0.5"], "--nu"),
    (["--nu", "0:0.7"], "--nu"),
    (["--size", "0,0.1"], "--size"),
    (["--element", "P3"], "--element"),
    (["four-triangles", "--size", "0.1"], "mesh.size"),
    (["--grading", "1.5"], "mesh.grading"),
])
def test_bad_sweep_input_exits_2_and_writes_nothing(tmp_path, monkeypatch, args, key):
    monkeypatch.chdir(tmp_path)
    res = run_cli("sweep", *args)
    assert res.exit_code == 2, res.output
    assert key in res.stderr and "Traceback" not in res.output
    assert list(tmp_path.iterdir()) == []


def test_changed_grid_exits_2_unless_forced(tmp_path):
    out = tmp_path / "s.h5"
    assert run_cli("sweep", "four-triangles", "--nu", "0.1,0.2", "-o", out, "-j", 1).exit_code == 0
    res = run_cli("sweep", "four-triangles", "--nu", "0.1,0.3", "-o", out, "-j", 1)
    assert res.exit_code == 2 and "--force" in res.stderr
    res = run_cli("sweep", "four-triangles", "--nu", "0.1,0.3", "-o", out, "--force", "--json",
              "-j", 1)
    assert res.exit_code == 0
    got = [p["positive"][0] for p in json.loads(res.stdout)["points"]]
    np.testing.assert_allclose(got, [four_triangles_alpha(0.1), four_triangles_alpha(0.3)],
                               rtol=1e-10)


def test_plot_of_a_sweep_file_writes_both_figures(tmp_path):
    case = tmp_path / "sq.toml"
    case.write_text(square_case(size=0.5))
    res = run_cli("sweep", case, "--nu", "0.2,0.4", "--size", "0.4,0.2,0.1", "--element", "P1,P2",
              "--jobs", "1", "-o", tmp_path / "s.h5", "--plot")
    assert res.exit_code == 0, res.output
    for name in ("s_critical.png", "s_convergence.png"):
        assert_png(tmp_path / name)
        assert name in res.stderr
    (tmp_path / "s_critical.png").unlink()
    res = run_cli("plot", tmp_path / "s.h5", "--nu", 0.4)
    assert res.exit_code == 0 and "s_critical.png" in res.stdout
    assert_png(tmp_path / "s_critical.png")


@pytest.mark.parametrize("element", ["P2", "Q1"])
def test_solve_plot_and_export(tmp_path, element):
    out = tmp_path / "r.h5"
    res = run_cli("solve", "unit-square", "--element", element, "--size", 0.25, "-o", out,
              "--plot", "--json")
    assert res.exit_code == 0, res.output
    json.loads(res.stdout)
    for name in ("deformed", "von_mises", "contact_forces", "spectrum"):
        assert_png(tmp_path / f"r_{name}.png")
    data = read_solve(out)
    lam, G = lame(1.0, 0.3)
    for fmt, cell in (("xdmf", {"P2": "triangle6", "Q1": "quad"}[element]),
                      ("vtu", {"P2": "triangle6", "Q1": "quad"}[element])):
        res = run_cli("export", out, "--format", fmt)
        assert res.exit_code == 0, res.output
        mesh = meshio.read(tmp_path / f"r_modes.{fmt}")
        assert mesh.cells[0].type == cell and len(mesh.points) == data.mesh.n_nodes
        phi = mesh.point_data["positive_0_phi"]
        assert phi.shape == (data.mesh.n_nodes, 3) and np.all(phi[:, 2] == 0)
        stored = data.modes["positive_0"]["phi"]
        scale = np.max(np.linalg.norm(stored, axis=1))
        np.testing.assert_allclose(phi[:, :2], stored / scale, atol=1e-12)
        stress = mesh.cell_data["positive_0_stress"][0].reshape(-1, 3, 3)
        expected = cell_stress(data.mesh, (stored / scale).ravel(), lam, G, at="centroid")[:, 0]
        np.testing.assert_allclose(stress[:, 0, 0], expected[:, 0], atol=1e-10)
        np.testing.assert_allclose(stress[:, 0, 1], stress[:, 1, 0])
        np.testing.assert_allclose(stress[:, 2, 2], expected[:, 3], atol=1e-10)
        np.testing.assert_allclose(mesh.cell_data["positive_0_von_mises"][0],
                                   von_mises(expected), atol=1e-10)
    assert run_cli("export", out, "--format", "vtu").exit_code == 2  # exists: needs --force
    assert run_cli("export", out, "--format", "vtu", "--force").exit_code == 0


def test_export_refuses_to_overwrite_its_input(tmp_path):
    out = tmp_path / "r.h5"
    critfric.write_result(critfric.solve_case(CASES / "four_triangles.toml"), out)
    res = run_cli("export", out, "--format", "xdmf", "-o", tmp_path / "r.xdmf")
    assert res.exit_code == 2 and "overwrite the input" in res.stderr
    assert run_cli("export", out, "--format", "stl").exit_code == 2
    assert run_cli("plot", tmp_path / "missing.h5").exit_code == 2


def test_a_sweep_file_opens_in_xarray_with_named_dimensions_and_units(tmp_path):
    xr = pytest.importorskip("xarray")
    pytest.importorskip("h5netcdf")
    out = tmp_path / "s.h5"
    res = run_cli("sweep", "four-triangles", "--nu", "0.3,0.1,0.2", "-o", out, "-j", "2")
    assert res.exit_code == 0, res.output
    with xr.open_dataset(out, engine="h5netcdf") as ds:
        assert ds.positive.dims == ("element", "size", "nu", "rank")
        assert list(ds.nu.values) == [0.1, 0.2, 0.3]  # grid order, whatever the finishing order
        assert ds.positive.attrs["units"] == "1" and "friction" in ds.positive.attrs["long_name"]
        got = ds.positive.sel(element="P1", nu=0.3).values.ravel()[0]
        assert got == pytest.approx(four_triangles_alpha(0.3), rel=1e-10)
        assert set(ds.status.values.ravel()) == {"ok"}


def test_solve_file_datasets_carry_units_and_long_names(tmp_path):
    import h5py

    assert run_cli("solve", "one-triangle", "-o", tmp_path / "r.h5").exit_code == 0
    with h5py.File(tmp_path / "r.h5") as f:
        names = []
        f.visititems(lambda n, o: names.append(n) if isinstance(o, h5py.Dataset) else None)
        assert names and all("units" in f[n].attrs and f[n].attrs["long_name"] for n in names)


def test_the_point_table_ends_in_grid_order(tmp_path):
    import h5py

    out = tmp_path / "s.h5"
    res = run_cli("sweep", "four-triangles", "--nu", "0.4,0.1,0.3,0.2,0.05,0.25", "-o", out,
                  "-j", "2")
    assert res.exit_code == 0, res.output
    with h5py.File(out) as f:
        assert list(f["points/nu"][()]) == [0.05, 0.1, 0.2, 0.25, 0.3, 0.4]
        alpha = f["points/positive"][:, 0]
    np.testing.assert_allclose(alpha, [four_triangles_alpha(v) for v in
                                       (0.05, 0.1, 0.2, 0.25, 0.3, 0.4)], rtol=1e-10)


def test_table_of_a_sweep_that_never_ran_says_so(tmp_path):
    """A sweep file whose workers failed to start has no point: `table` says so, exit 0."""
    from critfric.files.sweepfile import open_sweep
    from critfric.sweep import make_grid

    case = critfric.load_case("unit-square")
    path = tmp_path / "empty.h5"
    open_sweep(path, case=case, grid=make_grid(case, nu="0.3"))
    res = run_cli("table", str(path))
    assert res.exit_code == 0 and "no results yet" in res.stderr and "Traceback" not in res.output
    res = run_cli("table", str(path), "--json")
    assert res.exit_code == 0 and json.loads(res.stdout) == []
