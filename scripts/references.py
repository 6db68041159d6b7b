"""References for `make validate`: lowest critical coefficients from P2 and Q2 on meshes graded
radially at every singular point, converging at order ~4 (not critfric's sweep grading).

The local size at distance d from the nearest singular point (critfric.meshing.singular: the
ends of Gamma_C, the state junctions, the corners where the condition changes, re-entrant
corners) is h min(1, max(m, (d / R)^(3/4))), R half the length of Gamma_C, m = ``--finest``
(of the body's extent) / h: a grading that refines with h (no nesting) and resolves r^lambda
singularities down to lambda ~ 1/2 at the order of a smooth solution. The floor matters where
the singularity is strong: the unit square and the inclined body reach 1e-9 with 1e-5; the
corner and junction bodies move by 2e-6 and 5e-6 between 1e-5 and 1e-6 (scripts/validate.py).
Floors below ~3e-7 of the extent give cells too thin for critfric's degenerate-cell check.

Usage: python scripts/references.py BODY [--sizes 0.05,0.025,0.0125] [--elements P2,Q2]
       [--finest 1e-6]
with BODY one of scripts/validate.py's cases; prints one line per (element, size) and the
Richardson limit of the last three sizes of each element.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from unittest import mock

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

import critfric
from critfric import solve as solve_module
from critfric.meshing import from_case
from critfric.meshing import mesh as meshing
from critfric.sweep.extrapolate import richardson

EXPONENT = 0.75
FINEST = 1e-6  # of the body's extent (gmsh meshes the body scaled to unit extent)


def _radial(point_tags, h_min, h_max, dist_max):
    """Replaces critfric's linear Threshold field: size h (d / R)^EXPONENT, at least FINEST."""
    import gmsh

    field = gmsh.model.mesh.field
    dist = field.add("Distance")
    field.setNumbers(dist, "PointsList", [int(t) for t in point_tags])
    law = field.add("MathEval")
    field.setString(law, "F", f"{h_max!r} * Min(1, Max({FINEST / h_max!r}, "
                              f"(F{dist} / {dist_max!r})^{EXPONENT}))")
    field.setAsBackgroundMesh(law)
    gmsh.option.setNumber("Mesh.MeshSizeExtendFromBoundary", 0)
    gmsh.option.setNumber("Mesh.MeshSizeMin", FINEST)


def solve(case, element: str, size: float, count: int = 1):
    over = {"mesh.element": element, "mesh.size": size, "mesh.grading": FINEST / size,
            "solve.count": count}
    with mock.patch.object(meshing, "_set_grading", _radial), \
            mock.patch.object(meshing, "_refinements", lambda poly, h: 0), \
            mock.patch.object(from_case, "check_dofs", lambda *a, **k: None), \
            mock.patch.object(solve_module, "check_dofs", lambda *a, **k: None):
        return critfric.solve_case(case, overrides=over)


def main(argv=None) -> int:
    global FINEST
    from validate import CASES  # the bodies of `make validate`

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("body", choices=sorted(CASES))
    parser.add_argument("--sizes", default="0.05,0.025,0.0125")
    parser.add_argument("--elements", default="P2,Q2")
    parser.add_argument("--nu", type=float, default=0.3)
    parser.add_argument("--finest", type=float, default=1e-6,
                        help="the smallest cell size, relative to the body's extent")
    args = parser.parse_args(argv)
    FINEST = args.finest
    case = CASES[args.body]().with_overrides({"material.nu": args.nu})
    sizes = [float(s) for s in args.sizes.split(",")]
    for element in args.elements.split(","):
        pos, neg = [], []
        for h in sizes:
            t0 = time.perf_counter()
            r = solve(case, element, h)
            pos.append(r.positive[0] if len(r.positive) else np.nan)
            neg.append(r.negative[0] if len(r.negative) else np.nan)
            print(f"{args.body} {element} h={h:g} dofs={r.n_dofs} positive={pos[-1]:.12g} "
                  f"negative={neg[-1]:.12g} ({time.perf_counter() - t0:.1f} s)", flush=True)
        if len(sizes) >= 3:
            for fam, f in (("positive", pos), ("negative", neg)):
                limit, p = richardson(sizes, f)
                print(f"{args.body} {element} {fam}: Richardson {limit:.12g}, order {p:.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
