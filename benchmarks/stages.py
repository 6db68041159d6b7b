"""Stage table of `critfric solve` against one bare factorization (run by hand, not in CI).

    python benchmarks/stages.py                        # ~0.3 M and ~1.2 M DOFs, every backend
    python benchmarks/stages.py --sizes 0.3M --backends scipy
    python benchmarks/stages.py --root ../other-tree   # the same table for another checkout
    python benchmarks/stages.py --sizes 1.2M --backends pardiso --rounds 5   # and the median

For each size and backend, side by side in one run (a shared machine's load varies, so read
the ratios): ``critfric solve unit-square --size S --json --backend B`` in a fresh process,
its wall time from process start to exit and its peak RSS (wait4), the stage times it writes
in its result file (mesh, assembly, contact, eigen; rest = start-up, mesh diameter, modes,
the HDF5 write, exit), and, in another fresh process, one factorization of the same K with
the same backend and ordering (``benchmarks/scale.py --child factor``: PARDISO with METIS's
parallel version and the two-level factorization, critfric's fastest plain one, or SuperLU
with critfric's nested-dissection order). ratio = solve wall / factorization.
With ``--rounds N`` each row is measured N times (the factorization first in even rounds) and
the median ratio follows: a shared machine's load moves a single ratio by 5-10 %.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
SIZES = {"66k": 0.0056, "0.3M": 0.0028, "1.2M": 0.0014, "4.2M": 0.00078}  # mesh size -> DOFs
STAGES = ("mesh", "assembly", "contact", "eigen")


def solve(root: Path, size: float, backend: str) -> dict:
    import h5py

    env = dict(os.environ, PYTHONPATH=str(root))
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "r.h5"
        cmd = [sys.executable, "-m", "critfric", "solve", "unit-square", "--size", str(size),
               "--json", "--backend", backend, "-o", str(out), "--force"]
        wall, peak, stdout = _run_measured(cmd, env, cwd=root)
        with h5py.File(out) as f:
            stages = {s: float(f.attrs[f"seconds_{s}"]) for s in STAGES}
    summary = json.loads(stdout)
    return dict(stages, wall=wall, peak=peak, n_dofs=summary["n_dofs"],
                critical=summary["positive"][0])


def factor(root: Path, size: float, backend: str) -> dict:
    env = dict(os.environ, PYTHONPATH=str(root))
    cmd = [sys.executable, str(HERE / "scale.py"), "--child", "factor", str(size), backend]
    wall, peak, stdout = _run_measured(cmd, env)
    return dict(json.loads(stdout.strip().splitlines()[-1]), peak=peak)


def _run_measured(cmd: list[str], env: dict, cwd: Path | None = None
                  ) -> tuple[float, float, str]:
    """Wall seconds, peak RSS in MB (from wait4) and stdout of a fresh process. ``python -m``
    puts its working directory first on sys.path (before PYTHONPATH): run it in the checkout
    measured, or another checkout's critfric is measured instead."""
    t = time.perf_counter()
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=env,
                            text=True, cwd=cwd)
    out, err = proc.stdout.read(), proc.stderr.read()
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - t
    proc.returncode = os.waitstatus_to_exitcode(status)
    if proc.returncode:
        last = (err.strip().splitlines() or ["killed"])[-1]
        raise RuntimeError(f"{' '.join(cmd[1:5])} ... failed: {last}")
    return wall, usage.ru_maxrss / 1e3, out  # KB -> MB (Linux)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", default="0.3M,1.2M", help=f"of {', '.join(SIZES)}")
    ap.add_argument("--backends", default="pardiso,scipy")
    ap.add_argument("--root", default=str(HERE.parent), help="critfric checkout to measure")
    ap.add_argument("--rounds", type=int, default=1,
                    help="pairs of runs per row (the order alternated), then their median ratio")
    a = ap.parse_args()
    root = Path(a.root).resolve()
    print(f"critfric from {root}; seconds (share of the wall time), peak RSS in MB\n")
    print("| DOFs | backend | mesh | assembly | contact | eigen | rest | solve wall | peak MB "
          "| one factorization (peak MB) | ratio |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for name in filter(None, a.sizes.split(",")):
        for b in filter(None, a.backends.split(",")):
            ratios = []
            for rnd in range(a.rounds):
                try:
                    if rnd % 2 == 0:
                        r, f = solve(root, SIZES[name], b), factor(root, SIZES[name], b)
                    else:
                        f, r = factor(root, SIZES[name], b), solve(root, SIZES[name], b)
                except RuntimeError as exc:
                    print(f"| ~{name} | {b} | {exc} |" + " |" * 9, flush=True)
                    break
                rest = r["wall"] - sum(r[s] for s in STAGES)
                cells = [f"{r[s]:.2f} ({100 * r[s] / r['wall']:.0f}%)" for s in STAGES]
                cells.append(f"{rest:.2f} ({100 * rest / r['wall']:.0f}%)")
                print(f"| {r['n_dofs']} | {b} | " + " | ".join(cells)
                      + f" | {r['wall']:.2f} | {r['peak']:.0f} | {f['factor']:.2f} "
                      f"({f['peak']:.0f}) | {r['wall'] / f['factor']:.2f} |", flush=True)
                ratios.append(r["wall"] / f["factor"])
            if len(ratios) > 1:
                print(f"| | {b} | median ratio of {len(ratios)} rounds: "
                      f"{statistics.median(ratios):.2f} |" + " |" * 8, flush=True)


if __name__ == "__main__":
    main()
