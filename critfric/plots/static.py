"""PNG plots of the bifurcation diagram (``critfric solutions``) and of a verified branch
(``critfric verify``). Matplotlib's Agg canvas, no pyplot state: safe in any process."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .saving import save_figures


def _figure():
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(6.4, 4.8), layout="tight")
    FigureCanvasAgg(fig)
    return fig, fig.add_subplot()


def solutions_plot(sweep, path: Path | str, *, title: str = "") -> Path:
    """Mean tangential displacement of Gamma_C of every solution against the friction:
    isolated solutions as dots, branches (continua) as vertical segments."""
    fig, ax = _figure()
    fs, ys = [], []
    for e in sweep:
        for s in e.solutions:
            fs.append(e.friction)
            ys.append(float(np.mean(s.Ut)))
    ax.plot(fs, ys, "o", color="C0", ms=4, label="isolated solutions")
    span = (max(ys) - min(ys)) if len(ys) > 1 else 1.0
    labelled = False
    for e in sweep:
        for b in e.branches:
            y0 = float(np.mean(b.point.Ut))
            dy = float(np.mean(b.directions[0].Ut)) if len(b.directions) == 1 else 0.0
            ends = b.ends or [None, None]
            lo = float(np.mean(ends[0].Ut)) if ends[0] is not None else y0 - np.sign(dy) * span
            hi = float(np.mean(ends[1].Ut)) if ends[1] is not None else y0 + np.sign(dy) * span
            ax.plot([e.friction, e.friction], [lo, hi], "-", color="C3", lw=2.5,
                    label=None if labelled else "branch (continuum of solutions)")
            labelled = True
    ax.set_xlabel("friction coefficient")
    ax.set_ylabel("mean tangential displacement on $\\Gamma_C$")
    ax.set_title("Solutions of the static Coulomb problem (2.8) against friction"
                 + (f"\n{title}" if title else ""), fontsize=10)
    ax.grid(alpha=0.3)
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.13), ncol=2, fontsize=8)
    return save_figures([(fig, Path(path))], key="--plot", dpi=120, bbox_inches="tight")[0]


def branch_plot(verification, path: Path | str, *, title: str = "") -> Path:
    """The walk u + delta Phi at the critical coefficient: tangential displacement against the
    normal force at the contact node that moves most; passing points filled."""
    b = verification.critical
    k = b.node
    X = np.array([q.X[k] for q in b.points])
    Ut = np.array([q.Ut[k] for q in b.points])
    ok = np.array([q.passed for q in b.points])
    fig, ax = _figure()
    ax.plot(X, Ut, "-", color="0.7", lw=1)
    ax.plot(X[ok], Ut[ok], "o", color="C0", ms=5, label="solution of (2.8)")
    ax.plot(X[~ok], Ut[~ok], "x", color="C3", ms=6, label="violates (2.9)-(2.11)")
    base = next(q for q in b.points if q.delta == 0.0) if any(
        q.delta == 0.0 for q in b.points) else None
    if base is not None:
        ax.plot([base.X[k]], [base.Ut[k]], "s", color="k", ms=6, label="explicit solution")
    ax.set_xlabel(f"normal force X at contact node {k}")
    ax.set_ylabel(f"tangential displacement $U_t$ at contact node {k}")
    ax.set_title(title or f"friction = {b.friction:.8g}, delta0 = {b.delta0:.4g}, "
                 f"{'passed' if verification.passed else 'FAILED'}")
    ax.grid(alpha=0.3)
    ax.legend(loc="best", fontsize=8)
    return save_figures([(fig, Path(path))], key="--plot", dpi=120)[0]


def default_plot(case, kind: str) -> Path:
    """``<case name>_<kind>.png`` next to the case's result file (current directory)."""
    out = Path(case.output["file"] or f"{case.name}.h5")
    return out.with_name(f"{out.stem}_{kind}.png")
