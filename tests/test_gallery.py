"""The manual's examples as tests: every gallery script (docs/gallery/plot_*.py) runs, in a
child process with matplotlib's Agg backend in an empty directory, draws its figures and writes
nothing there; every page of the getting-started guide and of the user guide (docs/guide/)
runs in document order, in a fresh directory holding a copy of cases/: its ```python blocks
(one namespace per page), the `critfric` lines (in this process, through typer's CliRunner,
with their `> file` and globs) and `gmsh` lines of its ```sh blocks, and its ```{code-block}
blocks captioned with a file name, which are written to that file first. Lines that ask for
fine meshes or long ranges run coarser (QUICKER; small sweeps with -j 1) unless
CRITFRIC_DOCS_FULL=1; lines that show a refusal must end with their exit code in EXIT."""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from helpers import REPO, run_line

pytestmark = pytest.mark.once  # the same on both installs: run by `make test` only

DOCS = REPO / "docs"
PAGES = [DOCS / "getting-started.md", *sorted((DOCS / "guide").glob("*.md"))]
SCRIPTS = sorted((DOCS / "gallery").glob("plot_*.py"))
FULL = os.environ.get("CRITFRIC_DOCS_FULL") == "1"
RUN = ("critfric ", "gmsh ")  # the shell lines that run; others (pip, make, dask) are shown only
SCHEDULER = "tcp://scheduler-host:8786"  # the pages' Dask address: a local cluster in the test

#: page -> {text as written: what runs instead}, for lines of fine meshes or long ranges
QUICKER = {
    "01-paper-figures.md": {
        "--nu 0:0.5:26": "--nu 0:0.5:4",
        "--nu 0:0.5:21": "--nu 0:0.5:3 --size 0.1",
        "--size 0.1,0.05,0.025,0.0125 --element P1,P2,Q1,Q2": "--size 0.2,0.1,0.05 --element P1,Q2",
        "inclined-body --plot": "inclined-body --size 0.1 --plot",
    },
    "03-convergence.md": {"--size 0.1,0.05,0.025,0.0125": "--size 0.2,0.1,0.05",
                       '"0.1,0.05,0.025,0.0125"': '"0.2,0.1,0.05"'},
    "05-contact-states.md": {"--size 0.1,0.05,0.025,0.0125": "--size 0.2,0.1,0.05"},
    "08-3d.md": {
        "sweep box --slip-angle 0:180:13 --plot": "sweep box --slip-angle 0:180:4 --size 0.3 "
                                                 "--element P1 --plot",
        "sweep box --size 0.2,0.1,0.05 --element P2": "sweep box --size 0.4,0.3,0.2 --element P1",
        "solve box --plot": "solve box --size 0.3 --element P1 --plot",
        "solve box --slip-angle 45": "solve box --size 0.3 --element P1 --slip-angle 45",
        '"mesh.size": 0.1': '"mesh.size": 0.3',
    },
    "09-flutter.md": {"--size 0.05": "--size 0.125", '"mesh.size": 0.05': '"mesh.size": 0.125',
                   "--size 0.1,0.05,0.025 --element Q1": "--size 0.25 --element Q1"},
    "02-sweeps.md": {"--nu 0:0.5:21": "--nu 0:0.5:5"},
    "10-dask.md": {"--nu 0:0.5:51": "--nu 0:0.5:5"},
}
#: page -> {line: exit code}, for the lines that show a refusal or a failure
EXIT = {
    "04-geometries.md": {"critfric solve risky.toml": 2,
                      "critfric solve unit-square --size 0.002 --max-dofs 100000": 2},
    "12-batch.md": {"critfric solve unit-square --nu 0.5": 2,
                 "critfric solve missing.toml": 2},
}


# ------------------------------------------------------------------------------ the pages
def steps(text: str) -> list[tuple[str, str, str]]:
    """(kind, info, body) of each fenced block, in document order: kind is the language, or
    the directive's language for ```{code-block} LANG, with info its :caption: (else "")."""
    out, lines, i = [], text.splitlines(), 0
    while i < len(lines):
        opening = re.match(r"^(`{3,})\s*(\S*)\s*(.*)$", lines[i])
        if not opening:
            i += 1
            continue
        fence, kind, rest = opening.groups()
        body, i = [], i + 1
        while i < len(lines) and not re.match(rf"^{fence}\s*$", lines[i]):
            body.append(lines[i])
            i += 1
        i += 1
        info = ""
        if kind == "{code-block}":
            kind = rest.strip()
            while body and body[0].startswith(":"):
                option = re.match(r"^:caption:\s*(\S+)\s*$", body.pop(0))
                info = option.group(1) if option else info
        out.append((kind, info, "\n".join(body) + "\n"))
    return out


def shell_lines(body: str) -> list[str]:
    lines = [line.split("  #")[0].strip() for line in body.splitlines()]
    return [line for line in lines if line.startswith(RUN)]


def _quicker(page: str, text: str) -> str:
    if not FULL:
        for long, short in QUICKER.get(page, {}).items():
            text = text.replace(long, short)
        if text.startswith("critfric sweep") and not re.search(r" (-j|--jobs|--scheduler) ",
                                                                f"{text} "):
            text = text.replace("critfric sweep", "critfric sweep -j 1", 1)  # no worker start-up
    return text


