"""The manual: its generated references say what the code does (every case-file key with its
default, every command and option with the text of ``--help``), it builds without a warning
where Sphinx is installed (``make docs``), and the README stays short."""

from __future__ import annotations

import importlib.util
import os
import re
import shutil
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest
from helpers import REPO

pytestmark = pytest.mark.once  # the same on both installs: run by `make test` only

sys.path.insert(0, str(REPO / "docs" / "_ext"))
import critfric_refs as refs

from critfric.case import checks
from critfric.case.schema import OVERRIDES, SCHEMA, SHAPE_KEYS, TOP_LEVEL


def _sections(markdown: str) -> dict[str, str]:
    """The text under each ``## `` heading of a generated page, by heading."""
    parts = re.split(r"^## (.+)$", markdown, flags=re.MULTILINE)
    return {head.strip(): body for head, body in zip(parts[1::2], parts[2::2])}


def _row(body: str, first_cell: str) -> list[str]:
    """The cells of the table row whose first cell is ``first_cell`` (a Markdown table; a
    ``\\|`` inside a cell is text)."""
    for line in body.splitlines():
        cells = [c.strip() for c in re.split(r"(?<!\\)\|", line)[1:-1]]
        if cells and cells[0] == first_cell:
            return cells
    raise AssertionError(f"no row {first_cell} in\n{body}")


# ----------------------------------------------------------------------------- case files


@pytest.fixture(scope="module")
def case_page() -> dict[str, str]:
    return _sections(refs.case_file_markdown())


def test_the_case_file_reference_has_every_key_with_its_default(case_page):
    for section, keys in [("", TOP_LEVEL), *SCHEMA.items()]:
        body = case_page["Top level" if not section else f"`[{section}]`"]
        for key, spec in keys.items():
            _, kind, default, allowed, meaning, option = _row(body, f"`{key}`")
            if spec.default is checks.REQUIRED:
                assert default == "*required*", (section, key)
            elif spec.default is None:
                assert default == "*unset*", (section, key)
            else:  # the cell is TOML that reads back as the schema's default
                assert tomllib.loads(f"v = {default.strip('`')}")["v"] == spec.default
            assert kind and allowed and re.sub(r"\\(.)", r"\1", meaning) == spec.doc
            dotted = f"{section}.{key}"
            cli = [name for name, target in OVERRIDES.items() if target == dotted]
            if cli:
                assert option.startswith("`--" + cli[0].replace("_", "-")), (dotted, option)


def test_the_case_file_reference_says_which_keys_each_shape_takes(case_page):
    body = case_page["`[geometry]`"].split("Which keys each")[1]
    for shape, keys in SHAPE_KEYS.items():
        cells = _row(body, f"`{shape}`")
        assert all(f"`{k}`" in cells[1] for k in keys), shape


def test_the_case_file_reference_shows_allowed_values_in_the_checks_words(case_page):
    cells = _row(case_page["`[material]`"], "`nu`")
    assert cells[3] == "a finite number in \\[0, 0.5)"
    cells = _row(case_page["`[mesh]`"], "`element`")
    assert all(e in cells[3] for e in ("'P1'", "'P2'", "'Q1'", "'Q2'"))


def test_every_schema_check_has_a_toml_type_and_every_section_a_text():
    for keys in [TOP_LEVEL, *SCHEMA.values()]:
        for spec in keys.values():
            assert refs.check_type(spec.check)
    assert set(SCHEMA) <= set(refs.SECTIONS)


def test_markdown_escaping_keeps_code_and_hides_markup():
    assert refs.md_escape("size g*h, <case name>.h5, `critfric solve`, $x$") == \
        "size g\\*h, \\<case name\\>.h5, `critfric solve`, \\$x\\$"


# ----------------------------------------------------------------------------- commands


@pytest.fixture(scope="module")
def cli_page() -> tuple[str, dict[str, str]]:
    text = refs.cli_markdown()
    return text, _sections(text)


def test_the_command_reference_covers_every_command_and_option(cli_page):
    _, sections = cli_page
    group, root, commands = refs._contexts()
    assert [name for name, _, _ in commands] == group.list_commands(root)
    for name, command, ctx in commands:
        body = sections[f"`critfric {name}`"]
        for param in command.get_params(ctx):
            for opt in param.opts + param.secondary_opts:
                assert re.search(rf"\| `[^`|]*{re.escape(opt)}\b", body), (name, opt)
        assert command.get_help(ctx) in body  # the verbatim help text
    for param in group.get_params(root):
        assert all(opt in sections["`critfric`"] for opt in param.opts)


