"""Shared test set-up: ``helpers`` importable from every test folder, shared fixtures."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))  # tests/<stage>/ import helpers

from helpers import square_case


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
