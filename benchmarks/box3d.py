"""3D box: `critfric solve` against one bare factorization of its K, and the peak memory that
calibrates the 3D resource guard (run by hand, not in CI).

    python benchmarks/box3d.py                                  # P1 ~300 k DOFs, both backends
    python benchmarks/box3d.py --runs P1:0.016:pardiso,P1:0.025:scipy
    python benchmarks/box3d.py --runs P1:0.016:pardiso --csv benchmarks/box3d_memory.csv

The case is the box of the 3D example (1 x 0.5 x 1, contact y0, Dirichlet y1, nu = 0.3) at
mesh size h. For each run ``element:h:backend``, side by side: ``critfric solve`` in a fresh
process (wall time from process start to exit, its peak RSS from wait4, its stage times from
the result file; rest = start-up, modes, HDF5 write, exit), and, in another fresh process,
one factorization of the same K (all free DOFs, nu = 0.3) with the same backend: PARDISO
(METIS analysis, its parallel version, + two-level numeric phase) or SuperLU with critfric's nested-dissection order (the
order's computation included). ratio = solve wall / factorization. Each child is capped at
MEM_LIMIT_GB of address space.

Measured (P1 box, nu = 0.3; 2 cores, 23 GB, MKL 2026.2.0, SciPy 1.17; a machine shared with
other jobs: repeat runs vary by about +/-20%; solves = ARPACK's operator applications, each
one solve with the factor of K_c):

    python benchmarks/box3d.py --runs P1:0.0153:pardiso,P1:0.012:pardiso
    python benchmarks/box3d.py --runs P1:0.02:scipy,P1:0.02:pardiso

| DOFs | p | backend (method) | solves | mesh | assembly | contact | eigen | rest | wall | peak GB | factor s (peak GB) | ratio |
|---|---|---|---|---|---|---|---|---|---|---|---|---|
| 565140 | 8352 | pardiso (arpack) | 115 | 5.5 | 3.9 | 1.6 | 204.1 | 0.7 | 215.9 | 8.50 | 147.7 (9.62) | 1.46 |
| 278934 | 5170 | pardiso (arpack) | 131 | 2.7 | 1.4 | 0.9 | 45.2 | 0.7 | 50.7 | 3.38 | 25.7 (3.89) | 1.98 |
| 127560 | 3017 | pardiso (arpack) | 97 | 1.5 | 0.8 | 0.5 | 29.5 | 0.9 | 33.3 | 1.28 | 10.1 (1.49) | 3.30 |
| 127560 | 3017 | scipy (arpack) | 97 | 1.1 | 0.5 | 0.3 | 89.6 | 0.7 | 92.1 | 2.82 | 40.2 (3.07) | 2.29 |

Where the 279 k solve goes: the factorization of K_c (about one bare factorization), then
ARPACK's 131 solves at ~0.16 s each (0.0062 factorizations: the solves read the 330 M
entries of the factor and are bound by memory bandwidth), then 5.7 s of meshing, assembly,
contact basis and writing. The solves cost about n^(4/3), the factorization about n^2: the
ratio falls with the size (1.46 at 565 k DOFs). Measured beside it and not taken: block
solves (32 right-hand sides cost 4.9 single solves, but a block Krylov space needs 11 times
more vectors for the same two eigenvalues: 704 against 64 at 41 k DOFs), PARDISO's partial
solve for sparse right-hand sides (iparm[30]: it orders the marked rows last, 1.6 x the
factor's entries and 3.8 x the factorization time at 63 k DOFs), critfric's geometric
nested dissection as PARDISO's user order (21% more entries than METIS at 106 k DOFs).

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
HEADER = ("| DOFs | p | backend (method) | solves | mesh | assembly | contact | eigen | rest "
          "| wall | peak GB | factor s (peak GB) | ratio |\n" + "|---" * 13 + "|")
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


def append_row(path: str, fields, row: dict) -> None:
    """Append ``row`` (its ``fields``, floats to 2 decimals) to the CSV file ``path``, with
    the header line if the file is new."""
    new = not Path(path).exists()
    with open(path, "a", newline="") as f:
        w = csv.DictWriter(f, fieldnames=fields, extrasaction="ignore")
        if new:
            w.writeheader()
        w.writerow({k: (f"{v:.2f}" if isinstance(v, float) else v) for k, v in row.items()})


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", default="P1:0.0149:pardiso,P1:0.0149:scipy",
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
              f"{r['applications']} | "
              + " | ".join(f"{r[s]:.1f}" for s in STAGES)
              + f" | {rest:.1f} | {r['wall']:.1f} | {r['peak_mb'] / 1e3:.2f} "
              f"| {r['factor']:.1f} ({r['factor_peak_mb'] / 1e3:.2f}) | {r['ratio']:.2f} |",
              flush=True)
        if a.csv:
            append_row(a.csv, FIELDS, r)


if __name__ == "__main__":
    main()
