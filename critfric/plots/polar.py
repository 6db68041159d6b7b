"""The figure of a sweep over slip angles (3D bodies): the lowest positive critical coefficient
alpha+ against the slip direction, in polar axes and as a plain curve, with the body's
coefficient (the minimum over directions) marked.

Each sampled angle theta gives alpha+ twice: at theta (its lowest positive eigenvalue, dots)
and at theta + 180 (minus its negative eigenvalue of least modulus, crosses), since
alpha(theta + 180) = -alpha(theta). A direction with no positive eigenvalue is a gap.
"""

from __future__ import annotations

import math

import numpy as np
from matplotlib.figure import Figure

MAX_CURVES = 8  # (element, size, nu) curves drawn at most: the finest sizes first
_COLORS = ("tab:blue", "tab:orange", "tab:green", "tab:red", "tab:purple", "tab:brown",
           "tab:pink", "tab:olive")


def _curves(rows: list[dict]) -> dict[tuple, list[dict]]:
    """The rows by (element, size, nu), finest size first."""
    out: dict[tuple, list[dict]] = {}
    for r in rows:
        if r.get("slip_angle") is not None:
            out.setdefault((r["element"], r["size"], r["nu"]), []).append(r)
    return dict(sorted(out.items(), key=lambda kv: (
        -math.inf if kv[0][1] is None else kv[0][1], kv[0][0], kv[0][2])))


def _samples(rows: list[dict]) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(angles, alpha+) sampled directly and (angles + 180, -alpha-) mirrored, angles in
    [0, 360) ascending; NaN where a family has no value or the point failed."""
    ok = [r for r in rows if not r["status"].startswith("failed")]
    theta = np.array([float(r["slip_angle"]) for r in ok])
    pos = np.array([r["positive"][0] if r["positive"] else np.nan for r in ok])
    neg = np.array([-r["negative"][0] if r["negative"] else np.nan for r in ok])
    direct, mirrored = np.mod(theta, 360.0), np.mod(theta + 180.0, 360.0)
    a, b = np.argsort(direct, kind="stable"), np.argsort(mirrored, kind="stable")
    return direct[a], pos[a], mirrored[b], neg[b]


def _loop(angles: np.ndarray, values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The closed curve through every sample (direct and mirrored), ascending, back to the
    first: gaps (NaN) where a direction has no positive eigenvalue."""
    order = np.argsort(angles, kind="stable")
    a, v = angles[order], values[order]
    if len(a):
        a, v = np.r_[a, a[0] + 360.0], np.r_[v, v[0]]
    return a, v


def directions_figures(data: dict, title: str) -> dict[str, Figure]:
    """``directions``: alpha+ against the slip angle (polar, and plain) for each (element,
    size, nu) of a sweep file's ``data`` (:func:`critfric.files.sweepfile.read_sweep`), the
    minimum over directions marked."""
    curves = _curves(data["rows"])
    minima = {(m["element"], m["size"], m["nu"]): m for m in data.get("minima", [])}
    fig = Figure(figsize=(13.6, 6.4))
    polar = fig.add_subplot(1, 2, 1, projection="polar")
    plain = fig.add_subplot(1, 2, 2)
    shown = list(curves.items())[:MAX_CURVES]
    finite = []
    for k, ((element, size, nu), rows) in enumerate(shown):
        color = _COLORS[k % len(_COLORS)]
        label = f"{element}" + ("" if size is None else f", h = {size:g}") + f", ν = {nu:g}"
        a, pos, b, neg = _samples(rows)
        loop_a, loop_v = _loop(np.r_[a, b], np.r_[pos, neg])
        finite += [v for v in loop_v if np.isfinite(v)]
        for ax, x in ((polar, np.radians), (plain, lambda t: t)):
            ax.plot(x(loop_a), loop_v, color=color, lw=1, label=label)
            ax.plot(x(a), pos, "o", ms=4, color=color)
            ax.plot(x(b), neg, "x", ms=5, color=color)
        m = minima.get((element, size, nu))
        if m is not None and math.isfinite(m["positive"]):
            finite.append(m["positive"])
            text = f"minimum {m['positive']:.8g} at {m['slip_angle']:.6f}°"
            polar.plot([math.radians(m["slip_angle"])], [m["positive"]], "*", ms=14,
                       color=color, mec="k", label=f"{label}: {text}")
            plain.plot([m["slip_angle"]], [m["positive"]], "*", ms=14, color=color, mec="k",
                       label=f"{label}: {text}")
            plain.axvline(m["slip_angle"], color=color, ls=":", lw=1)
    notes = []
    if len(curves) > len(shown):
        notes.append(f"{len(curves) - len(shown)} more (element, size, ν) curves not drawn")
    failed = sum(r["status"].startswith("failed") for r in data["rows"])
    if failed:
        notes.append(f"{failed} failed point(s) left out")
    if any(m["status"] == "no-positive-alpha" for m in minima.values()):
        notes.append("no direction has a positive coefficient for some curves")
    if finite:
        lo, hi = min(finite), max(finite)
        pad = 0.05 * abs(hi) if hi == lo else 0.1 * (hi - lo)
        centre = max(0.0, lo - 3 * pad)
        polar.set_ylim(centre, hi + pad)
        plain.set_ylim(lo - pad, hi + pad)
        notes.append(f"polar radius: α from {centre:.4g} at the centre")
    polar.set_title("lowest positive coefficient α+ vs slip direction\n"
                    "(dots: sampled; crosses: −α− of the angle − 180°)", fontsize=9)
    plain.set_xlim(0, 360)
    plain.set_xticks(np.arange(0, 361, 45))
    plain.set_xlabel("slip angle θ (degrees from t1 towards t2 = n × t1)")
    plain.set_ylabel(r"lowest positive critical coefficient $\alpha_+(\theta)$")
    plain.set_title("the same curve; α+(θ + 180°) = −α−(θ)", fontsize=9)
    plain.grid(True, alpha=0.3)
    plain.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.12), ncol=2)
    if notes:
        polar.text(0.5, -0.12, "\n".join(notes), transform=polar.transAxes, fontsize=8,
                   ha="center", va="top")
    fig.suptitle(f"{title}: the critical coefficient over slip directions (the body's: the "
                 "minimum, ★)")
    fig.tight_layout()
    return {"directions": fig}
