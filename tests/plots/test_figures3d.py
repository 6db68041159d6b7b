"""Figures of 3D solve files: the spectrum coloured by r and each plotted mode on Gamma_C in
its plane coordinates; the 2D figures as before."""

from __future__ import annotations

import numpy as np
import pytest
from helpers import box_case, run_cli, square_case
from matplotlib.collections import PolyCollection
from matplotlib.image import imread
from matplotlib.quiver import Quiver

import critfric
from critfric.case.schema import loads_case
from critfric.files.results import write_result
from critfric.plots.figures import figures, plot_file

pytestmark = pytest.mark.once  # the same on both installs: run by `make test` only


def assert_png(path):
    assert path.exists() and path.stat().st_size > 1000
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    image = imread(path)
    assert image.ndim == 3 and image.shape[0] > 200 and image.shape[1] > 200
    assert np.ptp(image[..., :3]) > 0.5  # not a blank canvas


@pytest.mark.parametrize("element", ["P1", "Q2"])
def test_solve_plot_writes_the_3d_figures(tmp_path, element):
    case = tmp_path / "box.toml"
    case.write_text(box_case(element=element, size=0.4, depth=0.8, extra="[solve]\nslip_angle = 30"))
    out = tmp_path / "box.h5"
    res = run_cli("solve", case, "-o", out, "--plot")
    assert res.exit_code == 0, res.output
    names = ("contact_positive_0", "contact_negative_0", "spectrum")
    for name in names:
        assert_png(tmp_path / f"box_{name}.png")
        assert f"box_{name}.png" in res.stderr
    (tmp_path / "box_spectrum.png").unlink()
    res = run_cli("plot", out, "--format", "png,svg")
    assert res.exit_code == 0, res.output
    assert sorted(p.name for p in tmp_path.glob("box_*.*") if p.suffix != ".h5") == sorted(
        f"box_{n}.{ext}" for n in names for ext in ("png", "svg"))
    assert_png(tmp_path / "box_spectrum.png")


@pytest.fixture(scope="module")
def box(tmp_path_factory):
    result = critfric.solve_case(loads_case(box_case(element="P2", size=0.4, depth=0.8, extra="[solve]\nslip_angle = 30"), name="box"))
    path = tmp_path_factory.mktemp("box") / "box.h5"
    write_result(result, path)
    system = critfric.prepare(result.case).system
    return result, system, path


def test_the_contact_figure_draws_phi_t_and_x_in_plane_coordinates(box):
    result, system, path = box
    figs = figures(path)
    assert sorted(figs) == ["contact_negative_0", "contact_positive_0", "spectrum"]
    mode = next(m for m in result.modes if m["alpha"] > 0)
    left, right = figs["contact_positive_0"].axes[:2]  # (then their colour bars)
    t1 = system.tangent
    t2 = np.cross(system.normal, t1)
    phi = mode["phi"] / np.max(np.linalg.norm(mode["phi"], axis=1))
    nodes = system.nodes
    (arrows,) = [c for c in left.collections if isinstance(c, Quiver)]
    np.testing.assert_allclose(arrows.U, phi[nodes] @ t1, atol=1e-12)
    np.testing.assert_allclose(arrows.V, phi[nodes] @ t2, atol=1e-12)
    uv = result.mesh.points[nodes] @ np.column_stack([t1, t2])
    face = np.unique(np.concatenate([result.mesh.faces["y0"].ravel(), nodes]))
    uv -= (result.mesh.points[face] @ np.column_stack([t1, t2])).min(axis=0)
    np.testing.assert_allclose(arrows.X, uv[:, 0], atol=1e-12)
    np.testing.assert_allclose(arrows.Y, uv[:, 1], atol=1e-12)
    (dots,) = [c for c in right.collections if c.get_array() is not None
               and not isinstance(c, Quiver)]
    x = mode["theta_n"]
    np.testing.assert_allclose(dots.get_array(), x / np.max(np.abs(x)), atol=1e-12)
    (slips,) = [c for c in right.collections if isinstance(c, Quiver)]
    np.testing.assert_allclose(slips.U, np.cos(np.radians(30.0)), atol=1e-12)
    np.testing.assert_allclose(slips.V, np.sin(np.radians(30.0)), atol=1e-12)
    shade = [c for c in left.collections if isinstance(c, PolyCollection)
             or type(c).__name__ == "TriMesh"]
    assert shade  # |Phi_t| drawn over the contact face
    assert f"r = {mode['r']:.3g}" in figs["contact_positive_0"]._suptitle.get_text()


def test_the_3d_spectrum_colours_the_real_eigenvalues_by_r(box):
    result, _, path = box
    fig = figures(path)["spectrum"]
    real = result.alpha.imag == 0
    coloured = [c for ax in fig.axes for c in ax.collections
                if c.get_array() is not None and len(c.get_array()) == real.sum()]
    assert len(coloured) == 2  # both panels
    for c in coloured:
        np.testing.assert_allclose(c.get_array(), result.r[real])
    labels = fig.axes[1].get_legend_handles_labels()[1]
    assert any(f"r = {result.r_of(result.positive)[0]:.3g}" in text for text in labels)


def test_the_2d_figures_are_those_of_before(tmp_path):
    out = tmp_path / "sq.h5"
    write_result(critfric.solve_case(loads_case(square_case(size=0.5))), out)
    figs = figures(out)
    assert sorted(figs) == ["contact_forces", "deformed", "spectrum", "von_mises"]
    spectrum = figs["spectrum"]
    assert len(spectrum.axes) == 2  # no colour bar
    assert all(c.get_array() is None for ax in spectrum.axes for c in ax.collections)
    written = plot_file(out)
    assert sorted(p.name for p in written) == sorted(
        f"sq_{n}.png" for n in ("contact_forces", "deformed", "spectrum", "von_mises"))
