"""h -> 0 limits of sweep values: a fit f(h) = f0 + C h^p with the observed order p.

For one family (the lowest positive, or the lowest negative, coefficient at one nu with one
element) computed at sizes h1 > h2 > h3 > ..., the limit f0 and the order p come from a
least-squares fit of f0 + C h^p to the finest ``FIT_SIZES`` (4) sizes, weighted by (h1 / h)^2
(the finer, the nearer the asymptotic range; measured: inclined-body P1 and Q1 limits 2x
nearer the reference than unweighted, no estimate less safe) (p scanned over
[``MIN_ORDER``, 2 k + 1], k the element degree: eigenvalue errors converge at most as h^2k;
with exactly three sizes the fit is Richardson's extrapolation). The mesh parameter h is the
target size of the sweep (``--size``), exact and proportional across unstructured meshes.

Error estimate (what ``make validate`` checks, see docs/validation.md):

    error = max(F |f0 - f_finest|, |f0 - f0'|) + 3 sigma

with f0' the fit without the finest size (four sizes or more), sigma the scatter of the fit
and the safety factor F = ``SAFETY`` (1.25) when four sizes or more give an order below the
cap, else ``SAFETY_FEW`` (3): with three sizes nothing checks the order, and an order at the
cap means that the values change faster than the element can converge (mesh noise), and then
the error is at least ``SAFETY_FEW`` times the spread of the three finest values. When the
fit finds no order above ``MIN_ORDER`` but the values do not move one way with a growing last
step, the limit is the finest value and the error 3 times the spread of the fitted values
(order NaN: mesh noise or a pre-asymptotic step, not extrapolated; measured: a slip | free |
slip base, P1 negative family 1.812848, 1.812808, 1.812836, 1.812880 where P2 and Q2 converge
to 1.81295); values that all move one way, the last step the largest, drift: not converged.
Every error is at least ``ERROR_FLOOR`` (1e-8) of the limit. Measured on graded unit-square
and inclined-body families (P1, P2, Q1, Q2, nested meshes) against references from radically
graded P2 and Q2 (see docs/validation.md): g = 0.1 and 0.25, every window of 3 to 5 of the
sizes 0.2 ... 0.0125, 140 limits (4 more windows of coarse or pre-asymptotic values flagged),
|reference - f0| / error at most 0.91; g = 0.05 (the sweep default), every halving window of
3 to 5 of the sizes 0.2 ... 0.00625, 105 limits (3 windows flagged), at most 0.73 (0.96
without the floor: Q2, unit square, 0.05 ... 0.00625, 1.0e-8 off a reference known to 3e-8).

A family is *not converged*, and gets no limit, when fewer than three sizes have a finite
value, when its error estimate exceeds ``MAX_RELATIVE_ERROR`` (1.5%) of the limit (the values
jump between meshes; measured: converging families <= 1% on the coarsest windows, 0.2 to
0.05, and <= 0.1% from 0.1 down; the inclined body's negative family, whose P2 and Q2 values
differ by 30%, 2-15% on every window but one: Q2 at 0.2, 0.1, 0.05 looks converged, 0.3%),
when the values drift with an order below ``MIN_ORDER``, or when the limits of two elements
at the same nu differ by more than the sum of their error estimates, or when another
element's values of the family swing by more than ``ERRATIC`` (15%) over its three finest
sizes (a mesh-dependent family).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import brentq, minimize_scalar

MIN_ORDER = 0.5
MAX_ORDER = 20.0  # observed_order's search range
FIT_SIZES = 4  # the fit uses the finest this many sizes
SAFETY = 1.25  # error = SAFETY x the extrapolation correction (4+ sizes, order below the cap)
SAFETY_FEW = 3.0  # ... with 3 sizes, or an order at the element's cap
MAX_RELATIVE_ERROR = 1.5e-2  # a larger error estimate (relative to the limit): not converged
CHAIN_TOL = 0.02  # a family followed from size to size takes the nearest value within 2%
ERRATIC = 0.15  # values of one element that swing by more than this over its three finest
#                 sizes: the family is mesh-dependent, for every element at that nu
_ORDERS = 400  # orders scanned by the fit
WEIGHT_POWER = 2.0  # fit weights (h_max / h)^WEIGHT_POWER
#: an error estimate is at least this much of the limit: finer than that, a power law fitted
#: to four sizes is not evidence (measured: Q2 unit-square limits from 0.05 ... 0.00625 come
#: within 1e-8 of references known to 3e-8)
ERROR_FLOOR = 1e-8


@dataclass
class Limit:
    """The h -> 0 limit of one family; ``limit`` is NaN when it is not converged."""

    nu: float
    element: str
    family: str  # "positive", "negative" or "minimum" (over slip directions)
    limit: float
    order: float
    error: float
    n_sizes: int
    status: str  # "ok" or "not converged: <why>"
    slip_angle: float | None = None  # the angle of a sweep over slip angles
    note: str = ""  # how the family was found, when not as the lowest value of each size

    def to_json(self) -> dict:
        def num(v):
            return float(v) if math.isfinite(v) else None

        out = {"nu": self.nu, "element": self.element, "family": self.family,
               "limit": num(self.limit), "order": num(self.order), "error": num(self.error),
               "n_sizes": self.n_sizes, "status": self.status,
               **({"note": self.note} if self.note else {})}
        return out if self.slip_angle is None else {**out, "slip_angle": self.slip_angle}

    def to_row(self) -> dict:
        return dict(nu=self.nu, element=self.element, family=self.family, limit=self.limit,
                    order=self.order, error=self.error, n_sizes=self.n_sizes,
                    status=self.status,
                    slip_angle=math.nan if self.slip_angle is None else self.slip_angle)


def observed_order(h, f) -> float:
    """Order p of three values ``f`` at sizes ``h`` (decreasing); NaN without a positive one."""
    h1, h2, h3 = (float(x) for x in h)
    f1, f2, f3 = (float(x) for x in f)
    if not (h1 > h2 > h3 > 0):
        raise ValueError("sizes must decrease")
    d12, d23 = f1 - f2, f2 - f3
    if d23 == 0.0 or d12 == 0.0 or (d12 > 0) != (d23 > 0):
        return math.nan
    q = d12 / d23
    x2, x3 = h2 / h1, h3 / h1

    def gap(p):  # log g(p) - log q, g increasing in p
        return math.log((1 - x2**p) / (x2**p - x3**p)) - math.log(q)

    lo, hi = 1e-9, MAX_ORDER
    if gap(lo) >= 0 or gap(hi) <= 0:
        return math.nan
    return float(brentq(gap, lo, hi, xtol=1e-12))


def richardson(h, f) -> tuple[float, float]:
    """(limit, order) from the last three (h decreasing) values; NaNs without an order."""
    p = observed_order(h[-3:], f[-3:])
    if not math.isfinite(p):
        return math.nan, math.nan
    h2, h3 = float(h[-2]), float(h[-1])
    f2, f3 = float(f[-2]), float(f[-1])
    r = (h3 / h2) ** p
    return f3 + (f3 - f2) * r / (1 - r), p


def _linear_fits(h: np.ndarray, f: np.ndarray, orders: np.ndarray):
    """For each order p: the weighted least-squares f0 of f0 + C h^p (weights
    (h_max / h)^WEIGHT_POWER: the finer, the nearer the asymptotic range) and the weighted
    residual sum."""
    w = (h.max() / h) ** WEIGHT_POWER
    w = w / w.sum()
    x = (h / h.max())[None, :] ** orders[:, None]  # (orders, n), scaled: no under/overflow
    xc = x - (x @ w)[:, None]
    fc = f - f @ w
    slope = ((xc * w) @ fc) / np.einsum("ij,ij,j->i", xc, xc, w)
    f0 = f @ w - slope * (x @ w)
    return f0, np.sum(w * (f0[:, None] + slope[:, None] * x - f) ** 2, axis=1)


def fit(h, f, max_order: float) -> tuple[float, float, float, bool]:
    """Least-squares f0 + C h^p over ``h``, p in [MIN_ORDER, max_order]: (f0, p, sigma,
    p at a bound of the range); a scan of the orders (vectorised), then polished."""
    h, f = np.asarray(h, dtype=float), np.asarray(f, dtype=float)
    orders = np.linspace(MIN_ORDER, max_order, _ORDERS)
    f0, residual = _linear_fits(h, f, orders)
    k = int(np.argmin(residual))
    at_bound = k in (0, _ORDERS - 1)
    p = float(orders[k])
    if not at_bound:
        step = orders[1] - orders[0]
        best = minimize_scalar(lambda q: _linear_fits(h, f, np.array([q]))[1][0],
                               bounds=(p - step, p + step), method="bounded",
                               options={"xatol": 1e-10})
        p = float(best.x)
    f0, residual = (float(v[0]) for v in _linear_fits(h, f, np.array([p])))
    sigma = math.sqrt(residual * len(h) / (len(h) - 3)) if len(h) > 3 else 0.0
    return f0, p, sigma, at_bound


def max_order(element: str | None) -> float:
    """The largest order an eigenvalue of ``element`` converges with, plus one: 2 k + 1."""
    degree = 2 if element in ("P2", "Q2") else 1
    return 2.0 * degree + 1.0


def family_limit(h, f, element: str | None = None) -> tuple[float, float, float, str]:
    """(limit, order, error, status) of values ``f`` at sizes ``h`` (any order) of one
    ``element`` (its degree caps the order; None: degree 1)."""
    h, f = np.asarray(h, dtype=float), np.asarray(f, dtype=float)
    keep = np.isfinite(f)
    order_ = np.argsort(-h[keep])
    h, f = h[keep][order_][-FIT_SIZES:], f[keep][order_][-FIT_SIZES:]
    nan = math.nan
    if len(h) < 3:
        return nan, nan, nan, f"not converged: a finite value at only {len(h)} size(s)"
    cap = max_order(element)
    limit, p, sigma, at_bound = fit(h, f, cap)
    if at_bound and p < cap:  # no order >= MIN_ORDER explains the values
        steps = np.diff(f)
        size = np.abs(steps)
        if size[-1] >= size[:-1].max() and (np.all(steps > 0) or np.all(steps < 0)):
            return nan, nan, nan, (f"not converged: the values drift with an order below "
                                   f"{MIN_ORDER} (changes {size[0]:.2g}, then {size[-1]:.2g})")
        # mesh noise or a pre-asymptotic step: not extrapolated
        limit, p, error = float(f[-1]), nan, SAFETY_FEW * float(np.ptp(f))
    else:
        factor = SAFETY if len(h) >= 4 and not at_bound else SAFETY_FEW
        error = factor * abs(limit - f[-1])
        if at_bound:  # faster than the element converges: the values' spread counts
            error = max(error, SAFETY_FEW * float(np.ptp(f[-3:])))
        if len(h) >= 4:
            error = max(error, abs(limit - fit(h[:-1], f[:-1], cap)[0]))
        error += 3.0 * sigma
    error = max(error, ERROR_FLOOR * abs(limit))
    if error > MAX_RELATIVE_ERROR * abs(limit):
        return nan, p, error, (f"not converged: the values change by "
                               f"{np.ptp(f[-3:]) / abs(limit):.1%} over the three finest sizes "
                               f"(error estimate {error / abs(limit):.1%} of the value, above "
                               f"{MAX_RELATIVE_ERROR:.1%})")
    return limit, p, error, "ok"


def limits_of(rows: list[dict], minima: list[dict] = ()) -> list[Limit]:
    """Limits of every (nu, slip angle, element, family) of sweep rows with at least three
    sizes, and of the minima over slip directions (family "minimum") of each (nu, element)."""
    groups: dict[tuple, list[dict]] = {}
    for r in rows:
        if r["size"] is not None:
            key = (r["nu"], r.get("slip_angle"), r["element"], ("positive", "negative"))
            groups.setdefault(key, []).append(r)
    for m in minima:
        if m["size"] is not None:
            value = m["positive"]
            row = {"size": m["size"], "status": "ok" if math.isfinite(value) else "none",
                   "minimum": [value]}
            groups.setdefault((m["nu"], None, m["element"], ("minimum",)), []).append(row)
    out: list[Limit] = []
    erratic: dict[tuple, str] = {}  # (nu, angle, family) -> why
    for (nu, angle, element, families), rs in sorted(groups.items(), key=lambda kv: (
            kv[0][0], kv[0][3] == ("minimum",), -1e9 if kv[0][1] is None else kv[0][1],
            kv[0][2])):
        if len(rs) < 3:
            continue
        h = [r["size"] for r in rs]
        for family in families:
            f = [r[family][0] if r["status"] == "ok" and r[family] else math.nan for r in rs]
            limit, p, err, status = family_limit(h, f, element)
            note = ""
            if status != "ok":  # eigenvalues of the singular points below a family?
                values = [list(r[family]) if r["status"] == "ok" else [] for r in rs]
                limit, p, err, status, note = _followed(h, values, element) or (
                    limit, p, err, status, "")
            out.append(Limit(nu, element, family, limit, p, err, len(rs), status, angle,
                             note))
            swing = _swing(h, f)
            if swing > ERRATIC:
                erratic[nu, angle, family] = (f"{element} swings by {swing:.0%} over its three "
                                              "finest sizes")
    _flag_disagreement(out, erratic)
    return out


def _followed(h, values, element):
    """The lowest family that converges when each value at the finest size is followed to
    the coarser ones (at each, the value nearest it, within ``CHAIN_TOL``): (limit, order,
    error, "ok", note naming the lower values passed over), or None if none converges.

    Strong grading makes eigenvalues of the singular points' own (infinite-dimensional)
    problem appear, below the body's ones at the finer sizes, and they fall with every
    halving (docs/validation.md, "Strong grading"); the lowest value of each size then mixes
    two families and does not converge, where the body's family, followed, does."""
    order = np.argsort(-np.asarray(h, dtype=float))
    hs = np.asarray(h, dtype=float)[order]
    vs = [np.asarray([v for v in values[i] if math.isfinite(v)]) for i in order]
    best = None
    for start in vs[-1][1:]:
        chain, passed, current = [], [], start
        for v in vs[::-1]:  # finest to coarsest
            k = int(np.argmin(np.abs(v - current))) if len(v) else -1
            if k < 0 or abs(v[k] - current) > CHAIN_TOL * abs(current):
                break
            current = float(v[k])
            chain.append(current)
            passed += [float(x) for x in v[:k]]
        if len(chain) < 3:
            continue
        n = len(chain)
        limit, p, err, status = family_limit(hs[-n:], chain[::-1], element)
        if status == "ok" and (best is None or abs(limit) < abs(best[0])):
            note = ("followed from size to size: lower values of the singular points left "
                    "out (" + ", ".join(f"{x:.6g}" for x in passed) + ")")
            best = (limit, p, err, status, note)
    return best


