"""The root locus of ``critfric stability`` against the full pencil (run by hand, not in CI).

    python benchmarks/locus_accuracy.py                                  # unit square, P1
    python benchmarks/locus_accuracy.py --case inclined-body --size 0.02 --range 1.2
    python benchmarks/locus_accuracy.py --element P2 --size 0.04 --basis contact,modal

For each reduced basis (``--basis``: auto, contact, modal), the reduced model of the
all-slipping pencil (nu = 0.3, E = density = 1) is followed along ``--steps`` friction steps
each way up to ``--range``, as ``critfric stability`` follows it; at every ``--every``-th step
each followed branch's kappa is compared with the full pencil's nearest eigenvalue (shift-invert
at that kappa: an LU of L(f, kappa), ARPACK on its inverse). Printed: the basis's size, the
located onsets (the reduced model's), and the largest relative error of the branches up to
four times the onset and beyond (a branch near kappa = 0, a divergence, weighs there as a
relative error).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
import scipy.sparse.linalg as spla

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from helpers import case_pencil

from critfric import load_case
from critfric.stability import locus


def nearest(pencil, f: float, sigma: complex) -> complex:
    """The full pencil's eigenvalue kappa nearest ``sigma`` at friction f."""
    A = (pencil.Krr - f * pencil.GKnr).tocsc()
    B = (pencil.Mrr - f * pencil.GMnr).tocsc()
    lu = spla.splu((A - sigma * B).astype(complex).tocsc())
    op = spla.LinearOperator(A.shape, matvec=lambda x: lu.solve(B @ x), dtype=complex)
    nu = spla.eigs(op, k=1, which="LM", tol=1e-12, v0=np.ones(A.shape[0], complex))[0][0]
    return sigma + 1.0 / nu


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--case", default="unit-square")
    p.add_argument("--size", type=float, default=0.02)
    p.add_argument("--element", default="P1")
    p.add_argument("--modes", type=int, default=10)
    p.add_argument("--range", type=float, default=0.6, help="largest |friction| followed")
    p.add_argument("--steps", type=int, default=200)
    p.add_argument("--every", type=int, default=20, help="compare every this many steps")
    p.add_argument("--basis", default="auto", help="comma-separated: auto, contact, modal")
    a = p.parse_args()
    case = load_case(a.case, overrides={"mesh.size": a.size, "mesh.element": a.element})
    pencil = case_pencil(case)
    print(f"{a.case} {a.element} h = {a.size}: {pencil.size} kept DOFs, "
          f"{pencil.G.shape[1]} slipping nodes")
    factor = locus.factor_of(pencil, "scipy", None)
    for basis in a.basis.split(","):
        t0 = time.perf_counter()
        red = locus.reduce(pencil, a.modes, basis=basis, factor=factor)
        seconds = time.perf_counter() - t0
        for end in (-a.range, a.range):
            grid = np.linspace(0.0, end, a.steps + 1)
            branches = locus.follow(red, a.modes, grid)
            guess = locus.locate_flutter(red, branches)
            onset = abs(guess.friction) if guess else np.inf
            worst = [0.0, 0.0]  # up to 4 onsets, beyond
            for j in range(a.every // 2, a.steps + 1, a.every):
                f = branches.friction[j]
                for kappa in branches.kappa[j]:
                    error = abs(kappa - nearest(pencil, f, kappa)) / abs(kappa)
                    beyond = abs(f) > 4 * onset
                    worst[int(beyond)] = max(worst[int(beyond)], error)
            print(f"  {basis:7s} size {red.A0.shape[0]:3d} ({seconds:.2f} s)  friction "
                  f"{'-' if end < 0 else '+'}: onset {onset:.8f}, branches within "
                  f"{worst[0]:.1e} up to 4 onsets, {worst[1]:.1e} beyond")


if __name__ == "__main__":
    main()
