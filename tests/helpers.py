"""Shared test helpers: in-code cases and closed forms from the paper."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from critfric.assembly import lame

CASES = Path(__file__).resolve().parent.parent / "cases"


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
