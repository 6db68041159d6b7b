"""3D box: `critfric solve` against one bare factorization of its K, and the peak memory that
calibrates the 3D resource guard (run by hand, not in CI).

    python benchmarks/box3d.py                                  # P1 ~300 k DOFs, every backend
    python benchmarks/box3d.py --runs P1:0.016:pardiso,P1:0.025:scipy
    python benchmarks/box3d.py --runs P1:0.016:pardiso --csv benchmarks/box3d_memory.csv

The case is the box of the 3D example (1 x 0.5 x 1, contact y0, Dirichlet y1, nu = 0.3) at
mesh size h. For each run ``element:h:backend``, side by side: ``critfric solve`` in a fresh
process (wall time from process start to exit, its peak RSS from wait4, its stage times from
the result file; rest = start-up, modes, HDF5 write, exit), and, in another fresh process,
one factorization of the same K (all free DOFs, nu = 0.3) with the same backend: PARDISO
(METIS analysis + numeric phase) or SuperLU with critfric's nested-dissection order (the
order's computation included). ratio = solve wall / factorization. Each child is capped at
MEM_LIMIT_GB of address space.

Measured (P1 box, nu = 0.3; 2 cores, 23 GB, MKL 2026.2.0, SciPy 1.17; a shared machine:
repeat runs vary by about +/-20%). "before": this tree with ordering, backends, pardiso,
guards and eigen as before 3D orders (other modules as now), run side by side with "after".
"+ 3D ARPACK order": after, with ``eigenproblem.fill_order_for`` also giving the 3D order
(one line, outside this benchmark's change; measured on a copy of the tree).

Fast install (PARDISO). Target: a 300 k-DOF P1 box in at most 1.5 factorizations.

| DOFs | p | tree (method) | mesh | assembly | contact | eigen | rest | wall | peak GB | factor s (peak GB) | ratio |
|---|---|---|---|---|---|---|---|---|---|---|---|
| 283185 | 4754 | before (arpack) | 22.5 | 1.5 | 0.8 | 44.2 | 0.7 | 69.6 | 3.54 | 22.9 (4.10) | 3.03 |
| 283185 | 4754 | after (arpack) | 18.8 | 1.6 | 0.7 | 44.0 | 0.6 | 65.7 | 3.54 | 23.4 (4.11) | 2.81 |
| 75672 | 1930 | before (dense) | 3.5 | 0.3 | 0.2 | 9.7 | 0.5 | 14.2 | 1.90 | 1.9 (0.85) | 7.44 |
| 75672 | 1930 | after (dense) | 4.4 | 0.4 | 0.3 | 9.6 | 0.6 | 15.2 | 1.70 | 2.0 (0.85) | 7.47 |

Where the 283 k solve goes (cProfile, in one process): mesh 21.7 s = gmsh's generate(3)
13.0 + cells3d.locate_faces 7.3 (called once per face group, each time ranking all 6.4 M
cell faces); assembly 2.0; contact 1.3; eigen 46.5 = the factorization of K_c 21.2 (analysis
2.4, numeric 18.6) + ARPACK's 150 solves 24.7 (0.17 s each; k = 2). Measured beside it:
gmsh's HXT (Mesh.Algorithm3D = 10, one thread) meshes 51 k nodes in 1.1 s against Delaunay's
9.3 s (11% fewer nodes, a better worst cell); ARPACK needs 96 applications at tol = 1e-10
against 149 at tol = 0 (76 k DOFs, the same alpha to 12 digits), and no fewer with ncv 30-80.
The dense path (3p <= 8000) pays for its Schur complement: PARDISO's onto 5790 rows takes
10 s against 2.4 s for the plain factorization (76 k DOFs; 91 M against 51 M factor entries).

SciPy-only install (SuperLU with critfric's orders):

| DOFs | p | tree (method) | mesh | assembly | contact | eigen | rest | wall | peak GB | factor s (peak GB) | ratio |
|---|---|---|---|---|---|---|---|---|---|---|---|
| 283185 | 4754 | + 3D ARPACK order (arpack) | 20.6 | 1.4 | 0.7 | 299.1 | 0.6 | 322.3 | 11.10 | 212.9 (11.92) | 1.51 |
| 144351 | 3017 | after (arpack) | 7.6 | 0.6 | 0.4 | 1351.0 | 0.5 | 1360.1 | 12.42 | 54.6 (3.69) | 24.9 |
| 144351 | 3017 | + 3D ARPACK order (arpack) | 8.3 | 0.7 | 0.4 | 78.4 | 0.6 | 88.3 | 3.32 | 51.2 (3.70) | 1.73 |
| 75672 | 1930 | before (dense) | | | | | | 140.1 | 5.45 | | |
| 75672 | 1930 | after (dense) | 4.1 | 0.3 | 0.2 | 36.0 | 0.6 | 41.3 | 3.16 | 13.9 (1.57) | 2.98 |

The memory of every run that calibrates critfric.guards' 3D model: box3d_memory.csv (P1, P2,
Q1, Q2; 20 k-570 k DOFs; both backends).
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
STAGES = ("mesh", "assembly", "contact", "eigen")
MEM_LIMIT_GB = 18.0  # address space of each child: fail alone, never swamp the machine
CASE = """title = "box on a plane"
[geometry]
shape = "box"
size = [1.0, 0.5, 1.0]
[boundary]
contact = ["y0"]
dirichlet = ["y1"]
[material]
nu = 0.3
[mesh]
element = "{element}"
size = {size}
"""
HEADER = ("| DOFs | p | backend (method) | mesh | assembly | contact | eigen | rest | wall "
          "| peak GB | factor s (peak GB) | ratio |\n" + "|---" * 12 + "|")
FIELDS = ("element", "size", "backend", "n_dofs", "n_contact", "method", "applications",
          *STAGES, "wall", "peak_mb", "factor", "factor_peak_mb", "nnz_factor", "ratio", "note")


def _case(element: str, size: float):
    from critfric.case.schema import loads_case

    return loads_case(CASE.format(element=element, size=size))


def child_factor(element: str, size: float, backend: str) -> dict:
    """One factorization of the box's K (every free DOF) with ``backend``."""
    import critfric
    from critfric.fem.assembly import lame
    from critfric.solvers.backends import ScipyFactor
    from critfric.solvers.ordering import fill_order
    from critfric.solvers.pardiso import PardisoFactor

    prep = critfric.prepare(_case(element, size), max_dofs=10**9)
    K = prep.system.stiffness(*lame(1.0, 0.3))
    t = time.perf_counter()
    if backend == "pardiso":
        nnz = int(PardisoFactor(K, symmetric=True)._iparm[17])  # nonzeros in the factor
    else:
        nnz = ScipyFactor(K, symmetric=True, order=fill_order(prep.system))._lu.nnz  # L + U
    return {"factor": time.perf_counter() - t, "nnz_factor": nnz}


