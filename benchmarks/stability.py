"""Stability at scale (run by hand, not in CI): ``critfric stability`` against ``critfric
solve`` on the same P1 unit-square mesh, side by side in one run, each in a fresh process.

    python benchmarks/stability.py                  # 295 k DOFs, the installed backends
    python benchmarks/stability.py --size 0.004 --modes 10 --backend scipy
    python benchmarks/stability.py --rounds 5       # five pairs, the order alternated

Prints the wall time of each command (imports included), their ratio (the budget: stability
<= 4 static solves) and the stages of the stability run; with several rounds, each round's
ratio (the two commands back to back, solve first in odd rounds) and their median: a shared
machine's load moves a single ratio by 10-30 %.
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path


def run(args: list[str]) -> tuple[float, dict]:
    t0 = time.perf_counter()
    out = subprocess.run([sys.executable, "-m", "critfric", "-v", *args, "--json"],
                         capture_output=True, text=True, check=True)
    return time.perf_counter() - t0, {"summary": json.loads(out.stdout), "log": out.stderr}


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--size", type=float, default=0.00296, help="mesh size (0.00296: 295 k DOFs)")
    p.add_argument("--modes", type=int, default=10)
    p.add_argument("--backend", default="auto")
    p.add_argument("--rounds", type=int, default=1, help="pairs of runs (order alternated)")
    a = p.parse_args()
    common = ["unit-square", "--size", str(a.size), "--backend", a.backend, "--force"]
    ratios = []
    with tempfile.TemporaryDirectory() as tmp:
        solve_args = ["solve", *common, "-o", str(Path(tmp) / "s.h5")]
        stab_args = ["stability", *common, "--modes", str(a.modes), "-o", str(Path(tmp) / "t.h5")]
        for r in range(a.rounds):
            if r % 2 == 0:
                (t_solve, solve), (t_stab, stab) = run(solve_args), run(stab_args)
            else:
                (t_stab, stab), (t_solve, solve) = run(stab_args), run(solve_args)
            s = stab["summary"]
            if r == 0:
                print(f"n_dofs {s['n_dofs']}, backend {s['backend']}, modes {s['modes']}")
            print(f"round {r + 1}: solve {t_solve:6.2f} s (critical "
                  f"{solve['summary']['positive'][:1]}), stability {t_stab:6.2f} s (flutter "
                  f"{s['flutter']}, divergence {s['divergence']}), ratio {t_stab / t_solve:.2f}")
            print("  " + "".join(line for line in stab["log"].splitlines() if "stages" in line))
            ratios.append(t_stab / t_solve)
    print(f"ratio stability / solve = {statistics.median(ratios):.2f} (median of "
          f"{len(ratios)}: {', '.join(f'{x:.2f}' for x in ratios)})")


if __name__ == "__main__":
    main()
