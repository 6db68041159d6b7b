"""The figure of a path file: the bifurcation diagram of the static problem (2.8).

``<file>_diagram``, three axes over the parameter: the tangential displacement U_t of the
diagram's contact node on every curve (one colour per piece; kinks, folds, branch points and
isolated solutions marked), the contact state of each node along Gamma_C on one curve, and
the margin of each piece (its state's positive critical coefficient over the friction).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.colors import BoundaryNorm, ListedColormap
from matplotlib.figure import Figure
from matplotlib.patches import Patch

from ..files.pathfile import read_path

PIECE_COLORS = "tab10"  # a qualitative colormap, cycled over the pieces
STYLES = ("-", "--", "-.", ":")  # one line style per curve, cycled
STATE_COLORS = {"free": "0.88", "stuck": "tab:blue", "slip+": "tab:red", "slip-": "tab:orange",
                "cone": "tab:purple"}
AXIS = {"friction": "friction coefficient", "load": "load factor"}


def path_figures(path: Path | str) -> dict[str, Figure]:
    """``diagram``: the bifurcation diagram, the contact-state map and the margins."""
    data = read_path(Path(path))
    fig = Figure(figsize=(8.0, 10.0), layout="constrained")
    top, middle, bottom = fig.subplots(3, 1, sharex=True,
                                       gridspec_kw={"height_ratios": (3, 2, 1.6)})
    colors = _piece_colors(data)
    _diagram(top, data, colors)
    _states(middle, data)
    _margins(bottom, data, colors)
    bottom.set_xlabel(AXIS.get(data["parameter"], data["parameter"]))
    name = data["case_name"] + (f": {data['title']}" if data["title"] else "")
    what = f"along the {AXIS.get(data['parameter'], data['parameter'])}"
    if data["friction"] is not None:
        what += f" at friction {data['friction']:.6g}"
    c = data["counts"]
    told = ", ".join(_count(c.get(k, 0), word) for k, word in (
        ("curves", "curve"), ("pieces", "piece"), ("kinks", "kink"), ("folds", "fold"),
        ("branches", "branch point")))
    fig.suptitle(f"Solutions of the static Coulomb problem (2.8) {what}\n{name}: {told}; "
                 f"{_count(data['n_contact'], 'contact node')}, {data['n_dofs']} DOFs",
                 fontsize=10)
    return {"diagram": fig}


def _count(n: int, word: str) -> str:
    return f"{n} {word}" + ("" if n == 1 else "es" if word.endswith("h") else "s")


def _piece_colors(data: dict) -> list[list]:
    """The colour of each piece of each curve, cycling through the qualitative map."""
    from matplotlib import colormaps

    cmap = colormaps[PIECE_COLORS]
    out, k = [], 0
    for curve in data["curves"]:
        out.append([cmap(j % cmap.N) for j in range(k, k + len(curve["pieces"]))])
        k += len(curve["pieces"])
    return out


def _xy(curve: dict, node: int) -> tuple[np.ndarray, np.ndarray]:
    points = curve["points"]
    return (np.array([q["value"] for q in points], dtype=float),
            np.array([q["Ut"][node] for q in points], dtype=float).reshape(-1))


def _at(x: np.ndarray, y: np.ndarray, value: float, candidates) -> tuple[float, float] | None:
    """The point among ``candidates`` (indices; all if empty) nearest the parameter value."""
    idx = np.asarray(sorted(candidates) or range(len(x)), dtype=int)
    if not len(idx):
        return None
    i = idx[np.argmin(np.abs(x[idx] - value))]
    return float(x[i]), float(y[i])


def _event_points(data: dict, event: dict, index: int) -> list[tuple[float, float]]:
    """Where an event lies in the diagram, on each curve that meets there."""
    out = []
    for c in event["curves"]:
        curve = data["curves"][c]
        x, y = _xy(curve, data["node"])
        piece = [q.get("piece", 0) for q in curve["points"]]
        if event["kind"] == "kink":
            near = {i for k in range(1, len(x)) if piece[k] != piece[k - 1] for i in (k - 1, k)}
        elif event["kind"] == "fold":
            d = np.diff(x)
            near = {k for k in range(1, len(x) - 1) if d[k - 1] * d[k] < 0}
        else:  # a branch point: where a curve leaving it starts, else the nearest point
            seed = curve["seed"]
            near = {0} if isinstance(seed, dict) and seed.get("event") == index else set()
        at = _at(x, y, event["value"], near)
        if at is not None:
            out.append(at)
    return out


def _diagram(ax, data: dict, colors) -> None:
    node = data["node"]
    for c, curve in enumerate(data["curves"]):
        x, y = _xy(curve, node)
        style = STYLES[c % len(STYLES)]
        steps = _step_pieces(curve)
        start = 0
        for k in range(1, len(steps) + 1):  # runs of steps on one piece, one line each
            if k == len(steps) or steps[k] != steps[start]:
                j = steps[start]
                color = colors[c][j] if j is not None else "0.5"
                ax.plot(x[start:k + 1], y[start:k + 1], style, color=color, lw=1.6)
                start = k
        if len(x) == 1:
            ax.plot(x, y, "o", color=colors[c][0] if colors[c] else "0.5", ms=3)
        ax.plot([], [], style, color="0.3", label=f"curve {c}: seed {_seed(curve['seed'])}")
    marks = {"kink": dict(marker=".", ms=7, color="k", ls="none"),
             "fold": dict(marker="^", ms=7, color="k", mfc="none", ls="none"),
             "branch": dict(marker="o", ms=13, mfc="none", mec="k", mew=1.5, ls="none")}
    names = {"kink": "kink (a node changes status)", "fold": "fold (the curve turns back)",
             "branch": "branch point (singular state)"}
    shown = set()
    for k, event in enumerate(data["events"]):
        kind = event["kind"]
        at = [] if event["unbounded"] else _event_points(data, event, k)
        label = None if kind in shown else names[kind]
        if at:
            ax.plot(*zip(*at), **marks[kind], label=label)
        elif kind == "branch":  # reached only at infinity, or on no stored point
            ax.axvline(event["value"], color="k", lw=0.8, ls=":",
                       label=label and "branch point reached at infinity")
        shown.add(kind)
        if kind == "branch" and event["critical"] is not None:
            text = f"{event['critical']:.6g}"
            if at:
                ax.annotate(text, at[0], textcoords="offset points", xytext=(8, 8), fontsize=8)
            else:
                ax.annotate(text, (event["value"], 0.95), xycoords=("data", "axes fraction"),
                            textcoords="offset points", xytext=(4, 0), fontsize=8)
    if data["isolated"]:
        ax.plot([q["value"] for q in data["isolated"]],
                [q["Ut"][node] for q in data["isolated"]], "x", color="tab:red", ms=8, mew=1.5,
                label="isolated solution (on no curve)")
    if not data["curves"] and not data["isolated"]:
        _note(ax, "no solution curve in this file")
    ax.set_ylabel(f"tangential displacement $U_t$\nat contact node {node}")
    ax.grid(alpha=0.3)
    if ax.get_legend_handles_labels()[0]:
        ax.legend(fontsize=7, loc="best", framealpha=0.9)


def _seed(seed) -> str:
    if isinstance(seed, dict):
        return f"{seed.get('value', 0):.4g}" + (f" (event {seed['event']})"
                                                if "event" in seed else "")
    return str(seed)


def _note(ax, text: str) -> None:
    ax.text(0.5, 0.5, text, transform=ax.transAxes, ha="center", va="center", fontsize=9,
            color="0.3")


def _edges(v: np.ndarray) -> np.ndarray:
    """Cell edges around sorted centres: midpoints, the ends at the first and last value."""
    if len(v) == 1:
        half = 0.01 * max(abs(float(v[0])), 1.0)
        return np.array([v[0] - half, v[0] + half])
    return np.concatenate([[v[0]], 0.5 * (v[1:] + v[:-1]), [v[-1]]])


def _step_pieces(curve: dict) -> list[int | None]:
    """The piece each step between consecutive points lies on (None: unknown). Two points on
    one piece: that piece; else, if one point is at an end of the other's piece (it is the
    vertex where they meet), the other's piece; else the one whose interval holds the
    step's middle."""
    points, pieces = curve["points"], curve["pieces"]
    known = lambda j: j if 0 <= j < len(pieces) else None
    at_end = lambda q, j: j is not None and any(
        abs(q["value"] - pieces[j][e]) <= 1e-12 * max(1.0, abs(q["value"]))
        for e in ("start", "end"))
    out = []
    for a, b in zip(points[:-1], points[1:]):
        ja, jb = known(a.get("piece", 0)), known(b.get("piece", 0))
        if ja == jb or at_end(a, jb) != at_end(b, ja):
            out.append(jb if ja == jb or at_end(a, jb) else ja)
            continue
        mid = 0.5 * (a["value"] + b["value"])
        held = [j for j in (ja, jb) if j is not None and min(
            pieces[j]["start"], pieces[j]["end"]) <= mid <= max(pieces[j]["start"],
                                                                 pieces[j]["end"])]
        out.append(held[0] if held else jb)
    return out


