"""Sweep benchmark: 11 nu x 3 sizes on the unit square (P1), meshes reused or rebuilt.

Run by hand (not in CI):  python benchmarks/sweep_reuse.py [--jobs 1,2] [--sizes ...]
Prints, for each job count, the wall time with mesh/assembly reuse and without (every point
meshes and assembles its own system), and checks that both give the same values.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np

import critfric
from critfric.sweep import make_grid, run_sweep


def timed(case, grid, out: Path, *, jobs: int, reuse: bool):
    t0 = time.perf_counter()
    sweep = run_sweep(case, grid, output=out, jobs=jobs, reuse=reuse, force=True)
    return time.perf_counter() - t0, sweep


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--nu", default="0.02:0.48:11")
    parser.add_argument("--sizes", default="0.05,0.025,0.0125")
    parser.add_argument("--element", default="P1")
    parser.add_argument("--jobs", default="1,2")
    args = parser.parse_args()
    case = critfric.load_case("unit-square")
    grid = make_grid(case, nu=args.nu, size=args.sizes, element=args.element)
    print(f"unit square, {args.element}, {len(grid.nu)} nu x sizes {grid.size}: "
          f"{len(grid.points())} points")
    with tempfile.TemporaryDirectory() as tmp:
        for jobs in (int(j) for j in args.jobs.split(",")):
            t_reuse, a = timed(case, grid, Path(tmp) / "a.h5", jobs=jobs, reuse=True)
            t_fresh, b = timed(case, grid, Path(tmp) / "b.h5", jobs=jobs, reuse=False)
            for ra, rb in zip(a.rows, b.rows):
                np.testing.assert_allclose(ra["positive"], rb["positive"], rtol=1e-9)
            busy = sum(r["seconds"] for r in a.rows), sum(r["seconds"] for r in b.rows)
            print(f"jobs {jobs}: reuse {t_reuse:6.2f} s (points {busy[0]:6.2f} s)   "
                  f"no reuse {t_fresh:6.2f} s (points {busy[1]:6.2f} s)   "
                  f"speed-up {t_fresh / t_reuse:.2f}x")


if __name__ == "__main__":
    main()
