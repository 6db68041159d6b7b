"""Singular exponents at a vertex of the body, and the frictions where one crosses Re s = 0.

Near a vertex whose two edges (angle omega) carry the conditions ``first`` (the edge theta = 0)
and ``second`` (theta = omega), the solutions of plane-strain elasticity behave as
u = r^s Phi(theta). The exponents s solve a quadratic eigenproblem in s (the Navier equations
in polar coordinates, u_r = r^s a, u_theta = r^s b):

    s^2 (lam + 2) a + s (lam + 1) b' + a'' - (lam + 2) a - (lam + 3) b' = 0
    s^2 b + s (lam + 1) a' + (lam + 3) a' + (lam + 2) b'' - b = 0        (shear modulus 1)

discretized by Chebyshev collocation in theta, with the rows of each edge replaced by its
conditions: clamped (a = b = 0; also a stuck contact node), free (S_tt = S_rt = 0) or slip
(b = 0 and S_rt = c f S_tt, the friction law of (3.2) along the edge, c = +-1 the slip sense
relative to the edge's direction). Checked: a crack (omega = 2 pi, free) gives 1/2, a clamped
one 1/2, a free half-plane 0, 1, 2.

A root crossing Re s = 0 as the friction f grows is where the eigenproblem (3.2) stops being
Fredholm of index 0 in H^1 (r^s has finite energy iff Re s > 0): beyond it, graded meshes find
eigenvalues that depend on how far the grading goes (docs/validation.md, "Strong grading").

Usage: python scripts/exponents.py OMEGA/PI FIRST SECOND [--nu 0.3] [--fmax 12]
e.g. ``0.5 slip clamped`` (a contact edge meeting a Dirichlet edge at a right angle).
"""

from __future__ import annotations

import argparse
import sys

import numpy as np
import scipy.linalg as sl
from scipy.optimize import brentq

KINDS = ("clamped", "free", "slip")


def _cheb(n: int):
    x = np.cos(np.pi * np.arange(n + 1) / n)
    c = np.r_[2, np.ones(n - 1), 2] * (-1) ** np.arange(n + 1)
    dx = x[:, None] - x[None, :]
    d = np.outer(c, 1 / c) / (dx + np.eye(n + 1))
    return d - np.diag(d.sum(axis=1))


def exponents(omega: float, first: str, second: str, friction: float, *, sense: float = 1.0,
              nu: float = 0.3, n: int = 40) -> np.ndarray:
    """The finite exponents s (|s| < 20) of the vertex, both sides of Re s = 0."""
    lam = 2 * nu / (1 - 2 * nu)
    d = _cheb(n) * 2 / omega  # node 0: theta = omega, node n: theta = 0
    m = n + 1
    eye, zero = np.eye(m), np.zeros((m, m))
    a2 = np.block([[(lam + 2) * eye, zero], [zero, eye]])
    a1 = np.block([[zero, (lam + 1) * d], [(lam + 1) * d, zero]])
    a0 = np.block([[d @ d - (lam + 2) * eye, -(lam + 3) * d], [(lam + 3) * d,
                                                                  (lam + 2) * d @ d - eye]])
    for kind, i in ((second, 0), (first, n)):
        e, z = eye[i], np.zeros(m)
        stt0, stt1 = np.r_[(lam + 2) * e, (lam + 2) * d[i]], np.r_[lam * e, z]
        srt0, srt1 = np.r_[d[i], -e], np.r_[z, e]
        ua, ub, none = np.r_[e, z], np.r_[z, e], np.zeros(2 * m)
        rows = {"clamped": [(ua, none), (ub, none)], "free": [(stt0, stt1), (srt0, srt1)],
                "slip": [(ub, none), (srt0 - sense * friction * stt0,
                                      srt1 - sense * friction * stt1)]}[kind]
        for k, (r0, r1) in enumerate(rows):
            a0[i + k * m], a1[i + k * m], a2[i + k * m] = r0, r1, 0.0
    big = 2 * m
    lhs = np.block([[np.zeros((big, big)), np.eye(big)], [-a0, -a1]])
    rhs = np.block([[np.eye(big), np.zeros((big, big))], [np.zeros((big, big)), a2]])
    s = sl.eig(lhs, rhs, right=False)
    s = s[np.isfinite(s)]
    return s[np.abs(s) < 20]


def nearest_real(omega, first, second, friction, sense, nu) -> float:
    """The real exponent nearest 0 (those within 1e-3 of it, which exist for every friction
    where the edges allow a rigid translation, left out)."""
    s = exponents(omega, first, second, friction, sense=sense, nu=nu)
    s = s[np.abs(s.imag) < 1e-8].real
    s = s[np.abs(s) > 1e-3]
    return float(s[np.argmin(np.abs(s))]) if len(s) else np.nan


def crossings(omega, first, second, *, nu=0.3, fmax=12.0, steps=97) -> list[tuple[float, float]]:
    """(sense, friction) where a real exponent crosses 0, for 0 < friction <= fmax."""
    out = []
    grid = np.linspace(1e-3, fmax, steps)
    for sense in (1.0, -1.0):
        g = np.array([nearest_real(omega, first, second, f, sense, nu) for f in grid])
        small = np.abs(g) < 0.3  # a root moving across 0, not a jump from one root to another
        for k in np.flatnonzero(small[:-1] & small[1:] & (g[:-1] * g[1:] < 0)):
            f = brentq(lambda x, sense=sense: nearest_real(omega, first, second, x, sense, nu),
                       grid[k], grid[k + 1], xtol=1e-10)
            out.append((sense, f))
    return out


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("omega", type=float, help="the vertex angle / pi")
    parser.add_argument("first", choices=KINDS)
    parser.add_argument("second", choices=KINDS)
    parser.add_argument("--nu", type=float, default=0.3)
    parser.add_argument("--fmax", type=float, default=12.0)
    args = parser.parse_args(argv)
    omega = args.omega * np.pi
    for f in np.linspace(0.0, args.fmax, 7):
        for sense in (1.0, -1.0):
            s = exponents(omega, args.first, args.second, f, sense=sense, nu=args.nu)
            s = s[np.argsort(np.abs(s.real))][:4]
            print(f"friction {f:6.2f} sense {sense:+.0f}: " + "  ".join(
                f"{z.real:+.4f}{z.imag:+.4f}j" for z in s))
    found = crossings(omega, args.first, args.second, nu=args.nu, fmax=args.fmax)
    for sense, f in found:
        print(f"a real exponent crosses 0 at friction {f:.8f} (sense {sense:+.0f})")
    if not found:
        print(f"no real exponent crosses 0 for friction in (0, {args.fmax:g}]")
    return 0


if __name__ == "__main__":
    sys.exit(main())