def _swing(h, f) -> float:
    """max - min of the three finest finite values, relative to the finest (0 without three)."""
    h, f = np.asarray(h, dtype=float), np.asarray(f, dtype=float)
    keep = np.isfinite(f)
    f = f[keep][np.argsort(-h[keep])][-3:]
    return float(np.ptp(f) / abs(f[-1])) if len(f) == 3 and f[-1] != 0 else 0.0


def _flag_disagreement(limits: list[Limit], erratic: dict[tuple, str]) -> None:
    """Mark families whose elements disagree beyond the error estimates at the same nu, and
    every element's limit of a family that another element finds erratic (``ERRATIC``: a
    mesh-dependent family, e.g. the positive one of a mixed-state base, which converges on
    nested quad meshes, 8.28 and 8.33 (Q1, Q2), and jumps between 11.6 and 228 on triangles)."""
    for lim in limits:
        why = erratic.get((lim.nu, lim.slip_angle, lim.family))
        if lim.status == "ok" and why:
            lim.status = f"not converged: elements disagree ({why}; {lim.element} {lim.limit:.6g})"
            lim.limit = math.nan
    by_family: dict[tuple, list[Limit]] = {}
    for lim in limits:
        if lim.status == "ok":
            by_family.setdefault((lim.nu, lim.slip_angle, lim.family), []).append(lim)
    for group in by_family.values():
        bad = set()
        for i, a in enumerate(group):
            for b in group[i + 1:]:
                if abs(a.limit - b.limit) > a.error + b.error:
                    bad |= {id(a), id(b)}
        notes = {id(lim): ", ".join(f"{o.element} {o.limit:.6g}" for o in group if o is not lim)
                 for lim in group}
        for lim in group:
            if id(lim) in bad:
                lim.status = (f"not converged: elements disagree ({lim.element} "
                              f"{lim.limit:.6g} vs {notes[id(lim)]})")
                lim.limit = math.nan
