"""Scaling benchmark (run by hand, not in CI): P1 unit square, nu = 0.3, per-stage times and
peak memory for each available linear-solver backend, from 66 k to 4 M DOFs.

    python benchmarks/scale.py                       # every size, every backend
    python benchmarks/scale.py --sizes 66k,263k      # a subset
    python benchmarks/scale.py --sweep 263k          # also an 11-value nu sweep on one mesh

Every measurement runs in a fresh subprocess, so that its peak memory (``ru_maxrss``, which
counts the C allocations of the solvers, unlike tracemalloc) is its own. Columns:

* mesh, assembly, contact: ``critfric.prepare`` stages; eigen: ``solve_prepared`` (the whole
  eigen stage: stiffness at nu, factorization(s), eigenvalues, modes); write: the HDF5 file;
  total: the subprocess wall time, imports included (what ``critfric solve`` costs), and
  its CPU time (user + system, all threads): on a shared machine wall times vary;
* factor: a separate subprocess that only factors the same K with the same backend;
  eigen/factor is the ratio of the two;
* plain: a plain SciPy script on the same mesh (``splu`` with its defaults, then the dense
  contact blocks of K^-1 by 2p solves and the p x p eigenproblem of Remark 3.2), and
  plain/total. It is skipped above ``--plain-max`` DOFs (it needs ~10 GB at 1 M DOFs), and
  the scipy backend above ``--scipy-max`` DOFs; each subprocess is capped at MEM_LIMIT_GB.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
SIZES = {"66k": 0.006, "263k": 0.003, "1M": 0.0015, "4M": 0.00075}  # mesh size h -> ~DOFs
NUS = [0.0, 0.05, 0.1, 0.15, 0.2, 0.25, 0.3, 0.35, 0.4, 0.45, 0.49]


def _case(h: float, backend: str):
    from critfric.case.schema import loads_case
    return loads_case(f'[geometry]\nshape = "square"\n[material]\nnu = 0.3\n[mesh]\n'
                      f'size = {h}\n[solve]\nbackend = "{backend}"\n')


def _peak_gb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1e6  # KB -> GB (Linux)


def _cpu() -> float:
    u = resource.getrusage(resource.RUSAGE_SELF)
    return u.ru_utime + u.ru_stime


def child_pipeline(h: float, backend: str, out: str) -> dict:
    import critfric
    case = _case(h, backend)
    prep = critfric.prepare(case, max_dofs=10**9)
    result = critfric.solve_prepared(prep, case)
    t = time.perf_counter()
    critfric.write_result(result, out, force=True)
    write = time.perf_counter() - t
    Path(out).unlink()
    return dict(result.timings, write=write, n_dofs=result.n_dofs, p=result.n_contact,
                critical=result.critical, solver=result.solver, backend=result.backend)


def child_factor(h: float, backend: str) -> dict:
    import numpy as np

    import critfric
    from critfric.fem.assembly import lame
    from critfric.solvers.backends import factorize
    from critfric.solvers.eigenproblem import fill_order_for
    prep = critfric.prepare(_case(h, backend), max_dofs=10**9)
    K = prep.system.stiffness(*lame(1.0, 0.3))
    t = time.perf_counter()  # with the ordering the eigen stage uses (computed in it too)
    factorize(K, symmetric=True, backend=backend,
              order=fill_order_for(prep.system, np.arange(K.shape[0]), backend))
    return {"factor": time.perf_counter() - t}


def child_plain(h: float) -> dict:
    """A plain SciPy script: default splu, dense contact blocks of K^-1, Remark 3.2."""
    import numpy as np
    import scipy.sparse.linalg as spla

    import critfric
    from critfric.fem.assembly import lame
    prep = critfric.prepare(_case(h, "scipy"), max_dofs=10**9)
    s = prep.system
    K = s.stiffness(*lame(1.0, 0.3)).tocsc()
    t = time.perf_counter()
    lu = spla.splu(K)
    c = np.concatenate([s.cn, s.ct])
    C = np.empty((len(c), len(c)))
    for j in range(0, len(c), 64):
        E = np.zeros((K.shape[0], min(64, len(c) - j)))
        E[c[j:j + E.shape[1]], np.arange(E.shape[1])] = 1.0
        C[:, j:j + E.shape[1]] = lu.solve(E)[c]
    p = s.n_contact
    w = np.linalg.eigvals(np.linalg.solve(C[:p, :p], C[:p, p:]))  # eigenvalues -1/alpha
    alpha = -1.0 / w[np.abs(w) > 1e-6]
    real = alpha[np.abs(alpha.imag) <= 1e-8 * np.abs(alpha)].real
    return {"plain": time.perf_counter() - t, "critical": float(np.min(real[real > 0]))}


def child_sweep(h: float, backend: str) -> dict:
    import critfric
    case = _case(h, backend)
    t = time.perf_counter()
    prep = critfric.prepare(case, max_dofs=10**9)
    eigen = []
    for nu in NUS:
        r = critfric.solve_prepared(prep, case.with_overrides({"material.nu": nu}))
        eigen.append(r.timings["eigen"])
    return dict(prep.seconds, eigen_each=eigen, total=time.perf_counter() - t,
                n_dofs=prep.system.n_dofs)


MEM_LIMIT_GB = 20.0  # address-space cap of each subprocess: fail alone, never swamp the machine


def _cap_memory() -> None:
    limit = int(MEM_LIMIT_GB * 2**30)
    resource.setrlimit(resource.RLIMIT_AS, (limit, limit))


def run(kind: str, *args, timeout: float) -> dict:
    """One measurement in a fresh subprocess: its result, wall time and peak memory."""
    t = time.perf_counter()
    cmd = [sys.executable, __file__, "--child", kind, *map(str, args)]
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    try:
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, env=env,
                              preexec_fn=_cap_memory)
    except subprocess.TimeoutExpired:
        return {"error": f"> {timeout:.0f} s"}
    if proc.returncode != 0:
        last = (proc.stderr.strip().splitlines() or ["killed"])[-1]
        return {"error": f"failed ({last[:60]})"}
    out = json.loads(proc.stdout.strip().splitlines()[-1])
    out["wall"] = time.perf_counter() - t
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", default=",".join(SIZES))
    ap.add_argument("--backends", default="")
    ap.add_argument("--plain-max", type=float, default=1.2e6)
    ap.add_argument("--timeout", type=float, default=1800)
    ap.add_argument("--plain-timeout", type=float, default=900)
    ap.add_argument("--scipy-max", type=float, default=2e6,
                    help="skip the scipy backend above this many DOFs")
    ap.add_argument("--sweep", default="", help="size of the nu sweep (e.g. 263k)")
    ap.add_argument("--child", nargs="+", help=argparse.SUPPRESS)
    a = ap.parse_args()
    if a.child:
        kind, args = a.child[0], a.child[1:]
        h = float(args[0])
        fn = {"pipeline": lambda: child_pipeline(h, args[1], args[2]),
              "factor": lambda: child_factor(h, args[1]), "plain": lambda: child_plain(h),
              "sweep": lambda: child_sweep(h, args[1])}[kind]
        out = fn()
        out["peak_gb"], out["cpu"] = _peak_gb(), _cpu()
        print(json.dumps(out))
        return
    sys.path.insert(0, str(ROOT))
    from critfric.solvers.backends import available_backends
    backends = a.backends.split(",") if a.backends else list(available_backends())
    head = ("| DOFs | p | backend | mesh | assembly | contact | eigen | write | total (cpu) "
            "| peak GB | factor | eigen/factor | critical | plain SciPy | plain/total |")
    print(head)
    print("|" + "---|" * (head.count("|") - 1))
    for name in filter(None, a.sizes.split(",")):
        h = SIZES[name]
        plain = None
        for b in backends:
            if b == "scipy" and 2.33 / h**2 > a.scipy_max:  # ~DOFs of the unit square
                print(f"| ~{name} | | {b} | skipped (> {a.scipy_max:.3g} DOFs) |" + " |" * 11)
                continue
            r = run("pipeline", h, b, f"/tmp/critfric-bench-{os.getpid()}.h5",
                    timeout=a.timeout)
            if "error" in r:
                print(f"| ~{name} | | {b} | {r['error']} |" + " |" * 11, flush=True)
                continue
            f = run("factor", h, b, timeout=a.timeout)
            if plain is None:
                plain = (run("plain", h, timeout=a.plain_timeout) if r["n_dofs"] <= a.plain_max
                         else {"error": f"skipped (> {a.plain_max:.3g} DOFs)"})
            fac = f"{f['factor']:.2f}" if "factor" in f else f["error"]
            ratio = f"{r['eigen'] / f['factor']:.2f}" if "factor" in f else "-"
            pl = (f"{plain['plain']:.1f} s, {plain['peak_gb']:.2f} GB" if "plain" in plain
                  else plain["error"])
            pr = f"{plain['plain'] / r['wall']:.1f}x" if "plain" in plain else "-"
            print(f"| {r['n_dofs']} | {r['p']} | {r['backend']} ({r['solver']}) "
                  f"| {r['mesh']:.2f} | {r['assembly']:.2f} | {r['contact']:.2f} "
                  f"| {r['eigen']:.2f} | {r['write']:.2f} | {r['wall']:.2f} ({r['cpu']:.1f}) "
                  f"| {r['peak_gb']:.2f} | {fac} | {ratio} | {r['critical']:.12f} "
                  f"| {pl} | {pr} |", flush=True)
    if a.sweep:
        b = backends[0]
        r = run("sweep", SIZES[a.sweep], b, timeout=a.timeout)
        if "error" in r:
            print(f"\nsweep: {r['error']}")
            return
        each = ", ".join(f"{t:.2f}" for t in r["eigen_each"])
        print(f"\nnu sweep ({len(NUS)} values, {r['n_dofs']} DOFs, {b}): one mesh "
              f"{r['mesh']:.2f} s, one assembly {r['assembly']:.2f} s, contact "
              f"{r['contact']:.2f} s; eigen per nu: {each} s; total {r['total']:.1f} s, "
              f"peak {r['peak_gb']:.2f} GB")


if __name__ == "__main__":
    main()
