"""h -> 0 limits of sweep values: Richardson extrapolation with the observed order.

For one family (the lowest positive, or the lowest negative, coefficient at one nu with one
element) computed at sizes h1 > h2 > h3 > ..., with f(h) = f0 + C h^p + ..., the observed
order p of the three finest sizes solves

    (f1 - f2) / (f2 - f3) = (h1^p - h2^p) / (h2^p - h3^p)

(p = log(q) / log(r) for a constant ratio r = h1/h2 = h2/h3), and the limit is
f0 = f3 + (f3 - f2) h3^p / (h2^p - h3^p). The mesh parameter h is the target size of the
sweep (``--size``), which is exact and proportional across unstructured meshes, unlike the
measured largest cell diameter.

Error estimate: with four sizes or more, max(|f0 - f0'|, |f0 - f3| / 4) where f0' is the limit
of the previous three sizes (successive limits alone proved optimistic: on unstructured P1
meshes they agreed to 1e-5 while missing the P2 and Q2 limits by 1.4e-4, a quarter of the
correction |f0 - f3|); with three sizes, |f0 - f3|. A family is *not converged*, and
gets no limit, when fewer than three sizes have a finite value, when the differences do not
shrink with a positive order of at least ``MIN_ORDER``, when the last two orders differ by more
than ``ORDER_SPREAD`` (relative), or when the limits of two elements at the same nu differ by
more than the sum of their error estimates (a mode localised at a corner of
Gamma_C drifts with h and differs between elements).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import brentq

MIN_ORDER = 0.5
MAX_ORDER = 20.0
ORDER_SPREAD = 0.5
ERROR_FRACTION = 0.25  # the error estimate is at least this fraction of |f0 - f_finest|


@dataclass
class Limit:
    """The h -> 0 limit of one family; ``limit`` is NaN when it is not converged."""

    nu: float
    element: str
    family: str  # "positive" or "negative"
    limit: float
    order: float
    error: float
    n_sizes: int
    status: str  # "ok" or "not converged: <why>"

    def to_json(self) -> dict:
        def num(v):
            return float(v) if math.isfinite(v) else None

        return {"nu": self.nu, "element": self.element, "family": self.family,
                "limit": num(self.limit), "order": num(self.order), "error": num(self.error),
                "n_sizes": self.n_sizes, "status": self.status}

    def to_row(self) -> dict:
        return dict(nu=self.nu, element=self.element, family=self.family, limit=self.limit,
                    order=self.order, error=self.error, n_sizes=self.n_sizes,
                    status=self.status)


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


def family_limit(h, f) -> tuple[float, float, float, str]:
    """(limit, order, error, status) of values ``f`` at sizes ``h`` (any order)."""
    h, f = np.asarray(h, dtype=float), np.asarray(f, dtype=float)
    keep = np.isfinite(f)
    order_ = np.argsort(-h[keep])
    h, f = h[keep][order_], f[keep][order_]
    nan = math.nan
    if len(h) < 3:
        return nan, nan, nan, f"not converged: a finite value at only {len(h)} size(s)"
    limit, p = richardson(h, f)
    if not math.isfinite(p):
        return nan, nan, nan, "not converged: the differences do not shrink with h"
    if p < MIN_ORDER:
        return nan, p, nan, f"not converged: observed order {p:.2g} < {MIN_ORDER}"
    error = abs(limit - f[-1])
    if len(h) >= 4:
        prev, p_prev = richardson(h[:-1], f[:-1])
        if not math.isfinite(p_prev):
            return nan, p, nan, ("not converged: no positive order on the previous three "
                                 f"sizes (order {p:.2g} on the last three)")
        if abs(p - p_prev) > ORDER_SPREAD * max(p, p_prev):
            return nan, p, nan, (f"not converged: inconsistent orders ({p_prev:.2g} on the "
                                 f"previous three sizes, {p:.2g} on the last three)")
        error = max(abs(limit - prev), ERROR_FRACTION * error)
    return limit, p, error, "ok"


def limits_of(rows: list[dict]) -> list[Limit]:
    """Limits of every (nu, element, family) of sweep rows with at least three sizes."""
    groups: dict[tuple, list[dict]] = {}
    for r in rows:
        if r["size"] is not None:
            groups.setdefault((r["nu"], r["element"]), []).append(r)
    out: list[Limit] = []
    for (nu, element), rs in sorted(groups.items(), key=lambda kv: (kv[0][0], kv[0][1])):
        if len(rs) < 3:
            continue
        h = [r["size"] for r in rs]
        for family in ("positive", "negative"):
            f = [r[family][0] if r["status"] == "ok" and r[family] else math.nan for r in rs]
            limit, p, err, status = family_limit(h, f)
            out.append(Limit(nu, element, family, limit, p, err, len(rs), status))
    _flag_disagreement(out)
    return out


def _flag_disagreement(limits: list[Limit]) -> None:
    """Mark families whose elements disagree beyond the error estimates at the same nu."""
    by_family: dict[tuple, list[Limit]] = {}
    for lim in limits:
        if lim.status == "ok":
            by_family.setdefault((lim.nu, lim.family), []).append(lim)
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
