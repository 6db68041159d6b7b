"""``critfric path`` against ``critfric solve`` on the same mesh (run by hand, not in CI).

    python benchmarks/path.py                            # ~210 k DOFs, 401 contact nodes, all paths
    python benchmarks/path.py --paths load --size 0.005  # one path, a smaller mesh
    python benchmarks/path.py --element P2 --size 0.005  # P2: ~200 k DOFs, 401 nodes

The body is a rectangle (width x height), clamped on top, in contact on the bottom; P1 with
size 0.0025 gives about 210 k DOFs and 401 contact nodes. Paths (``--paths``, comma-separated):

  load       press (top displacement [0, -0.01], friction 0.5), then shear: t in [0, 1] of
             L1 = top displacement [0.05, 0] (about one piece per contact node)
  friction   top displacement [0.02, -0.01], friction in [0, 2]
  tilt       the press, then shear and tilt: t in [-1, 1] of L1 = top displacement
             ux = 0.05, uy = 0.02 x (slip-, stuck, slip+, free: more pieces per node)

For each path, side by side in one run (a shared machine's load varies, so read the ratios),
each command in a fresh process in the checkout measured, with ``--json -o tmp --force``: the
wall and CPU time of ``critfric solve`` on the case (mesh, assembly, one factorization, the
critical coefficients; the best of --repeat runs) and of ``critfric path``, the seconds each
reports itself, the number of pieces (summed over the curves of the JSON) and events, and
the ratios path / solve (the target: 1000 pieces at this scale within 3 solves). The CPU
ratio is the steadier one where other jobs share the machine (the path runs on one thread).
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
PRESS = "{ top = [0.0, -0.01] }"
PATHS = {  # name -> ([load] lines, [path] lines)
    "load": (["friction = 0.5", f"displacement = {PRESS}"],
             ['parameter = "load"', "range = [0.0, 1.0]",
              "load = { displacement = { top = [0.05, 0.0] } }"]),
    "friction": (["displacement = { top = [0.02, -0.01] }"],
                 ['parameter = "friction"', "range = [0.0, 2.0]"]),
    "tilt": (["friction = 0.5", f"displacement = {PRESS}"],
             ['parameter = "load"', "range = [-1.0, 1.0]",
              "load = { displacement = { top = [[0.05, 0.0, 0.0], [0.0, 0.02, 0.0]] } }"]),
}


def case_text(name: str, a: argparse.Namespace) -> str:
    load, path = PATHS[name]
    return "\n".join([
        f'title = "path benchmark: {name}"', "[geometry]", 'shape = "rectangle"',
        f"width = {a.width}", f"height = {a.height}",
        "[boundary]", 'contact = ["bottom"]', 'dirichlet = ["top"]',
        "[mesh]", f'element = "{a.element}"', f"size = {a.size}",
        "[load]", *load,
        "[path]", *path, 'start = "newton"', f"samples = {a.samples}", ""])


def run(root: Path, args: list[str], timeout: float) -> tuple[float, float, dict]:
    """Wall and CPU seconds (user + system, all threads) and the JSON summary of ``python -m
    critfric ARGS --json`` in a fresh process. ``python -m`` puts its working directory first
    on sys.path: run it in the checkout measured."""
    env = dict(os.environ, PYTHONPATH=str(root))
    before, t = resource.getrusage(resource.RUSAGE_CHILDREN), time.perf_counter()
    proc = subprocess.run([sys.executable, "-m", "critfric", *args, "--json"], cwd=root,
                          env=env, capture_output=True, text=True, timeout=timeout, check=False)
    wall, after = time.perf_counter() - t, resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = sum(getattr(after, k) - getattr(before, k) for k in ("ru_utime", "ru_stime"))
    if proc.returncode:
        last = (proc.stderr.strip().splitlines() or ["killed"])[-1]
        raise RuntimeError(f"critfric {args[0]} failed: {last}")
    return wall, cpu, json.loads(proc.stdout)


def measure(root: Path, name: str, a: argparse.Namespace) -> dict:
    with tempfile.TemporaryDirectory() as tmp:
        case = Path(tmp) / f"{name}.toml"
        case.write_text(case_text(name, a))
        solves = [run(root, ["solve", str(case), "-o", str(Path(tmp) / "s.h5"), "--force"],
                      a.timeout) for _ in range(a.repeat)]
        t_solve, cpu_solve, solve = min(solves, key=lambda r: r[0])  # the best of a few
        t_path, cpu_path, path = run(root, ["path", str(case), "-o", str(Path(tmp) / "p.h5"),
                                  "--force"], a.timeout)
    kinds = [e["kind"] for e in path["events"]]
    return {"n_dofs": path["n_dofs"], "n_contact": path["n_contact"],
            "solve": t_solve, "solve_own": solve["seconds"], "solve_cpu": cpu_solve,
            "path": t_path, "path_own": path["seconds"], "path_cpu": cpu_path,
            "curves": len(path["curves"]),
            "pieces": sum(len(c["pieces"]) for c in path["curves"]),
            "events": "/".join(str(kinds.count(k)) for k in ("kink", "fold", "branch"))}


def revision(root: Path) -> str:
    """The commit of the checkout measured, "+ edits" if critfric/ differs from it."""
    git = ["git", "-C", str(root)]
    head = subprocess.run([*git, "rev-parse", "--short", "HEAD"], capture_output=True,
                          text=True, check=False).stdout.strip()
    if not head:
        return "not a git checkout"
    dirty = subprocess.run([*git, "status", "--porcelain", "--", "critfric"],
                           capture_output=True, text=True, check=False).stdout.strip()
    return head + (" + edits" if dirty else "")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--paths", default=",".join(PATHS), help=f"of {', '.join(PATHS)}")
    ap.add_argument("--size", type=float, default=0.0025, help="mesh size h (0.0025, P1: "
                    "~210 k DOFs, 401 contact nodes)")
    ap.add_argument("--element", default="P1")
    ap.add_argument("--width", type=float, default=1.0)
    ap.add_argument("--height", type=float, default=0.55)
    ap.add_argument("--samples", type=int, default=101)
    ap.add_argument("--repeat", type=int, default=3, help="solves timed (the best counts)")
    ap.add_argument("--timeout", type=float, default=7200.0, help="seconds per command")
    ap.add_argument("--root", default=str(HERE.parent), help="critfric checkout to measure")
    a = ap.parse_args()
    root = Path(a.root).resolve()
    print(f"critfric from {root} ({revision(root)}); {a.element}, rectangle {a.width} x "
          f"{a.height}, h = {a.size}, {a.samples} samples; seconds: wall (the command's "
          "own) and CPU (all threads); ratio = path / solve\n")
    print("| path | DOFs | contact nodes | curves | pieces | kinks/folds/branches | solve wall "
          "| solve CPU | path wall | path CPU | path wall / piece | ratio wall | ratio CPU |")
    print("|---" * 13 + "|", flush=True)
    for name in filter(None, a.paths.split(",")):
        try:
            r = measure(root, name, a)
        except (RuntimeError, subprocess.TimeoutExpired) as exc:
            print(f"| {name} | {exc} |" + " |" * 11, flush=True)
            continue
        per = r["path"] / max(r["pieces"], 1)
        print(f"| {name} | {r['n_dofs']} | {r['n_contact']} | {r['curves']} | {r['pieces']} "
              f"| {r['events']} | {r['solve']:.2f} ({r['solve_own']:.2f}) | {r['solve_cpu']:.2f} "
              f"| {r['path']:.1f} ({r['path_own']:.1f}) | {r['path_cpu']:.1f} | {per:.3f} "
              f"| {r['path'] / r['solve']:.1f} | {r['path_cpu'] / r['solve_cpu']:.1f} |",
              flush=True)


if __name__ == "__main__":
    main()
