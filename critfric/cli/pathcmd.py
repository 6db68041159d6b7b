"""``critfric path``: the solution curves of the static problem (2.8) along the friction or a
load factor (a thin command over :func:`critfric.multiplicity.path.path_case`). Registered on
the app of :mod:`.common` when :mod:`.app` is imported."""

from __future__ import annotations

import json
from pathlib import Path

import typer

from ..case.numbers import plain_number, shown
from ..case.schema import OVERRIDES, load_case
from ..errors import CaseError
from ..fem.elements import NAMES
from .common import MaxDofs, TrustGeo, app, computed_and_written, figures_and_notes, fmt_values
from .failures import reported, say

RANGE_ALLOWED = ("A:B, two plain (ASCII) numbers with A < B (the case key path.range; a "
                 "friction path: 0 <= A), e.g. 0:3")


SHOWN = 12  # events and curves printed (folds and branch points first); --json has all


def parse_range(text: str | None) -> list[float] | None:
    """--range A:B -> [A, B] (the schema checks A < B, and 0 <= A for a friction path)."""
    if text is None:
        return None
    parts = text.split(":")
    if len(parts) != 2:
        raise CaseError(f"got {shown(text)}; allowed: {RANGE_ALLOWED}", key="--range")
    return [plain_number(p, "--range", allowed=RANGE_ALLOWED, within=text) for p in parts]


def _seed(seed) -> str:
    if not isinstance(seed, dict):
        return str(seed)
    if "event" in seed:
        return f"event {seed['event']} at {seed['value']:.10g}"
    return f"a solution at {seed['value']:.10g}"


def _covered(curve) -> str:
    ends = [v for p in curve.pieces for v in (p.start, p.end)] or [p.value for p in curve.points]
    return f"{min(ends):.10g} .. {max(ends):.10g}" if ends else "-"


@app.command(epilog="\b\nExamples:\n  critfric path one-triangle --range 0:3 --plot\n  critfric path cases/unit_square.toml --parameter load --range 0:1 --json")
def path(
    case: str = typer.Argument(..., help="Case file (TOML) or shipped case name; its [load] is "
                                         "the load (L0 of a load path)."),
    parameter: str | None = typer.Option(None, help="Parameter followed: friction (the load "
                                         "of [load] fixed) or load (the factor t of L0 + t L1, "
                                         "L1 = [path] load; the friction of [load] fixed) "
                                         "[default: the case's [path] parameter, else friction]."),
    interval: str | None = typer.Option(None, "--range", help="Parameter range A:B, A < B "
                                        "(friction: 0 <= A) [default: the case's [path] range]."),
    start: str | None = typer.Option(None, help="Solutions the curves start from: auto (every "
                                     "solution by enumeration with at most 8 contact nodes, "
                                     "else the Newton solution), newton, enumerate [default: "
                                     "the case's, else auto]."),
    samples: int | None = typer.Option(None, help="Parameter values, evenly spaced with the "
                                       "ends, at which every curve holds a point [default: "
                                       "the case's, else 101]."),
    node: int | None = typer.Option(None, help="Contact node (index along t) whose tangential "
                                    "displacement the diagram shows [default: the one that "
                                    "moves most]."),
    nu: float | None = typer.Option(None, help="Poisson ratio, overrides [material] nu [default: the case's]."),
    element: str | None = typer.Option(None, help="Element: " + ", ".join(NAMES) + " [default: the case's]."),
    size: float | None = typer.Option(None, help="Target mesh size h [default: the case's]."),
    output: Path | None = typer.Option(None, "--output", "-o", help="HDF5 result file [default: one named after the case, here]."),
    force: bool = typer.Option(False, "--force", help="Overwrite an existing result file."),
    as_json: bool = typer.Option(False, "--json", help="Print only a JSON summary on stdout."),
    max_dofs: MaxDofs = None,
    trust_geo: TrustGeo = False,
    plot: bool = typer.Option(False, "--plot", help="Also write the diagram (PNG)."),
) -> None:
    """Every solution curve of the static problem (2.8) along the friction or a load factor:
    the pieces (one contact state each) and where they meet: kinks, folds and branch points
    (a critical coefficient of a piece's state, where a continuum of solutions joins curves)."""
    with reported("no result written (an existing file is unchanged)") as ending:
        given = {"nu": nu, "element": element, "size": size, "parameter": parameter,
                 "range": parse_range(interval), "start": start, "samples": samples,
                 "node": node}
        loaded = load_case(case, overrides={OVERRIDES[k]: v for k, v in given.items()
                                            if v is not None})
        from ..files.pathfile import default_path_output, write_path
        from ..multiplicity.path import path_case

        out, result = computed_and_written(
            output or default_path_output(loaded), force=force, inputs=loaded.inputs(),
            ending=ending, write=write_path,
            compute=lambda: path_case(loaded, max_dofs=max_dofs, trust_geo=trust_geo))
        figures_and_notes(out, result, plot=plot)
        if as_json:
            typer.echo(json.dumps(result.to_json()))
            return
        say(f"wrote {out}")
        a, b = result.range
        fixed = "" if result.friction is None else f" at friction {result.friction:.10g}"
        name = "friction" if result.parameter == "friction" else "load factor t"
        typer.echo(f"case       {loaded.title or loaded.name} ({loaded.source})")
        typer.echo(f"mesh       {loaded.mesh['element']}, {result.n_dofs} DOFs, "
                   f"{result.n_contact} contact nodes   {result.seconds:.2f} s")
        typer.echo(f"parameter  {name} over [{a:.10g}, {b:.10g}]{fixed}")
        typer.echo("found      " + ", ".join(f"{n} {k}" for k, n in result.counts().items()))
        shown = [e for e in result.events if e.kind != "kink"] or result.events
        for e in shown[:SHOWN]:
            critical = "" if e.critical is None else f"   critical {e.critical:.10g}"
            typer.echo(f"{e.kind:<10} at {e.value:.10g}   nodes {fmt_values(e.nodes, 8)}"
                       + critical + ("   (reached at infinity)" if e.unbounded else ""))
        if len(result.events) > len(shown[:SHOWN]):
            typer.echo(f"           ... {len(result.events) - len(shown[:SHOWN])} more events "
                       "(--json lists them all)")
        for i, c in enumerate(result.curves[:SHOWN]):
            typer.echo(f"curve {i:<4} from {_seed(c.seed)}: {len(c.pieces)} pieces, "
                       f"{name} {_covered(c)}")
        if len(result.curves) > SHOWN:
            typer.echo(f"           ... {len(result.curves) - SHOWN} more curves")
