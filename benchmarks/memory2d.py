"""Peak memory of 2D `critfric solve` on the unit square, against the estimate the resource
guard makes before meshing (run by hand, not in CI): the runs that calibrate critfric.guards'
2D model.

    nice -n 10 python benchmarks/memory2d.py                     # P1 and P2, 0.1-4 M DOFs
    nice -n 10 python benchmarks/memory2d.py --backends scipy --elements P2 --dofs 0.1,0.5
    nice -n 10 python benchmarks/memory2d.py --csv benchmarks/memory2d.csv
    nice -n 10 python benchmarks/memory2d.py --backends scipy --elements P2 --dofs 4 --mem-limit 40
    python benchmarks/memory2d.py --fit benchmarks/memory2d.csv  # MODEL_2D and its ratios

For each (backend, element, DOFs): the mesh size that gives about that many DOFs
(:meth:`critfric.guards.Footprint.finest_size`), then ``critfric solve unit-square --size h
--element E --backend B --json --max-dofs 1e9`` (--max-dofs skips the memory guard) in a
fresh process of the install that has the backend (PARDISO: this checkout's ``.venv``, the
``fast`` extra; SciPy: its ``.venv-nofast``; else this interpreter; the code measured is
``--root``'s), its peak RSS from wait4, and the estimate
:func:`critfric.guards.memory_estimate` gives for the DOFs and contact nodes that
:func:`critfric.meshing.from_case.polygon_estimate` predicts before meshing (the solve's own guard). One
solve at a time; each child is capped at ``--mem-limit`` GB of address space (default
box3d.MEM_LIMIT_GB; SciPy reserves about 3 x its resident memory: P2 at 4 M DOFs needs more).
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import sys
import tempfile
from pathlib import Path

import box3d
from box3d import _run_measured, append_row  # the 3D runs' measurement and CSV rows

ROOT = Path(__file__).resolve().parent.parent
VENVS = {"pardiso": ".venv", "scipy": ".venv-nofast"}
DOFS = "0.1,0.25,0.5,1,2,4"  # millions
MARGIN = 1.05  # estimates at least this x every peak: repeat runs differ by up to 1.5% on
#               PARDISO, 5% on SciPy (its two pieces factored in threads)
FIELDS = ("backend", "element", "size", "est_dofs", "est_contact", "n_dofs", "n_contact",
          "method", "wall", "peak_mb")


def _case(element: str, size: float | None = None, backend: str = "auto"):
    from critfric.case import load_case

    overrides = {"mesh.element": element, "solve.backend": backend}
    if size is not None:
        overrides["mesh.size"] = size
    return load_case("unit-square", overrides=overrides)


def mesh_size(element: str, dofs: float) -> float:
    """The mesh size whose estimated DOF count on the unit square is ``dofs``."""
    from critfric.guards import polygon_footprint
    from critfric.meshing.from_case import geometry_polygon

    square = geometry_polygon(_case(element))
    return float(f"{polygon_footprint(square.vertices).finest_size(dofs, element):.4g}")


def estimate(element: str, size: float, backend: str) -> dict:
    """What the guard is given before meshing, and the peak it estimates (MB)."""
    from critfric.guards import memory_estimate
    from critfric.meshing.from_case import polygon_estimate

    dofs, contact = polygon_estimate(_case(element, size, backend))
    try:
        est = memory_estimate(dofs, contact, element=element, backend=backend)
    except KeyError:  # a model not fitted yet
        est = math.nan
    return {"est_dofs": round(dofs), "est_contact": round(contact), "estimate_mb": est / 1e6}


def python_for(backend: str) -> str:
    venv = ROOT / VENVS[backend] / "bin" / "python"
    return str(venv) if venv.exists() else sys.executable


def solve(root: Path, element: str, size: float, backend: str) -> dict:
    with tempfile.TemporaryDirectory() as tmp:
        cmd = [python_for(backend), "-m", "critfric", "solve", "unit-square",
               "--size", str(size), "--element", element, "--backend", backend, "--json",
               "-o", str(Path(tmp) / "r.h5"), "--force", "--max-dofs", str(10**9)]
        wall, peak, stdout = _run_measured(cmd, root)
    summary = json.loads(stdout)
    return {"wall": wall, "peak_mb": peak, "n_dofs": summary["n_dofs"],
            "n_contact": summary["n_contact"], "method": summary["method"]}


def fit(rows: list[dict]) -> dict:
    """MODEL_2D's coefficients (base, bytes per DOF, bytes per n log2 n) for each model key
    (:func:`critfric.guards.model_key_2d`) and element, by linear programming: every estimate
    (from the DOFs and contact nodes predicted before meshing, and from those of the mesh
    made) at least MARGIN x the measured peak, the largest estimate / peak as small as can
    be, then the sum of the ratios as small as can be; rounded up to three digits."""
    import numpy as np
    from scipy.optimize import linprog

    from critfric import guards

    points: dict[tuple[str, str], list] = {}
    for r in rows:
        for n, p in ((float(r["est_dofs"]), float(r["est_contact"])),
                     (float(r["n_dofs"]), float(r["n_contact"]))):
            key = (guards.model_key_2d(r["backend"], n), r["element"])
            points.setdefault(key, []).append(
                (1.0, n, n * np.log2(n), guards.dense_bytes(p), float(r["peak_mb"]) * 1e6))
    model: dict[str, dict] = {}
    for (key, element), pts in sorted(points.items()):
        a = np.array(pts)
        x, dense, peak = a[:, :3], a[:, 3], a[:, 4]
        # variables c (3) and t: MARGIN peak <= x c + dense <= t peak
        a_ub = np.vstack([np.hstack([-x, np.zeros((len(a), 1))]),
                          np.hstack([x, -peak[:, None]])])
        b_ub = np.concatenate([dense - MARGIN * peak, -dense])
        t = linprog(np.r_[0.0, 0.0, 0.0, 1.0], A_ub=a_ub, b_ub=b_ub,
                    bounds=[(0, None)] * 4).x[-1]
        c = linprog(np.r_[(x / peak[:, None]).sum(axis=0), 0.0], A_ub=a_ub, b_ub=b_ub,
                    bounds=[(0, None)] * 3 + [(t * 1.001,) * 2]).x[:3]
        model.setdefault(key, {})[element] = tuple(_up(v) for v in c)
    return model


def _up(v: float) -> float:
    """``v`` rounded up to three significant digits."""
    if v <= 0:
        return 0.0
    step = 10.0 ** (math.floor(math.log10(v)) - 2)
    return float(f"{math.ceil(v / step * (1 - 1e-12)) * step:.3g}")


def report(path: str) -> None:
    """The model fitted to the runs in ``path`` (to paste into critfric.guards.MODEL_2D), and
    each run's estimate / peak under guards' model: before meshing (what decides) and from
    the mesh made."""
    from critfric import guards

    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    model = fit(rows)
    same = "the same as" if model == guards.MODEL_2D else "NOT the same as"
    print(f"fitted: MODEL_2D = {model!r}\n({same} critfric.guards.MODEL_2D, used below)\n")
    print("| backend | element | DOFs | contact nodes | peak MB | estimate MB | ratio "
          "| ratio, mesh made |\n" + "|---" * 8 + "|")
    ratios = []
    for r in sorted(rows, key=lambda r: (r["backend"], r["element"], int(r["n_dofs"]))):
        peak, e = float(r["peak_mb"]), {}
        for kind in ("est", "n"):
            e[kind] = guards.memory_estimate(
                float(r[f"{kind}_dofs"]), float(r[f"{kind}_contact"]), element=r["element"],
                backend=r["backend"]) / 1e6
            ratios.append(e[kind] / peak)
        print(f"| {r['backend']} | {r['element']} | {r['n_dofs']} | {r['n_contact']} "
              f"| {peak:.0f} | {e['est']:.0f} | {e['est'] / peak:.2f} "
              f"| {e['n'] / peak:.2f} |")
    print(f"\n{len(rows)} runs: estimate / peak {min(ratios):.3f}-{max(ratios):.3f}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--backends", default="pardiso,scipy")
    ap.add_argument("--elements", default="P1,P2")
    ap.add_argument("--dofs", default=DOFS, help="target DOF counts in millions")
    ap.add_argument("--root", default=str(ROOT), help="critfric checkout to measure")
    ap.add_argument("--csv", default="", help="append the rows to this CSV file")
    ap.add_argument("--fit", default="", help="fit the 2D model to this CSV file instead")
    ap.add_argument("--mem-limit", type=float, default=box3d.MEM_LIMIT_GB,
                    help="address space of each child, GB")
    a = ap.parse_args()
    box3d.MEM_LIMIT_GB = a.mem_limit
    if a.fit:
        report(a.fit)
        return
    root = Path(a.root).resolve()
    print(f"critfric from {root}; estimate before meshing against the peak RSS\n")
    print("| backend | element | size | DOFs | contact nodes | method | wall s | peak MB "
          "| estimate MB | ratio |\n" + "|---" * 10 + "|")
    for millions in map(float, filter(None, a.dofs.split(","))):
        for element in filter(None, a.elements.split(",")):
            size = mesh_size(element, millions * 1e6)
            for backend in filter(None, a.backends.split(",")):
                r = {"backend": backend, "element": element, "size": f"{size:g}",
                     **estimate(element, size, backend)}
                try:
                    r.update(solve(root, element, size, backend))
                except RuntimeError as exc:
                    print(f"| {backend} | {element} | {size} | {exc} |" + " |" * 6, flush=True)
                    continue
                print(f"| {backend} | {element} | {size} | {r['n_dofs']} | {r['n_contact']} "
                      f"| {r['method']} | {r['wall']:.1f} | {r['peak_mb']:.0f} "
                      f"| {r['estimate_mb']:.0f} | {r['estimate_mb'] / r['peak_mb']:.2f} |",
                      flush=True)
                if a.csv:
                    append_row(a.csv, FIELDS, r)


if __name__ == "__main__":
    main()