def run_page(page: Path, work: Path, scheduler: str | None = None) -> None:
    """Run ``page``'s blocks in order in ``work``; fail with the block or line that broke."""
    import matplotlib

    matplotlib.use("Agg")
    env = {**os.environ, "PYTHONPATH": str(REPO), "MPLBACKEND": "Agg"}
    namespace: dict = {"__name__": "__main__"}
    name, expected = page.name, EXIT.get(page.name, {})
    for kind, info, body in steps(page.read_text()):
        if info and "." in info and "/" not in info:  # a file shown on the page: write it
            (work / info).write_text(body)
        elif kind == "python":
            code = _quicker(name, body)
            if scheduler:
                code = code.replace(SCHEDULER, scheduler)
            exec(compile(code, f"{page.name} (python block)", "exec"), namespace)
        elif kind == "sh":
            for line in shell_lines(body):
                command = _quicker(name, line)
                if scheduler:
                    command = command.replace(SCHEDULER, scheduler)
                status, stderr = run_line(command, work, env)
                want = expected.get(line, 0)
                assert status == want, f"{page.name}: {command}\nexit {status}, not {want}\n" \
                                       f"{stderr[-3000:]}"
                assert "Traceback" not in stderr, f"{page.name}: {command}\n{stderr[-3000:]}"


def _workdir(tmp_path: Path) -> Path:
    shutil.copytree(REPO / "cases", tmp_path / "cases")
    return tmp_path


SLOW_PAGES = {"01-paper-figures.md", "getting-started.md", "09-flutter.md", "10-dask.md"}  # 3 s or more


@pytest.mark.parametrize("page", [pytest.param(p, id=p.stem, marks=[pytest.mark.slow]
                                               if p.name in SLOW_PAGES else [])
                                  for p in PAGES])
def test_every_example_of_the_page_runs_in_order(page, tmp_path, monkeypatch):
    work = _workdir(tmp_path)
    monkeypatch.chdir(work)
    monkeypatch.setenv("PATH", f"{Path(sys.executable).parent}{os.pathsep}"
                       f"{os.environ.get('PATH', '')}")  # `critfric` for subprocess calls
    if "--scheduler" not in page.read_text():
        run_page(page, work)
        return
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=True,
                                  host="127.0.0.1", dashboard_address=":0") as cluster:
        run_page(page, work, scheduler=cluster.scheduler_address)


def test_the_pages_run_commands_and_code_and_link_to_pages_that_exist():
    assert len(PAGES) >= 10 and (DOCS / "getting-started.md").is_file()
    for page in PAGES:
        kinds = [kind for kind, _, _ in steps(page.read_text())]
        assert "python" in kinds or "sh" in kinds, f"{page.name} runs nothing"
        for target in re.findall(r"\]\(([^)#\s]+\.md)(?:#[^)]*)?\)", page.read_text()):
            assert (page.parent / target).resolve().is_file(), f"{page.name}: {target}"
    for page, lines in EXIT.items():  # every expected failure is still on its page
        shown = {line for _, _, body in steps((DOCS / "guide" / page).read_text())
                 for line in shell_lines(body)}
        assert set(lines) <= shown, f"{page}: {set(lines) - shown}"


# ------------------------------------------------------------------------------ the gallery
RUNNER = """
import json, os, runpy, sys, traceback
import matplotlib
matplotlib.use("Agg")
import matplotlib.pyplot as plt
report = {}
for script, work in zip(sys.argv[1::2], sys.argv[2::2]):
    os.chdir(work)
    try:
        runpy.run_path(script, run_name="__main__")
        report[script] = "" if plt.get_fignums() else \\
            "the script drew no figure that sphinx-gallery would keep"
    except BaseException:
        report[script] = traceback.format_exc()
    plt.close("all")
print(json.dumps(report))
"""


@pytest.mark.slow
def test_every_gallery_script_runs_and_draws(tmp_path):
    """One child process runs the scripts one after another, as sphinx-gallery does, each in
    its own empty working directory, which must stay empty."""
    env = {**os.environ, "PYTHONPATH": str(REPO), "MPLBACKEND": "Agg"}
    works = [tmp_path / script.stem for script in SCRIPTS]
    args = []
    for script, work in zip(SCRIPTS, works):
        work.mkdir()
        args += [str(script), str(work)]
    proc = subprocess.run([sys.executable, "-c", RUNNER, *args], cwd=tmp_path, env=env,
                          text=True, capture_output=True, timeout=600, check=False)
    assert proc.returncode == 0, proc.stderr[-3000:]
    report = json.loads(proc.stdout.splitlines()[-1])
    failed = {Path(s).name: error[-3000:] for s, error in report.items() if error}
    assert not failed, failed
    assert sorted(report) == sorted(map(str, SCRIPTS))
    for work in works:
        assert not list(work.iterdir()), "a gallery script must write into a temporary " \
            f"directory only, not its working directory: {list(work.iterdir())}"


def test_the_gallery_has_a_header_and_scripts_in_sphinx_gallery_form():
    header = (DOCS / "gallery" / "GALLERY_HEADER.rst").read_text().splitlines()
    assert header[0].strip() and set(header[1].strip()) == {"="}
    assert 6 <= len(SCRIPTS) <= 10
    for script in SCRIPTS:
        text = script.read_text()
        title = re.match(r'^"""\n(.+)\n(=+)\n\n', text)
        assert title and len(title.group(2)) >= len(title.group(1)), script.name
        assert "# %%" in text, f"{script.name}: no # %% cells"
