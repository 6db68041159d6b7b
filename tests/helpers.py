"""Shared test helpers: in-code cases and closed forms from the paper."""

from __future__ import annotations

import glob
import math
import os
import shlex
import signal
import subprocess
import sys
import time
import traceback
from pathlib import Path

import numpy as np

from critfric.fem.assembly import lame

REPO = Path(__file__).resolve().parents[1]
CASES = REPO / "cases"

# a gmsh .geo script of the unit square with the named groups critfric needs
SQUARE_GEO = """\
Point(1) = {0, 0, 0, 0.5}; Point(2) = {1, 0, 0, 0.5};
Point(3) = {1, 1, 0, 0.5}; Point(4) = {0, 1, 0, 0.5};
Line(1) = {1, 2}; Line(2) = {2, 3}; Line(3) = {3, 4}; Line(4) = {4, 1};
Curve Loop(1) = {1, 2, 3, 4}; Plane Surface(1) = {1};
Physical Curve("bottom") = {1}; Physical Curve("top") = {3};
Physical Surface("domain") = {1};
"""


def resume_exactly_once(out, grid_nu: str, total: int, kept: int):
    """Re-run the unit-square sweep of ``grid_nu`` into ``out`` (interrupted with ``kept``
    points): only the missing points are computed and every point is there exactly once."""
    import critfric
    from critfric.files.sweepfile import read_sweep
    from critfric.sweep.runner import make_grid, run_sweep

    case = critfric.load_case("unit-square")
    grid = make_grid(case, nu=grid_nu, size="0.025", element="P1")
    resumed = run_sweep(case, grid, output=out, jobs=1)
    assert resumed.computed == total - kept
    keys = [(r["element"], r["size"], r["nu"]) for r in read_sweep(out)["rows"]]
    assert len(keys) == len(set(keys)) == total
    return case, grid, resumed, keys


def four_triangles_alpha(nu: float) -> float:
    """Paper, section 4.2: the positive critical coefficient of Fig. 3."""
    return math.sqrt((1 - nu) * (5 - 8 * nu) / (nu * (3 - 4 * nu)))


def one_triangle_alpha(nu: float) -> float:
    """Paper, section 4.1: 3 - 4 nu."""
    return 3.0 - 4.0 * nu


def paper_one_triangle_K(nu: float, E: float = 1.0) -> np.ndarray:
    lam, G = lame(E, nu)
    return 0.5 * np.array([[lam + 3 * G, lam + G], [lam + G, lam + 3 * G]])


def square_case(*, element="P1", size=0.25, nu=0.3, method="auto", structured=False,
                extra="") -> str:
    return f"""
[geometry]
shape = "square"
[material]
nu = {nu}
[mesh]
element = "{element}"
size = {size}
structured = {str(structured).lower()}
[solve]
method = "{method}"
{extra}
"""


def box_case(*, element="P1", size=0.3, depth=1.0, extra="") -> str:
    """A box [0, 1] x [0, 0.5] x [0, depth] resting on its face y0, clamped on y1 (3D)."""
    return f"""
title = "box on a plane"
[geometry]
shape = "box"
size = [1.0, 0.5, {depth}]
[boundary]
contact = ["y0"]
dirichlet = ["y1"]
[mesh]
element = "{element}"
size = {size}
{extra}
"""


def case_pencil(case, state=None):
    """The sliding pencil of a case's mesh at nu = 0.3 (E = density = 1): of ``state``, or
    of every contact node slipping."""
    from critfric.fem.assembly import assemble_mass
    from critfric.solve import prepare
    from critfric.solvers.eigen import ContactState
    from critfric.stability import sliding_pencil

    prep = prepare(case)
    K = prep.system.stiffness(*lame(1.0, 0.3))
    M = prep.system.restrict(assemble_mass(prep.mesh))
    if callable(state):
        state = state(prep.system)
    return sliding_pencil(prep.system, K, M,
                          state or ContactState.all_slipping(prep.system.n_contact))


def run_cli(*args, cwd: Path | None = None):
    """``critfric ARGS`` in this process (typer's CliRunner); every argument str()-ed; in the
    working directory ``cwd`` if given (the former one restored after)."""
    from typer.testing import CliRunner

    from critfric.cli.app import app

    here = os.getcwd()
    if cwd is not None:
        os.chdir(cwd)
    try:
        return CliRunner().invoke(app, [str(a) for a in args])
    finally:
        os.chdir(here)


def run_python(code: str, timeout: float = 120) -> subprocess.CompletedProcess:
    """``code`` run by this interpreter in a fresh process (its own signals, its own MKL)."""
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          check=False, timeout=timeout)


def run_line(command: str, work: Path, env: dict, *, shell: bool = False) -> tuple[int, str]:
    """Run one shell line in ``work``: a `critfric` line in this process (typer's CliRunner;
    a start-up of the command saved per line) with its `> file` redirection and its globs,
    anything else (every line with ``shell``: as pasted) in bash. Its exit code and its
    stderr (with a traceback if one escaped)."""
    if shell or not command.startswith("critfric "):
        proc = subprocess.run(["bash", "-c", command], cwd=work, env=env, text=True,
                              capture_output=True, timeout=300, check=False)
        return proc.returncode, proc.stderr
    command, _, target = command.partition(" > ")
    args = []
    for word in shlex.split(command)[1:]:
        found = sorted(glob.glob(word, root_dir=work)) if any(c in word for c in "*?[") else []
        args += found or [word]
    result = run_cli(*args, cwd=work)
    if target:
        (work / target.strip()).write_text(result.stdout)
    error = result.stderr
    if result.exception is not None and not isinstance(result.exception, SystemExit):
        error += "".join(traceback.format_exception(result.exception))
    return result.exit_code, error


def cli_process(*args, stdout=subprocess.PIPE, **env) -> subprocess.Popen:
    """``python -m critfric ARGS`` in a child process with Ctrl-C at its default action
    (so a test can interrupt it), this checkout first on the path, ``env`` added."""
    env = dict(os.environ, PYTHONPATH=str(REPO), **env)
    return subprocess.Popen([sys.executable, "-m", "critfric", *map(str, args)], env=env,
                            stdout=stdout, stderr=subprocess.PIPE, text=True,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))


FILE_CASE = """[geometry]
shape = "file"
file = "{file}"
[boundary]
contact = ["bottom"]
dirichlet = ["top"]
"""


def folder_files(folder: Path) -> dict:
    """Every file of ``folder``: name -> bytes (to check that nothing was created or changed)."""
    return {p.name: p.read_bytes() for p in folder.iterdir()}


def run_file_case(folder: Path, name: str, content: str | bytes, *more):
    """``critfric solve`` of a case whose geometry is the file ``name`` (written with
    ``content``) in ``folder``: (result, the folder's files before, seconds)."""
    (folder / name).write_bytes(content.encode() if isinstance(content, str) else content)
    (folder / "case.toml").write_text(FILE_CASE.format(file=name))
    before = folder_files(folder)
    start = time.monotonic()
    res = run_cli("solve", folder / "case.toml", "-o", folder / "out.h5", *more)
    return res, before, time.monotonic() - start


def assert_refused(res, folder: Path, before: dict, *words, code: int = 2) -> None:
    """One ``critfric: error:`` line naming ``words``, exit ``code``, no traceback, and the
    folder as it was."""
    out = res.output
    assert res.exit_code == code, out
    assert out.count("critfric: error:") == 1 and "Traceback" not in out, out
    for w in words:
        assert w in out, (w, out)
    assert folder_files(folder) == before
