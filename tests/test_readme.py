"""The README as a tested document: every `critfric` command of its shell blocks runs, in
order, in a fresh directory, and every Python block runs. Lines that ask for fine meshes or
long ranges run coarser unless CRITFRIC_README_FULL=1."""

from __future__ import annotations

import os
import re
import shutil
import sys
from pathlib import Path

import pytest
from helpers import REPO, run_line

README = (REPO / "README.md").read_text()
FULL = os.environ.get("CRITFRIC_README_FULL") == "1"
QUICKER = {"--size 0.1,0.05,0.025,0.0125": "--size 0.2,0.1,0.05",
           "stability unit-square --size 0.05": "stability unit-square --size 0.125",
           "sweep box --slip-angle 0:180:13": "sweep box --slip-angle 0:180:4 --size 0.3 "
                                              "--element P1"}
#: the main jobs the README shows, one command at least each: short, but every kind of work
JOBS = {"solve", "sweep", "stability", "solutions", "verify", "path", "table"}


def _blocks(language: str) -> list[str]:
    return re.findall(rf"```{language}\n(.*?)```", README, flags=re.DOTALL)


def _commands() -> list[str]:
    lines = [line.split("  #")[0].strip() for block in _blocks("sh")
             for line in block.splitlines()]
    return [line for line in lines if line.startswith("critfric ")]


@pytest.fixture(scope="module")
def workdir(tmp_path_factory):
    work = tmp_path_factory.mktemp("readme")
    shutil.copytree(REPO / "cases", work / "cases")
    return work


def test_the_readme_has_commands_and_code():
    commands = _commands()
    assert 5 <= len(commands) <= 10 and _blocks("python")
    assert JOBS <= {c.split()[1] for c in commands}
    assert any(c.startswith("critfric sweep box --slip-angle") and "--plot" in c
               for c in commands), "a 3D example with its polar figure"
    assert any("--size" in c and len(c.split("--size")[1].split()[0].split(",")) >= 3
               for c in commands if c.startswith("critfric sweep")), "a sweep with h -> 0 limits"
    for long in QUICKER:  # every shortcut still matches a line it is meant for
        assert any(long in c for c in commands), long


def test_the_readme_is_short_and_says_where_the_rest_is():
    lines = README.splitlines()
    assert len(lines) <= 150
    for needed in ("make demo", "make test", "make docs", "docs/_build/html",
                   "Hassani", "4517-4531", "as root or as an ordinary user"):
        assert needed in README, needed


@pytest.mark.once
@pytest.mark.slow
def test_every_readme_command_runs_in_order(workdir):
    """Each line as pasted into a shell with CRITFRIC_README_FULL=1; otherwise in this process
    (typer's CliRunner, the globs expanded as bash would: a start-up saved per line)."""
    env = {**os.environ, "PATH": f"{Path(sys.executable).parent}{os.pathsep}"
           f"{os.environ.get('PATH', '')}", "PYTHONPATH": str(REPO)}
    for command in _commands():
        if not FULL:
            for long, short in QUICKER.items():
                command = command.replace(long, short)
        status, stderr = run_line(command, workdir, env, shell=FULL)
        assert status == 0, f"{command}\n{stderr[-2000:]}"
        assert "Traceback" not in stderr


def test_every_readme_python_block_runs(workdir, monkeypatch):
    monkeypatch.chdir(workdir)
    for block in _blocks("python"):
        exec(compile(block, "README.md", "exec"), {})
