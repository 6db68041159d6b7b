"""What a set of critfric files holds, one summary row per solve, sweep point, stability
analysis or path, and the table of the solve and sweep rows."""

from __future__ import annotations

import json
from pathlib import Path

from ..errors import CaseError
from .opening import kind_of, open_file
from .pathfile import read_path_summary
from .results import read_summary
from .stabilityfile import read_stability_summary
from .sweepfile import read_sweep


def summaries(paths) -> tuple[list[dict], list[tuple[Path, str]]]:
    """Rows (as ``critfric solve --json`` prints them, plus ``file``) of every solve file and
    every point of every sweep file in ``paths``, and of every stability file (as
    ``critfric stability --json``, plus ``file`` and ``kind`` = "stability") and of every path
    file (:func:`~critfric.files.pathfile.read_path_summary`, plus ``file`` and ``kind`` =
    "path"; :func:`~critfric.files.pathfile.path_table` prints them); and (path, why) for
    each path skipped (not a critfric file, or not a valid one)."""
    rows: list[dict] = []
    skipped: list[tuple[Path, str]] = []
    for path in map(Path, paths):
        try:
            with open_file(path) as f:
                kind = kind_of(f)
        except CaseError as exc:
            skipped.append((path, exc.detail))
            continue
        except (OSError, ValueError) as exc:
            reason = exc.strerror if isinstance(exc, OSError) and exc.strerror else "not HDF5"
            skipped.append((path, f"cannot read this file ({reason})"))
            continue
        try:
            if kind == "solve":
                rows.append({**read_summary(path), "file": str(path)})
            elif kind == "stability":
                rows.append({**read_stability_summary(path), "file": str(path),
                             "kind": "stability"})
            elif kind == "path":
                rows.append({**read_path_summary(path), "file": str(path), "kind": "path"})
            elif kind == "sweep":
                data = read_sweep(path)
                name = str(data["attrs"].get("case_name", ""))
                quantity = _quantity(data["attrs"])
                for r in data["rows"]:
                    rows.append({"case": name, "file": str(path), "complete": True,
                                 "warnings": [], "method": "sweep", "quantity": quantity,
                                 **r})
            else:
                skipped.append((path, "not a critfric solve, sweep, stability or path file "
                                      "(an export's arrays, or another program's)"))
        except CaseError as exc:
            skipped.append((path, exc.detail))
    return rows, skipped


def _quantity(attrs) -> str:
    """What a sweep file's points hold: "critical" coefficients or "flutter" thresholds."""
    try:
        quantity = json.loads(attrs.get("grid", "{}")).get("quantity", "critical")
    except (ValueError, AttributeError):
        return "critical"
    return quantity if quantity in ("critical", "flutter") else "critical"


def static_table(rows: list[dict]) -> str:
    """The table of solve rows and sweep points (as :func:`summaries` gives them): the lowest
    positive and negative coefficients per row. With a 3D solve among them, the columns dim,
    law and slip angle follow the case, and the lowest values of 3D rows show their r (0: the
    eigenpair is an exact static branch)."""
    solid = any(r.get("dim") == 3 for r in rows)
    wide = 8 if solid else 0
    kinds = {r.get("quantity", "critical") for r in rows}
    what = f"{next(iter(kinds))} (lowest > 0)" if len(kinds) == 1 else "lowest > 0"
    names = [r["case"] if len(kinds) == 1 else f"{r['case']} [{r.get('quantity', 'critical')}]"
             for r in rows]  # mixed files: what each row's values are
    w = max([16, *map(len, names)])
    head = f"{'case':<{w}} " + (f"{'dim':>3} {'law':<6} {'slip':>6} " if solid else "") \
        + f"{'element':<7} {'nu':>6} {'h':>9} {'n_dofs':>8} {'p':>5} " \
        + f"{what:>{22 + wide}} {'lowest < 0':>{14 + wide}} " \
        + f"{'complex':>7} {'seconds':>8}"
    lines = [head, "-" * len(head)]
    for name, r in zip(names, rows):
        pos = f"{r['positive'][0]:.10f}" if r["positive"] else "none"
        neg = f"{r['negative'][0]:.8f}" if r["negative"] else "none"
        three = r.get("dim") == 3
        if solid and three:
            pos += f" (r {r['r_positive'][0]:.3f})" if r.get("r_positive") else ""
            neg += f" (r {r['r_negative'][0]:.3f})" if r.get("r_negative") else ""
        angle = f"{r['slip_angle']:g}" if three and "slip_angle" in r else "-"
        frame = f"{r.get('dim', 2):>3} {r.get('law', '-'):<6} {angle:>6} " if solid else ""
        lines.append(f"{name:<{w}} {frame}{r['element']:<7} {r['nu']:>6.3f} "
                     f"{r['h']:>9.4g} {r['n_dofs']:>8d} {r['n_contact']:>5d} "
                     f"{pos:>{22 + wide}} {neg:>{14 + wide}} {r['complex_count']:>7d} "
                     f"{r['seconds']:>8.2f}")
    return "\n".join(lines)