def _steps(curve: dict) -> list[list[str]]:
    """The status words of each step between consecutive points: the state of the piece it
    lies on (the later point's status if unknown); a single point: its own status."""
    points, pieces = curve["points"], curve["pieces"]
    if len(points) == 1:
        return [points[0]["status"]]
    return [pieces[j]["state"] if j is not None else b["status"]
            for j, b in zip(_step_pieces(curve), points[1:])]


def _states(ax, data: dict) -> None:
    """The status of each contact node (y: arc length s) over the points of the curve with
    most pieces (x: parameter; along the curve if it turns back)."""
    shown = [c for c in data["curves"] if c["points"]]
    if not shown or not data["n_contact"]:
        _note(ax, "no curve with points: no contact-state map")
        ax.set_ylabel(r"arc length s along $\Gamma_C$")
        return
    index = max(range(len(data["curves"])), key=lambda c: (
        len(data["curves"][c]["pieces"]) if data["curves"][c]["points"] else -1, -c))
    curve = data["curves"][index]
    x = np.array([q["value"] for q in curve["points"]], dtype=float)
    status = _steps(curve)
    words = list(STATE_COLORS) + sorted({w for row in status for w in row} - set(STATE_COLORS))
    codes = np.array([[words.index(w) for w in row] for row in status]).T  # (p, cells)
    d = np.diff(x)
    monotone = bool(np.all(d >= 0) or np.all(d <= 0))
    s = np.asarray(data["s"], dtype=float)
    order = np.argsort(s, kind="stable")
    y = _edges(s[order]) if len(s) > 1 else np.array([-0.5, 0.5])
    cmap = ListedColormap([STATE_COLORS.get(w, "tab:gray") for w in words])
    norm = BoundaryNorm(np.arange(len(words) + 1) - 0.5, len(words))
    if len(x) == 1:
        ax.pcolormesh(_edges(x), y, codes[order], cmap=cmap, norm=norm)
        where = ""
    elif monotone:  # cell k: from point k to point k + 1
        turn = slice(None) if d.sum() >= 0 else slice(None, None, -1)
        ax.pcolormesh(x[turn], y, codes[order][:, turn], cmap=cmap, norm=norm)
        where = ""
    else:  # the curve turns back: along its points, their parameter values as ticks
        twin = ax.twiny()
        twin.pcolormesh(np.arange(len(x)), y, codes[order], cmap=cmap, norm=norm)
        ticks = np.unique(np.linspace(0, len(x) - 1, min(len(x), 8)).round().astype(int))
        twin.set_xticks(ticks, [f"{x[t]:.4g}" for t in ticks], fontsize=7)
        twin.set_xlabel("parameter at points along the curve (it turns back: fold)", fontsize=8)
        where = ", drawn along the curve"
    used = sorted({int(v) for v in codes.ravel()})
    ax.legend(handles=[Patch(color=cmap(k), label=words[k]) for k in used], fontsize=7,
              loc="center left", bbox_to_anchor=(1.01, 0.5), title="status", title_fontsize=7)
    ax.set_ylabel(r"arc length s along $\Gamma_C$")
    ax.set_title(f"Contact state of each node on curve {index}{where}", fontsize=9)


