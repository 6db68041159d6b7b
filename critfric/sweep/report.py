"""The text report of ``critfric sweep``: every point, the h -> 0 limits and, for a sweep
over slip angles, the minimum over directions of each (nu, size, element)."""

from __future__ import annotations

import math


def _value(v):
    """None for what has no value (NaN, inf, a negative count)."""
    if isinstance(v, float) and not math.isfinite(v):
        return None
    if isinstance(v, int) and v < 0:
        return None
    return v


def _num(v, fmt: str) -> str:
    return "-" if _value(v) is None else fmt % v


def report_sweep(sweep) -> str:
    """The text summary of a :class:`~critfric.sweep.runner.Sweep`."""
    rows, grid = sweep.rows, sweep.grid
    angles = grid.slip_angle is not None
    axes = f"{len(grid.nu)} nu x {len(grid.size)} size x {len(grid.element)} element" + (
        f" x {len(grid.slip_angle)} slip angle" if angles else "")
    lines = [(f"sweep {sweep.path}: {len(rows)} points ({axes}), {sweep.computed} computed "
              f"now in {sweep.seconds:.1f} s")]
    angle_head = f"{'angle':>8} " if angles else ""
    head = (f"{'nu':>7} {'element':<7} {'size':>8} {angle_head}{'h':>8} {'n_dofs':>8} "
            f"{'p':>5} {'lowest > 0':>14} {'lowest < 0':>14} {'complex':>7} {'seconds':>8}  "
            "status")
    lines += [head, "-" * len(head)]
    for r in rows:
        pos = r["positive"][0] if r["positive"] else None
        neg = r["negative"][0] if r["negative"] else None
        angle = f"{_num(r.get('slip_angle'), '%.4g'):>8} " if angles else ""
        lines.append(f"{r['nu']:>7.4g} {r['element']:<7} {_num(r['size'], '%.4g'):>8} "
                     f"{angle}{_num(r['h'], '%.4g'):>8} {_num(r['n_dofs'], '%d'):>8} "
                     f"{_num(r['n_contact'], '%d'):>5} {_num(pos, '%.10f'):>14} "
                     f"{_num(neg, '%.8f'):>14} {_num(r['complex_count'], '%d'):>7} "
                     f"{r['seconds']:>8.2f}  {r['status']}")
    if sweep.minima:
        lines += ["", ("the body's coefficient: the minimum over slip directions of the lowest "
                       "positive eigenvalue (alpha(angle + 180) = -alpha(angle); bracketed on "
                       "the samples, located by Brent's method; '-': none)")]
        head = (f"{'nu':>7} {'element':<7} {'size':>8} {'angle':>14} {'minimum':>14} "
                f"{'r':>8} {'bracket':>19} {'solves':>6}  status")
        lines += [head, "-" * len(head)]
        for m in sweep.minima:
            bracket = f"[{_num(m['bracket_lo'], '%.4g')}, {_num(m['bracket_hi'], '%.4g')}]"
            lines.append(f"{m['nu']:>7.4g} {m['element']:<7} {_num(m['size'], '%.4g'):>8} "
                         f"{_num(m['slip_angle'], '%.7f'):>14} "
                         f"{_num(m['positive'], '%.10f'):>14} "
                         f"{_num(m['r_positive'], '%.4f'):>8} {bracket:>19} "
                         f"{m['evaluations']:>6d}  {m['status']}")
    if not sweep.limits:
        lines += [""] if sweep.minima else []
        lines.append("h -> 0 limits: need at least three sizes (--size h1,h2,h3)")
        return "\n".join(lines)
    lines.append("")
    lines.append("h -> 0 limits (a fit f0 + C h^p to the four finest sizes, Richardson's "
                 "extrapolation with three; observed order p; - where not extrapolated)")
    angle_head = f"{'angle':>8} " if angles else ""
    head = (f"{'nu':>7} {'element':<7} {angle_head}{'family':<8} {'limit':>14} {'error':>9} "
            f"{'p':>5}  status")
    lines += [head, "-" * len(head)]
    for lim in sweep.limits:
        angle = f"{_num(lim.slip_angle, '%.4g'):>8} " if angles else ""
        lines.append(f"{lim.nu:>7.4g} {lim.element:<7} {angle}{lim.family:<8} "
                     f"{_num(lim.limit, '%.10f'):>14} {_num(lim.error, '%.1e'):>9} "
                     f"{_num(lim.order, '%.2f'):>5}  {lim.status}"
                     + (f" ({lim.note})" if lim.note else ""))
    return "\n".join(lines)
