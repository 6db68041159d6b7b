"""Stability at scale (run by hand, not in CI): ``critfric stability`` against ``critfric
solve`` on the same P1 unit-square mesh, side by side in one run, each in a fresh process.

    python benchmarks/stability.py                  # 295 k DOFs, the installed backends
    python benchmarks/stability.py --size 0.004 --modes 10 --backend scipy

Prints the wall time of each command (imports included), their ratio (the budget: stability
<= 4 static solves) and the stages of the stability run.
"""

from __future__ import annotations

import argparse
import json
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
    a = p.parse_args()
    common = ["unit-square", "--size", str(a.size), "--backend", a.backend, "--force"]
    with tempfile.TemporaryDirectory() as tmp:
        t_solve, solve = run(["solve", *common, "-o", str(Path(tmp) / "s.h5")])
        t_stab, stab = run(["stability", *common, "--modes", str(a.modes),
                            "-o", str(Path(tmp) / "t.h5")])
    s = stab["summary"]
    print(f"n_dofs {s['n_dofs']}, backend {s['backend']}, modes {s['modes']}")
    print(f"solve      {t_solve:8.2f} s   critical {solve['summary']['positive'][:1]}")
    print(f"stability  {t_stab:8.2f} s   flutter {s['flutter']}  divergence {s['divergence']}")
    print(f"ratio stability / solve = {t_stab / t_solve:.2f}")
    print([line for line in stab["log"].splitlines() if "stages" in line])


if __name__ == "__main__":
    main()