def _margins(ax, data: dict, colors) -> None:
    """crit / friction along each piece: a hyperbola on a friction path, a constant on a load
    path (where the friction is fixed)."""
    drawn, values = False, []
    along = data["parameter"] == "friction"
    for c, curve in enumerate(data["curves"]):
        for j, piece in enumerate(curve["pieces"]):
            crit = piece["critical"]["positive"]
            if crit is None or not np.isfinite(crit):
                continue
            lo, hi = sorted((piece["start"], piece["end"]))
            t = np.linspace(lo, hi, 50) if along else np.array([lo, hi])
            f = t if along else np.full(2, data["friction"] or 0.0)
            with np.errstate(divide="ignore"):
                m = np.where(f > 0, crit / np.maximum(f, 1e-300), np.inf)
            keep = np.isfinite(m)
            if not keep.any():
                continue
            ax.plot(t[keep], m[keep], color=colors[c][j], lw=3)
            if lo == hi:
                ax.plot([lo], [m[keep][0]], "o", color=colors[c][j], ms=4)
            values += m[keep].tolist()
            drawn = True
    if not drawn:
        _note(ax, "no piece with a margin (no slipping piece, or no real positive critical "
                  "coefficient)")
    else:
        ax.axhline(1.0, color="k", lw=1, ls="--")
        if max(values) > 30 * max(min(values), 1e-300):
            ax.set_yscale("log")
    ax.set_title("Margin of each piece: its state's lowest positive critical coefficient over "
                 "the friction\n(dashed: 1; below it the friction exceeds the state's critical "
                 "coefficient)", fontsize=8)
    ax.set_ylabel("margin")
    ax.grid(alpha=0.3)
