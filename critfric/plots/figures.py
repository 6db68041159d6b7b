"""Figures (PNG, matplotlib Agg, no pyplot state) of sweep and solve files, as in the paper.

Sweep file ``s.h5``: ``s_critical.png`` (critical coefficient vs nu per element and size,
with the h -> 0 limits: Figs. 4 and 7) and ``s_convergence.png`` (coefficient vs h and
|alpha_h - limit| vs h per element on log axes at one nu: Fig. 5).
Solve file ``r.h5``: ``r_deformed.png`` (the eigenfunction Phi, Fig. 8), ``r_von_mises.png``
(von Mises stress of Phi, Fig. 9), ``r_contact_forces.png`` (theta_n, theta_t along Gamma_C)
and ``r_spectrum.png`` (eigenvalues in the complex plane, real critical ones marked); of a 3D
body ``r_contact_positive_0.png``, ``r_contact_negative_0.png`` (Phi and X on Gamma_C, see
plots/solid.py) and ``r_spectrum.png`` (real eigenvalues coloured by r).
Stability and path files: see plots/stability.py and plots/path.py (``p_diagram.png``).
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from textwrap import shorten

import numpy as np
from matplotlib.collections import LineCollection
from matplotlib.figure import Figure
from matplotlib.tri import Triangulation

from ..errors import CaseError
from ..fem.arrays import distinct
from ..fem.loads import traction_load
from ..files.export import SolveData, mode_fields, read_solve
from ..files.opening import kind_of, open_file
from ..files.sweepfile import read_sweep
from .meshdraw import segments as _segments
from .meshdraw import triangles as _triangles
from .saving import FORMATS, save_figures
from .solid import contact_figures

DPI = 150
ALPHA_LABEL = r"critical friction coefficient $\mu_{\rm cr}$"
_STYLE = {"P1": ("tab:blue", "o"), "P2": ("tab:orange", "s"), "Q1": ("tab:green", "^"),
          "Q2": ("tab:red", "D")}


def plot_file(path: Path | str, *, nu: float | None = None,
              formats: tuple[str, ...] = ("png",)) -> list[Path]:
    """Write the figures of a sweep, solve, stability or path file next to it, in each of
    ``formats`` (png, pdf, svg); return their paths."""
    path = Path(path)
    bad = [f for f in formats if f not in FORMATS]
    if bad or not formats:
        raise CaseError(f"got {','.join(formats)}; allowed: a comma list of "
                        + ", ".join(FORMATS), key="--format")

    drawn = figures(path, nu=nu)
    items = [(fig, path.with_name(f"{path.stem}_{name}.{fmt}")) for name, fig in drawn.items()
             for fmt in formats]
    return save_figures(items, inputs=[path], dpi=DPI, bbox_inches="tight")


def figures(path: Path | str, *, nu: float | None = None) -> dict[str, Figure]:
    """The figures of a sweep, solve, stability or path file, by name, as matplotlib Figures
    to show, compose or save (:func:`plot_file` saves them next to the file)."""
    path = Path(path)
    try:
        with open_file(path) as f:
            kind = kind_of(f)
    except OSError as exc:
        raise CaseError(f"cannot read this file ({exc})", file=str(path)) from None
    if kind == "sweep":
        return sweep_figures(path, nu=nu)
    if kind == "solve":
        return solve_figures(path)
    if kind == "stability":
        from .stability import stability_figures

        return stability_figures(path)
    if kind == "path":
        from .path import path_figures

        return path_figures(path)
    raise CaseError("is not a sweep, solve, stability or path file of critfric",
                    file=str(path))


WIREFRAME_CELLS = 3000  # above this, a deformed mesh is drawn as colour, not as wires


# ------------------------------------------------------------------------------ sweeps
def sweep_figures(path: Path, *, nu: float | None = None) -> dict[str, Figure]:
    """``critical`` (coefficients against nu, Figs. 4 and 7) and, with two sizes or more,
    ``convergence`` (against h, Fig. 5); a sweep over slip angles has ``directions`` only
    (:mod:`.polar`)."""
    data = read_sweep(path)
    rows, limits = data["rows"], data["limits"]
    order = {el: i for i, el in enumerate(json.loads(data["attrs"]["grid"])["element"])}
    rows = sorted(rows, key=lambda r: (order.get(r["element"], 99), r["nu"]))
    title = f"{data['attrs'].get('case_name', '')}"
    if json.loads(data["attrs"]["grid"]).get("quantity") == "flutter":
        title += ": FLUTTER thresholds of steady sliding (critfric stability), not static"
    _check_drawable(path, rows, limits, data.get("minima", []))
    if json.loads(data["attrs"]["grid"]).get("slip_angle") is not None:  # over directions
        from .polar import directions_figures

        return directions_figures(data, title)
    out = {"critical": _critical_vs_nu(rows, limits, title)}
    sized = [r for r in rows if r["size"] is not None]
    if len({r["size"] for r in sized}) >= 2 and any(
            math.isfinite(_value(r, "positive")) for r in sized):
        out["convergence"] = _convergence(rows, limits, title, nu)
    return out


class NothingToDraw(CaseError):
    """A file that holds no value a figure could show (no point, or every one failed or
    without a value): said instead of drawing empty axes."""


def _check_drawable(path: Path, rows, limits, minima) -> None:
    """Raise :class:`NothingToDraw` unless a point, a limit or a minimum has a finite value."""
    finite = lambda v: v is not None and math.isfinite(v)
    if any(finite(_value(r, f)) for r in rows for f in ("positive", "negative")) or any(
            lim["status"] == "ok" and finite(lim["limit"]) for lim in limits) or any(
            finite(m["positive"]) for m in minima):
        return
    if not rows:
        raise NothingToDraw("holds no finished point yet (a sweep resumes with the same "
                            "command); nothing to draw, no figure written", file=str(path))
    failed = [r["status"] for r in rows if r["status"].startswith("failed")]
    first = f" (the first: {shorten(failed[0], 100, placeholder='...')})" if failed else ""
    raise NothingToDraw(f"has no value to draw: of its {len(rows)} points, {len(failed)} "
                        f"failed{first} and {len(rows) - len(failed)} have no real value "
                        "(status in `critfric table`); no figure written", file=str(path))


def _value(row: dict, family: str) -> float:
    return row[family][0] if row["status"] == "ok" and row[family] else math.nan


def _legend(ax, **kw) -> None:
    """A legend if the axes have labelled artists (matplotlib warns otherwise)."""
    if ax.get_legend_handles_labels()[0]:
        ax.legend(**kw)


def _critical_vs_nu(rows, limits, title) -> Figure:
    families = ["positive"] + (["negative"] if any(r["negative"] for r in rows) else [])
    fig = Figure(figsize=(6.4 * len(families), 4.8))
    axes = fig.subplots(1, len(families), squeeze=False)[0]
    elements = list(dict.fromkeys(r["element"] for r in rows))
    sizes = sorted({r["size"] for r in rows}, key=lambda s: -1 if s is None else -s)
    for ax, family in zip(axes, families):
        sign = 1.0 if family == "positive" else -1.0
        for el in elements:
            color, marker = _STYLE[el]
            for k, size in enumerate(sizes):
                rs = sorted((r for r in rows if r["element"] == el and r["size"] == size),
                            key=lambda r: r["nu"])
                x = [r["nu"] for r in rs]
                y = [sign * _value(r, family) for r in rs]
                shade = 0.35 + 0.65 * (k + 1) / len(sizes)
                label = el if size is None else f"{el}, h = {size:g}"
                ax.plot(x, y, marker=marker, ms=4, lw=1, color=color, alpha=shade, label=label)
            lims = sorted((lim for lim in limits if lim["element"] == el
                           and lim["family"] == family), key=lambda lim: lim["nu"])
            if any(lim["status"] == "ok" for lim in lims):  # NaN (a gap) where not converged
                ax.plot([lim["nu"] for lim in lims], [sign * lim["limit"] for lim in lims],
                        ls="--", lw=2, marker="*", ms=8, color=color,
                        label=f"{el}, h → 0 limit")
        bad = [lim for lim in limits if lim["family"] == family and lim["status"] != "ok"]
        notes = [f"{len(bad)} (ν, element) famil{'y' if len(bad) == 1 else 'ies'} not "
                 "converged: no limit drawn"] if bad else []
        missing = sorted({r["nu"] for r in rows if not r[family]})
        if missing:
            shown = ", ".join(f"{v:g}" for v in missing[:6]) + (", ..." if len(missing) > 6
                                                                 else "")
            notes.append(f"no real {family} eigenvalue found at ν = {shown}")
        failed = sum(r["status"].startswith("failed") for r in rows)
        if failed:
            notes.append(f"{failed} of {len(rows)} points failed: left out")
        if notes:
            ax.text(0.02, 0.02, "\n".join(notes), transform=ax.transAxes, fontsize=8)
        ax.set_xlabel(r"Poisson ratio $\nu$")
        what = "lowest positive eigenvalue" if family == "positive" else \
            "|lowest negative eigenvalue|"
        ax.set_ylabel(f"{ALPHA_LABEL}\n({what})")
        ax.set_title(f"{title}: {what} vs ν")
        ax.grid(True, alpha=0.3)
        _legend(ax, fontsize=8)
    fig.tight_layout()
    return fig


def _pick_nu(rows, nu):
    counts: dict[float, int] = {}
    for r in rows:
        if r["size"] is not None and not math.isnan(_value(r, "positive")):
            counts[r["nu"]] = counts.get(r["nu"], 0) + 1
    if not counts:
        return rows[0]["nu"]
    if nu is not None:
        return min(counts, key=lambda v: abs(v - nu))
    best = max(counts.values())
    candidates = sorted(v for v, c in counts.items() if c == best)
    return candidates[len(candidates) // 2]


def _convergence(rows, limits, title, nu) -> Figure:
    nu = _pick_nu(rows, nu)
    elements = list(dict.fromkeys(r["element"] for r in rows))
    found = {m["element"]: m for m in limits if m["nu"] == nu and m["family"] == "positive"}
    with_limit = [el for el in elements if found.get(el, {}).get("status") == "ok"]
    fig = Figure(figsize=(12.8 if with_limit else 6.4, 4.8))
    axes = fig.subplots(1, 2 if with_limit else 1, squeeze=False)[0]
    left = axes[0]
    sizes = sorted({r["size"] for r in rows if r["size"] is not None}, reverse=True)
    for el in elements:
        color, marker = _STYLE[el]
        rs = sorted((r for r in rows if r["element"] == el and r["nu"] == nu
                     and r["size"] is not None), key=lambda r: -r["size"])
        h = np.array([r["size"] for r in rs])
        y = np.array([_value(r, "positive") for r in rs])
        left.plot(h, y, marker=marker, color=color, label=f"{el}: computed")
        lim = found.get(el)
        if lim is not None and lim["status"] != "ok":
            why = shorten(lim["status"].removeprefix("not converged: "), 60, placeholder="...")
            left.plot([], [], " ", label=f"{el}: no limit ({why})")
        if el not in with_limit:
            continue
        left.axhline(lim["limit"], color=color, ls="--", lw=1,
                     label=f"{el}: h → 0 limit {lim['limit']:.6f} ± {lim['error']:.1e}")
        err = np.abs(y - lim["limit"])
        ok = np.isfinite(err) & (err > 0)
        if ok.any():  # none: every value equals the limit (or is missing)
            axes[1].plot(h[ok], err[ok], marker=marker, color=color,
                         label=f"{el}: observed order p = {lim['order']:.2f}")
    for ax in axes:
        ax.set_xscale("log")
        ax.set_xticks(sizes, [f"{v:g}" for v in sizes])
        ax.minorticks_off()
        ax.invert_xaxis()
        ax.set_xlabel("mesh size h (case length units)")
        ax.grid(True, which="both", alpha=0.3)
        _legend(ax, fontsize=8)
    left.set_ylabel(f"{ALPHA_LABEL}\n(lowest positive eigenvalue)")
    left.set_title(f"{title}: convergence at ν = {nu:g}")
    if with_limit and axes[1].lines:
        axes[1].set_yscale("log")
    elif with_limit:
        axes[1].set_xlim(left.get_xlim())
        axes[1].text(0.5, 0.5, "no distance to draw: every computed value equals its limit "
                     "or is missing", transform=axes[1].transAxes, ha="center", fontsize=8)
    if with_limit:
        axes[1].set_ylabel(r"$|\mu_{\rm cr}(h) - \mu_{\rm cr}(h \to 0)|$")
        axes[1].set_title("distance to the extrapolated limit (log-log)")
    fig.tight_layout()
    return fig


# ------------------------------------------------------------------------------ solves
def solve_figures(path: Path) -> dict[str, Figure]:
    """``deformed`` (Fig. 8), ``von_mises`` (Fig. 9), ``contact_forces`` (of the first stored
    mode) and ``spectrum``; of a 3D body ``contact_<mode>`` (:mod:`.solid`) and
    ``spectrum``."""
    data = read_solve(path)
    if data.dim == 3:
        return {**contact_figures(data), "spectrum": _spectrum(data)}
    out = {}
    if data.modes:
        name, mode = next(iter(data.modes.items()))
        fields = mode_fields(data, mode)
        out["deformed"] = _deformed(data, name, mode, fields)
        out["von_mises"] = _von_mises(data, name, mode, fields)
        out["contact_forces"] = _contact_forces(data)
    out["spectrum"] = _spectrum(data)
    return out


def _label(data: SolveData, name: str, mode: dict) -> str:
    a = data.attrs
    return (f"{a.get('case_name', '')}, {a['element']}, ν = {float(a['nu']):g}: "
            f"{name.replace('_', ' ')}, α = {mode['alpha']:.6g}")


def _boundary(data: SolveData, points, names=None) -> np.ndarray:
    edges = data.mesh.edges
    chosen = [e for n, e in edges.items() if names is None or n in names]
    if not chosen:
        return np.zeros((0, 2, 2))
    facets = np.concatenate([e[:, :2] if e.shape[1] == 2 else e[:, [0, 2, 2, 1]].reshape(-1, 2)
                             for e in chosen])
    return points[facets]


def _deformed(data, name, mode, fields) -> Figure:
    mesh = data.mesh
    extent = float(np.ptp(mesh.points, axis=0).max())
    scale = 0.1 * extent  # fields["phi"] has max |Phi| = 1
    moved = mesh.points + scale * fields["phi"]
    fig = Figure(figsize=(6.4, 6.4))
    ax = fig.subplots()
    ax.add_collection(LineCollection(_boundary(data, mesh.points), colors="0.6", lw=1,
                                     linestyles="--", label="undeformed boundary"))
    if mesh.n_cells <= WIREFRAME_CELLS:
        ax.add_collection(LineCollection(_segments(mesh, moved), colors="tab:blue", lw=0.4,
                                         label=r"deformed mesh $x + s\,\Phi$"))
    else:  # a fine mesh: its wireframe would be a solid blot; |Phi| in colour shows the mode
        tri = Triangulation(moved[:, 0], moved[:, 1], _triangles(mesh))
        shade = ax.tripcolor(tri, np.linalg.norm(fields["phi"], axis=1), shading="gouraud",
                             cmap="Blues")
        fig.colorbar(shade, ax=ax, shrink=0.7, label=r"$|\Phi|$ on the deformed body")
        ax.add_collection(LineCollection(_boundary(data, moved), colors="tab:blue", lw=1,
                                         label=r"deformed boundary $x + s\,\Phi$"))
    ax.add_collection(LineCollection(_boundary(data, moved, data.contact_edges),
                                     colors="tab:red", lw=2, label=r"$\Gamma_C$"))
    ax.autoscale_view()
    ax.set_aspect("equal")
    ax.set_xlabel("x")
    ax.set_ylabel("y")
    ax.set_title(f"Eigenfunction Φ ({_label(data, name, mode)})\n"
                 f"displacement scaled to max |sΦ| = {scale:.3g} (10% of the body size)",
                 fontsize=9)
    ax.legend(fontsize=8, loc="upper center", bbox_to_anchor=(0.5, -0.08), ncol=3)
    return fig


def _von_mises(data, name, mode, fields) -> Figure:
    mesh = data.mesh
    tris = _triangles(mesh)
    tri = Triangulation(mesh.points[:, 0], mesh.points[:, 1], tris)
    values = fields["von_mises_node"]
    used = distinct(tris)
    top = float(np.percentile(values[used], 99))
    fig = Figure(figsize=(7.2, 6.4))
    ax = fig.subplots()
    art = ax.tripcolor(tri, values, shading="gouraud", cmap="viridis", vmin=0.0,
                       vmax=top if top > 0 else None)
    bar = fig.colorbar(art, ax=ax, extend="max" if values.max() > top else "neither")
    bar.set_label(r"von Mises stress $\sigma_{\rm VM}(\Phi)$ / E  (max |Φ| = 1)")
    ax.add_collection(LineCollection(_boundary(data, mesh.points, data.contact_edges),
                                     colors="tab:red", lw=2, label=r"$\Gamma_C$"))
    ax.set_aspect("equal")
    ax.set_xlabel("x")
    ax.set_ylabel("y")
    ax.set_title(f"Von Mises stress of Φ ({_label(data, name, mode)})\n"
                 f"colour scale capped at the 99th percentile ({top:.3g}; max "
                 f"{values.max():.3g})", fontsize=9)
    ax.legend(fontsize=8, loc="upper right")
    return fig


def _contact_forces(data: SolveData) -> Figure:
    """Nodal contact forces X, Y divided by int N_a ds: estimates of theta_n, theta_t, for
    the lowest positive and the lowest negative mode."""
    mesh, nodes = data.mesh, data.contact_nodes
    lumped = sum(traction_load(mesh, e, (1.0, 0.0))[0::2] for e in data.contact_edges)
    w = lumped[nodes]
    normal = np.asarray(data.attrs["normal"], dtype=float)
    s = mesh.points[nodes] @ np.array([-normal[1], normal[0]])
    s = s - s.min()
    shown = [n for n in ("positive_0", "negative_0") if n in data.modes]
    fig = Figure(figsize=(6.4 * len(shown), 4.8))
    for ax, name in zip(fig.subplots(1, len(shown), squeeze=False)[0], shown):
        mode = data.modes[name]
        tn, tt = mode["theta_n"] / w, mode["theta_t"] / w
        peak = np.max(np.abs(tn)) or 1.0
        ax.plot(s, tn / peak, color="tab:blue", marker=".", ms=4, label=r"$\theta_n$")
        ax.plot(s, tt / peak, color="tab:orange", marker=".", ms=4,
                label=r"$\theta_t = \alpha\,\gamma\,\theta_n$")
        ax.axhline(0, color="0.5", lw=0.5)
        ax.set_xlabel(r"position s along $\Gamma_C$ (direction t, case length units)")
        ax.set_ylabel(r"contact force density (normalised: max $|\theta_n|$ = 1)")
        ax.set_title(f"Contact forces along Γ_C ({_label(data, name, mode)})", fontsize=9)
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=8)
    fig.tight_layout()
    return fig


def _spectrum(data: SolveData) -> Figure:
    """All eigenvalues on symmetric-log axes, and a linear view around the critical ones
    (3D: the real ones coloured by r)."""
    alpha = np.asarray(data.alpha)
    real = alpha.imag == 0
    marked = np.concatenate([data.positive[:1], data.negative[:1]])
    reach = 3.0 * np.max(np.abs(marked)) if len(marked) else (
        float(np.percentile(np.abs(alpha), 50)) if len(alpha) else 1.0)
    fig = Figure(figsize=(12.8, 6.0))
    for k, ax in enumerate(fig.subplots(1, 2)):
        ax.scatter(alpha.real[~real], alpha.imag[~real], s=12, c="0.5", label="complex")
        if data.r is None:
            ax.scatter(alpha.real[real], alpha.imag[real], s=20, c="tab:blue",
                       label="real: critical coefficients")
        else:
            shade = ax.scatter(alpha.real[real], alpha.imag[real], s=20, c=data.r[real],
                               cmap="viridis", vmin=0.0, vmax=1.0,
                               label="real: critical coefficients (colour: r)")
        for v, name in [(data.positive, "lowest positive"), (data.negative, "lowest negative")]:
            if len(v):
                r = "" if data.r is None else f", r = {data.r_of(v[:1])[0]:.3g}"
                ax.scatter([v[0]], [0], s=120, facecolors="none", edgecolors="tab:red", lw=2,
                           label=f"{name}: α = {v[0]:.6g}{r}")
        ax.axhline(0, color="0.7", lw=0.5)
        ax.axvline(0, color="0.7", lw=0.5)
        ax.set_xlabel(r"Re $\alpha$")
        ax.set_ylabel(r"Im $\alpha$")
        ax.grid(True, alpha=0.3)
        if k == 0:
            ax.set_xscale("symlog", linthresh=1.0)
            ax.set_yscale("symlog", linthresh=1.0)
            ax.set_title(f"All {len(alpha)} finite eigenvalues found by the "
                         f"{data.attrs.get('solver', '')} solver (symmetric log axes)",
                         fontsize=9)
        else:
            outside = int(np.count_nonzero(np.abs(alpha) > reach))
            ax.set_xlim(-reach, reach)
            ax.set_ylim(-reach, reach)
            ax.set_aspect("equal")
            ax.set_title(f"Near the critical coefficients ({outside} eigenvalues outside)",
                         fontsize=9)
            if data.r is not None:  # r = 0: an exact static branch of both slip laws
                fig.colorbar(shade, cax=ax.inset_axes([1.04, 0.0, 0.03, 1.0]),
                             label="r of the real eigenvalues (0: exact static branch)")
    handles, labels = fig.axes[1].get_legend_handles_labels()
    fig.legend(handles, labels, fontsize=9, loc="lower center", ncol=len(labels))
    fig.suptitle(f"Spectrum of (3.2): {data.attrs.get('case_name', '')}, "
                 f"{data.attrs['element']}, ν = {float(data.attrs['nu']):g}")
    fig.tight_layout(rect=(0, 0.07, 1, 1))  # room for the legend below the data
    return fig
