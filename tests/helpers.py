"""Shared test helpers: in-code cases and closed forms from the paper."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from critfric.assembly import lame

CASES = Path(__file__).resolve().parent.parent / "cases"

# a gmsh .geo script of the unit square with the named groups critfric needs
SQUARE_GEO = """\
Point(1) = {0, 0, 0, 0.5}; Point(2) = {1, 0, 0, 0.5};
Point(3) = {1, 1, 0, 0.5}; Point(4) = {0, 1, 0, 0.5};
Line(1) = {1, 2}; Line(2) = {2, 3}; Line(3) = {3, 4}; Line(4) = {4, 1};
Curve Loop(1) = {1, 2, 3, 4}; Plane Surface(1) = {1};
Physical Curve("bottom") = {1}; Physical Curve("top") = {3};
Physical Surface("domain") = {1};
"""


def resume_exactly_once(out, grid_nu: str, total: int, kept: int):
    """Re-run the unit-square sweep of ``grid_nu`` into ``out`` (interrupted with ``kept``
    points): only the missing points are computed and every point is there exactly once."""
    import critfric
    from critfric.sweep import make_grid, run_sweep
    from critfric.sweepfile import read_sweep

    case = critfric.load_case("unit-square")
    grid = make_grid(case, nu=grid_nu, size="0.025", element="P1")
    resumed = run_sweep(case, grid, output=out, jobs=1)
    assert resumed.computed == total - kept
    keys = [(r["element"], r["size"], r["nu"]) for r in read_sweep(out)["rows"]]
    assert len(keys) == len(set(keys)) == total
    return case, grid, resumed, keys


def four_triangles_alpha(nu: float) -> float:
    """Paper, section 4.2: the positive critical coefficient of Fig. 3."""
    return math.sqrt((1 - nu) * (5 - 8 * nu) / (nu * (3 - 4 * nu)))


def one_triangle_alpha(nu: float) -> float:
    """Paper, section 4.1: 3 - 4 nu."""
    return 3.0 - 4.0 * nu


def paper_one_triangle_K(nu: float, E: float = 1.0) -> np.ndarray:
    lam, G = lame(E, nu)
    return 0.5 * np.array([[lam + 3 * G, lam + G], [lam + G, lam + 3 * G]])


def square_case(*, element="P1", size=0.25, nu=0.3, method="auto", structured=False,
                extra="") -> str:
    return f"""
[geometry]
shape = "square"
[material]
nu = {nu}
[mesh]
element = "{element}"
size = {size}
structured = {str(structured).lower()}
[solve]
method = "{method}"
{extra}
"""
