"""Shared test set-up: ``helpers`` importable from every test folder, shared fixtures."""

from __future__ import annotations

import os
import sys
from pathlib import Path

import pytest
from threadpoolctl import threadpool_limits

from critfric.guards import usable_cpus
from critfric.sweep.workers import THREAD_VARS

sys.path.insert(0, str(Path(__file__).resolve().parent))  # tests/<stage>/ import helpers

from helpers import square_case


def _share_the_cores() -> None:
    """Under ``pytest -n N`` each worker runs its BLAS and OpenMP libraries (OpenBLAS, MKL's
    PARDISO, gmsh) on its share of the cores, as a sweep's worker processes do: with each
    library's default count the workers' thread teams contend for the same cores (the suite
    takes 10-15 % longer on 2 cores). Variables the caller set are kept. The tests of thread
    counts raise them where they need more (threadpoolctl)."""
    workers = int(os.environ.get("PYTEST_XDIST_WORKER_COUNT", "1"))
    if "PYTEST_XDIST_WORKER" not in os.environ or workers < 2:
        return
    share = max(1, usable_cpus() // workers)
    for name in THREAD_VARS:
        os.environ.setdefault(name, str(share))  # MKL reads it when PARDISO first loads it
    blas = os.environ["OPENBLAS_NUM_THREADS"]
    threadpool_limits(int(blas) if blas.isdigit() else share, user_api="blas")  # loaded


_share_the_cores()


def pytest_collection_modifyitems(items):
    """The tests marked slow first (stable order otherwise): under ``pytest -n`` the long
    ones no longer start last and leave one worker running alone."""
    items.sort(key=lambda item: item.get_closest_marker("slow") is None)


@pytest.fixture(scope="session")
def coarse_square():
    """The unit square case at size 0.2 (P1) and its prepared system, shared by the session."""
    from critfric import loads_case, prepare

    case = loads_case(square_case(size=0.2))
    return case, prepare(case)


@pytest.fixture(autouse=True)
def no_analysis_outlives_its_test():
    """No background factorization analysis is still running once a test is over: the call
    that started one waits for it on every way out (an error included). The MKL thread stays,
    idle."""
    import threading

    from critfric.solvers.pardiso import MKL_THREAD

    yield
    left = [t.name for t in threading.enumerate()
            if t.name.startswith("critfric-") and t.name != "critfric-mkl"]
    assert not left, f"background threads still running: {left}"
    assert MKL_THREAD.idle, "an MKL call is still queued or running"
