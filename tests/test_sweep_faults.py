"""Sweeps under faults: killed while writing a point, Ctrl-C with worker processes, two
sweeps on one file, and the same values with any number of jobs."""

from __future__ import annotations

import os
import random
import signal
import time

import numpy as np
import pytest

import critfric
from critfric.errors import CaseError
from critfric.sweep import Point, empty_row, make_grid, run_sweep
from critfric.sweepfile import append_point, open_sweep, read_sweep

from helpers import CASES


def _row(i: int) -> dict:
    row = empty_row(Point(round(0.1 + 1e-6 * i, 9), None, "P1"), "ok")
    row.update(positive=[1.0 + i], negative=[-1.0 - i], n_dofs=6, n_contact=2, h=1.0,
               complex_count=0)
    return row


def test_a_sweep_file_killed_while_writing_a_point_stays_readable_and_appendable(tmp_path):
    """A child process appends points as fast as it can and is killed (SIGKILL) at random
    moments, nearly always inside a write: the file must keep every point written before and
    take the next one."""
    case = critfric.load_case(CASES / "four_triangles.toml")
    grid = make_grid(case, nu="0.1,0.2")
    rng = random.Random(6)
    for k in range(20):
        path = tmp_path / f"s{k}.h5"
        open_sweep(path, case=case, grid=grid)
        pid = os.fork()
        if pid == 0:  # the child: append until killed
            try:
                i = 0
                while True:
                    append_point(path, _row(i))
                    i += 1
            finally:
                os._exit(0)
        time.sleep(rng.uniform(0.01, 0.12))
        os.kill(pid, signal.SIGKILL)
        os.waitpid(pid, 0)
        rows = read_sweep(path)["rows"]
        assert [r["positive"] for r in rows] == [[1.0 + i] for i in range(len(rows))]
        append_point(path, _row(10**6))
        again = read_sweep(path)["rows"]
        assert len(again) == len(rows) + 1 and again[-1]["positive"] == [1.0 + 10**6]
        for leftover in tmp_path.glob(f".s{k}.h5.*"):  # a temporary file may remain: harmless
            leftover.unlink()