def _cap_memory() -> None:
    limit = int(MEM_LIMIT_GB * 2**30)
    resource.setrlimit(resource.RLIMIT_AS, (limit, limit))


def _run_measured(cmd: list[str], cwd: Path) -> tuple[float, float, str]:
    """Wall seconds, peak RSS in MB (wait4) and stdout of a fresh process (run in the
    checkout: ``python -m`` puts its working directory first on sys.path)."""
    env = dict(os.environ, PYTHONPATH=str(cwd))
    with tempfile.TemporaryFile("w+") as out, tempfile.TemporaryFile("w+") as err:
        t = time.perf_counter()
        proc = subprocess.Popen(cmd, stdout=out, stderr=err, env=env, text=True, cwd=cwd,
                                preexec_fn=_cap_memory)  # noqa: PLW1509 (no threads here)
        _, status, usage = os.wait4(proc.pid, 0)
        wall = time.perf_counter() - t
        proc.returncode = os.waitstatus_to_exitcode(status)
        out.seek(0), err.seek(0)
        if proc.returncode:
            last = (err.read().strip().splitlines() or ["killed"])[-1]
            raise RuntimeError(f"{' '.join(cmd[1:6])} ... failed: {last}")
        return wall, usage.ru_maxrss / 1e3, out.read()  # KB -> MB (Linux)


def solve(root: Path, element: str, size: float, backend: str) -> dict:
    import h5py

    with tempfile.TemporaryDirectory() as tmp:
        case, out = Path(tmp) / "box.toml", Path(tmp) / "box.h5"
        case.write_text(CASE.format(element=element, size=size))
        cmd = [sys.executable, "-m", "critfric", "solve", str(case), "--backend", backend,
               "--json", "-o", str(out), "--force", "--max-dofs", str(10**9)]
        wall, peak, stdout = _run_measured(cmd, root)
        with h5py.File(out) as f:
            stages = {s: float(f.attrs[f"seconds_{s}"]) for s in STAGES}
            applications = int(f.attrs["applications"])
    summary = json.loads(stdout)
    return dict(stages, wall=wall, peak_mb=peak, n_dofs=summary["n_dofs"],
                n_contact=summary["n_contact"], method=summary["method"],
                applications=applications, critical=summary["positive"][0])


def factor(root: Path, element: str, size: float, backend: str) -> dict:
    cmd = [sys.executable, str(Path(__file__).resolve()), "--child", element, str(size),
           backend]
    _, peak, stdout = _run_measured(cmd, root)
    return dict(json.loads(stdout.strip().splitlines()[-1]), factor_peak_mb=peak)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", default="P1:0.016:pardiso,P1:0.016:scipy",
                    help="element:size:backend, comma-separated")
    ap.add_argument("--root", default=str(ROOT), help="critfric checkout to measure")
    ap.add_argument("--csv", default="", help="append the rows to this CSV file")
    ap.add_argument("--child", nargs=3, help=argparse.SUPPRESS)
    a = ap.parse_args()
    if a.child:
        print(json.dumps(child_factor(a.child[0], float(a.child[1]), a.child[2])))
        return
    root = Path(a.root).resolve()
    print(f"critfric from {root}; seconds, peak RSS in GB\n")
    print(HEADER)
    for run in filter(None, a.runs.split(",")):
        element, size, backend = run.split(":")
        try:
            r = solve(root, element, float(size), backend)
            r.update(factor(root, element, float(size), backend))
        except RuntimeError as exc:
            print(f"| {run} | {exc} |" + " |" * 10, flush=True)
            continue
        r.update(element=element, size=size, backend=backend, ratio=r["wall"] / r["factor"])
        rest = r["wall"] - sum(r[s] for s in STAGES)
        print(f"| {r['n_dofs']} | {r['n_contact']} | {backend} ({r['method']}) | "
              + " | ".join(f"{r[s]:.1f}" for s in STAGES)
              + f" | {rest:.1f} | {r['wall']:.1f} | {r['peak_mb'] / 1e3:.2f} "
              f"| {r['factor']:.1f} ({r['factor_peak_mb'] / 1e3:.2f}) | {r['ratio']:.2f} |",
              flush=True)
        if a.csv:
            new = not Path(a.csv).exists()
            with open(a.csv, "a", newline="") as f:
                w = csv.DictWriter(f, fieldnames=FIELDS, extrasaction="ignore")
                if new:
                    w.writeheader()
                w.writerow({k: (f"{v:.2f}" if isinstance(v, float) else v)
                            for k, v in r.items()})


if __name__ == "__main__":
    main()
