"""The command line: thin typer commands over the library's plain functions.

Only the cli package prints or exits; :mod:`.failures` turns errors into messages and exit
codes (2 for bad input, 1 for a numerical failure, 130 for Ctrl-C).
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import typer

from .._version import __version__
from ..case.numbers import plain_number, shown
from ..case.schema import (
    BACKENDS,
    METHODS,
    OVERRIDES,
    SWEEP_GRADING,
    load_case,
    shipped_cases,
)
from ..errors import CaseError, SolverError
from ..fem.elements import NAMES
from ..files.catalog import static_table
from ..files.results import default_output, write_result
from ..files.safety import interrupt_guard, output_lock
from ..solve import solve_case
from .common import MaxDofs, TrustGeo, app, computed_and_written, figures_and_notes, fmt_values
from .failures import reported, say, set_verbosity, verbosity


def _table(rows: list[dict]) -> str:
    static = [r for r in rows if r.get("kind") not in ("stability", "path")]
    stability = [r for r in rows if r.get("kind") == "stability"]
    paths = [r for r in rows if r.get("kind") == "path"]
    parts = ([static_table(static)] if static else []) + (
        [_stability_table(stability)] if stability else [])
    if paths:
        from ..files.pathfile import path_table

        parts.append(path_table(paths))
    return "\n\n".join(parts)


def _stability_table(rows: list[dict]) -> str:
    head = f"{'case':<16} {'element':<7} {'nu':>6} {'h':>9} {'n_dofs':>8} " \
           f"{'flutter > 0':>13} {'flutter < 0':>13} {'divergence > 0':>14} " \
           f"{'divergence < 0':>14} {'first':>9} {'seconds':>8}"
    lines = [head, "-" * len(head)]
    value = lambda v: "none" if v is None else f"{v:.8g}"
    for r in rows:
        first = {r["first"][d] for d in ("positive", "negative")} - {None}
        lines.append(f"{r['case']:<16} {r['element']:<7} {r['nu']:>6.3f} {r['h']:>9.4g} "
                     f"{r['n_dofs']:>8d} {value(r['flutter']['positive']):>13} "
                     f"{value(r['flutter']['negative']):>13} "
                     f"{value(r['divergence']['positive']):>14} "
                     f"{value(r['divergence']['negative']):>14} "
                     f"{'/'.join(sorted(first)) or 'none':>9} {r['seconds']:>8.2f}")
    return "\n".join(lines)


@app.command(epilog="\b\nExamples:\n  critfric solve inclined-body\n  critfric solve cases/unit_square.toml --nu 0.45 --element Q2 -o sq.h5\n  critfric solve unit-square --json > summary.json")
def solve(
    case: str = typer.Argument(..., help="Case file (TOML) or shipped case name "
                                         "(see `critfric cases`)."),
    nu: float | None = typer.Option(None, help="Poisson ratio, overrides [material] nu [default: the case's]."),
    element: str | None = typer.Option(None, help="Element: " + ", ".join(NAMES) + " [default: the case's]."),
    size: float | None = typer.Option(None, help="Target mesh size h [default: the case's]."),
    count: int | None = typer.Option(None, help="Lowest positive coefficients wanted [default: the case's, else 1]."),
    shift: float | None = typer.Option(None, help="Find eigenvalues nearest this value [default: the case's, else 0: the lowest]."),
    method: str | None = typer.Option(None, help="Eigen solver: " + ", ".join(METHODS) + " [default: the case's, else auto]."),
    backend: str | None = typer.Option(None, help="Sparse linear solver: "
                                          + ", ".join(BACKENDS) + " [default: the case's, else auto]."),
    slip_angle: float | None = typer.Option(None, help="3D: slip direction in degrees from t1 "
                                               "towards t2 in the contact plane [default: the "
                                               "case's, else 0]."),
    direction_law: str | None = typer.Option(None, help="3D: rate (the slip direction follows "
                                                "the slip rate) or frozen (prescribed) "
                                                "[default: the case's, else rate]."),
    output: Path | None = typer.Option(None, "--output", "-o", help="HDF5 result file [default: <case name>.h5]."),
    force: bool = typer.Option(False, "--force", help="Overwrite an existing result file."),
    as_json: bool = typer.Option(False, "--json", help="Print only a JSON summary on stdout."),
    max_dofs: MaxDofs = None,
    trust_geo: TrustGeo = False,
    plot: bool = typer.Option(False, "--plot", help="Also write the figures (PNG)."),
) -> None:
    """Compute the critical friction coefficients of a case and write an HDF5 result."""
    given = {"nu": nu, "element": element, "size": size, "count": count, "shift": shift,
             "method": method, "backend": backend, "slip_angle": slip_angle,
             "direction_law": direction_law,
             "output": str(output) if output is not None else None}
    overrides = {OVERRIDES[k]: v for k, v in given.items() if v is not None}
    with reported("no result written (an existing file is unchanged)") as ending:
        loaded = load_case(case, overrides=overrides)
        path, result = computed_and_written(
            default_output(loaded), force=force, inputs=loaded.inputs(), ending=ending,
            compute=lambda: solve_case(loaded, max_dofs=max_dofs, trust_geo=trust_geo),
            write=write_result)
        figures_and_notes(path, result, plot=plot)
        stages = ", ".join(f"{k} {v:.3f} s" for k, v in result.timings.items())
        say(f"critfric: stages: {stages}; solver {result.solver}, backend {result.backend}",
            level=2)
        summary = result.summary()
        if as_json:
            typer.echo(json.dumps(summary))
            return
        say(f"wrote {path}")
        typer.echo(f"case      {loaded.title or loaded.name} ({loaded.source})")
        typer.echo(f"mesh      {result.element}, h = {result.h:.4g}, {result.n_dofs} DOFs, "
                   f"{result.n_contact} contact nodes")
        typer.echo(f"nu        {result.nu:g}   solver {result.solver}   "
                   f"{result.seconds:.2f} s")
        if result.dim == 3:
            r = result.r_of(result.positive[:1])
            typer.echo(f"slip      angle {result.slip_angle:g} deg, {result.law} law"
                       + (f", r = {r[0]:.3g} for the lowest (0: a static branch too)"
                          if len(r) else ""))
        typer.echo(f"positive  {fmt_values(result.positive)}")
        typer.echo(f"negative  {fmt_values(result.negative)}")
        typer.echo(f"complex   {result.complex_count}")
        typer.echo("critical friction coefficient: " + (
            f"{result.critical:.10g}" if len(result.positive) else "none (no positive real one)"))


def _friction_range(text: str | None) -> list[float] | None:
    """--friction A:B -> [A, B] (the schema checks A <= 0 <= B)."""
    if text is None:
        return None
    allowed = ("A:B, two plain (ASCII) numbers with A <= 0 <= B (e.g. -2:2, or 0:3 for one "
               "sliding direction)")
    parts = text.split(":")
    if len(parts) != 2:
        raise CaseError(f"got {shown(text)}; allowed: {allowed}", key="--friction")
    return [plain_number(p, "--friction", allowed=allowed, within=text) for p in parts]


@app.command(epilog="\b\nExamples:\n  critfric stability unit-square --plot\n  critfric stability unit-square --modes 6 --friction 0:1 --json\n  critfric stability inclined-body --size 0.05 -o inclined_stability.h5")
def stability(
    case: str = typer.Argument(..., help="Case file (TOML) or shipped case name."),
    nu: float | None = typer.Option(None, help="Poisson ratio, overrides [material] nu [default: the case's]."),
    element: str | None = typer.Option(None, help="Element: " + ", ".join(NAMES) + " [default: the case's]."),
    size: float | None = typer.Option(None, help="Target mesh size h [default: the case's]."),
    modes: int | None = typer.Option(None, help="Lowest-frequency mode pairs followed [default: the case's [stability] modes, else 10]."),
    friction: str | None = typer.Option(None, help="Signed friction range A:B followed from 0 both ways, A <= 0 <= B [default: 1.25 x the larger |static coefficient|]."),
    steps: int | None = typer.Option(None, help="Friction steps each way that locate the thresholds [default: the case's, else 200]."),
    backend: str | None = typer.Option(None, help="Sparse linear solver: " + ", ".join(BACKENDS) + " [default: the case's, else auto]."),
    output: Path | None = typer.Option(None, "--output", "-o", help="HDF5 result file [default: <case name>_stability.h5]."),
    force: bool = typer.Option(False, "--force", help="Overwrite an existing result file."),
    as_json: bool = typer.Option(False, "--json", help="Print only a JSON summary on stdout."),
    max_dofs: MaxDofs = None,
    trust_geo: TrustGeo = False,
    plot: bool = typer.Option(False, "--plot", help="Also write the root locus and flutter modes (PNG)."),
) -> None:
    """Flutter and divergence thresholds of steady sliding: the friction at which the sliding
    state's small vibrations first grow, each sliding direction (signed friction: < 0 is
    sliding the other way). Divergence is the static critical coefficient of `solve`."""
    with reported("no result written (an existing file is unchanged)") as ending:
        from ..files.stabilityfile import default_stability_output, write_stability
        from ..stability import stability_case

        given = {"nu": nu, "element": element, "size": size, "modes": modes,
                 "friction": _friction_range(friction), "steps": steps, "backend": backend}
        overrides = {OVERRIDES[k]: v for k, v in given.items() if v is not None}
        loaded = load_case(case, overrides=overrides)
        path, result = computed_and_written(
            output or default_stability_output(loaded), force=force, inputs=loaded.inputs(),
            ending=ending, write=write_stability,
            compute=lambda: stability_case(loaded, max_dofs=max_dofs, trust_geo=trust_geo))
        figures_and_notes(path, result, plot=plot)
        stages = ", ".join(f"{k} {v:.3f} s" for k, v in result.timings.items())
        say(f"critfric: stages: {stages}; Newton steps {result.newton_steps}", level=2)
        if as_json:
            typer.echo(json.dumps(result.summary()))
            return
        say(f"wrote {path}")
        fmt = lambda v: "none found" if v is None else f"{v:.10g}"
        typer.echo(f"case        {loaded.title or loaded.name} ({loaded.source})")
        typer.echo(f"mesh        {result.element}, h = {result.h:.4g}, {result.n_dofs} DOFs, "
                   f"{len(result.contact_nodes)} contact nodes")
        typer.echo(f"nu          {result.nu:g}   {result.modes} modes followed over friction "
                   f"{result.friction[0]:.4g} .. {result.friction[-1]:.4g}   "
                   f"{result.seconds:.2f} s")
        typer.echo(f"frequencies {fmt_values(result.frequencies, 5)} (friction 0)")
        for d in ("positive", "negative"):
            typer.echo(f"{d:<11} flutter {fmt(result.flutter[d]):>16}   divergence "
                       f"{fmt(result.divergence[d]):>16}   first: {result.first(d) or '-'}")


@app.command(epilog="\b\nExamples:\n  critfric cases")
def cases() -> None:
    """List the shipped cases (usable by name: `critfric solve inclined-body`)."""
    for name, path in shipped_cases().items():
        title = load_case(path).title or ""
        typer.echo(f"{name:<16} {title}")


@app.command(epilog="\b\nExamples:\n  critfric table *.h5\n  critfric table sq.h5 --json")
def table(
    files: list[Path] = typer.Argument(..., help="Solve, sweep or stability files (other "
                                       "files are skipped, and named)."),
    as_json: bool = typer.Option(False, "--json", help="Print a JSON list instead."),
) -> None:
    """Print a table of the results in solve files, of the points of sweep files and of
    stability files (a second table)."""
    from ..files.catalog import summaries

    with reported():
        rows, skipped = summaries(files)
        if not rows and skipped:  # nothing to show: one error naming each file and why
            (path, why), *more = skipped
            raise CaseError(why + "".join(f"; {p}: {w}" for p, w in more), file=str(path))
        if not rows:  # readable files, but no point computed yet (a sweep that never ran)
            say("critfric: note: no results yet in " + ", ".join(map(str, files))
                + " (a sweep resumes with the same command)")
        for path, why in skipped:
            say(f"critfric: note: skipped {path}: {why}")
        typer.echo(json.dumps(rows) if as_json else _table(rows))


@app.command(epilog="\b\nExamples:\n  critfric sweep --nu 0:0.5\n  critfric sweep unit-square --nu 0.3 --size 0.1,0.05,0.025 --element P1,P2 -o fig5.h5\n  critfric sweep inclined-body --nu 0:0.5:21 --plot -j 2\n  critfric sweep box.toml --slip-angle 0:180:13 --plot")
def sweep(
    case: str | None = typer.Argument(None, help="Case file or shipped case name "
                                                    "[default: unit-square]."),
    nu: str | None = typer.Option(None, help="Poisson ratios: A:B[:N] (N points, default "
                                     "11; a range ending at 0.5 stops just short of it) or "
                                     "v1,v2,... [default: the case's nu]."),
    size: str | None = typer.Option(None, help="Mesh sizes h1,h2,... (three or more give "
                                       "h -> 0 limits) [default: the case's size]."),
    element: str | None = typer.Option(None, help="Elements, e.g. P1,P2 [default: the "
                                          "case's element]."),
    slip_angle: str | None = typer.Option(None, "--slip-angle", help="3D bodies: slip "
                                          "angles in degrees, A:B[:N] (N points, ends "
                                          "included, default 13) or v1,v2,...; each also "
                                          "gives alpha at angle + 180, and two directions or "
                                          "more locate the body's coefficient, the minimum "
                                          "over directions [default: the case's "
                                          "[solve] slip_angle, no minimum]."),
    grading: float | None = typer.Option(None, help="Meshes graded at every singular "
                                            "point (contact ends, state junctions, corners "
                                            "where the condition changes, re-entrant "
                                            "corners): size g*h there, g in (0, 1]; 1: "
                                            f"uniform [default: {SWEEP_GRADING:g} with three "
                                            "sizes or more, else the case's]."),
    count: int | None = typer.Option(None, help="Lowest coefficients stored per family."),
    quantity: str = typer.Option("critical", help="What each point computes: critical (the "
                                 "static coefficients of `solve`) or flutter (the flutter "
                                 "thresholds of `stability`, each sliding direction)."),
    jobs: int | None = typer.Option(None, "--jobs", "-j", min=1, help="Worker processes "
                                       "[default: all cores]."),
    scheduler: str | None = typer.Option(None, help="Run on this Dask scheduler "
                                            "(e.g. tcp://host:8786) instead."),
    output: Path | None = typer.Option(None, "--output", "-o", help="Sweep file "
                                          "[default: <case name>_sweep_<digest of case and grid>.h5]."),
    force: bool = typer.Option(False, "--force", help="Discard an existing sweep file written "
                               "for another case or grid."),
    as_json: bool = typer.Option(False, "--json", help="Print only a JSON summary on stdout."),
    plot: bool = typer.Option(False, "--plot", help="Also write the figures (PNG)."),
    max_dofs: MaxDofs = None,
    trust_geo: TrustGeo = False,
) -> None:
    """Sweep nu, mesh size, element and (3D) slip angle; resumable; h -> 0 limits with error
    estimates; over slip angles, the minimum over directions."""
    with reported("every finished point is kept in the sweep file; run the same command "
                  "again to compute only the rest"):
        from ..plots.figures import NothingToDraw, plot_file
        from ..sweep.runner import default_output as sweep_output
        from ..sweep.runner import make_grid, report_sweep, run_sweep
        from .progress import progress_bar

        loaded = load_case(case or "unit-square",
                           overrides={"mesh.grading": grading, "solve.count": count})
        grid = make_grid(loaded, nu=nu, size=size, element=element, max_dofs=max_dofs,
                         trust_geo=trust_geo, quantity=quantity, slip_angle=slip_angle)
        for note in grid.notes:
            say(f"critfric: note: {note}")
        out = output or sweep_output(loaded, grid)
        with interrupt_guard() as interrupted, output_lock(out), \
                progress_bar(enabled=not as_json and verbosity() > 0,
                             terminal=sys.stderr.isatty()) as on_point:

            def point_done(row, done, total):  # after each point written: honour Ctrl-C
                on_point(row, done, total)
                interrupted.check()

            result = run_sweep(loaded, grid, output=out, jobs=jobs, scheduler=scheduler,
                               force=force, on_point=point_done, max_dofs=max_dofs,
                               trust_geo=trust_geo)
        typer.echo(json.dumps(result.summary()) if as_json else report_sweep(result))
        say(f"wrote {out}")
        try:
            for png in plot_file(result.path) if plot else []:
                say(f"wrote {png}")
        except NothingToDraw as exc:  # every point failed: the report said why
            say(f"critfric: note: no figure: {exc}")
        if result.failed:  # a batch job must see it: exit 1, every point kept in the file
            raise SolverError(f"{result.failed} of {len(result.rows)} points failed (the "
                              f"status of each says why); {out} keeps every point: run the "
                              "sweep again with other settings for those")


@app.command(epilog="\b\nExamples:\n  critfric plot fig5.h5\n  critfric plot inclined_body.h5 --format png,pdf")
def plot(
    file: Path = typer.Argument(..., help="A sweep or solve file."),
    nu: float | None = typer.Option(None, help="Sweep: the nu of the convergence figure "
                                       "[default: the middle one]."),
    fmt: str = typer.Option("png", "--format", help="Comma list of png, pdf, svg."),
) -> None:
    """Write the figures of a sweep or solve file next to it (PNG by default)."""
    with reported("the figures already written are kept"):
        from ..plots.figures import plot_file

        formats = tuple(f.strip() for f in fmt.split(",") if f.strip())
        for figure in plot_file(file, nu=nu, formats=formats):
            typer.echo(str(figure))


@app.command(epilog="\b\nExamples:\n  critfric export inclined_body.h5\n  critfric export inclined_body.h5 --format vtu -o modes.vtu")
def export(
    file: Path = typer.Argument(..., help="A solve file."),
    fmt: str = typer.Option("xdmf", "--format", help="xdmf or vtu."),
    output: Path | None = typer.Option(None, "--output", "-o", help="Output file "
                                          "[default: <file>_modes.<format>]."),
    force: bool = typer.Option(False, "--force", help="Overwrite an existing export."),
) -> None:
    """Export the mesh and the critical modes (Phi, stress, von Mises) for ParaView."""
    with reported():
        from ..files.export import export_file

        typer.echo(str(export_file(file, fmt=fmt, output=output, force=force)))


@app.command(epilog="\b\nExamples:\n  critfric solutions one-triangle --friction 1:3:11")
def solutions(
    case: str = typer.Argument(..., help="Case file or shipped case name; its [load] is used."),
    friction: str = typer.Option(..., "--friction", help="Friction values: a:b:N (N values "
                                 "from a to b) or one value."),
    nu: float | None = typer.Option(None, help="Poisson ratio, overrides [material] nu [default: the case's]."),
    as_json: bool = typer.Option(False, "--json", help="Print only a JSON list on stdout."),
    plot: Path | None = typer.Option(None, "--plot", help="PNG of the bifurcation diagram "
                                        "[default: <case name>_solutions.png]."),
    no_plot: bool = typer.Option(False, "--no-plot", help="Write no PNG."),
) -> None:
    """Every solution of the static Coulomb problem (2.8) of a small case (p <= 8 contact
    nodes), by enumeration, over a range of friction values."""
    with reported():
        from ..multiplicity.enumeration import parse_frictions, report_solutions, solutions_of_case
        from ..plots.saving import check_figure_paths
        from ..plots.static import default_plot, solutions_plot

        loaded = load_case(case, overrides={"material.nu": nu})
        png = None if no_plot else plot or default_plot(loaded, "solutions")
        check_figure_paths([png] if png else [], inputs=loaded.inputs(), key="--plot")
        sweep = solutions_of_case(loaded, parse_frictions(friction))
        if png:
            solutions_plot(sweep, png, title=loaded.title or "")
        typer.echo(json.dumps([e.to_json() for e in sweep]) if as_json
                   else report_solutions(sweep))
        if png:
            say(f"wrote {png}")


@app.command(epilog="\b\nExamples:\n  critfric verify inclined-body\n  critfric verify unit-square --element P2 --json")
def verify(
    case: str = typer.Argument(..., help="Case file or shipped case name."),
    nu: float | None = typer.Option(None, help="Poisson ratio, overrides [material] nu [default: the case's]."),
    element: str | None = typer.Option(None, help="Element: " + ", ".join(NAMES) + " [default: the case's]."),
    size: float | None = typer.Option(None, help="Target mesh size h [default: the case's]."),
    off: float = typer.Option(0.01, help="Counter-check at friction * (1 -/+ off)."),
    as_json: bool = typer.Option(False, "--json", help="Print only a JSON summary on stdout."),
    plot: Path | None = typer.Option(None, "--plot", help="PNG of the branch "
                                        "[default: <case name>_verify.png]."),
    no_plot: bool = typer.Option(False, "--no-plot", help="Write no PNG."),
) -> None:
    """Check the explicit non-uniqueness example of section 5 at the critical coefficient:
    a whole branch u + delta Phi of solutions. Exit code 1 if the check fails."""
    given = {"nu": nu, "element": element, "size": size}
    with reported():
        from ..multiplicity.verify import report_verification
        from ..multiplicity.verify import verify as run_verify
        from ..plots.saving import check_figure_paths
        from ..plots.static import branch_plot, default_plot

        loaded = load_case(case, overrides={OVERRIDES[k]: v for k, v in given.items()})
        png = None if no_plot else plot or default_plot(loaded, "verify")
        check_figure_paths([png] if png else [], inputs=loaded.inputs(), key="--plot")
        result = run_verify(loaded, off=off)
        if png:
            branch_plot(result, png)
        typer.echo(json.dumps(result.summary()) if as_json else report_verification(result))
        if png:
            say(f"wrote {png}")
    if not result.passed:
        raise typer.Exit(1)


from . import pathcmd  # noqa: F401 -- registers `critfric path` (in its own module)


def version_callback(value: bool) -> None:
    if value:
        typer.echo(f"critfric {__version__}")
        raise typer.Exit()


@app.callback()
def main_callback(
    version: bool = typer.Option(False, "--version", callback=version_callback,
                                 is_eager=True, help="Print the version and exit."),
    quiet: bool = typer.Option(False, "--quiet", "-q", help="Print only errors on stderr "
                               "(no notes, progress or names of written files)."),
    verbose: bool = typer.Option(False, "--verbose", "-v", help="Also print the time of "
                                 "each stage and how the eigen search went."),
) -> None:
    """critfric: critical friction coefficients (Hassani, Hild, Ionescu, Sakki 2003)."""
    set_verbosity(0 if quiet else 2 if verbose else 1)