def test_the_command_reference_is_what_help_prints(cli_page):
    from typer.testing import CliRunner

    from critfric.cli.app import app

    text, _ = cli_page
    group, root, commands = refs._contexts()
    for name, _, _ in commands:
        shown = CliRunner().invoke(app, [name, "--help"], prog_name="critfric",
                                   terminal_width=refs.HELP_WIDTH)
        assert shown.exit_code == 0 and shown.output.rstrip("\n") == refs.help_text(name)
        assert f"```text\n{shown.output.rstrip()}\n```" in text
    # the installed command itself, on a wide terminal, prints the same text
    exe = Path(sys.executable).parent / "critfric"
    if not exe.exists() and shutil.which("critfric") is None:
        pytest.skip("no installed critfric command")
    exe = str(exe) if exe.exists() else shutil.which("critfric")
    env = {**os.environ, "COLUMNS": "200"}
    for args, name in (([], None), (["sweep"], "sweep")):
        out = subprocess.run([exe, *args, "--help"], capture_output=True, text=True, env=env,
                             timeout=60)
        assert out.returncode == 0 and out.stdout.rstrip("\n") == refs.help_text(name)


def test_the_generated_pages_are_written_only_when_they_change(tmp_path):
    first = refs.write_generated(tmp_path)
    assert sorted(p.name for p in first) == sorted(refs.PAGES)
    assert refs.write_generated(tmp_path) == []


# ----------------------------------------------------------------------------- validation


def test_make_validate_writes_its_table_between_the_markers(tmp_path):
    spec = importlib.util.spec_from_file_location("validate", REPO / "scripts" / "validate.py")
    validate = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(validate)
    page = tmp_path / "validation.md"
    page.write_text(f"# V\n\n{validate.BEGIN}\nold\n{validate.END}\n\nafter\n")
    validate.write_docs(page, "| a |\n|---|\n| 1 |", 0, 12.0)
    text = page.read_text()
    assert "old" not in text and "| 1 |" in text and text.endswith(f"{validate.END}\n\nafter\n")
    real = (REPO / "docs" / "validation.md").read_text()
    assert real.count(validate.BEGIN) == 1 and real.count(validate.END) == 1
    page.write_text("no markers\n")
    with pytest.raises(SystemExit):
        validate.check_docs(page)


# ----------------------------------------------------------------------------- the README

HASH = re.compile(r"\b(?=[0-9a-f]*[a-f])(?=[0-9a-f]*[0-9])[0-9a-f]{7,40}\b")


def _project_pages() -> list[Path]:
    """The README and the manual's pages as written (not what a build generates)."""
    built = {"_build", "_generated", "auto_examples"}
    return [REPO / "README.md", *sorted(p for p in (REPO / "docs").rglob("*.md")
                                        if not built & set(p.relative_to(REPO).parts))]


def test_the_readme_is_short():
    lines = (REPO / "README.md").read_text().splitlines()
    assert len(lines) <= 160, f"README.md has {len(lines)} lines; the rest belongs in docs/"


@pytest.mark.parametrize("page", _project_pages(), ids=lambda p: str(p.relative_to(REPO)))
def test_no_issue_numbers_sessions_or_commit_hashes_outside_the_changelog(page):
    text = page.read_text()
    for pattern in (r"#\d+\b", r"(?i)\bissues?\s*#?\d+", r"(?i)\bsessions?\b"):
        assert not re.search(pattern, text), (page, re.search(pattern, text).group())
    assert not HASH.search(text), (page, HASH.search(text).group())


# ----------------------------------------------------------------------------- the build

SPHINX = all(importlib.util.find_spec(m) for m in
             ("sphinx", "myst_parser", "sphinx_gallery", "pydata_sphinx_theme"))


@pytest.mark.slow
@pytest.mark.skipif(not SPHINX, reason="the docs extra is not installed (make docs installs it "
                    "and builds the manual)")
def test_the_manual_builds_without_a_warning(tmp_path):
    proc = subprocess.run(
        [sys.executable, "-m", "sphinx", "-W", "--keep-going", "-q", "-b", "html",
         "-d", str(tmp_path / "doctrees"), str(REPO / "docs"), str(tmp_path / "html")],
        capture_output=True, text=True, timeout=1800, cwd=REPO)
    assert proc.returncode == 0, proc.stderr[-4000:]
    for page in ("index", "reference/case-file", "reference/cli", "reference/api", "method"):
        assert (tmp_path / "html" / f"{page}.html").is_file(), page
