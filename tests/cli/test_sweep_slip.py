"""`critfric sweep --slip-angle` on the command line: refusals, the JSON summary with the
minimum over directions, the file's identity, the polar figure and the gridded view."""

from __future__ import annotations

import json

import h5py
import numpy as np
import pytest
from helpers import box_case, run_cli, square_case
from matplotlib.image import imread

BOX = box_case()


@pytest.fixture
def box(tmp_path):
    path = tmp_path / "box.toml"
    path.write_text(BOX)
    return path


@pytest.mark.parametrize("args,key", [
    (["unit-square", "--slip-angle", "0:180:7"], "--slip-angle"),
    (["square.toml", "--slip-angle", "0,90"], "--slip-angle"),
    (["box.toml", "--slip-angle", "0:900:4"], "--slip-angle"),
    (["box.toml", "--slip-angle", "0:90:1"], "--slip-angle"),
    (["box.toml", "--slip-angle", "north"], "--slip-angle"),
    (["box.toml", "--slip-angle", "0,90", "--quantity", "flutter"], "--slip-angle"),
    (["ruled.toml", "--slip-angle", "0,90"], "contact.rules"),
])
def test_slip_angles_a_case_cannot_take_exit_2_naming_the_key(tmp_path, monkeypatch, args,
                                                              key):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "square.toml").write_text(square_case())
    (tmp_path / "box.toml").write_text(BOX)
    (tmp_path / "ruled.toml").write_text(BOX + '[contact]\nrules = [{from = [0, 0], to = '
                                         '[0.5, 1], status = "slip", slip_angle = 30}]\n')
    before = set(tmp_path.iterdir())
    res = run_cli("sweep", *args)
    assert res.exit_code == 2, res.output
    assert key in res.stderr and "Traceback" not in res.output
    assert set(tmp_path.iterdir()) == before  # no sweep file


def test_angle_sweep_json_file_identity_and_polar_figure(tmp_path, monkeypatch, box):
    monkeypatch.chdir(tmp_path)
    res = run_cli("sweep", box, "--slip-angle", "0:150:6", "-j", "1", "--json", "--plot")
    assert res.exit_code == 0, res.output
    data = json.loads(res.stdout)
    assert set(data) == {"points", "limits", "minima"} and len(data["points"]) == 6
    assert [p["slip_angle"] for p in data["points"]] == [0, 30, 60, 90, 120, 150]
    assert all(len(p["r_positive"]) == len(p["positive"]) == 1 for p in data["points"])
    (m,) = data["minima"]
    assert m["status"] == "ok" and 0 <= m["slip_angle"] < 360 and m["evaluations"] > 0
    samples = [p["positive"][0] for p in data["points"]] + [-p["negative"][0]
                                                            for p in data["points"]]
    assert m["positive"] <= min(samples)
    (out,) = tmp_path.glob("box_sweep_*.h5")
    with h5py.File(out) as f:
        assert json.loads(f.attrs["grid"])["slip_angle"] == [0, 30, 60, 90, 120, 150]
        assert f["minima/positive"][0] == m["positive"]
    png = out.with_name(f"{out.stem}_directions.png")
    assert png.exists() and png.name in res.stderr
    image = imread(png)
    assert image.shape[0] > 200 and image.shape[1] > 400 and np.ptp(image[..., :3]) > 0.5
    png.unlink()
    plotted = run_cli("plot", out)
    assert plotted.exit_code == 0 and png.name in plotted.stdout and png.exists()
    again = run_cli("sweep", box, "--slip-angle", "0:150:6", "-j", "1", "--json")
    assert again.exit_code == 0 and json.loads(again.stdout) == data  # nothing recomputed
    assert list(tmp_path.glob("box_sweep_*.h5")) == [out]  # resumed: the same file
    other = run_cli("-q", "sweep", box, "--slip-angle", "0:120:5", "-j", "1")
    assert other.exit_code == 0 and len(list(tmp_path.glob("box_sweep_*.h5"))) == 2
    clash = run_cli("sweep", box, "--slip-angle", "0,90", "-o", out)  # another grid
    assert clash.exit_code == 2 and "--force" in clash.stderr


@pytest.mark.once
def test_an_angle_sweep_opens_in_xarray_with_a_slip_angle_dimension(tmp_path, box):
    xr = pytest.importorskip("xarray")
    pytest.importorskip("h5netcdf")
    out = tmp_path / "s.h5"
    res = run_cli("sweep", box, "--nu", "0.2,0.3", "--slip-angle", "60,0,120", "-o", out,
                  "-j", "2")
    assert res.exit_code == 0, res.output
    with xr.open_dataset(out, engine="h5netcdf") as ds:
        assert ds.positive.dims == ("element", "size", "slip_angle", "nu", "rank")
        assert list(ds.slip_angle.values) == [0.0, 60.0, 120.0]
        assert ds.minimum.dims == ("element", "size", "nu")
        assert np.all(ds.minimum.values <= ds.positive.isel(rank=0).min("slip_angle").values)
        assert ds.minimum_slip_angle.attrs["units"] == "degree"
