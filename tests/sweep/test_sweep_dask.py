"""The Dask path: the same points on a LocalCluster (loopback), the file written by the client."""

from __future__ import annotations

import numpy as np
import pytest
from helpers import CASES, square_case

import critfric
from critfric.errors import CaseError
from critfric.files.sweepfile import read_sweep
from critfric.sweep import workers
from critfric.sweep.runner import make_grid, run_sweep

pytestmark = pytest.mark.once  # the same on both installs: run by `make test` only

distributed = pytest.importorskip("distributed")


@pytest.fixture(scope="module")
def cluster():
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  host="127.0.0.1", dashboard_address=None) as c:
        yield c.scheduler_address


@pytest.mark.parametrize("name,grid", [
    ("square", dict(nu="0.1,0.3,0.45", size="0.2,0.1", element="P1,Q2")),
    ("four", dict(nu="0:0.5:6")),
])
def test_dask_gives_the_local_numbers(tmp_path, cluster, name, grid):
    case = (critfric.loads_case(square_case(size=0.2)) if name == "square"
            else critfric.load_case(CASES / "four_triangles.toml"))
    g = make_grid(case, **grid)
    local = run_sweep(case, g, output=tmp_path / "local.h5", jobs=1)
    seen = []
    remote = run_sweep(case, g, output=tmp_path / "dask.h5", scheduler=cluster,
                       on_point=lambda row, done, total: seen.append(done))
    assert remote.computed == len(g.points()) and seen[-1] == len(g.points())
    rows = read_sweep(tmp_path / "dask.h5")["rows"]
    assert len({(r["element"], r["size"], r["nu"]) for r in rows}) == len(rows) == len(seen) - 1
    for a, b in zip(local.rows, remote.rows):
        assert (a["nu"], a["size"], a["element"], a["status"]) == \
            (b["nu"], b["size"], b["element"], b["status"])
        np.testing.assert_allclose(a["positive"], b["positive"], rtol=1e-10)
        np.testing.assert_allclose(a["negative"], b["negative"], rtol=1e-10)
    again = run_sweep(case, g, output=tmp_path / "dask.h5", scheduler=cluster)
    assert again.computed == 0


def test_an_unreachable_scheduler_is_a_case_error(tmp_path, monkeypatch):
    case = critfric.load_case(CASES / "four_triangles.toml")
    monkeypatch.setattr(workers, "CONNECT_TIMEOUT", "1s")
    with pytest.raises(CaseError, match="--scheduler"):
        run_sweep(case, make_grid(case, nu="0.2,0.3"), output=tmp_path / "s.h5",
                  scheduler="tcp://127.0.0.1:9")
    assert not (tmp_path / "s.h5").exists()  # refused before anything is written
