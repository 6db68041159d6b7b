"""Sweep benchmark: 11 nu x 3 sizes on the unit square (P1), meshes reused or rebuilt.

Run by hand (not in CI):  python benchmarks/sweep_reuse.py [--jobs 1,2] [--sizes ...]
Prints, for each job count, the best wall time of --repeat runs with mesh/assembly reuse and
without (every point meshes and assembles its own system), and checks that both give the
same values. Timings on a shared machine vary: run it on an idle one.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np

import critfric
from critfric.sweep.runner import make_grid, run_sweep


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
    parser.add_argument("--repeat", type=int, default=2)
    args = parser.parse_args()
    case = critfric.load_case("unit-square")
    grid = make_grid(case, nu=args.nu, size=args.sizes, element=args.element)
    print(f"unit square, {args.element}, {len(grid.nu)} nu x sizes {grid.size}: "
          f"{len(grid.points())} points")
    with tempfile.TemporaryDirectory() as tmp:
        warm = make_grid(case, nu="0.3", size=args.sizes.split(",")[0], element=args.element)
        run_sweep(case, warm, output=Path(tmp) / "warm.h5", jobs=1)  # imports, gmsh, BLAS
        for jobs in (int(j) for j in args.jobs.split(",")):
            best = {True: float("inf"), False: float("inf")}
            busy, rows = {}, {}
            for _ in range(args.repeat):  # alternate the order; keep the best of each
                for reuse in (False, True):
                    t, sweep = timed(case, grid, Path(tmp) / f"{reuse}.h5", jobs=jobs,
                                     reuse=reuse)
                    if t < best[reuse]:
                        best[reuse] = t
                        busy[reuse] = sum(r["seconds"] for r in sweep.rows)
                    rows[reuse] = sweep.rows
            for ra, rb in zip(rows[True], rows[False]):
                np.testing.assert_allclose(ra["positive"], rb["positive"], rtol=1e-9)
            print(f"jobs {jobs}: reuse {best[True]:6.2f} s (sum over points {busy[True]:6.2f} s)"
                  f"   no reuse {best[False]:6.2f} s (sum {busy[False]:6.2f} s)   "
                  f"speed-up {best[False] / best[True]:.2f}x")


if __name__ == "__main__":
    main()
